"""The observed-knowledge kernel (sat_node/knowledge_kernels.py) gives numpy's bits.

Oracle: the numpy expression ``kernel_exponent`` replaces in ``ObservedView._ref`` (``einsum`` of
the (G, N, 3) differences, the scalings), run here as first written; a view whose region sums are
made by that expression, against the view as it is, on planner-shaped queries; and for
``innovation_grid`` the view's general (broadcast numpy) path, asked for the same pairs flat. For the distance term
made once per place (``place_exponent``, ``gathered_exponent``): ``kernel_exponent`` itself, and a
view whose region sums are made as before it (``kernel_exponent``, a fresh ``np.exp``), kept here
as the oracle, on looks that revisit GPs, with regions large enough that BLAS shares the
matrix-vector product among threads.
"""

from __future__ import annotations

import numpy as np
from dp_instances import square_region_gp_ecef_km

from ground_station.osse import OsseField
from sat_node.inference import Inference
from sat_node.knowledge import KnowledgeParams, KnowledgeState, ObservedView
from sat_node.knowledge_kernels import gathered_exponent, kernel_exponent, place_exponent


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

    def _exponent(self, gp_xyz, o, mo):
        return _exponent_as_first_written(gp_xyz, o["xyz"][mo], o["t_s"][mo], self._t,
                                          self._p.spread_km, self._p.memory_s)

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
            k = np.exp(self._exponent(self._xyz[gps[sel]], o, mo))
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


def test_gathered_exponent_has_the_kernels_bits():
    """Looks at GPs (the places), many at the same ones, random times; GPs asked for a subset of the
    region or all of it: the gathered exponent's bits are kernel_exponent's and numpy's."""
    rng = np.random.default_rng(12)
    sq = square_region_gp_ecef_km(51.5, -0.1, 100.0, 2.0)
    cases = 0
    for _ in range(60):
        n = int(rng.integers(1, 3000))
        looks = rng.choice(len(sq), n) if rng.uniform() < 0.5 else rng.choice(int(rng.integers(1, 40)), n)
        gps = np.sort(rng.choice(len(sq), int(rng.integers(1, 300)), replace=False))
        t = rng.uniform(0.0, 21600.0, n)
        t_now, spread, mem = float(rng.uniform(21600.0, 23000.0)), float(rng.uniform(2.0, 30.0)), float(
            rng.uniform(300.0, 4000.0))
        obs = np.ascontiguousarray(sq[looks])
        _ids, first, place_of = np.unique(looks, return_index=True, return_inverse=True)
        gxyz = np.ascontiguousarray(sq[gps])
        out = np.full((len(gps), n), np.nan)
        got = gathered_exponent(place_exponent(gxyz, np.ascontiguousarray(obs[first]), spread ** 2), place_of, t,
                                t_now, mem, out)
        assert got is out
        want = kernel_exponent(gxyz, obs, t, t_now, spread ** 2, mem)
        assert got.tobytes() == want.tobytes()
        assert got.tobytes() == _exponent_as_first_written(gxyz, obs, t, t_now, spread, mem).tobytes()
        cases += 1
    assert cases == 60


class _KernelView(_NumpyView):
    """The view with its region sums made as before the places: kernel_exponent over every look, a
    fresh np.exp, then numpy's product and row sums."""

    def _exponent(self, gp_xyz, o, mo):
        return kernel_exponent(np.ascontiguousarray(gp_xyz), np.ascontiguousarray(o["xyz"][mo], np.float64),
                               np.ascontiguousarray(o["t_s"][mo], np.float64), self._t,
                               self._p.spread_km ** 2, self._p.memory_s)


def test_observed_view_by_places_equals_the_view_before_them():
    """Two 80-km regions of 2-km GPs (1600 each) and a small one; thousands of looks revisiting GPs
    (a region's GPs by its looks: up to 1600 x 6000, past the size at which BLAS shares the product
    among threads), asked as a planner asks, whole regions, parts, one GP; and a view whose looks'
    positions are not their GPs' (the path without places): the values' bits are the old view's."""
    rng = np.random.default_rng(21)
    xyz = np.concatenate([square_region_gp_ecef_km(lat, lon, size, 2.0) for lat, lon, size in
                          ((23.8, 90.4, 80.0), (51.5, -0.1, 80.0), (-6.2, 106.8, 10.0))])
    regions = np.repeat([0, 1, 2], [1600, 1600, 25])
    n_gp = len(xyz)
    vals = rng.integers(1, 257, (40, n_gp)).astype(np.int16)
    f = OsseField(values=vals, slot_s=900.0, lat_deg=np.zeros(n_gp), lon_deg=np.linspace(0, 1, n_gp),
                  region_index=regions, region_names=["a", "b", "c"],
                  forecast=rng.integers(1, 257, (40, n_gp)).astype(np.int16))
    params = KnowledgeParams(model="observed", spread_km=10.0, memory_s=1298.4)
    ks = KnowledgeState(params, "sat_11")
    hot = rng.choice(1600, 120, replace=False)  # GPs looked at again and again
    for i in range(9000):
        g = int(hot[i % 120] if i % 3 else rng.integers(0, n_gp))
        if i % 2:
            g = g % 1600 + 1600 if g < 3200 else g
        t = float(rng.uniform(11000, 20000))
        ks.learn(Inference(f"sat_{i % 7}", g, int(t * 1e9), float(rng.uniform(1, 256)), int(regions[g]),
                           float(rng.normal()), float(rng.normal())))
    view = ks.knowledge(f, regions, xyz, 20000.0, [], None).value
    assert all(view._region_looks(r)[3] is not None for r in (0, 1, 2))
    assert max(len(view._region_looks(r)[1]) for r in (0, 1)) > 3000
    old = _KernelView(f, regions, xyz, view._obs, view._insight, params, 20000.0)
    times = 20000.0 + 10.0 * np.arange(61)
    asked = 0
    for ids in (np.arange(n_gp), np.arange(0, 1600), np.arange(1500, 1700), np.sort(rng.choice(n_gp, 333, replace=False)),
                np.array([1601]), np.arange(3190, n_gp), np.arange(n_gp)):
        got = view.value_at(ids[None, :], times[:, None])
        assert got.tobytes() == old.value_at(ids[None, :], times[:, None]).tobytes()
        assert view.innovation(ids, times[7]).tobytes() == old.innovation(ids, times[7]).tobytes()
        asked += 1
    assert asked == 7
    # looks of one GP at different positions: no places, every look by itself
    o = dict(view._obs, xyz=view._obs["xyz"] + rng.normal(size=view._obs["xyz"].shape) * 1e-6)
    moved = ObservedView(f, regions, xyz, o, view._insight, params, 20000.0)
    assert moved._region_looks(0)[3] is None
    ref = _KernelView(f, regions, xyz, o, view._insight, params, 20000.0)
    ids = np.arange(n_gp)
    assert moved.value_at(ids[None, :], times[:, None]).tobytes() == ref.value_at(ids[None, :], times[:, None]).tobytes()
