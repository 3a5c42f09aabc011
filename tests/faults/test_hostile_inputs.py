"""A hostile-input corpus through the command line: every class of bad input gets one line, exit 2.

Each case is an in-process call of ``bringup.cli.main`` (the console script's body) with one bad
input: scenario files (binary, UTF-16 with and without a byte-order mark, Latin-1, empty, oversized,
NaN/inf numbers, sizes that would need terabytes), number options (nan, inf, negative, huge), output
folders (a file, a place that cannot be made), contact plans and traffic tables (undecodable,
NaN/inf/negative numbers, overlaps, unknown nodes, a million rows), bags (not an MCAP file, a
malformed /run/meta record) and errors the core raises about its inputs (an OSSE file that is not
one, a slew model that is not increasing). Oracle for each: exit status 2, exactly one stderr line
``constellation <cmd>: error: ...`` naming the thing (file, key or option), no "Traceback", and the
call returns within 60 s (a SIGALRM turns a hang into a failure naming the case).

Where the old behaviour was a wrong success, the right answer is checked: duplicated traffic rows
and contacts give the figures of the table without the copies (with a warning); out-of-range
report payloads are not counted (the report equals the one without them); a full disk (a 256 KiB
tmpfs the test mounts and removes: root) is named as "no space left on device" with the file.
"""

from __future__ import annotations

import codecs
import contextlib
import json
import os
import shutil
import signal
import subprocess
from pathlib import Path

import pytest
from scenario_edit import raw_scenario, set_key, to_toml

from bringup.cli.main import main
from bringup.scenario.config import load_scenario

pytestmark = [pytest.mark.faults]

PAPER_TOML = Path(__file__).resolve().parents[2] / "bringup" / "scenario" / "toml" / "paper.toml"
HANG_S = 60


@contextlib.contextmanager
def _no_hang(what: str):
    def alarm(*_):
        raise TimeoutError(f"{what}: still running after {HANG_S} s (a hang)")

    old = signal.signal(signal.SIGALRM, alarm)
    signal.setitimer(signal.ITIMER_REAL, HANG_S)
    try:
        yield
    finally:
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, old)


def cli(capsys, *argv: str) -> tuple[int, str, str]:
    with _no_hang(" ".join(map(str, argv))):
        code = main([str(a) for a in argv])
    got = capsys.readouterr()
    return code, got.out, got.err


def one_line_error(capsys, argv, *names: str) -> str:
    """Run ``argv``: exit 2, no traceback, exactly one error line - the last on stderr, after any
    progress lines (``run: ...``) - naming each of ``names``; returns it."""
    code, _out, err = cli(capsys, *argv)
    assert "Traceback" not in err, err
    lines = [ln for ln in err.splitlines() if ln.strip()]
    errors = [ln for ln in lines if ": error: " in ln]
    assert code == 2 and len(errors) == 1 and lines[-1] == errors[0], (argv, code, err)
    assert errors[0].startswith(f"constellation {argv[0]}: error: "), errors[0]
    assert all(ln.startswith(("run: ", f"constellation {argv[0]}: warning: ")) for ln in lines[:-1]), err
    for n in names:
        assert str(n) in errors[0], (n, errors[0])
    return errors[0]


def _scenario(tmp_path: Path, name: str = "BAD.toml", **keys) -> Path:
    raw = raw_scenario(load_scenario("paper"))
    for k, v in keys.items():
        set_key(raw, k.replace("__", "."), v)
    p = tmp_path / name
    p.write_text(to_toml(raw))
    return p


# -- scenario files ---------------------------------------------------------------------------------
def _undecodable(tmp_path: Path) -> dict[str, Path]:
    text = PAPER_TOML.read_text()
    files = {
        "binary": os.urandom(3000) + b"\x00" * 10,
        "utf16le-bom": codecs.BOM_UTF16_LE + text.encode("utf-16-le"),
        "utf16be-nobom": text.encode("utf-16-be"),
        "latin1": text.replace("Rio de Janeiro", "S\u00e3o Paulo").encode("latin-1"),
    }
    out = {}
    for k, data in files.items():
        p = tmp_path / f"{k}.toml"
        p.write_bytes(data)
        out[k] = p
    return out


@pytest.mark.parametrize("kind,expect", [("binary", "binary data"), ("utf16le-bom", "UTF-16"),
                                         ("utf16be-nobom", "UTF-16"), ("latin1", "not UTF-8")])
