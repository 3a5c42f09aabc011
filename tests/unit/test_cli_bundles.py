"""``constellation bundles send|listen`` on loopback (bringup/cli/bundles.py): every convergence
layer, the listener a separate process, the files compared byte for byte with what was sent."""

from __future__ import annotations

import os
import subprocess
import sys
from datetime import UTC, datetime
from pathlib import Path

import pytest

from bringup.cli.main import main
from sat_node.dtn.bpv7 import Bundle, encode_bundle, ipn

REPO = Path(__file__).resolve().parents[2]
# 2026-11-27T12:00:00Z in DTN time [ms since 2000-01-01T00:00:00Z] (RFC 9171 4.2.6)
_CREATED_MS = int((datetime(2026, 11, 27, 12, tzinfo=UTC) - datetime(2000, 1, 1, tzinfo=UTC)).total_seconds()) * 1000


def _bundles(tmp_path: Path, n: int = 4, step: int = 20_000) -> list[Path]:
    files = []
    for i in range(n):
        b = Bundle(dest=ipn(2, 1), src=ipn(1, 1), creation_ms=_CREATED_MS + i, seq=i, lifetime_ms=3_600_000,
                   payload=bytes([i]) * (10 + step * i))
        f = tmp_path / f"b{i}.bpv7"
        f.write_bytes(encode_bundle(b))
        files.append(f)
    return files


def _listener(cl: str, out: Path, count: int):
    env = dict(os.environ, PYTHONPATH=str(REPO))
    p = subprocess.Popen([sys.executable, "-m", "bringup.cli", "bundles", "listen", "--cl", cl, "--at",
                          "127.0.0.1:0", "--out", str(out), "--count", str(count), "--duration", "30",
                          "--segment", "5000"],
                         stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, env=env, cwd=REPO)
    first = p.stdout.readline()
    assert first.startswith(f"listening on {cl}://127.0.0.1:"), first + p.stderr.read()
    port = int(first.split(",")[0].rsplit(":", 1)[1])
    return p, port


@pytest.mark.parametrize("cl", ["tcpcl4", "tcpcl3", "udp"])
def test_send_and_listen_byte_identical(cl, tmp_path, capsys):
    files = _bundles(tmp_path)
    out = tmp_path / "in"
    p, port = _listener(cl, out, len(files))
    code = main(["bundles", "send", "--cl", cl, "--to", f"127.0.0.1:{port}", "--segment", "7000",
                 *map(str, files)])
    sent = capsys.readouterr().out.splitlines()
    if code != 0:
        p.kill()
    rest, err = p.communicate(timeout=30)
    assert code == 0 and p.returncode == 0, err
    assert len([s for s in sent if s.startswith("sent ")]) == len(files)
    received = sorted(out.glob("*.bpv7"))
    assert [r.read_bytes() for r in received] == [f.read_bytes() for f in files]
    lines = [ln for ln in rest.splitlines() if ln.startswith("received ")]
    assert len(lines) == len(files)
    assert "ipn:1.1 -> ipn:2.1 created 2026-11-27T12:00:00.000Z" in lines[0] and "seq 0" in lines[0]
    assert rest.splitlines()[-1] == f"{len(files)} bundles received"


def test_send_refuses_bad_files_up_front(tmp_path, capsys):
    good = _bundles(tmp_path, 1)[0]
    bad = tmp_path / "bad.bpv7"
    bad.write_bytes(b"\x9f\x88junk")
    # port 9 (discard) is never contacted: the files are checked first
    assert main(["bundles", "send", "--cl", "tcpcl4", "--to", "127.0.0.1:9", str(good), str(bad)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "bad.bpv7: not a BPv7 bundle" in err[0]
    assert main(["bundles", "send", "--cl", "udp", "--to", "nowhere", str(good)]) == 2
    assert "expected HOST:PORT" in capsys.readouterr().err
    assert main(["bundles", "send", "--cl", "tcpcl3", "--to", "127.0.0.1:9", str(tmp_path / "none.bpv7")]) == 2
    assert "none.bpv7: cannot read" in capsys.readouterr().err
    big = _bundles(tmp_path, 2, step=70_000)[1]
    assert main(["bundles", "send", "--cl", "udp", "--to", "127.0.0.1:9", str(big)]) == 2
    assert "over one datagram (65507)" in capsys.readouterr().err


def test_listener_rejects_and_counts_what_is_not_a_bundle(tmp_path, capsys):
    good = _bundles(tmp_path, 1)[0]
    junk = tmp_path / "junk.bin"
    junk.write_bytes(b"not a bundle at all")
    out = tmp_path / "in"
    p, port = _listener("tcpcl4", out, 1)
    assert main(["bundles", "send", "--cl", "tcpcl4", "--to", f"127.0.0.1:{port}", "--no-check",
                 str(junk), str(good)]) == 0
    rest, _ = p.communicate(timeout=30)
    assert [f.read_bytes() for f in sorted(out.glob("*.bpv7"))] == [good.read_bytes()]
    assert "rejected 19 B from 127.0.0.1:" in rest
    assert rest.splitlines()[-1] == "1 bundles received, 1 rejected (not BPv7)"


def test_connection_refused_is_one_line(tmp_path, capsys):
    import socket
    s = socket.socket()
    s.bind(("127.0.0.1", 0))
    port = s.getsockname()[1]
    s.close()
    f = _bundles(tmp_path, 1)[0]
    assert main(["bundles", "send", "--cl", "tcpcl4", "--to", f"127.0.0.1:{port}", str(f)]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "cannot connect" in err[0]
