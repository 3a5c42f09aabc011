"""The DTN alone on the study's inputs gives, to the last digit, the figures it gave before (the
files in tests/fixtures/dtn_expected): every dtn.* figure of the report - counts, latency mean,
percentiles and maxima per priority, transmissions, radio busy fractions, the per-pair bound - for
case4 with unicast and multicast forwarding at 1 kb/s with 2000-bit bundles. A change of speed must
not change them; a change of model that does regenerates the files and says why in its commit
message.

The files were written by the code before the DTN-alone speed-ups (bringup/analysis/dtn_alone.py,
engine, port and traffic-node fast paths), with the same calls as :func:`_report` below; the report
does not depend on the BPSec key (its bytes differ, not its size). Beside the figures, every bundle
event of the run (sat_node/dtn/agent.py BundleEvent: time, kind, node, bundle, priority, recipient,
creation, reason, deadline) is the same: the SHA-256 of their sorted list and their count
(events_sha256.json, written by the code of main ed1bdad with :func:`_events_digest`)."""

import hashlib
import json
from pathlib import Path

import pytest

from bringup.analysis.dtn_alone import run_dtn
from bringup.analysis.dtn_bounds import latency_lower_bounds
from orbit_clock.contact_plan_io import read_contact_plan
from sat_node.dtn.agent import AgentConfig
from sat_node.dtn.traffic import read_traffic
from tests.keys import TEST_BPSEC_KEY

EXPECTED = Path(__file__).resolve().parents[1] / "fixtures" / "dtn_expected"


def _report(paper_inputs: Path, case: str, forwarding: str) -> tuple[dict, dict]:
    """The run's report (with the per-pair bounds) and :func:`_events_digest` of its events."""
    plan = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000)
    traffic = read_traffic(paper_inputs / f"traffic_{case}.csv")
    run = run_dtn(plan, traffic, config=AgentConfig(key=TEST_BPSEC_KEY, forwarding=forwarding))
    return run.report(latency_lower_bounds(plan, traffic, 2000, run.created_ids,
                                           per_observation=forwarding == "multicast")), _events_digest(run.events)


def _events_digest(events) -> dict:
    """Count and SHA-256 of the bundle events, sorted (one ``repr`` of the event's fields a line)."""
    h = hashlib.sha256()
    for ev in sorted(events):
        h.update(repr(tuple(ev)).encode() + b"\n")
    return {"events": len(events), "sha256": h.hexdigest()}


@pytest.mark.parametrize("case, forwarding", [("case4", "unicast"), ("case4", "multicast")])
def test_study_inputs_figures_unchanged(paper_inputs, case, forwarding):
    expected = json.loads((EXPECTED / f"{case}_{forwarding}.json").read_text())
    report, digest = _report(paper_inputs, case, forwarding)
    got = json.loads(json.dumps(report))  # the file's JSON round trip
    assert got.keys() == expected.keys()
    diff = {k: (got[k], expected[k]) for k in expected if got[k] != expected[k]}
    assert not diff, diff
    assert digest == json.loads((EXPECTED / "events_sha256.json").read_text())[f"{case}_{forwarding}"]
