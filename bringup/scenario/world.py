"""Everything a run derives from its scenario before the first step, computed once and cached.

The world of a run is a pure function of the scenario (its seed and its element files, whose
contents enter the cache key): the constellation (SGP4; Walker and catalogue satellites,
bringup/scenario/fleet.py, each with its own field of regard, slew model and ISL radio),
the ground points, the OSSE value field, GP access windows over the horizon (bundle priority
order), the ISL contact plan and the ground-station contact plan, and the planner every
satellite and the ground segment plan with (sat_node.scheduler.planner). The ROS engine starts one
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

from bringup.scenario import fleet
from bringup.scenario.canonical import canonical_data
from bringup.scenario.config import Scenario
from bringup.scenario.limits import check_run_size
from ground_station.osse_sources import osse_from_scenario
from orbit_clock import (
    access_windows,
    build_constellation,
    ground_contact_plan,
    ground_points,
    isl_contact_plan,
    priority_order,
)
from orbit_clock.access import RegionPrefilter
from orbit_clock.contact_plan import ContactPlan
from orbit_clock.fork_split import available_workers
from orbit_clock.propagation import Constellation
from sat_node.acs import SlewModel
from sat_node.dtn.cgr import ContactGraph
from sat_node.scheduler.planner import Planner, PlannerSettings, SatPayload

__all__ = ["OrbitContext", "World", "for_deg_per_sat", "own_payloads", "scenario_key"]

_FORMAT = 2


def scenario_key(sc: Scenario) -> str:
    """Stable hash of every scenario field (not where it was loaded from, nor how the object was
    made: tests/unit/test_world.py checks a pickled and a re-read scenario give the same key)."""
    raw = canonical_data(sc)
    raw.pop("source_path", None)
    doc = {"format": _FORMAT, "scenario": raw}
    if fleet.element_files(sc):
        doc["element_files"] = fleet.files_digest(sc)
    blob = msgspec.json.encode(doc)
    return hashlib.sha256(blob).hexdigest()[:16]


@dataclass
class OrbitContext:
    """A scenario with its constellation (SGP4, orbit_clock), GPs, OSSE field and slew model."""

    scenario: Scenario
    constellation: object  # orbit_clock.propagation.Constellation
    gps: object  # orbit_clock.ground_points.GroundPoints
    osse: object  # ground_station.osse.OsseField
    slew: SlewModel

    @classmethod
    def from_scenario(cls, sc: Scenario) -> OrbitContext:
        """Refused before anything is allocated when the scenario would not fit in memory
        (bringup/scenario/limits.py)."""
        check_run_size(sc)
        gps = ground_points(sc)
        return cls(scenario=sc, constellation=build_constellation(sc), gps=gps,
                   osse=osse_from_scenario(sc, gps), slew=SlewModel.from_scenario(sc))

    def planner(self) -> Planner:
        """The scenario's planner: its orbits, GPs, slew model and settings, with the region
        pre-filter over the horizon (orbit_clock.access.RegionPrefilter) as its GP pre-filter."""
        sc = self.scenario
        prefilter = RegionPrefilter(self.constellation, self.gps, sc.scenario.horizon_s, for_deg_per_sat(sc))
        return Planner(self.constellation, self.gps.ecef_km, self.slew, PlannerSettings.from_scenario(sc),
                       candidates=prefilter.candidate_gp_ids, own=own_payloads(sc),
                       passes=prefilter)


def for_deg_per_sat(sc: Scenario) -> np.ndarray:
    """Every satellite's field of regard [deg], in sat_names order."""
    return np.array([p.for_off_nadir_deg for p in sc.sat_params], dtype=float)


def own_payloads(sc: Scenario) -> dict[str, SatPayload]:
    """The satellites whose payload or slew model differ from the scenario's [instrument] / [acs]."""
    base = (float(sc.instrument.for_off_nadir_deg), float(sc.instrument.footprint_km),
            tuple(float(c) for c in sc.acs.slew_coeffs_s), float(sc.acs.slew_margin_s))
    out = {}
    for name, p in zip(sc.sat_names, sc.sat_params):
        mine = (p.for_off_nadir_deg, p.footprint_km, p.slew_coeffs_s, p.slew_margin_s)
        if mine != base:
            out[name] = SatPayload(p.for_off_nadir_deg, p.footprint_km, SlewModel(p.slew_coeffs_s, p.slew_margin_s))
    return out


