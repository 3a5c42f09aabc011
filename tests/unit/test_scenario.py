"""Scenario loading: the paper file loads; every field broken in turn gives one clear error."""

from __future__ import annotations

import subprocess
import sys

import pytest
from scenario_edit import bad_value as _bad_value
from scenario_edit import leaves as _leaves
from scenario_edit import raw_scenario as _raw
from scenario_edit import set_key as _set

from bringup.scenario.config import SCENARIO_DIR, ScenarioError, load_scenario, sat_names


def test_paper_scenario_matches_design(paper_scenario):
    sc = paper_scenario
    assert sc.constellation.total_sats == 24 and sc.constellation.planes == 3
    assert sc.constellation.altitude_km == 710.0 and sc.constellation.inclination_deg == 98.5
    assert sc.scenario.horizon_s == 21600.0
    assert sc.sat_names[0] == "sat_11" and sc.sat_names[-1] == "sat_38"
    assert [r.name for r in sc.regions.list] == ["Dhaka", "Sydney", "Dallas", "London", "Rio de Janeiro"]
    assert sc.gp_spacing_km == 4.0 == sc.instrument.footprint_km / 2  # Nyquist: 20 x 20 per region
    assert (sc.isl.ttl_s(1), sc.isl.ttl_s(3), sc.isl.ttl_s(4), sc.isl.ttl_s(15)) == (900, 1800, 3000, 3000)
    assert sc.epoch.isoformat() == "2000-01-01T11:59:28+00:00"


def test_overrides_keep_planes_when_possible(paper_scenario):
    s6 = paper_scenario.with_overrides(sats=6, hours=1, seed=7)
    assert (s6.constellation.total_sats, s6.constellation.planes) == (6, 3)
    assert s6.scenario.horizon_s == 3600.0 and s6.scenario.seed == 7
    s5 = paper_scenario.with_overrides(sats=5)
    assert s5.constellation.total_sats % s5.constellation.planes == 0


def test_sat_names():
    assert sat_names(2, 2) == ["sat_11", "sat_12", "sat_21", "sat_22"]


_KEYS = [k for k, _ in _leaves(_raw(load_scenario("paper")))]


@pytest.mark.parametrize("key", _KEYS)
def test_every_field_wrong_in_turn_gives_one_clear_error(paper_scenario, key):
    from bringup.scenario.config import _validate

    raw = _raw(paper_scenario)
    value = dict(_leaves(raw))[key]
    _set(raw, key, _bad_value(value))
    with pytest.raises(ScenarioError) as exc:
        _validate(raw, "broken.toml")
    msg = str(exc.value)
    assert "\n" not in msg and msg.startswith("broken.toml: ")
    assert key in msg, msg


@pytest.mark.parametrize(
    "key,value,needle",
    [
        ("isl.rate_bps", -1.0, "> 0"),
        ("constellation.total_sats", 25, "split evenly"),
        ("constellation.pattern", "ring", "enum"),
        ("scenario.epoch_utc", "2000-01-01 11:59:28", "ending in 'Z'"),
        ("value.belief_sigma_min", 0.5, "above belief_sigma_max"),
        ("regions.list[0].lat_deg", 91.0, "<= 90"),
        ("isl.ttl_p1_s", 5000.0, "must not shrink"),
        ("isl.forwarding", "flood", "enum"),
    ],
)
def test_out_of_range_values_are_named(paper_scenario, key, value, needle):
    from bringup.scenario.config import _validate

    raw = _raw(paper_scenario)
    _set(raw, key, value)
    with pytest.raises(ScenarioError, match=needle) as exc:
        _validate(raw, "x.toml")
    assert key in str(exc.value)


def test_unknown_key_rejected(paper_scenario):
    from bringup.scenario.config import _validate

    raw = _raw(paper_scenario)
    raw["isl"]["rate_kbps"] = 1
    with pytest.raises(ScenarioError, match="rate_kbps"):
        _validate(raw, "x.toml")


def test_broken_toml_and_missing_file(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text("[scenario\nname=1\n")
    with pytest.raises(ScenarioError, match="not valid TOML"):
        load_scenario(bad)
    with pytest.raises(ScenarioError, match="no such file"):
        load_scenario("no_such_scenario")
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.toml")


def test_cli_prints_one_line_without_traceback(tmp_path):
    bad = tmp_path / "bad.toml"
    bad.write_text((SCENARIO_DIR / "paper.toml").read_text()
                   .replace("rate_bps = 1000.0", "rate_bps = -5.0"))
    r = subprocess.run([sys.executable, "-m", "bringup.cli", "constellation", "--scenario", str(bad)],
                       capture_output=True, text=True, timeout=60)
    assert r.returncode == 2
    assert "Traceback" not in r.stderr
    lines = [ln for ln in r.stderr.splitlines() if ln.strip()]
    assert len(lines) == 1 and "isl.rate_bps" in lines[0], r.stderr


def test_forwarding_override(paper_scenario):
    """``--forwarding`` (run, compare, sweep) sets isl.forwarding; the paper's default is multicast."""
    assert paper_scenario.isl.forwarding == "multicast"
    assert paper_scenario.with_overrides(forwarding="unicast").isl.forwarding == "unicast"
    with pytest.raises(ScenarioError, match="isl.forwarding"):
        paper_scenario.with_overrides(forwarding="flood")
    from bringup.cli.main import build_parser
    from bringup.cli.common import scenario_from_args

    args = build_parser().parse_args(["run", "--forwarding", "unicast", "--hours", "1"])
    assert scenario_from_args(args).isl.forwarding == "unicast"