@pytest.mark.parametrize("cmd", ["run", "access", "constellation"])
def test_undecodable_scenario(tmp_path, capsys, kind, expect, cmd):
    path = _undecodable(tmp_path)[kind]
    argv = [cmd, "--scenario", path] + (["--engine", "local", "--out", tmp_path / "o"] if cmd == "run" else [])
    one_line_error(capsys, argv, path.name, expect)


def test_empty_huge_and_folder_scenarios(tmp_path, capsys):
    empty = tmp_path / "empty.toml"
    empty.write_text("")
    one_line_error(capsys, ["constellation", "--scenario", empty], "empty.toml", "missing required field")
    huge = tmp_path / "huge.toml"
    with open(huge, "wb") as fh:  # sparse: 17 MiB on paper, nothing on disk
        fh.truncate(17 * 2**20)
    one_line_error(capsys, ["constellation", "--scenario", huge], "huge.toml", "limit")
    (tmp_path / "dir.toml").mkdir()
    one_line_error(capsys, ["constellation", "--scenario", tmp_path / "dir.toml"], "dir.toml", "folder")


@pytest.mark.parametrize("key,value", [
    ("scenario.horizon_s", float("inf")), ("scenario.horizon_s", float("nan")),
    ("constellation.altitude_km", float("nan")), ("acs.slew_coeffs_s", [1.0, float("inf")]),
    ("regions.list[0].size_km", float("inf")), ("ground.stations[0].alt_m", float("-inf")),
])
def test_scenario_numbers_not_finite(tmp_path, capsys, key, value):
    raw = raw_scenario(load_scenario("paper"))
    if key.startswith("ground.stations"):
        raw["ground"]["stations"] = [{"name": "x", "lat_deg": 0.0, "lon_deg": 0.0, "alt_m": 0.0}]
    set_key(raw, key, value)
    p = tmp_path / "BAD.toml"
    p.write_text(to_toml(raw))
    one_line_error(capsys, ["run", "--scenario", p, "--engine", "local", "--out", tmp_path / "o"],
                   "BAD.toml", key.split("[")[0])


@pytest.mark.parametrize("key,value,driver", [
    ("regions.gp_spacing_km", 1e-3, "gp_spacing_km"),
    ("scenario.horizon_s", 1e12, "horizon_s"),
    ("scheduler.dp_step_s", 1e-6, "dp_step_s"),
    ("regions.gp_spacing_km", 1e-300, "gp_spacing_km"),
])
@pytest.mark.parametrize("cmd", ["run", "access", "contacts"])
def test_scenarios_too_big_are_refused_with_the_estimate(tmp_path, capsys, key, value, driver, cmd):
    p = _scenario(tmp_path, **{key.replace(".", "__"): value})
    argv = [cmd, "--scenario", p] + (["--engine", "local", "--out", tmp_path / "o"] if cmd == "run" else [])
    line = one_line_error(capsys, argv, "BAD.toml", "would need about", "budget", driver)
    assert "iB of memory" in line
    assert not (tmp_path / "o").exists()  # refused before anything was made


def test_core_errors_about_inputs_are_one_line(tmp_path, capsys):
    # an OSSE file that is not one (OsseError), a slew model that is not increasing (SlewModelError)
    junk = tmp_path / "field.nc"
    junk.write_bytes(b"\x00\x01not netcdf" * 50)
    p = _scenario(tmp_path, "osse.toml", value__osse_source="file", value__osse_file=str(junk))
    one_line_error(capsys, ["run", "--scenario", p, "--engine", "local", "--out", tmp_path / "o1"], "field.nc")
    p = _scenario(tmp_path, "slew.toml", acs__slew_coeffs_s=[-1.0, 5.0])
    one_line_error(capsys, ["run", "--scenario", p, "--engine", "local", "--out", tmp_path / "o2"],
                   "acs.slew_coeffs_s")


# -- number options ---------------------------------------------------------------------------------
RUN = ["run", "--engine", "local", "--sats", "6", "--no-plots", "--no-progress"]


