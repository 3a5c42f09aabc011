"""Scenario files: TOML with units in every key, validated on load (docs/design.md section 1).

A scenario is named (``paper`` -> ``bringup/scenario/toml/paper.toml``) or given as a path. Loading
validates every field with msgspec (types, ranges, unknown keys) and cross-field rules below; any
problem raises :class:`ScenarioError` with one line naming the file, the key and what is wrong.

Why one module: the scenario is one msgspec schema validated in one pass, with its cross-field rules
beside it so that every key's one-line error comes from the same loader (the operations tables and
their rules: bringup/scenario/operations_cfg.py; constellation groups: groups.py and fleet.py).

Oracle: ``tests/unit/test_scenario.py`` breaks every field of paper.toml in turn and expects one
ScenarioError naming that key.
"""

from __future__ import annotations

import datetime as _dt
import math
import tomllib
from pathlib import Path
from typing import Annotated, List, Literal

import msgspec

from bringup.scenario import fleet
from bringup.scenario.groups import ConstellationCfg, group_errors
from bringup.scenario.operations_cfg import CommandCfg, FaultCfg, OperationsCfg, check_operations
from msgs_json.names import MAX_SATS, MAX_STATIONS
from msgs_json.names import sat_names as _sat_names
from msgs_json.text_input import TextInputError, read_text

__all__ = [
    "ScenarioError",
    "Scenario",
    "load_scenario",
    "scenario_path",
    "SCENARIO_DIR",
    "sat_names",
]

SCENARIO_DIR = Path(__file__).resolve().parent / "toml"
MAX_SCENARIO_BYTES = 16 * 2 ** 20  # a scenario is a page of TOML (1000 stations: ~100 KiB)

Pos = Annotated[float, msgspec.Meta(gt=0)]
NonNeg = Annotated[float, msgspec.Meta(ge=0)]
Lat = Annotated[float, msgspec.Meta(ge=-90, le=90)]
Lon = Annotated[float, msgspec.Meta(ge=-180, le=180)]
Frac = Annotated[float, msgspec.Meta(ge=0, le=1)]
Name = Annotated[str, msgspec.Meta(min_length=1)]


class ScenarioError(ValueError):
    """A scenario file that cannot be used; the message is one line naming file and key."""


class _S(msgspec.Struct, forbid_unknown_fields=True, frozen=True, kw_only=True):
    pass


class ScenarioMeta(_S, kw_only=True):
    name: Name
    # "" (or absent): the newest catalogue element set's epoch, or with a Walker shell alone the
    # study's 2000-01-01T11:59:28Z (bringup/scenario/fleet.py)
    epoch_utc: str = ""
    horizon_s: Pos
    seed: Annotated[int, msgspec.Meta(ge=0)] = 1
    lockstep_max_step_s: Pos = 10.0


class InstrumentCfg(_S, kw_only=True):
    footprint_km: Pos = 8.0
    for_off_nadir_deg: Annotated[float, msgspec.Meta(gt=0, lt=90)] = 55.0


class AcsCfg(_S, kw_only=True):
    slew_coeffs_s: Annotated[list[float], msgspec.Meta(min_length=1, max_length=8)]
    slew_margin_s: NonNeg = 0.0


_UNSET = msgspec.UNSET
_Unset = msgspec.UnsetType


class Region(_S, kw_only=True):
    """A region: a square (``lat_deg``, ``lon_deg``, ``size_km``: its centre and side), a bounding box
    (``bbox_deg = [west, south, east, north]``), or a drawn shape (``polygon_deg``: GeoJSON
    MultiPolygon coordinates, what ``regions.geojson_file`` and ``--regions FILE.geojson`` become);
    exactly one of the three. ``source`` names where a shape came from (file and feature) for errors.
    Gridding: orbit_clock/ground_points.py (squares), orbit_clock/region_shapes.py (the others)."""

    name: Name
    lat_deg: Lat | _Unset = _UNSET
    lon_deg: Lon | _Unset = _UNSET
    size_km: Annotated[float, msgspec.Meta(gt=0, le=2000)] | _Unset = _UNSET
    bbox_deg: Annotated[list[float], msgspec.Meta(min_length=4, max_length=4)] | _Unset = _UNSET
    polygon_deg: list[list[list[list[float]]]] | _Unset = _UNSET
    source: str | _Unset = _UNSET

    @property
    def kind(self) -> str:
        """'square', 'bbox' or 'polygon'."""
        if self.polygon_deg is not _UNSET:
            return "polygon"
        return "bbox" if self.bbox_deg is not _UNSET else "square"

    @property
    def shape_deg(self) -> list | None:
        """MultiPolygon coordinates of a box or a polygon; None for a square."""
        if self.polygon_deg is not _UNSET:
            return self.polygon_deg
        if self.bbox_deg is not _UNSET:
            from orbit_clock.region_shapes import bbox_polygon

            return bbox_polygon(self.bbox_deg)
        return None

    @property
    def label(self) -> str:
        """How errors name it: ``region 'X'`` and, for a shape from a file, ``(FILE feature N)``."""
        return f"region '{self.name}'" + (f" ({self.source})" if self.source is not _UNSET and self.source else "")


