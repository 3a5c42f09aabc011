"""Network impairment of the containers' interfaces (bringup/deploy/impair.py; marker ``containers``).

Oracles:
* between two containers on an internal network, with the impairment on one container's
  interface: no UDP round trip beats delay - jitter, the median round trip is at the delay (within
  the scheduling noise the un-impaired round trip shows at the same time: the machine may be
  loaded), the impairer's drawn delays average the configured delay, the loss fraction is within 4
  standard deviations of the binomial's mean, and with a ``rate`` the received throughput stays
  under the token bucket's rate; once the impairer stops, the delay is gone and so is its iptables
  rule;
* the 12-satellite, 1-h run with delay 50 ms +- 10 ms and 1 % loss on every container gives exactly
  the local engine's observations and bundle deliveries (the lockstep absorbs a slow, lossy DDS
  transport), and every container's impairer saw its traffic (so DDS really crossed the interfaces);
* with an ISL cut and ``--isl-delay-s`` too, the report's consensus figures and the traces equal the
  host run's with the same options.
"""

from __future__ import annotations

import json
import math
import subprocess
import sys
import time

import pytest
from conftest import RUN_ID, local_run, traces

from bringup.deploy.impair import parse_impairment

pytestmark = [pytest.mark.containers, pytest.mark.timeout(1800)]

_UDP = r'''
import socket, sys, time, json
mode = sys.argv[1]
s = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
if mode == "echo":
    s.bind(("0.0.0.0", 9999))
    while True:
        d, a = s.recvfrom(4096)
        if d == b"bye": break
        s.sendto(d, a)
elif mode == "sink":
    s.bind(("0.0.0.0", 9998)); s.settimeout(3.0); n = 0; t0 = t1 = None
    try:
        while True:
            d, _ = s.recvfrom(4096)
            t1 = time.monotonic(); t0 = t0 or t1; n += len(d)
    except socket.timeout:
        pass
    print(json.dumps({"bytes": n, "span_s": (t1 - t0) if t0 else 0}))
elif mode == "ping":
    peer, n = sys.argv[2], int(sys.argv[3]); s.settimeout(0.5); rtts = []; lost = 0
    for i in range(n):
        t = time.monotonic(); s.sendto(str(i).encode(), (peer, 9999))
        try:
            while True:
                d, _ = s.recvfrom(4096)
                if d == str(i).encode(): break
            rtts.append(time.monotonic() - t)
        except socket.timeout:
            lost += 1
    print(json.dumps({"rtts": rtts, "lost": lost}))
elif mode == "blast":
    peer, n = sys.argv[2], int(sys.argv[3])
    for i in range(n):
        s.sendto(b"x" * 1000, (peer, 9998)); time.sleep(0.0005)
    s.sendto(b"bye", (peer, 9999))
'''


def test_parse_impairment_netem_words():
    imp = parse_impairment("delay=50ms,jitter=10ms,loss=1%")
    assert (imp.delay_s, imp.jitter_s, imp.loss, imp.rate_bps) == (0.05, 0.01, 0.01, None)
    assert parse_impairment("delay=0.2s, loss=0.5, rate=2mbit").rate_bps == 2_000_000
    for bad, word in (("delay=50", "delay=50"), ("loss=1x", "loss"), ("wobble=1ms", "wobble"),
                      ("delay=5ms,jitter=10ms", "jitter"), ("loss=100%", "loss")):
        with pytest.raises(ValueError, match=word):
            parse_impairment(bad)


def _podman(*a, timeout=120):
    from bringup.deploy.podman import podman

    return podman(*a, timeout=timeout)


