"""KnowledgeState keeps the inferences it knows in numpy columns: the same numbers as its lists.

Oracle: the state as first written (``_ListState``, kept here: Python lists of every inference,
converted with ``np.asarray`` at every plan and every own look), fed the same inferences and own
looks in the same order (bundles learned twice, looks in several regions, times out of order,
old looks past the memory): every region insight an own look carries, every view's inputs
(looks, innovations) and values, bit for bit; and a pickled state (the satellite's checkpoint)
holds the columns without spare room and goes on as the original.
"""

from __future__ import annotations

import math
import pickle

import numpy as np

from ground_station.osse import OsseField
from sat_node.inference import Inference
from sat_node.knowledge import _LN_MAX, KnowledgeParams, KnowledgeState, ObservedView


class _ListState:
    """KnowledgeState's record and its two readers as first written (lists)."""

    def __init__(self, params, me):
        self.params, self.me = params, me
        self.insight: dict = {}
        self._keys: set = set()
        self._gp, self._t, self._v, self._region = [], [], [], []

    def learn(self, inf):
        key = (inf.src, int(inf.gp), int(inf.t_ns))
        if key in self._keys:
            return False
        self._keys.add(key)
        t = inf.t_ns / 1e9
        self._gp.append(int(inf.gp))
        self._t.append(t)
        self._v.append(float(inf.value))
        self._region.append(int(inf.region))
        old = self.insight.get(int(inf.region))
        if old is None or t > old[0]:
            self.insight[int(inf.region)] = (t, float(inf.omega), float(inf.delta))
        return True

    def observe(self, field, gp, t_ns, inferred, region):
        t_s = t_ns / 1e9
        self._gp.append(int(gp))
        self._t.append(t_s)
        self._v.append(float(inferred))
        self._region.append(int(region))
        omega, delta = self.region_insight(field, int(region), t_s)
        for lst in (self._gp, self._t, self._v, self._region):
            lst.pop()
        inf = Inference(src=self.me, gp=int(gp), t_ns=int(t_ns), value=float(inferred), region=int(region),
                        omega=omega, delta=delta)
        self.learn(inf)
        return inf

    def region_insight(self, field, region, t_s):
        t_all = np.asarray(self._t, np.float64)
        sel = np.flatnonzero((np.asarray(self._region, np.int64) == region) & (t_all <= t_s))
        if len(sel) == 0:
            return 0.0, 0.0
        gp = np.asarray(self._gp, np.int64)[sel]
        t = t_all[sel]
        v = np.asarray(self._v, np.float64)[sel]
        d = np.log(np.maximum(v, 1.0) / field.forecast_at(gp, t).astype(np.float64))
        w = np.exp(-(t_s - t) / self.params.memory_s)
        omega = float(np.clip((w @ d) / w.sum(), -_LN_MAX, _LN_MAX))
        delta = 0.0
        prev = self.insight.get(region)
        if prev is not None and 0.0 < t_s - prev[0] <= self.params.memory_s:
            delta = float(np.clip((omega - prev[1]) / ((t_s - prev[0]) / 3600.0), -_LN_MAX, _LN_MAX))
        return omega, delta

    def view(self, field, region_index, gp_ecef_km, t_now_s):
        gp = np.asarray(self._gp, np.int64)
        t = np.asarray(self._t, np.float64)
        keep = (t <= t_now_s) & (t_now_s - t < 7.0 * self.params.memory_s)
        gp, t = gp[keep], t[keep]
        v = np.asarray(self._v, np.float64)[keep]
        d = np.log(np.maximum(v, 1.0) / field.forecast_at(gp, t).astype(np.float64)) if len(gp) else np.zeros(0)
        obs = {"gp": gp, "t_s": t, "d": d, "region": np.asarray(region_index)[gp] if len(gp) else np.zeros(0, int),
               "xyz": gp_ecef_km[gp] if len(gp) else np.zeros((0, 3))}
        insight = {r: x for r, x in self.insight.items() if x[0] <= t_now_s}
        return ObservedView(field, np.asarray(region_index), gp_ecef_km, obs, insight, self.params, t_now_s)


