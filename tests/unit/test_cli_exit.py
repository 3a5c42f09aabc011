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