class RegionsCfg(_S, kw_only=True):
    """``list``: the regions in GP id order. A ``geojson_file`` key (a path, relative to the scenario
    file) is read on load: its features are appended to ``list`` as polygon regions (names from the
    ``name`` property) and the key is dropped, so a loaded scenario holds its shapes (the world's cache
    key and a resolved scenario's TOML include them): bringup/scenario/regions_geojson.py."""

    gp_spacing_km: NonNeg = 0.0
    list: Annotated[List[Region], msgspec.Meta(min_length=1)]


FIELD_STEP_MAX_S = 900.0  # the transient field's longest drawing step [s] (ValueCfg.field_step_s)
# sat_node/knowledge.py MODELS, the default first (checked by a test); RENAMED_KNOWLEDGE its RENAMED keys
KNOWLEDGE_MODELS = ("observed", "region-truth", "oracle")
RENAMED_KNOWLEDGE = ("study",)


class GridCfg(_S, kw_only=True):
    """How ``value.osse_file`` is read and scaled (ground_station/osse_geofiles.py, osse_scale.py)."""

    # NetCDF: the truth's variable ('' = the file's only gridded variable, or NPZ/NetCDF-3 names)
    variable: str = ""
    # the forecast's variable, in value.osse_forecast_file if given, else in value.osse_file
    forecast_variable: str = ""
    # the variable's (band's) units attribute must read this ('' = not checked; no conversion is made)
    units: str = ""
    # physical values -> 1..256: none (already 1..256), linear or log between low and high, quantile
    scale: Literal["none", "linear", "log", "quantile"] = "none"
    low: float = 0.0
    high: float = 0.0
    # GeoTIFF bands: band 1 at band_start_utc ('' = the scenario epoch), then every band_step_s
    # (0: the bands' ISO 8601 descriptions, or one band held over the run)
    band_start_utc: str = ""
    band_step_s: NonNeg = 0.0
    # refuse to read more of a file than this (the part around the regions and the run)
    max_memory_mib: Annotated[float, msgspec.Meta(gt=0, le=2 ** 20)] = 1024.0


class ValueCfg(_S, kw_only=True):
    osse_source: Literal["synthetic", "file"] = "synthetic"
    osse_file: str = ""
    osse_forecast_file: str = ""
    grid: GridCfg = GridCfg()
    # the study's "transiency": the OSSE's time resolution [min], the value slot and Eq. 1's zero window
    osse_resolution_min: Annotated[float, msgspec.Meta(gt=0, le=1440)] = 15.0
    belief_sigma_min: Frac = 0.02
    belief_sigma_max: Frac = 0.08
    knowledge: Literal["observed", "region-truth", "oracle"] = "observed"
    # 0: the slow storm-cell field; else the transient field's decorrelation [min] (up to a day): the
    # lag at which the GP values' Spearman rank correlation falls to 0.5 (not the study's
    # "transiency", which is osse_resolution_min)
    transiency_min: Annotated[float, msgspec.Meta(ge=0, le=1440)] = 15.0
    # the transient field's episodic flash floods (cells that appear without warning); false: none
    flash_floods: bool = True
    observation_spread_km: Annotated[float, msgspec.Meta(gt=0, le=500)] = 10.0
    # 0: derived from the field's transiency (sat_node/knowledge.py)
    observation_memory_min: Annotated[float, msgspec.Meta(ge=0, le=10080)] = 0.0
    # spatial-diversity term (sat_node/diversity.py): weight (0: off), length [km], look-back window [min]
    spatial_diversity_weight: Annotated[float, msgspec.Meta(ge=0, le=100)] = 0.0
    spatial_diversity_km: Annotated[float, msgspec.Meta(gt=0, le=2000)] = 8.0
    spatial_diversity_window_min: Annotated[float, msgspec.Meta(gt=0, le=1440)] = 60.0

    # derived [s]: the value slot and Eq. 1's zero window are the OSSE's time resolution, as in the study;
    # the transient field is drawn (and its decorrelation measured) on the slot split into parts <= 15 min
    slot_s = revisit_zero_s = property(lambda self: 60.0 * self.osse_resolution_min)
    field_step_s = property(lambda self: self.slot_s / math.ceil(self.slot_s / FIELD_STEP_MAX_S - 1e-9))


