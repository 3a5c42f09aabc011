"""The authors' DTN simulator on the study's inputs, for bench/bench_dtn.py --side-by-side.

dtnsim (github msancheznet/dtnsim, the simulator that accompanied Nag et al.'s study; Python 3.7 with
2019-era packages) is never part of this repository: the caller names a checkout of it
(``--dtnsim-src``) and a Python 3.7 that has its dependencies (``--dtnsim-python``), e.g.::

    ~/.pyenv/versions/3.7.16/bin/python -m venv /tmp/dtnsim-venv
    /tmp/dtnsim-venv/bin/pip install pydantic==0.13 simpy==3.0.11 'networkx<2.6' pandas==0.25.3 \\
        numpy==1.17.5 pyyaml==5.1.2 tables==3.6.1 xlrd==1.2.0 'openpyxl<3.1' lxml==4.6.5

:func:`write_inputs` writes, into a scratch folder, its walker scenario (DTNSIM_SRC/tests/test_walker_cons.yaml
of that checkout: 24 satellites, CGR router, scheduled broadcast connections, its own contact plan
and range workbooks) edited to the study's DTN-alone setting: 21600 s, a 1 kb/s radio, and each
satellite's traffic written from this repository's traffic table (tests/fixtures/paper_inputs, itself
converted from that checkout's files), so both simulators read the same bundles. Its packet
generator gives every bundle a 100-min TTL; the driver (:data:`DRIVER`, run by the given Python)
replaces that one method with the study's TTLs by priority (the same table as ``constellation dtn
--ttl-s``) before it runs the simulation, and prints one JSON line: wall time of the simulation,
bundles created and arrived.
"""

from __future__ import annotations

import csv
import json
import resource
import subprocess
import time
from pathlib import Path

# dtnsim's DTNSIM_SRC/tests/test_walker_cons.yaml with the study's DTN-alone edits (until, rate, traffic folder)
SCENARIO = """\
globals:
  indir:   {indir}
  outdir:  {outdir}
  outfile: side_by_side.h5
  logfile: side_by_side.log
  log:     False
  track:   True
scenario:
  epoch:  01-JAN-2000 11:59:28 UTC
  seed:   0
  until:  {until}
scheduled_mobility:
  class:    DtnScheduledMobilityModel
  contacts: 3p_8s_contact_plan.xlsx
  ranges:   3p_8s_range_intervals.xlsx
network:
  constellation:
    {{node: {{type: satellite, alias: s}}, num_sat: 8, num_planes: 3}}
  connections:
    Con: {{origin:, destination:, type: connection}}
satellite:
  class:          DtnNode
  relay:          True
  router:         agc_router
  generators:     [packet_generator]
  selector:       band_selector
  radios:         [basic_radio]
  mobility_model: scheduled_mobility
agc_router:
  class:            AgcCgrRouter
  excluded_routes:  []
  relays:           all
  max_relay_hops:   100000000
band_selector:
  class: DtnDefaultSelector
connection:
  class:    DtnScheduledBroadcastConnection
  ducts:    {{D: basic_duct}}
  mobility_model: scheduled_mobility
basic_duct:
  class: ['DtnInductBasic', 'DtnOutductBasic']
  radio: 'basic_radio'
basic_radio:
  class: DtnBasicRadio
  rate:  !!float {rate_bps}
  BER:   !!float 0.0
packet_generator:
  class:        AgcPacketGenerator
  file:         ./traffic/{{}}_withPriority
  data_type:    file
  bundle_size:  {bundle_bits}
  bundle_TTL:   3600
  critical:     False
  until:        {until}
reports:
  - DtnSentBundlesReport
  - DtnArrivedBundlesReport
  - DtnDroppedBundlesReport
"""

