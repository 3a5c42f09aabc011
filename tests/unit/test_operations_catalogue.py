"""The event catalogue and the dictionary (sat_node/operations/catalogue.py, `constellation ops`).

Oracles: the rule table (every reason modes.mode_for gives, found by driving it over one telemetry
per rule), the rejection reasons CommandGuard gives (driven here), msgspec's own inspection of the
schemas for the dictionary's fields.
"""

from __future__ import annotations

import json

import msgspec

from msgs_json import schemas as S
from sat_node.operations.catalogue import EVENTS, MESSAGES, REJECTIONS, RULE_REASONS, dictionary, event_of
from sat_node.operations.commands import SETTABLE
from sat_node.operations.modes import Limits, Telemetry, mode_for


def test_every_rule_reason_and_rejection_has_one_event():
    reasons = {mode_for(tm, Limits(store_max_bundles=1)) for tm in (
        Telemetry(store_bundles=0), Telemetry(acs_fault=True), Telemetry(pointing_error_deg=90.0),
        Telemetry(commanded_safe=True), Telemetry(instrument_fault=True), Telemetry(store_bundles=1),
        Telemetry(clock_late_s=1e6))}
    assert {r for _m, r in reasons} == set(RULE_REASONS)
    for mode, reason in reasons:
        eid, sev, _text = event_of(S.ModeChange(sat="sat_11", t_ns=1, mode=mode, previous="SAFE" if mode == "NOMINAL"
                                                else "NOMINAL", reason=reason))
        assert EVENTS[eid]["mode"] == mode and EVENTS[eid]["reason"] == reason
        assert sev == {"NOMINAL": "informative", "DEGRADED": "medium", "SAFE": "high"}[mode]
    for reason in REJECTIONS:
        eid, _sev, text = event_of(S.CommandEvent(sat="sat_11", t_ns=1, command_id="c9", stage="rejected",
                                                  reason=reason))
        assert EVENTS[eid]["reason"] == reason and text.endswith(f"{reason} c9")
    assert event_of(S.CommandEvent(sat="sat_11", t_ns=1, command_id="c9", stage="executed"))[0] == 2002
    assert len({e["name"] for e in EVENTS.values()}) == len(EVENTS)


def test_the_guard_gives_only_catalogued_reasons():
    import re
    from pathlib import Path

    import sat_node.operations.commands as C
    import sat_node.operations.onboard as O

    src = Path(C.__file__).read_text() + Path(O.__file__).read_text()
    given = set(re.findall(r'CommandRejected\("(\w+)"', src)) | set(re.findall(r'why = "(\w+)" if', src)) | \
        set(re.findall(r'else "(\w+)"\n', src))
    assert given and given <= set(REJECTIONS), given - set(REJECTIONS)


def test_dictionary_lists_every_parameter_and_field(tmp_path):
    from bringup.cli.main import main

    out = tmp_path / "dictionary.json"
    assert main(["ops", "dictionary", "--out", str(out)]) == 0
    d = json.loads(out.read_text())
    assert d == json.loads(json.dumps(dictionary()))
    params = {p["name"]: p for c in d["commands"] for p in c.get("parameters", ())}
    assert set(params) == set(SETTABLE)
    assert params["operations.pointing_error_max_deg"]["unit"] == "deg"
    tele = {m["message"]: m for m in d["telemetry"]}
    for m in MESSAGES:
        names = [f.name for f in msgspec.inspect.type_info(m).fields if f.name != "v"]
        assert [f["name"] for f in tele[m.__name__]["fields"]] == names
    lat = next(f for f in tele["CommandEvent"]["fields"] if f["name"] == "latency_s")
    assert lat["unit"] == "s" and lat["type"] == "float"
    assert {e["id"] for e in d["events"]} == set(EVENTS)
