"""The observed-knowledge kernel (sat_node/knowledge_kernels.py) gives numpy's bits.

Oracle: the numpy expression ``kernel_exponent`` replaces in ``ObservedView._ref`` (``einsum`` of
the (G, N, 3) differences, the scalings), run here as first written; a view whose region sums are
made by that expression, against the view as it is, on planner-shaped queries; and for
``innovation_grid`` the view's general (broadcast numpy) path, asked for the same pairs flat.
"""

from __future__ import annotations

import numpy as np
from dp_instances import square_region_gp_ecef_km

from ground_station.osse import OsseField
from sat_node.inference import Inference
from sat_node.knowledge import KnowledgeParams, KnowledgeState, ObservedView
from sat_node.knowledge_kernels import kernel_exponent


def _exponent_as_first_written(gp_xyz, obs_xyz, obs_t, t_now, spread_km, memory_s):
    dx = gp_xyz[:, None, :] - obs_xyz[None, :, :]
    return -0.5 * np.einsum("ijk,ijk->ij", dx, dx) / spread_km ** 2 - (t_now - obs_t)[None, :] / memory_s


def test_kernel_exponent_has_the_numpy_expressions_bits():
    """Random sizes (one GP, one look, hundreds), random places on the Earth and spreads; and the
    paper-like geometry: a 100-km square of 2-km GPs with looks at some of them."""
    rng = np.random.default_rng(11)
    cases = 0
    for _ in range(200):
        g, n = int(rng.integers(1, 200)), int(rng.integers(1, 300))
        c = rng.normal(size=3)
        c *= 6378.137 / np.linalg.norm(c)
        scale = float(rng.uniform(0.5, 150.0))
        gp = c + rng.normal(size=(g, 3)) * scale
        obs = c + rng.normal(size=(n, 3)) * scale
        t = rng.uniform(0.0, 20000.0, n)
        t_now, spread, mem = float(rng.uniform(20000.0, 22000.0)), float(rng.uniform(2.0, 30.0)), float(
            rng.uniform(300.0, 4000.0))
        got = kernel_exponent(gp, obs, t, t_now, spread ** 2, mem)
        assert got.tobytes() == _exponent_as_first_written(gp, obs, t, t_now, spread, mem).tobytes()
        cases += 1
    sq = square_region_gp_ecef_km(23.8, 90.4, 100.0, 2.0)
    for seed in range(5):
        r = np.random.default_rng(seed)
        looks = r.choice(len(sq), 400)
        t = r.uniform(0.0, 21600.0, 400)
        got = kernel_exponent(sq, np.ascontiguousarray(sq[looks]), t, 21600.0, 100.0, 1298.4)
        assert got.tobytes() == _exponent_as_first_written(sq, sq[looks], t, 21600.0, 10.0, 1298.4).tobytes()
    assert cases == 200


class _NumpyView(ObservedView):
    """The view with its region sums made by the numpy expression (``_ref`` as first written)."""

    def _ref(self, gps):
        n = np.zeros(len(gps))
        w = np.zeros(len(gps))
        o = self._obs
        if len(o["gp"]) == 0:
            return n, w
        for r in np.unique(self._region[gps]):
            sel = np.flatnonzero(self._region[gps] == r)
            mo = o["region"] == r
            if not mo.any():
                continue
            k = np.exp(_exponent_as_first_written(self._xyz[gps[sel]], o["xyz"][mo], o["t_s"][mo], self._t,
                                                  self._p.spread_km, self._p.memory_s))
            n[sel], w[sel] = k @ o["d"][mo], k.sum(axis=1)
        return n, w


def test_observed_view_with_the_kernel_equals_the_numpy_view():
    """Four 50-km regions of 2.5-km GPs, 600 looks in three of them; asked as a planner asks (a row
    of GPs by a column of times, whole regions and parts: the compiled innovation_grid) and flat
    (the general numpy path): the values' bits are the numpy view's."""
    rng = np.random.default_rng(4)
    xyz = np.concatenate([square_region_gp_ecef_km(lat, lon, 50.0, 2.5) for lat, lon in
                          ((23.8, 90.4), (51.5, -0.1), (-6.2, 106.8), (29.8, -95.4))])
    n_gp = len(xyz)
    regions = np.repeat([0, 1, 2, 3], n_gp // 4)  # region 3: no look, no insight
    vals = rng.integers(1, 257, (8, n_gp)).astype(np.int16)
    f = OsseField(values=vals, slot_s=900.0, lat_deg=np.zeros(n_gp), lon_deg=np.linspace(0, 1, n_gp),
                  region_index=regions, region_names=["a", "b", "c", "d"],
                  forecast=rng.integers(1, 257, (8, n_gp)).astype(np.int16))
    params = KnowledgeParams(model="observed", spread_km=10.0, memory_s=1298.4)
    ks = KnowledgeState(params, "sat_11")
    for _ in range(600):
        g, t = int(rng.integers(0, 3 * n_gp // 4)), float(rng.uniform(0, 6000))
        ks.learn(Inference("sat_21", g, int(t * 1e9), float(rng.uniform(1, 256)), int(regions[g]),
                           float(rng.normal()), float(rng.normal())))
    view = ks.knowledge(f, regions, xyz, 6000.0, [], None).value
    ref = _NumpyView(f, regions, xyz, view._obs, view._insight, params, 6000.0)
    times = 6000.0 + 9.0 * np.arange(67)
    assert set(view._insight) == {0, 1, 2}
    for ids in (np.arange(n_gp), np.arange(0, n_gp // 4), np.arange(3 * n_gp // 4 - 20, n_gp),
                np.sort(rng.choice(n_gp, 150, replace=False)), np.arange(n_gp)):
        got = view.value_at(ids[None, :], times[:, None])
        assert got.tobytes() == ref.value_at(ids[None, :], times[:, None]).tobytes()
        gg, tt = np.meshgrid(ids, times)
        assert view.value_at(gg.ravel(), tt.ravel()).tobytes() == got.tobytes()  # flat: the masked path