@pytest.mark.parametrize("args,names", [
    (["--hours", "inf"], ["--hours", "finite"]), (["--hours", "nan"], ["--hours", "finite"]),
    (["--hours", "-1"], ["horizon_s"]), (["--hours", "1e9"], ["would need about"]),
    (["--hours", "0.1", "--isl-delay-s", "nan"], ["--isl-delay-s", "finite"]),
    (["--hours", "0.1", "--isl-delay-s", "-5"], ["--isl-delay-s"]),
    (["--hours", "0.1", "--isl-delay-s", "1e300"], ["--isl-delay-s"]),
    (["--hours", "0.1", "--real-time-factor", "0"], ["--real-time-factor"]),
    (["--hours", "0.1", "--real-time-factor=-inf"], ["--real-time-factor", "finite"]),
    (["--hours", "0.1", "--restart", "-1"], ["--restart"]),
    (["--hours", "0.1", "--seed", "-1"], ["seed"]),
    (["--hours", "0.1", "--cut", "sat_11-sat_12@nan-5"], ["--cut"]),
    (["--hours", "0.1", "--cut", "sat_11-sat_12@-inf-5"], ["--cut"]),
    (["--hours", "0.1", "--cut", "sat_11-sat_99@0-10"], ["sat_99"]),
])
def test_run_options(tmp_path, capsys, args, names):
    line = one_line_error(capsys, RUN + args + ["--out", tmp_path / "o"], *names)
    assert "Traceback" not in line


def test_sats_out_of_range(tmp_path, capsys):
    for n in ("0", "-3", "100000"):
        one_line_error(capsys, ["run", "--engine", "local", "--sats", n, "--out", tmp_path / "o"], "total_sats")


# -- output folders ---------------------------------------------------------------------------------
def test_out_is_a_file_or_cannot_be_made(tmp_path, capsys):
    f = tmp_path / "afile"
    f.write_text("x")
    one_line_error(capsys, RUN + ["--hours", "0.1", "--out", f], "afile", "is a file")
    one_line_error(capsys, RUN + ["--hours", "0.1", "--out", f / "sub"], "afile/sub", "not a folder")
    one_line_error(capsys, RUN + ["--hours", "0.1", "--out", "/proc/self/no/such/run"], "/proc/self/no/such/run")
    assert f.read_text() == "x"


# -- contact plans and traffic ----------------------------------------------------------------------
@pytest.fixture(scope="module")
def dtn_inputs(tmp_path_factory, paper_inputs):
    """The study's plan and the first 40 rows of its case4 traffic."""
    d = tmp_path_factory.mktemp("dtn")
    traffic = (paper_inputs / "traffic_case4.csv").read_text().splitlines()
    shutil.copy(paper_inputs / "contact_plan_3p_8s.csv", d / "plan.csv")
    (d / "traffic.csv").write_text("\n".join(traffic[:41]) + "\n")
    return d


def _dtn(plan, traffic, *extra):
    return ["dtn", "--contact-plan", plan, "--traffic", traffic, "--json", "--no-lower-bound", *extra]


def _edit_csv(src: Path, dst: Path, line_no: int, col: int, value: str) -> Path:
    lines = src.read_text().splitlines()
    cells = lines[line_no].split(",")
    cells[col] = value
    lines[line_no] = ",".join(cells)
    dst.write_text("\n".join(lines) + "\n")
    return dst


@pytest.mark.parametrize("col,value,names", [
    (0, "nan", ["finite"]), (1, "inf", ["finite"]), (4, "inf", ["finite"]), (4, "1e300", ["light time"]),
    (0, "-5", ["start"]), (1, "0.0", ["start < end"]), (2, "bogus", ["bogus", "neither"]),
    (2, "s12", ["itself"]),
])
def test_bad_contact_plans(tmp_path, capsys, dtn_inputs, col, value, names):
    bad = _edit_csv(dtn_inputs / "plan.csv", tmp_path / "BADPLAN.csv", 1, col, value)
    one_line_error(capsys, _dtn(bad, dtn_inputs / "traffic.csv"), *names)


@pytest.mark.parametrize("fmt", ["csv", "json", "rc"])
def test_undecodable_plans_and_traffic(tmp_path, capsys, dtn_inputs, fmt):
    for kind, data in (("binary", os.urandom(2000) + b"\x00\x00"),
                       ("utf16", codecs.BOM_UTF16_LE + (dtn_inputs / "plan.csv").read_text().encode("utf-16-le"))):
        p = tmp_path / f"{kind}.{fmt}"
        p.write_bytes(data)
        one_line_error(capsys, _dtn(p, dtn_inputs / "traffic.csv"), p.name)
    t = tmp_path / "traffic16.csv"
    t.write_bytes((dtn_inputs / "traffic.csv").read_text().encode("utf-16-be"))
    one_line_error(capsys, _dtn(dtn_inputs / "plan.csv", t), "traffic16.csv", "UTF-16")
    big = tmp_path / "big.json"
    with open(big, "wb") as fh:
        fh.truncate(600 * 2**20)
    one_line_error(capsys, _dtn(big, dtn_inputs / "traffic.csv"), "big.json", "limit")