class SchedulerCfg(_S, kw_only=True):
    replan_period_s: Pos = 600.0
    # "news": replan every period and also when delivered news makes a planned look worthless (the
    # project's); "periodic": every period only (the study's scheme)
    replan_trigger: Literal["news", "periodic"] = "news"
    dp_step_s: Pos = 1.0
    plan_lookahead_s: Pos = 600.0
    joint_planning: bool = True
    # joint planning with at most this many partners, those that may first see one of the planned
    # satellite's GPs earliest (sat_node/scheduler/planner.py Planner.group); 0: every overlapping one
    joint_max_partners: Annotated[int, msgspec.Meta(ge=0, le=MAX_SATS)] = 0


class IslCfg(_S, kw_only=True):
    rate_bps: Pos = 1000.0
    bundle_bits: Annotated[int, msgspec.Meta(gt=0)] = 2000
    grazing_height_km: NonNeg = 80.0
    max_range_km: Pos = 6000.0
    ttl_p1_s: Pos = 900.0
    ttl_p2_3_s: Pos = 1800.0
    ttl_p4_15_s: Pos = 3000.0
    send_order: Literal["priority", "deadline", "fifo"] = "priority"
    hop_tolerance_s: NonNeg = 0.0
    forwarding: Literal["multicast", "unicast"] = "multicast"

    def ttl_s(self, priority: int) -> float:
        """Bundle lifetime [s] for a priority 1..15 (docs/design.md section 1)."""
        if priority <= 1:
            return self.ttl_p1_s
        if priority <= 3:
            return self.ttl_p2_3_s
        return self.ttl_p4_15_s


class VizCfg(_S, kw_only=True):
    # sim seconds between two visualisation frames: the bag's fixes, markers and /tf, and the ROS
    # engine's live topics (fixes, markers, /tf, per-satellite state on /diagnostics)
    period_s: Annotated[float, msgspec.Meta(gt=0, le=86400)] = 60.0


class Station(_S, kw_only=True):
    name: Name
    lat_deg: Lat
    lon_deg: Lon
    alt_m: float = 0.0


class GroundCfg(_S, kw_only=True):
    min_elevation_deg: Annotated[float, msgspec.Meta(ge=0, lt=90)] = 10.0
    rate_bps: Pos = 1.0e6
    stations: Annotated[list[Station], msgspec.Meta(max_length=MAX_STATIONS)] = []


