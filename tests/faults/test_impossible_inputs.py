"""Legal but impossible inputs refused up front (bringup/scenario/limits.py check_time_range, bringup/scenario/work.py).

Against main 8408404: an epoch after 2038-01-19 passed validation, the whole run simulated, then the
recorder failed on ROS's int32 seconds; ``--sats 1000 --planes 1 --hours 0.001`` built 272,410 ISL
contacts and did not finish 3.6 s of sim time in 300 s, with no estimate and no sign of progress.

Oracles:
* a 2040 epoch, a 1969 epoch and an epoch whose horizon crosses 2038-01-19T03:14:07Z: ``constellation
  run`` exits 2 with one line naming ``scenario.epoch_utc`` (and the horizon when it is the horizon
  that crosses), and no run folder is made (refused before anything is built); 2037 runs;
* 1000 satellites in one plane: refused in one line naming the ISL links in view and ``--force``,
  before the folder or the world exists;
* ``--force`` goes past the limit (the limit lowered for a 6-satellite run, which then completes) and
  the world's build says what stage it is in;
* the links-in-view count equals a brute force over every satellite pair with ``los_clear`` and the
  range limit, at the same instants.
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from bringup.cli.main import main
from bringup.scenario import work
from bringup.scenario.config import load_scenario
from orbit_clock.isl import los_clear
from orbit_clock.propagation import build_constellation
from tests.scenario_edit import raw_scenario, set_key, to_toml

pytestmark = [pytest.mark.faults]

RUN = ["run", "--engine", "local", "--no-plots", "--no-progress"]


def _scenario_with_epoch(tmp_path, epoch: str):
    raw = raw_scenario(load_scenario("paper"))
    set_key(raw, "scenario.epoch_utc", epoch)
    path = tmp_path / "sc.toml"
    path.write_text(to_toml(raw))
    return path


def _one_line(capsys) -> str:
    err = [ln for ln in capsys.readouterr().err.strip().splitlines() if not ln.startswith("run: estimate")]
    assert len(err) == 1 and "Traceback" not in err[0], err
    return err[0]


@pytest.mark.parametrize("epoch, hours, says", [
    ("2040-01-01T00:00:00Z", "1", "is after 2038-01-19T03:14:07Z"),
    ("2038-01-19T00:00:00Z", "6", "plus the horizon (21600 s"),
    ("1969-12-31T00:00:00Z", "1", "before 1970"),
])
def test_epoch_outside_ros_time_is_refused(tmp_path, capsys, epoch, hours, says):
    sc = _scenario_with_epoch(tmp_path, epoch)
    out = tmp_path / "out"
    assert main([*RUN, "--scenario", str(sc), "--sats", "6", "--hours", hours, "--out", str(out)]) == 2
    err = _one_line(capsys)
    assert "scenario.epoch_utc" in err and says in err, err
    assert not out.exists()


def test_epoch_just_inside_ros_time_runs(tmp_path, capsys):
    sc = _scenario_with_epoch(tmp_path, "2037-12-31T00:00:00Z")
    assert main([*RUN, "--scenario", str(sc), "--sats", "6", "--hours", "0.2", "--out", str(tmp_path / "o")]) == 0


def test_thousand_satellites_in_one_plane_refused_up_front(tmp_path, capsys):
    out = tmp_path / "out"
    assert main([*RUN, "--sats", "1000", "--planes", "1", "--hours", "0.001", "--out", str(out)]) == 2
    err = _one_line(capsys)
    assert "ISL links in view" in err and "--force" in err and "1000 satellites in 1 plane" in err, err
    assert not out.exists()


def test_force_goes_past_the_limit_and_the_build_shows_progress(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(work, "LINKS_LIMIT", 1)
    args = [*RUN, "--sats", "6", "--hours", "0.2"]
    assert main([*args, "--out", str(tmp_path / "a")]) == 2
    assert "--force" in _one_line(capsys)
    assert main([*args, "--out", str(tmp_path / "b"), "--force"]) == 0
    err = capsys.readouterr().err
    assert "run: estimate: ~" in err and "(--force)" in err
    for stage in ("access windows", "ISL contact plan", "ground contact plan"):
        assert f"run: building the world: {stage}" in err, err


def test_links_in_view_equals_brute_force():
    sc = load_scenario("paper").with_overrides(sats=40, planes=2, hours=1)
    t = np.array([0.0, 1234.0, 3000.0])
    r = build_constellation(sc).states_ecef(t)[0]
    brute = []
    for k in range(len(t)):
        n = 0
        for i, j in itertools.combinations(range(r.shape[0]), 2):
            a, b = r[i, k], r[j, k]
            if np.linalg.norm(a - b) <= sc.isl.max_range_km and los_clear(a, b, sc.isl.grazing_height_km):
                n += 1
        brute.append(n)
    assert work.links_in_view(sc, t) == pytest.approx(np.mean(brute))
    assert np.mean(brute) > 0