def test_overlapping_and_foreign_plans(tmp_path, capsys, dtn_inputs):
    lines = (dtn_inputs / "plan.csv").read_text().splitlines()
    start, end, a, b, rng = lines[1].split(",")
    over = tmp_path / "over.csv"
    over.write_text("\n".join(lines + [f"{float(start) + 1},{float(end) + 1},{a},{b},{rng}"]) + "\n")
    one_line_error(capsys, _dtn(over, dtn_inputs / "traffic.csv"), "overlap")
    hdtn = tmp_path / "deep.json"
    hdtn.write_text("[" * 100000 + "]" * 100000)
    one_line_error(capsys, _dtn(hdtn, dtn_inputs / "traffic.csv"), "deep.json")
    ion = tmp_path / "plan.rc"
    ion.write_text("@ 2000/01/01-11:59:28\na contact +0 +100 11 4242 125\n")
    one_line_error(capsys, _dtn(ion, dtn_inputs / "traffic.csv"), "4242")


@pytest.mark.parametrize("col,value,names", [
    (1, "nan", ["time_s"]), (1, "inf", ["time_s"]), (1, "-3", ["time_s"]), (1, "1e300", ["time_s"]),
    (5, "99", ["priority 99"]), (5, "-7", ["priority -7"]), (5, "1.5", ["not a number"]),
])
def test_bad_traffic(tmp_path, capsys, dtn_inputs, col, value, names):
    bad = _edit_csv(dtn_inputs / "traffic.csv", tmp_path / "BADTRAFFIC.csv", 3, col, value)
    one_line_error(capsys, _dtn(dtn_inputs / "plan.csv", bad), "BADTRAFFIC.csv:4", *names)


def test_traffic_unknown_nodes_conflicts_and_a_million_rows(tmp_path, capsys, dtn_inputs):
    lines = (dtn_inputs / "traffic.csv").read_text().splitlines()
    header = lines[0].split(",")
    renamed = tmp_path / "t1.csv"
    dest = next(i for i, p in enumerate(lines[1].split(",")) if i >= 4 and p not in ("0", "-1"))
    renamed.write_text("\n".join([",".join(header[:dest] + ["Sat99"] + header[dest + 1:])] + lines[1:]) + "\n")
    one_line_error(capsys, _dtn(dtn_inputs / "plan.csv", renamed), "sat_99", "no contact")
    other = lines[1].split(",")
    other[1] = str(float(other[1]) + 7)  # the same (source, packet_id), another time
    conflict = tmp_path / "t2.csv"
    conflict.write_text("\n".join(lines + [",".join(other)]) + "\n")
    one_line_error(capsys, _dtn(dtn_inputs / "plan.csv", conflict), "t2.csv", "already listed")
    big = tmp_path / "t3.csv"
    row = lines[1].split(",")
    with open(big, "w") as fh:
        fh.write(lines[0] + "\n")
        for i in range(1_000_001):
            row[2] = str(i)
            fh.write(",".join(row) + "\n")
    one_line_error(capsys, _dtn(dtn_inputs / "plan.csv", big), "t3.csv", "1,000,000 bundles")


def _figures(out: str) -> dict:
    rep = json.loads(out)  # strict JSON: no NaN or Infinity tokens
    return {k: v for k, v in rep.items() if "wall" not in k}


def test_duplicated_traffic_rows_and_contacts_count_once(tmp_path, capsys, dtn_inputs):
    plan, traffic = dtn_inputs / "plan.csv", dtn_inputs / "traffic.csv"
    code, out, err = cli(capsys, *_dtn(plan, traffic))
    assert code == 0, err
    clean = _figures(out)
    lines = traffic.read_text().splitlines()
    dup_t = tmp_path / "dup_traffic.csv"
    dup_t.write_text("\n".join(lines[:1] + lines[1:] * 5) + "\n")  # every row five times
    lines_p = plan.read_text().splitlines()
    dup_p = tmp_path / "dup_plan.csv"
    dup_p.write_text("\n".join(lines_p[:1] + lines_p[1:] * 2) + "\n")
    code, out, err = cli(capsys, *_dtn(dup_p, dup_t))
    assert code == 0, err
    assert _figures(out) == clean  # was 5x the bundles
    assert "160 rows repeat" in err and "1384 contacts listed twice" in err and "Traceback" not in err