class Scenario(_S, kw_only=True):
    scenario: ScenarioMeta
    # one group (a table) or several ([[constellation]]): bringup/scenario/fleet.py
    constellation: ConstellationCfg | Annotated[list[ConstellationCfg], msgspec.Meta(min_length=1, max_length=64)]
    instrument: InstrumentCfg = InstrumentCfg()
    acs: AcsCfg
    regions: RegionsCfg
    value: ValueCfg = ValueCfg()
    scheduler: SchedulerCfg = SchedulerCfg()
    isl: IslCfg = IslCfg()
    ground: GroundCfg = GroundCfg()
    viz: VizCfg = VizCfg()
    operations: OperationsCfg = OperationsCfg()
    faults: List[FaultCfg] = []
    commands: List[CommandCfg] = []
    # Where the file was loaded from (set by load_scenario; not a TOML key).
    source_path: str = ""

    # ---- derived, read-only helpers -------------------------------------------------------
    @property
    def name(self) -> str:
        return self.scenario.name

    @property
    def groups(self) -> list[ConstellationCfg]:
        """The constellation's groups (one for a single [constellation] table)."""
        c = self.constellation
        return list(c) if isinstance(c, list) else [c]

    @property
    def walker(self) -> ConstellationCfg | None:
        """The Walker shell of the constellation (at most one), or None."""
        return next((g for g in self.groups if g.is_walker), None)

    @property
    def epoch(self) -> _dt.datetime:
        """scenario.epoch_utc, or (none given) the newest catalogue element set's epoch, or with a
        Walker shell alone the study's (fleet.WALKER_EPOCH)."""
        if self.scenario.epoch_utc:
            return _parse_epoch(self.scenario.epoch_utc)
        return fleet.default_epoch(self)

    @property
    def epoch_iso(self) -> str:
        """The run's epoch as UTC ISO 8601 text ending in Z (scenario.epoch_utc, or the elements')."""
        e = self.epoch
        return e.strftime("%Y-%m-%dT%H:%M:%S") + (f".{e.microsecond:06d}".rstrip("0") if e.microsecond else "") + "Z"

    @property
    def n_sats(self) -> int:
        return len(self.sat_names)

    @property
    def orbit_elements(self) -> list:
        """Every satellite's elements, in sat_names order (orbit_clock WalkerElements / ElementSet)."""
        return fleet.resolve(self).elements

    @property
    def sat_params(self) -> list:
        """Every satellite's payload and bus (fleet.SatParams), in sat_names order."""
        return fleet.resolve(self).params

    @property
    def epoch_ns(self) -> int:
        """The epoch in Unix nanoseconds (UTC), exactly: what a bag's clock adds to every t_ns."""
        d = self.epoch - _dt.datetime(1970, 1, 1, tzinfo=_dt.timezone.utc)
        return (d.days * 86_400 + d.seconds) * 1_000_000_000 + d.microseconds * 1_000

    @property
    def horizon_ns(self) -> int:
        return int(round(self.scenario.horizon_s * 1e9))

    @property
    def gp_spacing_km(self) -> float:
        """GP spacing [km]: the key, or (0) half the footprint - Nyquist sampling, as the study."""
        return self.regions.gp_spacing_km or 0.5 * self.instrument.footprint_km

    @property
    def sat_names(self) -> list[str]:
        """Walker shell first (plane-major), then each catalogue group's satellites in file order."""
        c = self.constellation
        if not isinstance(c, list) and c.is_walker:
            return sat_names(c.planes, c.sats_per_plane)
        return fleet.resolve(self).names

    def with_overrides(self, *, sats: int | None = None, hours: float | None = None,
                       seed: int | None = None, planes: int | None = None, knowledge: str | None = None,
                       transiency_min: float | None = None, gp_spacing_km: float | None = None,
                       joint_planning: bool | None = None, joint_max_partners: int | None = None,
                       viz_period_s: float | None = None, forwarding: str | None = None,
                       regions: list[dict] | None = None, epoch_utc: str | None = None) -> "Scenario":
        """A copy with the CLI overrides applied (``--sats``, ``--planes``, ``--hours``, ``--seed``,
        ``--knowledge``, ``--transiency-min``, ``--gp-spacing-km``, ``--planning``,
        ``--joint-max-partners``, ``--viz-period-s``, ``--forwarding``, ``--regions``: region tables that
        replace the scenario's, bringup/scenario/regions_geojson.py; ``--epoch``: scenario.epoch_utc).

        ``sats`` without ``planes`` keeps the number of planes when it divides evenly, else takes
        the largest number of planes below it that does; ``planes`` sets it (``phasing_f`` is kept
        when it is still in 0..planes-1, else set to 1 % planes). The result is validated like a
        file: sizes beyond the limits (msgs_json/names.py) are one line naming the key.
        """
        raw = msgspec.to_builtins(self)
        raw.pop("source_path", None)
        for table, key, v in (("value", "knowledge", knowledge), ("value", "transiency_min", transiency_min),
                              ("regions", "gp_spacing_km", gp_spacing_km),
                              ("scheduler", "joint_planning", joint_planning), ("viz", "period_s", viz_period_s),
                              ("isl", "forwarding", forwarding)):
            if v is not None:
                raw[table][key] = float(v) if isinstance(v, int) and not isinstance(v, bool) else v
        groups = raw["constellation"] if isinstance(raw["constellation"], list) else [raw["constellation"]]
        c = next((g for g in groups if not (g.get("tle_file") or g.get("omm_file"))), None)
        if c is None and (planes is not None or sats is not None):
            raise ScenarioError(f"{self.source_path or '<overrides>'}: --sats / --planes size a Walker shell, and "
                                "this constellation has none (its satellites come from element files)")
        if planes is not None:
            c["planes"] = planes
            if planes >= 1 and not 0 <= c.get("phasing_f", 1) < max(planes, 2):
                c["phasing_f"] = 1 % planes
        if sats is not None:
            c["total_sats"] = sats
            p = c["planes"]
            if planes is None and sats >= 1 and sats % p != 0:
                p = max(1, min(p, sats))
                while sats % p:
                    p -= 1
                c["planes"] = p
        if hours is not None:
            raw["scenario"]["horizon_s"] = float(hours) * 3600.0
        if seed is not None:
            raw["scenario"]["seed"] = int(seed)
        if epoch_utc is not None:
            raw["scenario"]["epoch_utc"] = epoch_utc
        if joint_max_partners is not None:  # an integer key: not made a float like the others
            raw["scheduler"]["joint_max_partners"] = joint_max_partners
        if regions is not None:
            raw["regions"]["list"] = [dict(r) for r in regions]
        return _validate(raw, self.source_path or "<overrides>")


    def with_catalogue(self, tle: list[str] | tuple = (), omm: list[str] | tuple = ()) -> Scenario:
        """A copy whose constellation is the satellites of the given TLE and OMM files (the CLI's
        ``--tle FILE`` / ``--omm FILE``, each repeatable), one group per file in that order, with the
        scenario's payload and bus; the epoch is then the elements' (scenario.epoch_utc dropped)."""
        if not tle and not omm:
            return self
        raw = msgspec.to_builtins(self)
        raw.pop("source_path", None)
        groups = [{"tle_file": str(Path(p).expanduser().resolve())} for p in tle]
        groups += [{"omm_file": str(Path(p).expanduser().resolve())} for p in omm]
        raw["constellation"] = groups
        raw["scenario"].pop("epoch_utc", None)
        return _validate(raw, self.source_path or "<overrides>")

