"""The fleet of a scenario: its constellation groups resolved into named satellites, their orbits
and their own payload and bus.

A scenario's ``constellation`` is one group (a ``[constellation]`` table) or several
(``[[constellation]]`` tables). A group is either

* a Walker shell (``pattern``, ``total_sats``, ``planes``, ``phasing_f``, ``altitude_km``,
  ``inclination_deg``, ``raan0_deg``: orbit_clock/walker.py), at most one per scenario, its
  satellites named ``sat_PS`` / ``sat_PPPP_SSSS``; or
* the satellites of a catalogue file, ``tle_file`` (TLE / 3LE) or ``omm_file`` (CCSDS OMM: XML, KVN,
  JSON or CSV), all of them or only ``norad_ids``, named ``sat_n<NORAD>``
  (orbit_clock/elements.py, msgs_json/names.py). Paths are relative to the scenario file.

Order (the scenario's ``sat_names``): the groups in file order; a Walker shell plane-major, a
catalogue group in the file's order. Each group may carry its own ``instrument`` (footprint_km,
for_off_nadir_deg), ``acs`` (slew_coeffs_s, slew_margin_s) and ``isl`` (rate_bps, max_range_km)
tables; a key it leaves out is the scenario's ([instrument], [acs], [isl]). Per satellite: give it
its own group (``norad_ids = [n]``).

Epoch: ``scenario.epoch_utc``, or when absent the newest element set's epoch (rounded up to the
whole second, as bags and ION contact plans count whole seconds from it); with a Walker shell
alone, the study's 2000-01-01T11:59:28Z (:data:`WALKER_EPOCH`). Either way the run
must lie within every element set's validity (orbit_clock/elements.py ``VALIDITY_DAYS``): refused
in one line otherwise. A Walker shell's elements hold at the run's epoch.

Element files are read once per (file, size, modification time) and cached in the process.

How we know it is right: tests/unit/test_fleet.py (names and order of a mixed fleet, overrides
falling back to the scenario's keys, the epoch from the elements and the validity refused in one
line, a file edited on disk re-read); tests/system/test_catalogue_runs.py (a TLE fleet and the same
satellites as OMM give identical plans and access windows; a mixed fleet equal on both engines).
"""

from __future__ import annotations

import datetime as _dt
import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

import msgspec

from msgs_json.names import MAX_SATS
from orbit_clock.elements import ElementSet, read_elements, validity_error
from orbit_clock.walker import walker_elements
from sat_node.acs import SlewModel, SlewModelError

__all__ = ["WALKER_EPOCH", "Fleet", "FleetError", "SatParams", "check", "default_epoch", "element_files",
           "files_digest", "resolve"]


# The epoch of a scenario that gives none and has no element file: the study's (Nag et al. 2019,
# bringup/scenario/toml/paper.toml), J2000.0 as UTC
WALKER_EPOCH = _dt.datetime(2000, 1, 1, 11, 59, 28, tzinfo=_dt.UTC)


class FleetError(ValueError):
    """A constellation that cannot be built: ``key`` names the scenario key, the message the problem."""

    def __init__(self, key: str, msg: str):
        super().__init__(msg)
        self.key = key


@dataclass(frozen=True)
class SatParams:
    """One satellite's payload and bus (units in names)."""

    for_off_nadir_deg: float
    footprint_km: float
    slew_coeffs_s: tuple[float, ...]
    slew_margin_s: float
    isl_rate_bps: float
    isl_max_range_km: float


@dataclass(frozen=True)
class Fleet:
    names: list[str]
    elements: list  # orbit_clock WalkerElements | ElementSet, in names order
    params: list[SatParams]
    labels: list[str]  # catalogue name, or "walker" for the shell's satellites
    groups: list[int]  # group index of each satellite


_FILES: dict[tuple, list[ElementSet]] = {}
_FLEETS: dict[tuple, Fleet] = {}


def _key(scenario, i: int, field: str) -> str:
    return f"constellation[{i}].{field}" if isinstance(scenario.constellation, list) else f"constellation.{field}"


def _path(scenario, name: str) -> Path:
    p = Path(name).expanduser()
    src = scenario.source_path
    if not p.is_absolute() and src and not src.startswith("<"):
        p = Path(src).parent / p
    return p


def _read(path: Path, kind: str, key: str) -> list[ElementSet]:
    try:
        st = os.stat(path)
    except OSError as exc:
        raise FleetError(key, f"{path}: cannot read the {kind.upper()} file ({exc.strerror or exc})") from None
    k = (str(path.resolve()), kind, st.st_size, st.st_mtime_ns)
    got = _FILES.get(k)
    if got is None:
        try:
            got = read_elements(path, kind)
        except ValueError as exc:
            raise FleetError(key, str(exc)) from None
        _FILES[k] = got
    return got


def element_files(scenario) -> list[tuple[int, str, Path]]:
    """(group index, 'tle' | 'omm', resolved path) of every catalogue group."""
    out = []
    for i, g in enumerate(scenario.groups):
        for kind, name in (("tle", g.tle_file), ("omm", g.omm_file)):
            if name:
                out.append((i, kind, _path(scenario, name)))
    return out


def files_digest(scenario) -> str:
    """SHA-256 of the element files' contents (the world cache key changes when a file does)."""
    h = hashlib.sha256()
    for _i, _kind, p in element_files(scenario):
        try:
            h.update(p.read_bytes())
        except OSError:
            h.update(b"?")
    return h.hexdigest()[:16]