def test_json_output_is_strict_with_an_infinite_figure(tmp_path, capsys, dtn_inputs):
    code, out, _err = cli(capsys, *_dtn(dtn_inputs / "plan.csv", dtn_inputs / "traffic.csv"))
    assert code == 0
    assert "Infinity" not in out and "NaN" not in out
    json.loads(out, parse_constant=lambda c: pytest.fail(f"non-JSON constant {c}"))


def test_dtn_options(tmp_path, capsys, dtn_inputs):
    p, t = dtn_inputs / "plan.csv", dtn_inputs / "traffic.csv"
    for extra, name in ((["--rate-bps", "inf"], "--rate-bps"), (["--rate-bps", "0"], "--rate-bps"),
                        (["--bundle-bits", "0"], "--bundle-bits"), (["--hop-tolerance-s", "nan"], "--hop-tolerance-s"),
                        (["--ttl-s", "1:nan,15:5"], "--ttl-s"), (["--ttl-s", "15:inf"], "--ttl-s"),
                        (["--ttl-s", "15:1e300"], "--ttl-s"), (["--dump-bundles", p], "--dump-bundles")):
        one_line_error(capsys, _dtn(p, t, *extra), name)


# -- bags -------------------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def run_bag(tmp_path_factory):
    out = tmp_path_factory.mktemp("run") / "r"
    assert main(["run", "--engine", "local", "--sats", "6", "--hours", "0.5", "--no-plots", "--no-progress",
                 "--out", str(out)]) == 0
    return out


def _bag_with(tmp_path: Path, src: Path, extra) -> Path:
    """A copy of ``src``'s bag with envelopes ``extra`` added (a fresh bag: every message plus them)."""
    from bringup.recording.bag import BagReader, BagWriter

    dst = tmp_path / "bag"
    with BagReader(src) as r, BagWriter(dst, epoch_ns=r.epoch_ns) as w:
        for m in r.messages():
            if m.topic == "/run/meta" and extra.get("meta") is not None:
                continue
            w.write_raw(m.topic, m.msgtype, m.cdr, m.log_time_ns)
        for env in extra.get("envelopes", []):
            w.write_envelope(env)
        if extra.get("meta") is not None:
            from msgs_json.envelope import Envelope

            w.write_envelope(Envelope(0, "run", 0, "/run/meta", extra["meta"]))
    return dst


@pytest.mark.parametrize("meta,names", [
    ("not json", ["/run/meta"]), ('["a list"]', ["/run/meta", "not a JSON object"]),
    ('{"meta": {"scenario": "paper"}}', ["/run/meta", "missing"]),
    ('{"meta": {"scenario": "paper", "mode": "distributed", "engine": "local", "seed": 1, "horizon_s": NaN, '
     '"n_sats": 6, "n_gp": 500}}', ["horizon_s", "finite"]),
    ('{"meta": {"scenario": "paper", "mode": "distributed", "engine": "local", "seed": 1, "horizon_s": "x", '
     '"n_sats": 6, "n_gp": 500}}', ["horizon_s"]),
    ('{"meta": {"scenario": "paper", "mode": "distributed", "engine": "local", "seed": 1, "horizon_s": 3600.0, '
     '"n_sats": 6, "n_gp": -5}}', ["n_gp"]),
])
def test_malformed_run_meta(tmp_path, capsys, run_bag, meta, names):
    bag = _bag_with(tmp_path, run_bag / "bag", {"meta": meta})
    one_line_error(capsys, ["report", bag], *names)


def test_not_a_bag(tmp_path, capsys):
    d = tmp_path / "bag"
    d.mkdir()
    (d / "bag.mcap").write_bytes(os.urandom(5000))
    one_line_error(capsys, ["report", d], "not an MCAP file")
    one_line_error(capsys, ["bag-info", d], "not an MCAP file")
    (d / "bag.mcap").write_bytes(b"")
    one_line_error(capsys, ["bag-info", d], "not an MCAP file")
    (d / "bag.mcap").unlink()
    one_line_error(capsys, ["report", d], "no metadata.yaml")