DRIVER = """\
import json, os, sys, time
src, config_path, ttl = sys.argv[1], sys.argv[2], json.loads(sys.argv[3])
sys.path.insert(0, src)
os.chdir(src)
from simulator.utils.DtnConfigParser import load_configuration_file
from simulator.generators.AgcPacketGenerator import AgcPacketGenerator
from bin.main import run_simulation

def get_bundle_TTL(self, priority):  # the study's TTL by priority, as constellation dtn --ttl-s
    for top, seconds in sorted((int(k), v) for k, v in ttl.items()):
        if priority <= top:
            return seconds
    return max(ttl.values())

AgcPacketGenerator.get_bundle_TTL = get_bundle_TTL
config = load_configuration_file(config_path)
t0 = time.perf_counter()
env, res, ok = run_simulation(config=config, return_env=True)
wall = time.perf_counter() - t0
out = {"sim_wall_s": wall, "until_s": env.now}
for key in ("sent", "arrived", "dropped"):
    df = res.get(key)
    out[key] = None if df is None else int(len(df))
print("DTNSIM " + json.dumps(out))
"""


def write_inputs(dtnsim_src: Path, traffic_csv: Path, folder: Path, *, until_s: float = 21600.0,
                 rate_bps: float = 1000.0, bundle_bits: int = 2000) -> Path:
    """dtnsim's inputs for ``traffic_csv`` in ``folder`` (module docstring); returns the config file."""
    walker = Path(dtnsim_src) / "tests" / "inputs" / "test_walker_cons"
    if not (walker / "3p_8s_contact_plan.xlsx").is_file():
        raise SystemExit(f"--dtnsim-src {dtnsim_src}: no {walker / '3p_8s_contact_plan.xlsx'} "
                         "(a checkout of msancheznet/dtnsim?)")
    indir = folder / "inputs"
    (indir / "traffic").mkdir(parents=True, exist_ok=True)
    for name in ("3p_8s_contact_plan.xlsx", "3p_8s_range_intervals.xlsx"):
        (indir / name).write_bytes((walker / name).read_bytes())
    with open(traffic_csv, newline="") as fh:
        rows = list(csv.reader(fh))
    header, body = rows[0], rows[1:]
    sats = header[4:]
    by_src: dict[str, list[str]] = {s: [] for s in sats}
    for r in body:  # source,time_s,packet_id,region,Sat11..Sat38 -> dtnsim's whitespace table per source
        region = r[3].replace(" ", "")
        by_src[r[0]].append(" ".join([r[1], r[2], region, *r[4:]]))
    head = " ".join(["Time[s]", "DataPacket_ID", "(Super)Region_tag", *sats])
    for s, lines in by_src.items():
        (indir / "traffic" / f"{s}_withPriority").write_text("\n".join([head, *lines]) + "\n")
    (folder / "out").mkdir(exist_ok=True)
    config = folder / "scenario.yaml"
    config.write_text(SCENARIO.format(indir=indir, outdir=folder / "out", until=int(until_s), rate_bps=rate_bps,
                                      bundle_bits=bundle_bits))
    (folder / "driver.py").write_text(DRIVER)
    return config


def run_dtnsim(python: str, dtnsim_src: Path, config: Path, ttl_s_by_priority: dict[int, float]) -> dict:
    """Run dtnsim once; its JSON line plus the wall time and the CPU time of the whole process
    (``wall_s``, ``cpu_s``)."""
    r0 = resource.getrusage(resource.RUSAGE_CHILDREN)
    t0 = time.perf_counter()
    p = subprocess.run([python, str(config.parent / "driver.py"), str(Path(dtnsim_src).resolve()), str(config),
                        json.dumps({str(k): v for k, v in ttl_s_by_priority.items()})],
                       check=False, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    r1 = resource.getrusage(resource.RUSAGE_CHILDREN)
    lines = [ln for ln in p.stdout.splitlines() if ln.startswith("DTNSIM ")]
    if p.returncode != 0 or not lines:
        raise SystemExit(f"dtnsim failed (exit {p.returncode}): {p.stderr.strip().splitlines()[-1:]}")
    out = json.loads(lines[-1][len("DTNSIM "):])
    out["wall_s"] = wall
    out["cpu_s"] = (r1.ru_utime - r0.ru_utime) + (r1.ru_stime - r0.ru_stime)
    return out
