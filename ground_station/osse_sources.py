"""The OSSE sources a scenario can name (``value.osse_source``), and the field it gets from them.

A registry of named strategies (one line of help each, which drives scenario validation and the CLI
help): ``synthetic`` is the seeded storm-cell model of :mod:`ground_station.osse` (Nag et al., ICAPS
SPARK 2019, section 5, stand-in for their WRF-Hydro OSSE), ``file`` a gridded (time, lat, lon) value
field loaded by :mod:`ground_station.osse_io`. Both modules stay below this one, so neither imports
the other.

How we know it is right (tests/unit/test_osse.py): the registry holds exactly these two names, the
scenario's synthetic field is reproducible from its seed, a field written to a file and named by a
scenario (absolute or relative to the scenario file) loads back identical, and an unknown source is
one line naming the known ones.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

from ground_station.osse import OsseError, OsseField, synthetic_field
from ground_station.osse_io import load_value_grid

__all__ = ["OSSE_SOURCES", "osse_from_scenario"]


def _regions(scenario) -> tuple[list[str], list[tuple[float, float]], list[float]]:
    rl = scenario.regions.list
    return [r.name for r in rl], [(r.lat_deg, r.lon_deg) for r in rl], [r.size_km for r in rl]


def _synthetic_from_scenario(scenario, gps) -> OsseField:
    names, centers, sizes = _regions(scenario)
    return synthetic_field(gps, region_names=names, region_centers_deg=centers, region_sizes_km=sizes,
                           horizon_s=scenario.scenario.horizon_s, slot_s=scenario.value.slot_s,
                           seed=scenario.scenario.seed)


def _file_from_scenario(scenario, gps) -> OsseField:
    p = Path(scenario.value.osse_file)
    if not p.is_absolute() and scenario.source_path and not scenario.source_path.startswith("<"):
        p = Path(scenario.source_path).parent / p
    names, _, _ = _regions(scenario)
    return load_value_grid(p, gps, horizon_s=scenario.scenario.horizon_s, slot_s=scenario.value.slot_s,
                           region_names=names)


#: name -> (builder(scenario, gps) -> OsseField, one-line help). Drives scenario validation/CLI help.
OSSE_SOURCES: dict[str, tuple[Callable[[Any, Any], OsseField], str]] = {
    "synthetic": (_synthetic_from_scenario, "seeded storm cells moving over watersheds (seed = scenario.seed)"),
    "file": (_file_from_scenario, "gridded (time, lat, lon) values from value.osse_file (.npz, .csv, .nc)"),
}


def osse_from_scenario(scenario, gps) -> OsseField:
    """The OSSE field the scenario's ``value.osse_source`` names, over ground points ``gps``."""
    src = scenario.value.osse_source
    if src not in OSSE_SOURCES:
        raise OsseError(f"value.osse_source '{src}': unknown (known: {', '.join(sorted(OSSE_SOURCES))})")
    return OSSE_SOURCES[src][0](scenario, gps)