def test_columns_give_the_lists_numbers():
    rng = np.random.default_rng(8)
    n_gp = 300
    regions = np.repeat(np.arange(3), 100)
    f = OsseField(values=rng.integers(1, 257, (30, n_gp)).astype(np.int16), slot_s=900.0, lat_deg=np.zeros(n_gp),
                  lon_deg=np.linspace(0, 1, n_gp), region_index=regions, region_names=["a", "b", "c"],
                  forecast=rng.integers(1, 257, (30, n_gp)).astype(np.int16))
    xyz = 6378.0 * np.column_stack([np.ones(n_gp), rng.normal(size=n_gp) * 0.01, rng.normal(size=n_gp) * 0.01])
    params = KnowledgeParams(model="observed", spread_km=10.0, memory_s=1298.4)
    new, old = KnowledgeState(params, "sat_11"), _ListState(params, "sat_11")
    ids = np.arange(n_gp)
    delivered = []
    compared = 0
    for step in range(1500):
        t_now = 15.0 * step
        u = rng.uniform()
        if u < 0.3:  # an own look
            g = int(rng.integers(0, n_gp))
            t_ns = int(t_now * 1e9)
            a = new.observe(f, g, t_ns, float(rng.uniform(0.5, 256)), int(regions[g]))
            b = old.observe(f, a.gp, t_ns, a.value, a.region)
            assert (a.omega, a.delta) == (b.omega, b.delta) and math.isfinite(a.omega)
        elif u < 0.8:  # a delivered bundle, now and then again, times out of order
            if delivered and rng.uniform() < 0.2:
                inf = delivered[int(rng.integers(0, len(delivered)))]
            else:
                g = int(rng.integers(0, n_gp))
                inf = Inference(f"sat_{int(rng.integers(0, 9))}", g, int(max(0.0, t_now - rng.uniform(0, 3000)) * 1e9),
                                float(rng.uniform(0.5, 256)), int(regions[g]), float(rng.normal()), float(rng.normal()))
                delivered.append(inf)
            assert new.learn(inf) == old.learn(inf)
        if step % 50 == 49:  # a plan
            got = new.knowledge(f, regions, xyz, t_now, [], None).value
            want = old.view(f, regions, xyz, t_now)
            for k in ("gp", "t_s", "d", "region", "xyz"):
                assert got._obs[k].tobytes() == want._obs[k].tobytes() and got._obs[k].dtype == want._obs[k].dtype
            times = t_now + 10.0 * np.arange(20)
            assert got.value_at(ids[None, :], times[:, None]).tobytes() == \
                want.value_at(ids[None, :], times[:, None]).tobytes()
            for r in range(3):
                assert new.region_insight(f, r, t_now) == old.region_insight(f, r, t_now)
            compared += 1
    assert len(new) == len(old._gp) > 500 and compared == 30
    back = pickle.loads(pickle.dumps(new))
    assert len(back._cols[0]) == len(new)  # no spare room in the checkpoint
    for a, b in zip(back._columns(), new._columns()):
        assert a.tobytes() == b.tobytes()
    g = 5
    a = back.observe(f, g, int(22600e9), 77.0, int(regions[g]))
    b = new.observe(f, g, int(22600e9), 77.0, int(regions[g]))
    assert (a.omega, a.delta) == (b.omega, b.delta) and len(back) == len(new)


def test_innovations_in_batches_of_every_size_equal_one_batch():
    """The innovations are made for the inferences learned since the last plan: batches of 1 to 40
    and the rest, against all at once (the old view's one batch), bit for bit - numpy's log and
    the division are elementwise whatever the batch - and every view's looks equal the oracle's."""
    rng = np.random.default_rng(31)
    n_gp, n = 500, 60000
    f = OsseField(values=rng.integers(1, 257, (30, n_gp)).astype(np.int16), slot_s=900.0, lat_deg=np.zeros(n_gp),
                  lon_deg=np.linspace(0, 1, n_gp), region_index=np.zeros(n_gp, int), region_names=["a"],
                  forecast=rng.integers(1, 257, (30, n_gp)).astype(np.int16))
    ks = KnowledgeState(KnowledgeParams(model="observed"), "sat_11")
    gp = rng.integers(0, n_gp, n)
    t = rng.uniform(0.0, 26000.0, n)
    v = np.exp(rng.uniform(-1.0, 6.0, n))  # below 1 too: max(v, 1)
    i = 0
    batches = 0
    while i < n:
        k = int(rng.integers(1, 41)) if batches % 50 else n // 40
        for j in range(i, min(n, i + k)):
            ks.learn(Inference("sat_2", int(gp[j]), int(t[j] * 1e9), float(v[j]), 0, 0.0, 0.0))
        i += k
        batches += 1
        ks._innovations(f)
    g, tt, vv, _r = ks._columns()
    want = np.log(np.maximum(vv, 1.0) / f.forecast_at(g, tt).astype(np.float64))
    assert batches > 1000 and len(ks) == n
    assert ks._innovations(f).tobytes() == want.tobytes()
    other = OsseField(values=f.values, slot_s=900.0, lat_deg=f.lat_deg, lon_deg=f.lon_deg, region_index=f.region_index,
                      region_names=["a"], forecast=f.forecast[::-1].copy())
    assert ks._innovations(other).tobytes() != want.tobytes()  # another field: made again for it
    assert ks._innovations(f).tobytes() == want.tobytes()