def sat_names(planes: int, per_plane: int) -> list[str]:
    """Satellite names in plane-major order: ``sat_PS`` (plane P 1.., slot S 1..), as the study's
    Sat11..Sat38, up to 9 x 9; ``sat_PPPP_SSSS`` beyond (msgs_json/names.py)."""
    return _sat_names(planes, per_plane)


def scenario_path(name_or_path: str | Path) -> Path:
    """Resolve a scenario name (``paper``) or a path to a TOML file."""
    p = Path(name_or_path)
    if p.suffix == ".toml" or p.exists():
        return p
    cand = SCENARIO_DIR / f"{name_or_path}.toml"
    if cand.exists():
        return cand
    known = ", ".join(sorted(q.stem for q in SCENARIO_DIR.glob("*.toml")))
    raise ScenarioError(f"scenario '{name_or_path}': no such file or built-in scenario (built-in: {known})")


def load_scenario(name_or_path: str | Path) -> Scenario:
    """Load and validate a scenario; raises ScenarioError with a one-line message."""
    path = scenario_path(name_or_path)
    if path.is_dir():
        raise ScenarioError(f"{path}: is a folder, not a scenario file")
    try:
        text = read_text(path, "scenario", MAX_SCENARIO_BYTES)
    except TextInputError as exc:
        raise ScenarioError(str(exc)) from None
    try:
        raw = tomllib.loads(text)
    except (tomllib.TOMLDecodeError, RecursionError) as exc:
        raise ScenarioError(f"{path}: not valid TOML: {' '.join(str(exc).split())[:300]}") from None
    return _validate(raw, str(path))


def _parse_epoch(s: str) -> _dt.datetime:
    if not s.endswith("Z"):
        raise ValueError("must be UTC ISO 8601 ending in 'Z', e.g. 2000-01-01T11:59:28Z")
    t = _dt.datetime.fromisoformat(s[:-1])
    return t.replace(tzinfo=_dt.timezone.utc)