def _catalogue_sets(scenario) -> list[tuple[int, list[ElementSet]]]:
    out = []
    for i, g in enumerate(scenario.groups):
        if g.is_walker:
            continue
        kind, field = ("tle", "tle_file") if g.tle_file else ("omm", "omm_file")
        sets = _read(_path(scenario, getattr(g, field)), kind, _key(scenario, i, field))
        if g.norad_ids:
            by = {e.norad: e for e in sets}
            missing = [n for n in g.norad_ids if n not in by]
            if missing:
                raise FleetError(_key(scenario, i, "norad_ids"),
                                 f"NORAD {missing[0]} is not in {getattr(g, field)} (it holds "
                                 f"{', '.join(str(e.norad) for e in sets[:8])}{' ...' if len(sets) > 8 else ''})")
            sets = [by[n] for n in dict.fromkeys(g.norad_ids)]
        out.append((i, sets))
    return out


def default_epoch(scenario) -> _dt.datetime:
    """The newest element set's epoch (UTC), rounded up to the whole second; with no catalogue group
    (a Walker shell alone) :data:`WALKER_EPOCH`."""
    sets = [e for _i, ss in _catalogue_sets(scenario) for e in ss]
    if not sets:
        return WALKER_EPOCH
    newest = max(e.epoch for e in sets)
    return newest.replace(microsecond=0) + _dt.timedelta(seconds=1 if newest.microsecond else 0)


def _params(scenario, g) -> SatParams:
    ins, acs, isl = scenario.instrument, scenario.acs, scenario.isl
    oi, oa, ol = g.instrument, g.acs, g.isl

    def pick(over, key, base):
        v = getattr(over, key) if over is not None else None
        return getattr(base, key) if v is None else v

    return SatParams(float(pick(oi, "for_off_nadir_deg", ins)), float(pick(oi, "footprint_km", ins)),
                     tuple(float(c) for c in pick(oa, "slew_coeffs_s", acs)), float(pick(oa, "slew_margin_s", acs)),
                     float(pick(ol, "rate_bps", isl)), float(pick(ol, "max_range_km", isl)))


def resolve(scenario) -> Fleet:
    """The scenario's satellites (module docstring); FleetError naming the key on any problem."""
    stats = []
    for _i, _kind, p in element_files(scenario):
        try:
            st = os.stat(p)
            stats.append((str(p), st.st_size, st.st_mtime_ns))
        except OSError:
            stats.append((str(p), -1, -1))
    ck = (msgspec.json.encode(scenario.constellation), msgspec.json.encode(scenario.instrument),
          msgspec.json.encode(scenario.acs), msgspec.json.encode(scenario.isl), scenario.scenario.epoch_utc,
          scenario.source_path, tuple(stats))
    got = _FLEETS.get(ck)
    if got is not None:
        return got
    cat = dict(_catalogue_sets(scenario))
    epoch = scenario.epoch
    names, elements, params, labels, groups = [], [], [], [], []
    for i, g in enumerate(scenario.groups):
        if g.is_walker:
            els = walker_elements(pattern=g.pattern, total_sats=g.total_sats, planes=g.planes, phasing_f=g.phasing_f,
                                  altitude_km=g.altitude_km, inclination_deg=g.inclination_deg,
                                  raan0_deg=g.raan0_deg, epoch=epoch)
            lab = ["walker"] * len(els)
        else:
            els = cat[i]
            lab = [e.label for e in els]
        p = _params(scenario, g)
        for e, la in zip(els, lab):
            if e.name in names:
                first = groups[names.index(e.name)]
                raise FleetError(_key(scenario, i, "norad_ids" if not g.is_walker else "total_sats"),
                                 f"satellite {e.name} is also in constellation group {first} (one group per satellite)")
            names.append(e.name), elements.append(e), params.append(p), labels.append(la), groups.append(i)
    if len(names) > MAX_SATS:
        raise FleetError("constellation", f"{len(names)} satellites, over the {MAX_SATS} the project checks")
    fleet = Fleet(names, elements, params, labels, groups)
    if len(_FLEETS) > 64:
        _FLEETS.clear()
    _FLEETS[ck] = fleet
    return fleet


def check(scenario) -> None:
    """Every group resolves and the run lies within the element sets' validity; FleetError else."""
    walkers = [i for i, g in enumerate(scenario.groups) if g.is_walker]
    if len(walkers) > 1:
        raise FleetError(_key(scenario, walkers[1], "pattern"),
                         "a second Walker shell: at most one per scenario (its names would repeat the first's)")
    for i, g in enumerate(scenario.groups):
        p = _params(scenario, g)
        try:
            SlewModel(p.slew_coeffs_s, p.slew_margin_s)
        except SlewModelError as exc:
            raise FleetError(_key(scenario, i, "acs.slew_coeffs_s"), str(exc)) from None
    sets = [e for _i, ss in _catalogue_sets(scenario) for e in ss]
    if sets:
        start = scenario.epoch
        try:
            end = start + _dt.timedelta(seconds=float(scenario.scenario.horizon_s))
        except OverflowError:
            end = _dt.datetime.max.replace(tzinfo=_dt.UTC)
        why = validity_error(sets, start, end)
        if why is not None:
            raise FleetError("scenario.epoch_utc", why)
    if len(scenario.groups) > 1 or sets:
        resolve(scenario)

