"""report.json's value figures on a bag of nine observations, worked out by hand.

The bag is written with the project's bag writer (bringup/recording/bag.py): a ``/run/meta`` record
(2 satellites, 10 GPs, ``revisit_zero_s`` = 900 s) and nine ``Observation`` messages on
``/sat_11/observations`` and ``/sat_12/observations``. The report is rebuilt from the bag alone by
``constellation report BAG --out report.json`` (bringup/analysis/report.py ``report_from_bag``).

Oracle: the study's Eq. 1 (Nag et al., ICAPS SPARK 2019, section 4; sat_node/value.py) applied by
hand, observation by observation in time order (ties by satellite name): an observation of GP g
with recorded OSSE value ``v`` is worth 0 when g was seen less than 900 s before (a duplicate),
else ``v / (n + 1)`` with n the looks at g before it; every look counts as seen. The nine looks
cover: first looks, a second look exactly 900 s after (counts, halved), one 899.999 s after (0), a
tie at one time between two satellites written to the bag in the losing satellite's order first, a
look after a duplicate (the duplicate counts in n), and a look recording 0 - outside the OSSE's
values 1..256 (ground_station/osse.py), so no look of a run: the report does not count it and says
so in ``report_rejections``. Every expected figure below is
written out with its arithmetic; the sums are exact in binary floating point, so they are compared
exactly (the error means to 1e-12).
"""

from __future__ import annotations

import json

from bringup.analysis.report import RunMeta
from bringup.cli.main import main
from bringup.recording.bag import BagWriter
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json.envelope import Envelope

S_NS = 1_000_000_000
EPOCH_NS = 946_727_968 * S_NS  # 2000-01-01T11:59:28Z, the paper scenario's epoch

# (sat, gp, t_ns, recorded_value, assumed_value), in the order they are written to the bag
LOOKS = [
    ("sat_12", 3, 100 * S_NS, 120.0, 110.0),          # a: GP 3 first look
    ("sat_11", 5, 100 * S_NS, 64.0, 60.0),            # b: GP 5 first look
    ("sat_12", 7, 400 * S_NS, 200.0, 190.0),          # c: GP 7, same time as d, written first
    ("sat_11", 7, 400 * S_NS, 200.0, 210.0),          # d: GP 7, sat_11 sorts first: the first look
    ("sat_11", 3, 1000 * S_NS, 90.0, 80.0),           # e: GP 3, exactly 900 s after a
    ("sat_11", 7, 1300 * S_NS, 150.0, 40.0),          # f: GP 7, exactly 900 s after c and d
    ("sat_12", 3, 1_899_999_000_000, 90.0, 30.0),     # g: GP 3, 899.999 s after e
    ("sat_12", 9, 2000 * S_NS, 0.0, 5.0),             # h: GP 9, a value no OSSE holds: not counted
    ("sat_12", 3, 2900 * S_NS, 100.0, 20.0),          # i: GP 3, 1000.001 s after g
]

# Eq. 1 by hand, in time order (ties by satellite name: d before c):
#   a  t=100    GP3 never seen                -> 120 / (0+1) = 120     (sat_12)
#   b  t=100    GP5 never seen                ->  64 / (0+1) =  64     (sat_11)
#   d  t=400    GP7 never seen                -> 200 / (0+1) = 200     (sat_11)
#   c  t=400    GP7 seen 0 s before by d      ->   0, duplicate        (sat_12)
#   e  t=1000   GP3 last 100: 900 s, not < 900; n=1 ->  90 / 2 = 45  (sat_11)
#   f  t=1300   GP7 last 400: 900 s; n=2 (d, c)      -> 150 / 3 = 50  (sat_11)
#   g  t=1899.999 GP3 last 1000: 899.999 s < 900 ->   0, duplicate     (sat_12)
#   h  t=2000   recorded 0, outside 1..256    ->  not counted (report_rejections)
#   i  t=2900   GP3 last 1899.999: 1000.001 s; n=3 (a, e, g) -> 100 / 4 = 25 (sat_12)
CUMULATIVE = 120.0 + 64.0 + 200.0 + 0.0 + 45.0 + 50.0 + 0.0 + 25.0  # = 504
PER_SAT = {"sat_11": 64.0 + 200.0 + 45.0 + 50.0,  # = 359
           "sat_12": 120.0 + 0.0 + 0.0 + 25.0}  # = 145