def _key_of(path: str) -> str:
    """msgspec '$.isl.rate_bps' / '$.regions.list[2].lat_deg' -> 'isl.rate_bps' etc."""
    return path[2:] if path.startswith("$.") else path.lstrip("$") or "<top level>"


_MISSING = object()


def _lookup(raw: dict, key: str):
    """Value at a dotted key with [i] indices, or _MISSING."""
    cur = raw
    for part in key.replace("[", ".[").split("."):
        if not part:
            continue
        try:
            cur = cur[int(part[1:-1])] if part.startswith("[") else cur[part]
        except (KeyError, IndexError, TypeError, ValueError):
            return _MISSING
    return cur


def _non_finite(raw, key: str = "") -> str | None:
    """The dotted key of the first number that is not finite (TOML has inf and nan), or None."""
    if isinstance(raw, float) and not math.isfinite(raw):
        return key or "<top level>"
    if isinstance(raw, dict):
        items = ((f"{key}.{k}" if key else str(k), v) for k, v in raw.items())
    elif isinstance(raw, list):
        items = ((f"{key}[{i}]", v) for i, v in enumerate(raw))
    else:
        return None
    for k, v in items:
        got = _non_finite(v, k)
        if got is not None:
            return got
    return None


def _expand_geojson(raw: dict, where: str) -> None:
    """``regions.geojson_file``: its features appended to ``regions.list`` and the key dropped
    (RegionsCfg), the path relative to the scenario file."""
    regions = raw.get("regions")
    if not isinstance(regions, dict) or "geojson_file" not in regions:
        return
    name = regions.pop("geojson_file")
    if not isinstance(name, str) or not name:
        raise ScenarioError(f"{where}: key 'regions.geojson_file': must be a path to a GeoJSON file (got {name!r})")
    from bringup.scenario.regions_geojson import read_geojson_regions

    path = Path(name).expanduser()
    if not path.is_absolute() and not where.startswith("<"):
        path = Path(where).parent / path
    try:
        shapes = read_geojson_regions(path)
    except ValueError as exc:
        raise ScenarioError(f"{where}: key 'regions.geojson_file': {exc}") from None
    existing = regions.get("list", [])
    regions["list"] = (existing if isinstance(existing, list) else [existing]) + shapes


def _validate(raw: dict, where: str) -> Scenario:
    _expand_geojson(raw, where)
    bad = _non_finite(raw)
    if bad is not None:
        raise ScenarioError(f"{where}: key '{bad}': must be a finite number (got {_lookup(raw, bad)!r})")
    model = _lookup(raw, "value.knowledge")
    if isinstance(model, str) and model in RENAMED_KNOWLEDGE:
        from sat_node.knowledge import check_model  # the flight software's one message for it

        try:
            check_model(model)
        except ValueError as exc:
            raise ScenarioError(f"{where}: key 'value.knowledge': {exc}") from None
    try:
        sc = msgspec.convert(raw, Scenario, strict=True)
    except msgspec.ValidationError as exc:
        msg = str(exc)
        if " - at `" in msg:
            what, at = msg.rsplit(" - at `", 1)
            key = _key_of(at.rstrip("`"))
            got = _lookup(raw, key)
            got_s = "" if got is _MISSING or "unknown field" in what else f" (got {got!r})"
            raise ScenarioError(f"{where}: key '{key}': {what}{got_s}") from None
        if msg.startswith("Object missing required field"):
            raise ScenarioError(f"{where}: {msg}") from None
        raise ScenarioError(f"{where}: {msg}") from None
    sc = msgspec.structs.replace(sc, source_path=where)  # (before the checks: element files are relative to it)
    _cross_checks(sc, where)
    try:
        fleet.check(sc)
    except fleet.FleetError as exc:
        raise ScenarioError(f"{where}: key '{exc.key}': {exc}") from None
    return sc