def test_out_of_range_payloads_are_not_counted(tmp_path, capsys, run_bag):
    from msgs_json import codec
    from msgs_json import schemas as S
    from msgs_json.envelope import Envelope

    clean = json.loads((run_bag / "report.json").read_text())

    def obs(**kw):
        o = S.Observation(**{"sat": "sat_11", "gp": 3, "t_ns": 60 * 10**9, "assumed_value": 5.0,
                             "recorded_value": 5.0, **kw})
        return Envelope(o.t_ns, "sat_11", 10**6 + len(kw), "/sat_11/observations", codec.encode(o))

    bad = [obs(gp=99999), obs(recorded_value=1e308, gp=4), obs(t_ns=10**15, gp=5), obs(recorded_value=0.0, gp=6),
           Envelope(70 * 10**9, "sat_12", 10**6, "/sat_12/observations",
                    codec.encode(S.Observation(sat="sat_11", gp=7, t_ns=70 * 10**9, assumed_value=1.0,
                                               recorded_value=9.0)))]
    bag = _bag_with(tmp_path, run_bag / "bag", {"envelopes": bad})
    code, out, err = cli(capsys, "report", bag)
    assert code == 0 and "Traceback" not in err
    rep = json.loads(out)
    assert rep["value"] == clean["value"] and rep["observations"] == clean["observations"]
    assert rep["report_rejections"] == {"observation.after_horizon": 1, "observation.gp_out_of_range": 1,
                                        "observation.recorded_value_out_of_range": 2,
                                        "observation.sat_not_its_topic": 1}
    assert "5 payloads not counted" in err


def test_observations_under_a_namespace_count_and_another_satellites_do_not():
    # a run whose nodes were pushed into a namespace records /fleet/sat_11/observations: its own
    # satellite's observations count there; one naming another satellite does not
    from bringup.analysis.report import ReportBuilder
    from msgs_json import codec
    from msgs_json import schemas as S
    from msgs_json.envelope import Envelope

    b = ReportBuilder()
    o = S.Observation(sat="sat_11", gp=3, t_ns=10**9, assumed_value=5.0, recorded_value=5.0)
    b.add(Envelope(o.t_ns, "sat_11", 0, "/fleet/sat_11/observations", codec.encode(o)))
    b.add(Envelope(o.t_ns, "sat_11", 1, "/fleet/sat_12/observations", codec.encode(o)))
    assert len(b.obs) == 1 and dict(b.rejected) == {"observation.sat_not_its_topic": 1}


# -- a full disk ------------------------------------------------------------------------------------
@pytest.fixture
def small_disk(tmp_path):
    """``make(name, size)``: a tmpfs of ``size`` (256 KiB unless told) mounted for the test, all
    removed after it (root: the CI and this machine)."""
    mounts = []

    def make(name: str, size: str = "256k") -> Path:
        mnt = tmp_path / name
        mnt.mkdir()
        subprocess.run(["mount", "-t", "tmpfs", "-o", f"size={size}", "tmpfs", str(mnt)], check=True)
        mounts.append(mnt)
        return mnt

    try:
        yield make
    finally:
        for mnt in mounts:
            subprocess.run(["umount", "-l", str(mnt)], check=False)
            shutil.rmtree(mnt, ignore_errors=True)


def test_full_disk_is_named(tmp_path, capsys, small_disk, run_bag):
    # a local run's bag fills the disk (centralized: no bundle stores): the recorder's error names
    # the device and the bag file (the disk holds the world cache, ~390 KB with 2000 GPs, not the
    # bag, ~1 MB)
    disk = small_disk("d1", "640k")
    one_line_error(capsys, ["run", "--engine", "local", "--mode", "centralized", "--sats", "12", "--hours", "2",
                            "--no-plots", "--no-progress", "--out", disk / "r"],
                   "no space left on device", disk / "r" / "bag" / "bag.mcap")
    status = json.loads((disk / "r" / "run_status.json").read_text())
    assert status["status"] == "failed" and "no space left on device" in status["error"]
    # the satellites' SQLite stores and the world cache fill it: named with the file or folder
    disk = small_disk("d2")
    one_line_error(capsys, ["run", "--engine", "local", "--sats", "12", "--hours", "2", "--no-plots",
                            "--no-progress", "--out", disk / "r"], "no space left on device", disk / "r" / "")
    # report --out onto a full disk: named, and no half-written file left
    disk = small_disk("d3")
    with contextlib.suppress(OSError), open(disk / "filler", "wb") as fh:
        fh.write(b"\x00" * (4 * 2**20))
    assert shutil.disk_usage(disk).free == 0
    one_line_error(capsys, ["report", run_bag / "bag", "--out", disk / "report.json"],
                   "no space left on device", "report.json")
    assert sorted(os.listdir(disk)) == ["filler"]
