"""The aeossp case reader (bringup/benchmarks/aeossp/case.py): a tiny case in the benchmark's format
reads into typed objects; each malformed file is one UserError line naming the file and entry."""

from __future__ import annotations

import pytest
import yaml

from bringup.benchmarks.aeossp.case import Action, read_case, read_solution, write_solution
from bringup.errors import UserError
from tests.unit.aeossp_cases import standard


def test_reads_the_tiny_case(tmp_path):
    d, _ = standard(tmp_path / "c")
    c = read_case(d)
    assert c.mission.horizon_s == 3600 and c.mission.action_step_s == 5
    assert [s.sat_id for s in c.satellites] == ["sat_a", "sat_b"]
    assert c.sat("sat_b").sensor == "infrared" and c.sat("sat_a").max_off_nadir_deg == 25.0
    t1 = c.task("t1")
    assert (t1.release_s, t1.due_s, t1.duration_s, t1.weight) == (300, 900, 20, 3.0)


def _edit(d, fname, fn):
    doc = yaml.safe_load((d / fname).read_text())
    fn(doc)
    (d / fname).write_text(yaml.safe_dump(doc))


@pytest.mark.parametrize("fname, edit, words", [
    ("tasks.yaml", lambda d: d["tasks"][1].update(task_id="t1"), "tasks[1] (t1): duplicate task_id"),
    ("tasks.yaml", lambda d: d["tasks"][0].update(due_time=d["tasks"][0]["release_time"]), "due_time is not after"),
    ("tasks.yaml", lambda d: d["tasks"][0].update(required_duration_s=7), "not on the 5-s action grid"),
    ("tasks.yaml", lambda d: d["tasks"][0].update(weight="heavy"), "weight is not a number"),
    ("tasks.yaml", lambda d: d["tasks"][0].update(release_time="noon"), "not an ISO 8601 time"),
    ("satellites.yaml", lambda d: d["satellites"][0].update(tle_line2="2 garbage"), "satellites[0] (sat_a): bad TLE"),
    ("satellites.yaml", lambda d: d["satellites"][1].update(satellite_id="sat_a"), "duplicate satellite_id"),
    ("satellites.yaml", lambda d: d["satellites"][0]["attitude_model"].pop("settling_time_s"),
     "missing settling_time_s"),
    ("mission.yaml", lambda d: d["mission"].update(action_time_step_s=7), "not a multiple of action_time_step_s"),
])
def test_bad_files_are_one_line(tmp_path, fname, edit, words):
    d, _ = standard(tmp_path / "c")
    _edit(d, fname, edit)
    with pytest.raises(UserError) as e:
        read_case(d)
    msg = str(e.value)
    assert words in msg and fname in msg and "\n" not in msg


def test_missing_file_and_bad_yaml(tmp_path):
    d, _ = standard(tmp_path / "c")
    (d / "tasks.yaml").write_text("tasks: [unclosed\n")
    with pytest.raises(UserError, match="tasks.yaml: line .* not valid YAML"):
        read_case(d)
    (d / "tasks.yaml").unlink()
    with pytest.raises(UserError, match="tasks.yaml: no such file"):
        read_case(d)


def test_solution_round_trip_and_bad_references(tmp_path):
    d, _ = standard(tmp_path / "c")
    c = read_case(d)
    acts = [Action("sat_a", "t1", 590, 610), Action("sat_a", "t2", 630, 650)]
    write_solution(tmp_path / "s.json", c, acts)
    assert read_solution(tmp_path / "s.json", c) == acts
    (tmp_path / "bad.json").write_text('{"actions": [{"type": "observation", "satellite_id": "sat_z", '
                                       '"task_id": "t1", "start_time": "x", "end_time": "y"}]}')
    with pytest.raises(UserError, match=r"actions\[0\]: unknown satellite_id 'sat_z'"):
        read_solution(tmp_path / "bad.json", c)
