"""bringup/recording/metrics_feed.py: the plotted series (value so far, bundles in flight).

Oracles: the value points are the report's own Eq. 1 total (bringup/analysis/report.py true_values)
of the observations up to each point, whatever order they arrived in; a point is withheld while the
recorder misses an observation; the CDR is what rosbags serializes. The end-to-end check (the
series' last value equals report.json's ``value.cumulative`` after a recorded run) is in
tests/unit/test_record_process.py.
"""

from __future__ import annotations

import random

from bringup.analysis.report import true_values
from bringup.recording.bag import TYPESTORE
from bringup.recording.metrics_feed import FLOAT64, UINT32, MetricsFeed
from msgs_json import codec
from msgs_json import schemas as S
from msgs_json.envelope import Envelope
from msgs_json.topics import VIZ_IN_FLIGHT, VIZ_VALUE

S_NS = 1_000_000_000


class _Bag:
    def __init__(self):
        self.rows = []
        self.cdr = []

    def write_raw(self, topic, msgtype, cdr, t_ns):
        self.rows.append((topic, t_ns, TYPESTORE.deserialize_cdr(cdr, msgtype).data))
        self.cdr.append((msgtype, bytes(cdr)))


def _obs(rng, t_s, sat):
    return S.Observation(sat=sat, gp=rng.randrange(4), t_ns=t_s * S_NS, assumed_value=1.0,
                         recorded_value=float(rng.randrange(1, 257)))


def _env(o, seq):
    return Envelope(o.t_ns, o.sat, seq, f"/{o.sat}/observations", codec.encode(o))


def test_value_points_are_the_reports_total_in_any_arrival_order():
    rng = random.Random(3)
    obs = [_obs(rng, t, sat) for t in range(0, 3600, 37) for sat in ("sat_11", "sat_12") if rng.random() < 0.7]
    series = []
    for shuffle in (False, True):
        feed, bag = MetricsFeed(900.0), _Bag()
        step_s = 10
        for t in range(0, 3600 + step_s, step_s):
            batch = [o for o in obs if t - step_s < o.t_ns / S_NS <= t]  # what step t emitted
            if shuffle:
                rng.shuffle(batch)
            for i, o in enumerate(batch):
                feed.observe(_env(o, i))
            feed.write(bag, t * S_NS, in_flight=t // 100)
        series.append(bag.rows)
        points = [(tt, v) for topic, tt, v in bag.rows if topic == VIZ_VALUE]
        assert len(points) == 61  # every 60 s from 0 to 3600 s
        for tt, v in points:
            want = sum(val for _o, val, _d in true_values([o for o in obs if o.t_ns <= tt], 900.0))
            assert v == want
        flights = [(tt, v) for topic, tt, v in bag.rows if topic == VIZ_IN_FLIGHT]
        assert flights[:3] == [(0, 0), (60 * S_NS, 0), (120 * S_NS, 1)]
    assert series[0] == series[1]


def test_a_point_waits_for_missing_observations():
    feed, bag = MetricsFeed(900.0), _Bag()
    o1 = S.Observation(sat="sat_11", gp=1, t_ns=5 * S_NS, assumed_value=1.0, recorded_value=100.0)
    o2 = S.Observation(sat="sat_12", gp=1, t_ns=8 * S_NS, assumed_value=1.0, recorded_value=50.0)
    feed.observe(_env(o2, 0))  # o1 not recorded yet: the point is withheld, not written wrong
    feed.write(bag, 10 * S_NS, complete=False)
    assert bag.rows == []
    feed.observe(_env(o1, 0))
    feed.write(bag, 20 * S_NS)  # sat_11 at 5 s is worth 100, sat_12 repeats it within 15 min: 0
    assert bag.rows == [(VIZ_VALUE, 20 * S_NS, 100.0)]
    feed.write(bag, 30 * S_NS, final=True)  # the last point is written whatever the period
    assert bag.rows[-1] == (VIZ_VALUE, 30 * S_NS, 100.0)


def test_bad_payload_is_counted_and_cdr_matches_rosbags():
    feed, bag = MetricsFeed(900.0), _Bag()
    feed.observe(Envelope(0, "sat_11", 0, "/sat_11/observations", '{"sat": "sat_11"}'))
    feed.observe(Envelope(0, "sat_11", 1, "/sat_11/schedule", "not looked at"))
    assert feed.rejected == 1
    feed.write(bag, 0, in_flight=7)
    assert bag.rows == [(VIZ_VALUE, 0, 0.0), (VIZ_IN_FLIGHT, 0, 7)]
    T = TYPESTORE.types
    assert bag.cdr == [(FLOAT64, bytes(TYPESTORE.serialize_cdr(T[FLOAT64](data=0.0), FLOAT64))),
                       (UINT32, bytes(TYPESTORE.serialize_cdr(T[UINT32](data=7), UINT32)))]
