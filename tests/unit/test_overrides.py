"""``--set KEY=VALUE`` (bringup/scenario/overrides.py): the same value written into the TOML file is
the oracle; every key given a wrong value is one line naming it; the commands refuse a bad --set
with exit 2 before running anything."""

from __future__ import annotations

import json
import tomllib

import pytest
from scenario_edit import bad_value, leaves, raw_scenario, set_key, to_toml

from bringup.engine.ros.run_spec import RunSpec
from bringup.scenario.config import ScenarioError, load_scenario
from bringup.scenario.overrides import apply_sets, parse_set, parse_value

GOOD = [
    ("isl.rate_bps=250", "isl.rate_bps", 250),
    ("isl.rate_bps=2.5e2", "isl.rate_bps", 250.0),
    ("value.knowledge=region-truth", "value.knowledge", "region-truth"),
    ('value.knowledge="oracle"', "value.knowledge", "oracle"),
    ("scheduler.joint_planning=false", "scheduler.joint_planning", False),
    ("acs.slew_coeffs_s=[1.0, 0.5]", "acs.slew_coeffs_s", [1.0, 0.5]),
    ("regions.list[1].size_km=40", "regions.list[1].size_km", 40),
    ("ground.stations[0].name=Kiruna", "ground.stations[0].name", "Kiruna"),
    ("scheduler.joint_max_partners=2", "scheduler.joint_max_partners", 2),
]


@pytest.mark.parametrize("text,key,value", GOOD, ids=[g[0] for g in GOOD])
def test_set_equals_the_same_value_in_the_file(paper_scenario, tmp_path, text, key, value):
    raw = raw_scenario(paper_scenario)
    set_key(raw, key, value)
    path = tmp_path / "edited.toml"
    path.write_text(to_toml(raw))
    want = raw_scenario(load_scenario(path))
    got = raw_scenario(apply_sets(paper_scenario, [text]))
    assert got == want and got != raw_scenario(paper_scenario)


def test_sets_apply_in_order_and_together(paper_scenario):
    sc = apply_sets(paper_scenario, ["constellation.total_sats=6", "constellation.planes=2", "isl.rate_bps=1",
                                     "isl.rate_bps=8000"])
    assert (sc.constellation.total_sats, sc.constellation.planes, sc.isl.rate_bps) == (6, 2, 8000.0)


def test_values_parse_as_toml_literals():
    for text in ("250", "2.5e2", "true", '"a b"', "[1, 2.5]", '{ x = 1, y = "z" }', "-3", "1_000"):
        assert parse_value(text) == tomllib.loads(f"v = {text}")["v"]
    assert parse_value("observed") == "observed"
    with pytest.raises(ValueError, match="not a TOML value"):
        parse_value("[1, 2")


def test_every_key_with_a_wrong_value_is_one_line_naming_it(paper_scenario):
    n = 0
    for key, v in leaves(raw_scenario(paper_scenario)):
        bad = bad_value(v)
        text = f"{key}={json.dumps(bad)}"
        with pytest.raises(ScenarioError) as e:
            apply_sets(paper_scenario, [text])
        msg = str(e.value)
        assert "\n" not in msg and f"'{key}'" in msg and msg.startswith(f"--set {text}:"), msg
        n += 1
    assert n > 40


@pytest.mark.parametrize("text,named", [
    ("isl.rate_bsp=1", "rate_bsp"),
    ("isl.rate_bps=-5", "isl.rate_bps"),
    ("nosuch.key=1", "nosuch"),
    ("regions.list[9].size_km=1", "index [9]"),
    ("scheduler.dp_step_s=5000", "scheduler.dp_step_s"),  # a cross-field rule: longer than the replan period
    ("isl.rate_bps", "KEY=VALUE"),
    ("=3", "KEY=VALUE"),
    ("isl..rate_bps=3", "not a dotted scenario key"),
    ("isl.rate_bps=[1,", "not a TOML value"),
    ("isl.rate_bps=nan", "finite"),
])
def test_bad_keys_and_values_are_named(paper_scenario, text, named):
    with pytest.raises(ScenarioError) as e:
        apply_sets(paper_scenario, [text])
    assert named in str(e.value) and "\n" not in str(e.value)


def test_parse_set():
    assert parse_set("isl.rate_bps = 250") == ("isl.rate_bps", 250)
    assert parse_set("regions.list[0].name=Oslo") == ("regions.list[0].name", "Oslo")


def test_run_spec_applies_the_sets_as_the_command_line(paper_scenario):
    spec = RunSpec(factory="m:f", roles=["a"], scenario="paper",
                   overrides={"sats": 6, "set": ["isl.rate_bps=250", "value.knowledge=observed"]})
    sc = spec.load_scenario()
    assert (sc.constellation.total_sats, sc.isl.rate_bps, sc.value.knowledge) == (6, 250.0, "observed")


@pytest.mark.parametrize("argv,named", [
    (["run", "--engine", "local", "--set", "isl.rate_bsp=1"], "rate_bsp"),
    (["run", "--engine", "local", "--sats", "6", "--set", "constellation.total_sats=6"], "--sats"),
    (["compare", "--set", "value.knowledge=nosuch"], "value.knowledge"),
    (["sweep", "--set", "isl.rate_bps=abc"], "isl.rate_bps"),
    (["access", "--set", "instrument.footprint_km=0"], "instrument.footprint_km"),
    (["contacts", "--epoch", "now", "--set", "scenario.epoch_utc=2026-01-01T00:00:00Z"], "--epoch sets the same key"),
])
def test_commands_refuse_a_bad_set_in_one_line(tmp_path, capsys, argv, named):
    from bringup.cli.main import main

    assert main(argv + ["--out", str(tmp_path / "out")]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and named in err[0] and "error:" in err[0], err
    assert not (tmp_path / "out").exists()


def test_the_ros_processes_load_the_runs_scenario(tmp_path):
    """The ROS engine's processes rebuild the scenario from the run spec (scenario file + overrides):
    with --set and the named options it is the scenario the command line made."""
    import argparse

    from bringup.cli import run as run_cmd
    from bringup.cli.common import scenario_from_args

    p = argparse.ArgumentParser()
    run_cmd.add_arguments(p)
    args = p.parse_args(["--sats", "6", "--hours", "0.5", "--knowledge", "observed", "--viz-period-s", "30",
                         "--set", "isl.rate_bps=250", "--set", "regions.list[0].size_km=40",
                         "--epoch", "2026-11-27T12:00:00Z"])
    sc = scenario_from_args(args).with_overrides(viz_period_s=args.viz_period_s)
    spec = RunSpec(factory="m:f", roles=["a"], scenario=sc.source_path, overrides=run_cmd.spec_overrides(args))
    back = RunSpec.from_file(_spec_file(tmp_path, spec)).load_scenario()
    assert raw_scenario(back) == raw_scenario(sc) and back.isl.rate_bps == 250.0 and back.viz.period_s == 30.0
    assert back.scenario.epoch_utc == "2026-11-27T12:00:00Z"  # --epoch reaches the processes too


def _spec_file(tmp_path, spec):
    path = tmp_path / "run_spec.json"
    spec.to_file(path)
    return path
