"""Everything a run derives from its scenario before the first step, computed once and cached.

The world of a run is a pure function of the scenario (and its seed): the constellation (SGP4),
the ground points, the OSSE value field, GP access windows over the horizon (bundle priority
order), the ISL contact plan and the ground-station contact plan. The ROS engine starts one
process per satellite; rather than each recomputing it, the launcher builds it once and every
process loads the same pickle (`World.load`), so every process sees bit-identical inputs.

Oracle: tests/unit/test_world.py - a loaded world equals a freshly built one (contacts, windows,
OSSE values), and the cache key changes with any scenario field.
"""

from __future__ import annotations

import hashlib
import pickle
from dataclasses import dataclass
from pathlib import Path

import msgspec
import numpy as np

from bringup.scenario.config import Scenario

__all__ = ["World", "scenario_key"]

_FORMAT = 1


def scenario_key(sc: Scenario) -> str:
    """Stable hash of every scenario field (not where it was loaded from)."""
    raw = msgspec.to_builtins(sc)
    raw.pop("source_path", None)
    blob = msgspec.json.encode({"format": _FORMAT, "scenario": raw})
    return hashlib.sha256(blob).hexdigest()[:16]


@dataclass
class World:
    scenario: Scenario
    ctx: object  # sat_node.scheduler.problem.OrbitContext (constellation, gps, osse, slew)
    access: object  # orbit_clock.access.AccessWindows over [0, horizon]
    isl_plan: object  # orbit_clock.contact_plan.ContactPlan
    ground_plan: object  # orbit_clock.contact_plan.ContactPlan (sat <-> gs_*)
    key: str

    @property
    def constellation(self):
        return self.ctx.constellation

    @property
    def gps(self):
        return self.ctx.gps

    @property
    def osse(self):
        return self.ctx.osse

    @property
    def n_gp(self) -> int:
        return len(self.ctx.gps)

    @property
    def sat_names(self) -> list[str]:
        return list(self.scenario.sat_names)

    @property
    def station_nodes(self) -> list[str]:
        return [f"gs_{s.name}" for s in self.scenario.ground.stations]

    def region_of_gp(self, gp: int) -> int:
        return int(self.ctx.gps.region_index[gp])

    @classmethod
    def build(cls, sc: Scenario) -> "World":
        from orbit_clock import access_windows, ground_contact_plan, isl_contact_plan
        from sat_node.scheduler.problem import OrbitContext

        ctx = OrbitContext.from_scenario(sc)
        horizon_s = sc.scenario.horizon_s
        acc = access_windows(ctx.constellation, ctx.gps, 0.0, horizon_s, sc.instrument.for_off_nadir_deg)
        isl = isl_contact_plan(sc, ctx.constellation)
        gnd = ground_contact_plan(sc, ctx.constellation) if sc.ground.stations else None
        if gnd is None:
            from orbit_clock.contact_plan import ContactPlan

            gnd = ContactPlan([])
        return cls(scenario=sc, ctx=ctx, access=acc, isl_plan=isl, ground_plan=gnd, key=scenario_key(sc))

    # The SGP4 satellite records do not pickle: drop the constellation, rebuild it on load
    # (a pure function of the scenario, milliseconds).
    def __getstate__(self):
        st = dict(self.__dict__)
        st.pop("_coarse_cache", None)
        ctx = self.ctx
        st["ctx"] = {"gps": ctx.gps, "osse": ctx.osse, "slew": ctx.slew}
        return st

    def __setstate__(self, st):
        from orbit_clock import build_constellation
        from sat_node.scheduler.problem import OrbitContext

        c = st["ctx"]
        st["ctx"] = OrbitContext(scenario=st["scenario"], constellation=build_constellation(st["scenario"]),
                                 gps=c["gps"], osse=c["osse"], slew=c["slew"])
        self.__dict__.update(st)

    def save(self, path: Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        with open(tmp, "wb") as fh:
            pickle.dump(self, fh, protocol=pickle.HIGHEST_PROTOCOL)
        tmp.replace(path)
        return path

    @staticmethod
    def load(path: Path, expect_key: str | None = None) -> "World":
        try:
            with open(path, "rb") as fh:
                w = pickle.load(fh)
        except (OSError, pickle.UnpicklingError, EOFError) as exc:
            raise ValueError(f"world cache {path}: cannot load ({exc})") from None
        if not isinstance(w, World):
            raise ValueError(f"world cache {path}: not a World")
        if expect_key is not None and w.key != expect_key:
            raise ValueError(f"world cache {path}: built for another scenario (key {w.key} != {expect_key})")
        return w

    @classmethod
    def cached(cls, sc: Scenario, cache_dir: Path | None = None) -> "World":
        """Load from ``cache_dir/world-<key>.pkl`` or build and save there."""
        key = scenario_key(sc)
        if cache_dir is None:
            return cls.build(sc)
        path = Path(cache_dir) / f"world-{key}.pkl"
        if path.exists():
            try:
                return cls.load(path, key)
            except ValueError:
                pass
        w = cls.build(sc)
        w.save(path)
        return w

    # ---- queries used by the node logic ------------------------------------------------------
    def destinations(self, gp: int, t_s: float, source: str) -> list[tuple[str, int]]:
        """Bundle destinations for an observation of ``gp`` at ``t_s`` by ``source``:
        [(sat, priority)], 1 = next on scene over the GP's region (orbit_clock.priority_order)."""
        from orbit_clock import priority_order

        region = self.region_of_gp(gp)
        return priority_order(self.access, region, t_s, source=source)

    def candidate_gp_ids(self, sat: str, t0_s: float, t1_s: float) -> np.ndarray:
        """GP ids of the regions that may enter ``sat``'s field of regard during [t0_s, t1_s].

        A cheap pre-filter for the scheduler (it then computes the exact FOR mask on its grid):
        a region is kept when, at some sample of a 30 s ephemeris, the Earth central angle between
        the sub-satellite point and the region centre is below the FOR's central angle (55 deg
        off-nadir from the highest orbit radius) plus the region's half-diagonal plus the
        satellite's ground motion over one sample, with a 1 deg margin. Never drops a GP the exact
        mask would keep (tests/unit/test_world.py checks it against the full mask).
        """
        import math

        c = self._coarse()
        i = self.ctx.constellation.index(sat)
        k0 = max(0, int(math.floor(t0_s / c["step_s"])))
        k1 = min(c["unit"].shape[1] - 1, int(math.ceil(t1_s / c["step_s"])))
        u = c["unit"][i, k0:k1 + 1]  # (n, 3)
        cosang = u @ c["region_unit"].T  # (n, R)
        keep = np.flatnonzero((cosang >= c["cos_limit"][None, :]).any(axis=0))
        if len(keep) == 0:
            return np.zeros(0, dtype=np.int64)
        return np.concatenate([c["region_gps"][r] for r in keep])

    def _coarse(self) -> dict:
        import math

        c = self.__dict__.get("_coarse_cache")
        if c is not None:
            return c
        sc = self.scenario
        step_s = 30.0
        t = np.arange(0.0, sc.scenario.horizon_s + step_s, step_s)
        pos = self.ctx.constellation.positions_ecef_km(t)
        r = np.linalg.norm(pos, axis=2)
        unit = pos / r[..., None]
        gps = self.ctx.gps
        n_reg = len(sc.regions.list)
        region_gps = [np.flatnonzero(gps.region_index == k).astype(np.int64) for k in range(n_reg)]
        region_unit = np.zeros((n_reg, 3))
        half_ang = np.zeros(n_reg)
        for k in range(n_reg):
            g = gps.ecef_km[region_gps[k]]
            ctr = g.mean(axis=0)
            ctr /= np.linalg.norm(ctr)
            region_unit[k] = ctr
            gu = g / np.linalg.norm(g, axis=1, keepdims=True)
            half_ang[k] = float(np.max(np.arccos(np.clip(gu @ ctr, -1, 1)))) if len(g) else 0.0
        r_max = float(r.max())
        re = 6356.752  # smallest Earth radius [km]: the largest central angle for a given off-nadir
        eta = math.radians(sc.instrument.for_off_nadir_deg)
        x = min(1.0, r_max / re * math.sin(eta))
        lam = math.asin(x) - eta
        v_ang = 8.0 * step_s / re  # ground motion over one sample [rad], 8 km/s upper bound
        lim = lam + half_ang + v_ang + math.radians(1.0)
        c = {"step_s": step_s, "unit": unit, "region_unit": region_unit, "region_gps": region_gps,
             "cos_limit": np.cos(np.minimum(lim, math.pi))}
        self.__dict__["_coarse_cache"] = c
        return c

    def gp_region_name(self, gp: int) -> str:
        return str(self.ctx.gps.region_names[self.region_of_gp(gp)])

    def sat_positions_ecef_km(self, t_s: float) -> np.ndarray:
        return self.ctx.constellation.positions_ecef_km(np.array([t_s]))[:, 0, :]
