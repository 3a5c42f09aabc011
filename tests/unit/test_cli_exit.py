"""The console script's exit (bringup/cli/main.py entry): after a successful `run` it leaves with
os._exit once atexit handlers ran and the streams are flushed; nothing the run wrote may be lost
(oracle: the bag opens and `report BAG` equals report.json; stdout/stderr complete), and a failing
command still exits through sys.exit with its code and one-line message."""

from __future__ import annotations

import json
import subprocess
import sys


def _cli(*args, cwd=None):
    return subprocess.run([sys.executable, "-m", "bringup.cli", *args], capture_output=True, text=True,
                          timeout=300, cwd=cwd)


def test_fast_exit_after_run_loses_nothing(tmp_path):
    out = tmp_path / "run"
    r = _cli("run", "--engine", "local", "--sats", "6", "--hours", "0.25", "--out", str(out), "--no-progress")
    assert r.returncode == 0, r.stderr
    assert "run: done in" in r.stderr.splitlines()[-1]
    rep = json.loads((out / "report.json").read_text())
    assert (out / "report.md").read_text().strip()
    assert sorted(p.name for p in (out / "plots").iterdir())
    from bringup.analysis.report import report_from_bag

    again = report_from_bag(out / "bag")
    for k in ("observations", "value", "dtn", "coverage"):
        assert again[k] == rep[k], k
    for store in (out / "store").iterdir():  # closed: no WAL left beside any store
        assert not store.name.endswith("-wal"), store.name


def test_failing_command_exits_with_its_code_and_message(tmp_path):
    r = _cli("run", "--engine", "local", "--cut", "nonsense", "--out", str(tmp_path / "x"))
    assert r.returncode == 2
    assert r.stderr.strip().splitlines()[-1].startswith("constellation run: error: --cut")


def test_fast_exit_after_dtn_loses_nothing(tmp_path):
    """`dtn` leaves the same way: its JSON on stdout is whole, the dumped bundles and the key file are
    written (each bundle decodes, its BIB verifies under the key)."""
    from bringup.engine.keys import read_key_file
    from orbit_clock.contact_plan import Contact, ContactPlan
    from orbit_clock.contact_plan_io import write_contact_plan
    from sat_node.dtn.bpsec import verify_bib
    from sat_node.dtn.bpv7 import decode_bundle

    plan = ContactPlan([Contact(0.0, 1000.0, a, b, 1000.0, 0.5) for a, b in
                        [("sat_11", "sat_12"), ("sat_12", "sat_11"), ("sat_12", "sat_13"), ("sat_13", "sat_12")]])
    with open(tmp_path / "plan.csv", "w") as fh:
        write_contact_plan(plan, "csv", fh)
    rows = "".join(f"Sat11,{10 + k},{k},r,0,1,1\n" for k in range(40))
    (tmp_path / "traffic.csv").write_text("source,time_s,packet_id,region,Sat11,Sat12,Sat13\n" + rows)
    dump = tmp_path / "dump"
    r = _cli("dtn", "--contact-plan", str(tmp_path / "plan.csv"), "--traffic", str(tmp_path / "traffic.csv"),
             "--json", "--dump-bundles", str(dump))
    assert r.returncode == 0, r.stderr
    rep = json.loads(r.stdout)
    assert rep["dtn.bundles_created"] == 80 and rep["dtn.delivery_ratio"] == 1.0
    key = read_key_file(dump / "bpsec.key")
    files = sorted(dump.glob("*.bpv7"))
    assert len(files) == 80
    for f in files:
        verify_bib(decode_bundle(f.read_bytes()), key)  # raises IntegrityError on a wrong MAC
