"""Modes and FDIR rules (sat_node/operations/modes.py), mode notices (notice.py), the per-satellite
state (controller.py) and the report's operations figures (bringup/analysis/report.py).

Oracle: the rule table of modes.py written out here row by row on hand-made telemetry; time in mode
worked by hand; the scenario loader's one-line errors for bad faults.
"""

from __future__ import annotations

import msgspec
import pytest

from bringup.analysis.operations import operations_figures
from bringup.scenario.config import ScenarioError, load_scenario
from bringup.scenario.config import _validate as validate_raw
from msgs_json import schemas as S
from sat_node.operations.controller import Operations
from sat_node.operations.modes import (
    DEGRADED,
    NOMINAL,
    SAFE,
    Fault,
    FaultSchedule,
    Limits,
    Telemetry,
    imaging_allowed,
    mode_for,
)
from sat_node.operations.notice import ModeNotice, decode_notice, encode_notice, is_notice

LIM = Limits(pointing_error_max_deg=5.0, store_max_bundles=10, clock_late_max_s=60.0)


@pytest.mark.parametrize("tm, expected", [
    (Telemetry(), (NOMINAL, "")),
    (Telemetry(acs_fault=True), (SAFE, "acs_fault")),
    (Telemetry(pointing_error_deg=5.01), (SAFE, "pointing_error")),
    (Telemetry(pointing_error_deg=5.0), (NOMINAL, "")),  # the limit itself is within limits
    (Telemetry(commanded_safe=True), (SAFE, "commanded")),
    (Telemetry(instrument_fault=True), (DEGRADED, "instrument_fault")),
    (Telemetry(store_bundles=10), (DEGRADED, "store_full")),
    (Telemetry(store_bundles=9), (NOMINAL, "")),
    (Telemetry(clock_late_s=61.0), (DEGRADED, "clock_late")),
    # precedence: the most severe rule first
    (Telemetry(instrument_fault=True, acs_fault=True, store_bundles=99), (SAFE, "acs_fault")),
    (Telemetry(instrument_fault=True, store_bundles=99), (DEGRADED, "instrument_fault")),
    (Telemetry(commanded_safe=True, instrument_fault=True), (SAFE, "commanded")),
])
def test_rule_table(tm, expected):
    assert mode_for(tm, LIM) == expected


def test_imaging_by_mode_and_reason():
    assert imaging_allowed(NOMINAL, "")
    assert not imaging_allowed(SAFE, "acs_fault")
    assert not imaging_allowed(DEGRADED, "instrument_fault")
    assert imaging_allowed(DEGRADED, "store_full") and imaging_allowed(DEGRADED, "clock_late")


def test_fault_schedule_windows_and_wakeups():
    fs = FaultSchedule([Fault("sat_11", "acs_stuck", 100, 200), Fault("sat_11", "store_full", 150)])
    assert fs.active(99) == frozenset()
    assert fs.active(100) == {"acs_stuck"}
    assert fs.active(199) == {"acs_stuck", "store_full"}
    assert fs.active(200) == {"store_full"}  # until is exclusive
    assert [fs.next_change_ns(t) for t in (0, 100, 150, 200)] == [100, 150, 200, None]
    with pytest.raises(ValueError, match="radio_off"):
        FaultSchedule([Fault("sat_11", "radio_off", 0)])


def test_controller_time_in_mode_and_transitions():
    ops = Operations("sat_11", FaultSchedule([]), LIM)
    assert ops.update(10, Telemetry()) is None
    tr = ops.update(100, Telemetry(acs_fault=True))
    assert (tr.previous, tr.mode, tr.reason) == (NOMINAL, SAFE, "acs_fault") and not ops.imaging
    assert ops.update(150, Telemetry(acs_fault=True)) is None
    tr = ops.update(300, Telemetry())
    assert (tr.previous, tr.mode) == (SAFE, NOMINAL) and ops.imaging
    assert ops.time_in_mode_s(1000) == {NOMINAL: 800e-9, DEGRADED: 0.0, SAFE: 200e-9}


def test_notices_round_trip_and_newest_wins():
    n = ModeNotice("sat_12", SAFE, False, 5)
    blob = encode_notice(n)
    assert is_notice(blob) and decode_notice(blob) == n
    assert not is_notice(b'{"src":"sat_12","gp":1}')  # an inference payload
    for bad, field in ((b'{"notice":"mode","src":"","mode":"SAFE","imaging":false,"t_ns":1}', "src"),
                       (b'{"notice":"mode","src":"sat_12","mode":"OFF","imaging":false,"t_ns":1}', "mode"),
                       (b'{"notice":"mode","src":"sat_12","mode":"SAFE","imaging":0,"t_ns":1}', "imaging"),
                       (b'{"notice":"mode","src":"sat_12","mode":"SAFE","imaging":false,"t_ns":-1}', "t_ns"),
                       (b'{"notice":', "not JSON")):
        with pytest.raises(ValueError, match=field):
            decode_notice(bad)
    ops = Operations("sat_11", FaultSchedule([]), LIM)
    assert ops.learn_notice(n) and ops.peers_not_imaging() == {"sat_12"}
    assert not ops.learn_notice(ModeNotice("sat_12", NOMINAL, True, 4))  # older: ignored
    assert ops.peers_not_imaging() == {"sat_12"}
    assert ops.learn_notice(ModeNotice("sat_12", NOMINAL, True, 6)) and ops.peers_not_imaging() == frozenset()


def test_report_operations_figures_by_hand():
    ch = [S.ModeChange(sat="sat_12", t_ns=600_000_000_000, mode="SAFE", previous="NOMINAL", reason="acs_fault",
                       imaging=False, plan_value_dropped=12.5),
          S.ModeChange(sat="sat_12", t_ns=900_000_000_000, mode="NOMINAL", previous="SAFE")]
    f = operations_figures(ch, 3600.0)["operations"]
    assert operations_figures([], 3600.0) == {}
    assert f["time_in_mode_s"] == {"sat_12": {"NOMINAL": 3300.0, "DEGRADED": 0.0, "SAFE": 300.0}}
    assert f["transitions"] == 2 and f["value_lost_estimate"] == 12.5


def _raw_paper():
    raw = msgspec.to_builtins(load_scenario("paper"))
    raw.pop("source_path", None)
    return raw


@pytest.mark.parametrize("fault, key", [
    ({"sat": "sat_99", "kind": "acs_stuck", "at_s": 10.0}, "faults[0].sat"),
    ({"sat": "sat_11", "kind": "radio_off", "at_s": 10.0}, "faults[0].kind"),
    ({"sat": "sat_11", "kind": "acs_stuck", "at_s": 10.0, "until_s": 5.0}, "faults[0].until_s"),
    ({"sat": "sat_11", "kind": "melted", "at_s": 10.0}, "faults[0].kind"),
])
def test_bad_faults_are_one_line_naming_the_key(fault, key):
    raw = _raw_paper()
    raw["faults"] = [fault]
    with pytest.raises(ScenarioError) as ei:
        validate_raw(raw, "x.toml")
    msg = str(ei.value)
    assert "\n" not in msg and f"'{key}'" in msg