def test_udp_between_two_containers_sees_the_impairment(images, lab, tmp_path):
    from bringup.deploy.podman import LABEL, ULIMITS, podman_json

    project = f"cdtn-{RUN_ID}-udp"
    lab.projects.append(project)
    net = f"{project}_net"
    script = tmp_path / "udp.py"
    script.write_text(_UDP)
    sub = lab.subnet(project).removesuffix("0/24")
    _podman("network", "create", "--internal", "--disable-dns", "--subnet", f"{sub}0/24", "--label",
            f"{LABEL}={project}", net)
    common = ["--label", f"{LABEL}={project}", "--network", net, *ULIMITS, "-v", f"{script}:/udp.py:ro"]
    _podman("run", "-d", "--name", f"{project}-echo", "--ip", f"{sub}10", *common, images["image"],
            "python3", "/udp.py", "echo")
    _podman("create", "--name", f"{project}-ping", "--ip", f"{sub}11", *common, "--entrypoint", "sleep",
            images["image"], "600")
    _podman("start", f"{project}-ping")
    sandbox = podman_json("inspect", f"{project}-ping")[0]["NetworkSettings"]["SandboxKey"]

    def ping(n: int) -> dict:
        r = _podman("exec", f"{project}-ping", "python3", "/udp.py", "ping", f"{sub}10", str(n), timeout=300)
        return json.loads(r.stdout)

    def impaired(spec: str):
        imp = parse_impairment(spec)
        p = subprocess.Popen(["nsenter", f"--net={sandbox}", sys.executable, "-m", "bringup.deploy.impair",
                              *imp.args(), "--seed", "5"], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        assert '"ready"' in p.stdout.readline(), p.stderr.read()
        return imp, p

    def stop(p) -> dict:
        p.terminate()
        out, err = p.communicate(timeout=20)
        assert p.returncode == 0, err
        return json.loads(out.splitlines()[-1])["done"]

    def pct(xs, q):
        return sorted(xs)[min(len(xs) - 1, int(q * len(xs)))]

    # The machine may be loaded by other work, which only ever adds time: lower bounds are exact,
    # upper bounds allow the scheduling noise the un-impaired round trip shows at the same time.
    base = ping(100)
    assert not base["lost"]
    noise = pct(base["rtts"], 0.9)
    imp, p = impaired("delay=20ms,jitter=5ms,loss=10%")
    try:
        got = ping(400)
    finally:
        st = stop(p)
    rtts, n = got["rtts"], 400
    mean = sum(rtts) / len(rtts)
    sd = math.sqrt(n * imp.loss * (1 - imp.loss))
    print(f"CONTAINERS udp impairment={imp} rtt_mean_ms={mean * 1e3:.1f} rtt_min_ms={min(rtts) * 1e3:.1f} "
          f"rtt_median_ms={pct(rtts, 0.5) * 1e3:.1f} rtt_max_ms={max(rtts) * 1e3:.1f} base_p90_ms={noise * 1e3:.1f} "
          f"lost={got['lost']}/{n} impairer={json.dumps(st)}")
    assert min(rtts) >= imp.delay_s - imp.jitter_s - 0.0005  # no packet beats its delay
    assert pct(rtts, 0.1) <= imp.delay_s - imp.jitter_s / 2 + noise  # the jitter's low end is there
    # (the impairer is a process too: on a loaded machine its wake-ups add ~2 ms, hence up to + jitter)
    assert imp.delay_s - 0.002 <= pct(rtts, 0.5) <= imp.delay_s + imp.jitter_s + noise, (pct(rtts, 0.5), noise)
    assert abs(st["mean_delay_s"] - imp.delay_s) < 0.001  # the draws: uniform around the delay
    assert abs(got["lost"] - n * imp.loss) <= 4 * sd
    assert st["packets"] == n and st["dropped"] == got["lost"]
    after = ping(100)
    assert not after["lost"] and pct(after["rtts"], 0.5) < imp.delay_s - imp.jitter_s
    rules = subprocess.run(["nsenter", f"--net={sandbox}", "iptables-legacy", "-S", "OUTPUT"], capture_output=True,
                           text=True, check=True).stdout
    assert "NFQUEUE" not in rules

    # rate: a token bucket (tbf) on the interface; 1000-byte datagrams sent at ~16 Mbit/s arrive at <= 2 Mbit/s
    _podman("run", "-d", "--name", f"{project}-sink", "--ip", f"{sub}12", *common, images["image"],
            "python3", "/udp.py", "sink")
    imp, p = impaired("rate=2mbit")
    try:
        _podman("exec", f"{project}-ping", "python3", "/udp.py", "blast", f"{sub}12", "1500", timeout=300)
    finally:
        stop(p)
    _podman("wait", f"{project}-sink")
    sink = json.loads(_podman("logs", f"{project}-sink").stdout)
    rate = sink["bytes"] * 8 / sink["span_s"]
    print(f"CONTAINERS tbf rate=2mbit received_bytes={sink['bytes']} span_s={sink['span_s']:.2f} rate_bps={rate:.0f}")
    assert sink["bytes"] > 100_000 and rate <= 2_000_000 * 1.1
    _podman("exec", f"{project}-echo", "python3", "-c",
            "import socket; socket.socket(socket.AF_INET, socket.SOCK_DGRAM).sendto(b'bye', ('127.0.0.1', 9999))")


def _impaired_run(lab, tag: str, tmp_path, *compose_args: str):
    from bringup.deploy.containers import ContainerRun

    cr = ContainerRun(lab.compose(tag, *compose_args), impair=parse_impairment("delay=50ms,jitter=10ms,loss=1%"),
                      seed=7)
    try:
        cr.up()
        res = cr.wait(timeout_s=1500)
        assert res.ok, (res.message, res.exit_codes, cr.logs("clock")[-2000:])
        out = cr.copy_out(tmp_path / f"{tag}-run")
    finally:
        cr.down()
    return res, out


def test_run_under_delay_jitter_and_loss_equals_local_engine(lab, local_ref, tmp_path):
    t0 = time.monotonic()
    res, out = _impaired_run(lab, "netem", tmp_path)
    obs_ref, dl_ref = traces(local_ref)
    obs, dl = traces(out)
    packets = {s: sum(r["packets"] for r in runs) for s, runs in res.impair_stats.items()}
    dropped = sum(r["dropped"] for runs in res.impair_stats.values() for r in runs)
    print(f"CONTAINERS netem delay=50ms+-10ms loss=1% wall_s={time.monotonic() - t0:.1f} run_wall_s={res.wall_s:.1f} "
          f"steps={res.last_progress and res.last_progress['steps']} packets={sum(packets.values())} "
          f"dropped={dropped} overruns={sum(r['overruns'] for runs in res.impair_stats.values() for r in runs)}")
    assert set(packets) == set(res.exit_codes)
    assert all(n > 100 for n in packets.values()), packets
    assert dropped > 0
    assert obs == obs_ref
    assert dl == dl_ref


def test_cut_and_isl_delay_under_impairment_consensus_as_on_host(lab, tmp_path):
    opts = ("--isl-delay-s", "30", "--cut", "sat_11-sat_21@600-1800")
    host = local_run(tmp_path / "host", *opts)
    res, out = _impaired_run(lab, "cut", tmp_path, *opts)
    rep_host = json.loads((host / "report.json").read_text())
    rep = json.loads((out / "report.json").read_text())
    print(f"CONTAINERS cut+isl-delay under netem run_wall_s={res.wall_s:.1f} consensus={json.dumps(rep['consensus'])}")
    assert rep["consensus"] == rep_host["consensus"]
    assert traces(out) == traces(host)