@dataclass
class World:
    scenario: Scenario
    ctx: OrbitContext
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
    def build(cls, sc: Scenario, progress=None) -> "World":
        """``progress(stage)``: called with each stage's name as it starts (a long build says where it is)."""
        say = progress or (lambda _stage: None)
        n = sc.n_sats
        say(f"ground points and the OSSE field ({sc.scenario.horizon_s:g} s)")
        ctx = OrbitContext.from_scenario(sc)
        horizon_s = sc.scenario.horizon_s
        say(f"access windows ({n} satellites x {len(sc.regions.list)} regions)")
        acc = access_windows(ctx.constellation, ctx.gps, 0.0, horizon_s, for_deg_per_sat(sc))
        say(f"ISL contact plan ({n * (n - 1) // 2} satellite pairs)")
        # (its SGP4 work on every core this process may use: the same plan as on one,
        # orbit_clock/fork_split.py)
        isl = isl_contact_plan(sc, ctx.constellation, workers=available_workers())
        say(f"ground contact plan ({len(isl)} ISL contacts found)")
        gnd = ground_contact_plan(sc, ctx.constellation) if sc.ground.stations else None
        if gnd is None:
            gnd = ContactPlan([])
        return cls(scenario=sc, ctx=ctx, access=acc, isl_plan=isl, ground_plan=gnd, key=scenario_key(sc))

    # The SGP4 satellite records do not pickle: keep the constellation's elements, rebuild it on
    # load (milliseconds; the element files are not read again).
    def __getstate__(self):
        st = dict(self.__dict__)
        st.pop("_planner", None)
        st.pop("_graphs", None)
        ctx = self.ctx
        st["ctx"] = {"gps": ctx.gps, "osse": ctx.osse, "slew": ctx.slew,
                     "elements": ctx.constellation.elements, "epoch": ctx.constellation.epoch}
        return st

    def __setstate__(self, st):
        c = st["ctx"]
        st["ctx"] = OrbitContext(scenario=st["scenario"], constellation=Constellation(c["elements"], c["epoch"]),
                                 gps=c["gps"], osse=c["osse"], slew=c["slew"])
        self.__dict__.update(st)

    def save(self, path: Path) -> Path:
        path = Path(path)
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_suffix(".tmp")
        try:
            with open(tmp, "wb") as fh:
                pickle.dump(self, fh, protocol=pickle.HIGHEST_PROTOCOL)
            tmp.replace(path)
        except OSError as exc:  # (a full disk: named with the file, nothing half-written left)
            tmp.unlink(missing_ok=True)
            raise OSError(exc.errno, exc.strerror, str(path)) from None
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
    def cached(cls, sc: Scenario, cache_dir: Path | None = None, progress=None) -> "World":
        """Load from ``cache_dir/world-<key>.pkl`` or build and save there (``progress``: :meth:`build`)."""
        key = scenario_key(sc)
        if cache_dir is None:
            return cls.build(sc, progress)
        path = Path(cache_dir) / f"world-{key}.pkl"
        if path.exists():
            try:
                return cls.load(path, key)
            except ValueError:
                pass
        w = cls.build(sc, progress)
        w.save(path)
        return w

    # ---- queries used by the node logic ------------------------------------------------------
    def destinations(self, gp: int, t_s: float, source: str) -> list[tuple[str, int]]:
        """Bundle destinations for an observation of ``gp`` at ``t_s`` by ``source``:
        [(sat, priority)], 1 = next on scene over the GP's region (orbit_clock.priority_order)."""
        region = self.region_of_gp(gp)
        return priority_order(self.access, region, t_s, source=source)

    @property
    def planner(self) -> Planner:
        """The one planner of this world (:meth:`OrbitContext.planner`), built on first use and not
        pickled; the satellites and the ground segment plan with it."""
        p = self.__dict__.get("_planner")
        if p is None:
            p = self.__dict__["_planner"] = self.ctx.planner()
        return p

    def isl_graph(self, max_hops: int | None = None) -> ContactGraph:
        """The ISL plan as a contact graph for CGR (sat_node/dtn/cgr.py), routes of at most
        ``max_hops`` hops: built once per process on first use and shared by every satellite's
        bundle agent in it (its scratch arrays are reused query by query), not pickled."""
        graphs = self.__dict__.setdefault("_graphs", {})
        g = graphs.get(max_hops)
        if g is None:
            g = graphs[max_hops] = ContactGraph(self.isl_plan, max_hops)
        return g

    def gp_region_name(self, gp: int) -> str:
        return str(self.ctx.gps.region_names[self.region_of_gp(gp)])

    def sat_positions_ecef_km(self, t_s: float) -> np.ndarray:
        return self.ctx.constellation.positions_ecef_km(np.array([t_s]))[:, 0, :]