def _cross_checks(sc: Scenario, where: str) -> None:
    def bad(key: str, why: str) -> None:
        raise ScenarioError(f"{where}: key '{key}': {why}")

    try:
        if sc.scenario.epoch_utc:
            _parse_epoch(sc.scenario.epoch_utc)
    except ValueError as exc:
        bad("scenario.epoch_utc", f"{exc} (got {sc.scenario.epoch_utc!r})")
    for key, why in group_errors(sc):
        bad(key, why)
    v = sc.value
    if v.belief_sigma_min > v.belief_sigma_max:
        bad("value.belief_sigma_min", f"{v.belief_sigma_min} is above belief_sigma_max {v.belief_sigma_max}")
    if v.osse_source == "file" and not v.osse_file:
        bad("value.osse_file", "osse_source is 'file' but no osse_file is given")
    if v.osse_forecast_file and v.osse_source != "file":
        bad("value.osse_forecast_file", "a forecast file goes with osse_source 'file' (the synthetic "
            "sources make their own forecast)")
    gc = v.grid
    if gc != GridCfg() and v.osse_source != "file":
        bad("value.grid", "reads value.osse_file: it goes with osse_source 'file'")
    if gc.scale in ("linear", "log") and not gc.high > gc.low:
        bad("value.grid.high", f"scale '{gc.scale}' maps low..high to 1..256: high ({gc.high:g}) must be above "
            f"low ({gc.low:g})")
    if gc.scale == "log" and not gc.low > 0:
        bad("value.grid.low", f"scale 'log' needs low > 0 (got {gc.low:g})")
    if gc.band_start_utc:
        try:
            _parse_epoch(gc.band_start_utc)
        except ValueError as exc:
            bad("value.grid.band_start_utc", f"{exc} (got {gc.band_start_utc!r})")
    if 0 < v.transiency_min < v.field_step_s / 60.0:
        bad("value.transiency_min", f"{v.transiency_min} min is shorter than the field's drawing step "
            f"({v.field_step_s / 60.0:g} min; 0 = the slow storm-cell field)")
    if v.transiency_min == 0 and not v.flash_floods:
        bad("value.flash_floods", "false needs the transient field (transiency_min > 0): the slow "
            "storm-cell field has no flash-flood switch")
    if sc.scheduler.dp_step_s > sc.scheduler.replan_period_s:
        bad("scheduler.dp_step_s", "is longer than scheduler.replan_period_s")
    if sc.scheduler.joint_max_partners and not sc.scheduler.joint_planning:
        bad("scheduler.joint_max_partners", f"{sc.scheduler.joint_max_partners} partners, but joint_planning "
            "is false (0 = unbounded; it bounds joint planning's group)")
    i = sc.isl
    if not (i.ttl_p1_s <= i.ttl_p2_3_s <= i.ttl_p4_15_s):
        bad("isl.ttl_p1_s", "TTLs must not shrink with priority number (p1 <= p2_3 <= p4_15)")
    for k, r in enumerate(sc.regions.list):
        why = _region_problem(r)
        if why:
            bad(f"regions.list[{k}]", f"{r.label}: {why}")
    names = [r.name for r in sc.regions.list]
    if len(set(names)) != len(names):
        bad("regions.list", f"region names repeat: {names}")
    check_operations(sc, bad)
    gs = [s.name for s in sc.ground.stations]
    if len(set(gs)) != len(gs):
        bad("ground.stations", f"station names repeat: {gs}")


def _region_problem(r: Region) -> str | None:
    """A region's form (exactly one of square, box, polygon) and its shape (orbit_clock/region_shapes.py)."""
    square = [r.lat_deg is not _UNSET, r.lon_deg is not _UNSET, r.size_km is not _UNSET]
    forms = int(any(square)) + int(r.bbox_deg is not _UNSET) + int(r.polygon_deg is not _UNSET)
    if forms != 1:
        return ("give exactly one of: lat_deg + lon_deg + size_km (a square), bbox_deg = [west, south, east, "
                "north], or polygon_deg (GeoJSON MultiPolygon coordinates; or regions.geojson_file)")
    if any(square) and not all(square):
        missing = [k for k, s in zip(("lat_deg", "lon_deg", "size_km"), square, strict=True) if not s]
        return f"a square needs lat_deg, lon_deg and size_km: missing {', '.join(missing)}"
    if r.bbox_deg is not _UNSET:
        from bringup.scenario.regions_geojson import bbox_problem

        return bbox_problem(r.bbox_deg)
    if r.polygon_deg is not _UNSET:
        from orbit_clock.region_shapes import shape_problem

        return shape_problem(r.polygon_deg)
    return None