DUPLICATES = 2  # c, g
# first look at each GP: a (GP3, 120), b (GP5, 64), d (GP7, 200) -> 384 of 504
FIRST_LOOK_SHARE = (120.0 + 64.0 + 200.0) / 504.0  # = 0.761904...
# |assumed - true| / true over the looks with a true value > 0:
#   a |110-120|/120 = 1/12, b |60-64|/64 = 1/16, d |210-200|/200 = 1/20,
#   e |80-45|/45 = 7/9, f |40-50|/50 = 1/5, i |20-25|/25 = 1/5
#   mean = (60 + 45 + 36 + 560 + 144 + 144) / 720 / 6 = 989 / 4320 = 0.228935...
#   median of (1/20, 1/16, 1/12, 1/5, 1/5, 7/9) = (1/12 + 1/5) / 2 = 17/120 = 0.141666...
ERROR_MEAN = 989.0 / 4320.0
ERROR_MEDIAN = 17.0 / 120.0
N_GP = 10
# GPs 3, 5, 7 observed: 3 of 10; 8 looks counted over 10 GPs
GP_OBSERVED, GP_FRACTION, LOOKS_PER_GP = 3, 3 / 10, 8 / 10

META = RunMeta(scenario="hand-worked", mode="distributed", engine="local", seed=1, horizon_s=3600.0, n_sats=2,
               n_gp=N_GP, revisit_zero_s=900.0, knowledge="observed", osse={})


def _write_bag(path) -> None:
    seq: dict[str, int] = {}
    with BagWriter(path, epoch_ns=EPOCH_NS) as bag:
        bag.write_envelope(Envelope(0, "run", 0, "/run/meta", json.dumps({"meta": META.__dict__})))
        for sat, gp, t_ns, recorded, assumed in LOOKS:
            msg = S.Observation(sat=sat, gp=gp, t_ns=t_ns, assumed_value=assumed, recorded_value=recorded,
                                schedule_version=1)
            seq[sat] = seq.get(sat, -1) + 1
            bag.write_envelope(Envelope(t_ns, sat, seq[sat], f"/{sat}/observations", codec.encode(msg)))
        bag.write_envelope(Envelope(3600 * S_NS, "run", 1, "/run/meta",
                                    json.dumps({"meta": META.__dict__, "runtime": {"wall_s": 1.0}})))


def _report(tmp_path) -> dict:
    _write_bag(tmp_path / "bag")
    out = tmp_path / "report.json"
    assert main(["report", str(tmp_path / "bag"), "--out", str(out)]) == 0
    return json.loads(out.read_text())


def test_hand_worked_value_figures(tmp_path):
    rep = _report(tmp_path)
    assert CUMULATIVE == 504.0 and PER_SAT == {"sat_11": 359.0, "sat_12": 145.0}  # the sums above
    assert rep["value"]["cumulative"] == CUMULATIVE
    assert rep["value"]["per_sat"] == PER_SAT
    assert rep["value"]["first_look_share"] == FIRST_LOOK_SHARE
    assert abs(rep["value"]["assumed_error_mean"] - ERROR_MEAN) < 1e-12
    assert abs(rep["value"]["assumed_error_median"] - ERROR_MEDIAN) < 1e-12
    assert rep["observations"] == {"count": 8, "duplicates_15min": DUPLICATES, "duplicate_fraction": DUPLICATES / 8}
    assert rep["report_rejections"] == {"observation.recorded_value_out_of_range": 1}  # h
    assert rep["coverage"] == {"gp_observed": GP_OBSERVED, "gp_total": N_GP, "gp_observed_fraction": GP_FRACTION,
                               "looks_per_gp": LOOKS_PER_GP}
    assert (rep["scenario"], rep["n_sats"], rep["horizon_s"]) == ("hand-worked", 2, 3600.0)
    assert rep["runtime"]["wall_s"] == 1.0  # the last /run/meta record's runtime

