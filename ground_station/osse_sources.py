"""The OSSE sources a scenario can name (``value.osse_source``), and the field it gets from them.

A registry of named strategies (one line of help each, which drives scenario validation and the CLI
help): ``synthetic`` is a seeded stand-in for the study's WRF-Hydro OSSE (Nag et al., ICAPS SPARK
2019, section 5): the transient field of :mod:`ground_station.osse_transient` with the scenario's
``value.transiency_min`` (its decorrelation) drawn on a step of at most 15 min and sampled at
each slot's start (the slot is ``value.osse_resolution_min``, the study's "transiency": the OSSE's
time resolution), with or without its flash floods (``value.flash_floods``), or (0) the slow
storm-cell model of :mod:`ground_station.osse`; ``file`` a
gridded (time, lat, lon) truth field, and optionally a forecast, loaded by
:mod:`ground_station.osse_io`. Those modules stay below this one, so none imports another sideways.
Every field leaves here with its measured rank figures in ``meta["rank"]``
(:func:`ground_station.osse_stats.field_rank_figures`; the transient field's decorrelation measured
on its drawing step; the relative change of its values by slot lag), which every run reports.

How we know it is right (tests/unit/test_osse.py): the registry holds exactly these two names, the
scenario's synthetic field is reproducible from its seed, a field written to a file and named by a
scenario (absolute or relative to the scenario file) loads back identical, and an unknown source is
one line naming the known ones.
"""

from __future__ import annotations

import datetime as _dt
import math
from collections.abc import Callable
from pathlib import Path
from typing import Any

from ground_station.osse import OsseError, OsseField, as_ground_point_arrays, synthetic_field
from ground_station.osse_geofiles import GeoFileOptions
from ground_station.osse_io import load_value_grid
from ground_station.osse_scale import ValueScale
from ground_station.osse_stats import field_rank_figures, measured_transiency_min, relative_change_by_lag
from ground_station.osse_transient import TransientParams, transient_field_arrays

__all__ = ["OSSE_SOURCES", "osse_from_scenario"]


def _regions(scenario, gps=None) -> tuple[list[str], list[tuple[float, float]], list[float]]:
    """Names, centres and sizes [km]: a square's own; a drawn shape's (bbox, polygon) from its GPs
    (orbit_clock/ground_points.py: centre of the GPs, the square that reaches every GP)."""
    rl = scenario.regions.list
    centers, sizes = [], []
    for i, r in enumerate(rl):
        if getattr(r, "shape_deg", None) is None:
            centers.append((r.lat_deg, r.lon_deg))
            sizes.append(r.size_km)
        else:
            centers.append((float(gps.region_center_lat_deg[i]), float(gps.region_center_lon_deg[i])))
            sizes.append(float(gps.region_size_km[i]))
    return [r.name for r in rl], centers, sizes


def _synthetic_from_scenario(scenario, gps) -> OsseField:
    names, centers, sizes = _regions(scenario, gps)
    v = scenario.value
    if v.transiency_min == 0:  # the slow storm-cell field
        return synthetic_field(gps, region_names=names, region_centers_deg=centers, region_sizes_km=sizes,
                               horizon_s=scenario.scenario.horizon_s, slot_s=v.slot_s, seed=scenario.scenario.seed)
    g = as_ground_point_arrays(gps)
    step_s = v.field_step_s
    per_slot = round(v.slot_s / step_s)
    n_slots = math.ceil(scenario.scenario.horizon_s / v.slot_s - 1e-9)
    truth, forecast, drawn = transient_field_arrays(
        g, region_names=names, region_centers_deg=centers, region_sizes_km=sizes,
        horizon_s=n_slots * v.slot_s, slot_s=step_s, seed=scenario.scenario.seed,
        params=TransientParams(transiency_min=v.transiency_min, flash_floods=v.flash_floods))
    decorrelation = measured_transiency_min(truth, step_s)
    # the OSSE output at each slot's start, held over the slot (as a file source is sampled)
    truth, forecast = truth[::per_slot][:n_slots], forecast[::per_slot][:n_slots]
    return OsseField(values=truth, slot_s=float(v.slot_s), lat_deg=g.lat_deg, lon_deg=g.lon_deg,
                     region_index=g.region_index, region_names=names, source="synthetic",
                     meta={"seed": int(scenario.scenario.seed), "model": "transient", **drawn,
                           "field_step_s": step_s, "decorrelation_min": decorrelation,
                           "forecast": "conditional median of the epoch state, no event born later"},
                     forecast=forecast)


def _resolve(scenario, name: str) -> Path:
    p = Path(name)
    if not p.is_absolute() and scenario.source_path and not scenario.source_path.startswith("<"):
        p = Path(scenario.source_path).parent / p
    return p


def _file_from_scenario(scenario, gps) -> OsseField:
    names = [r.name for r in scenario.regions.list]
    v = scenario.value
    gc = getattr(v, "grid", None)
    scale, opts, fvar = ValueScale(), GeoFileOptions(epoch=scenario.epoch), ""
    if gc is not None:
        start = 0.0
        if gc.band_start_utc:
            start = (_dt.datetime.fromisoformat(gc.band_start_utc[:-1]).replace(tzinfo=_dt.UTC)
                     - scenario.epoch).total_seconds()
        scale = ValueScale(gc.scale, gc.low, gc.high)
        opts = GeoFileOptions(variable=gc.variable, units=gc.units, band_start_s=start, band_step_s=gc.band_step_s,
                              max_memory_mib=gc.max_memory_mib, epoch=scenario.epoch)
        fvar = gc.forecast_variable
    return load_value_grid(_resolve(scenario, v.osse_file), gps, horizon_s=scenario.scenario.horizon_s,
                           slot_s=v.slot_s, region_names=names,
                           forecast_path=_resolve(scenario, v.osse_forecast_file) if v.osse_forecast_file else None,
                           scale=scale, options=opts, forecast_variable=fvar)


#: name -> (builder(scenario, gps) -> OsseField, one-line help). Drives scenario validation/CLI help.
OSSE_SOURCES: dict[str, tuple[Callable[[Any, Any], OsseField], str]] = {
    "synthetic": (_synthetic_from_scenario, ("seeded synthetic flood field with value.transiency_min (0: the slow "
                                            "storm cells), its own forecast (seed = scenario.seed)")),
    "file": (_file_from_scenario, ("gridded (time, lat, lon) values from value.osse_file (.npz, .csv, .nc, "
                                  "NetCDF-4 / CF, GeoTIFF), read and scaled as [value.grid] says, forecast "
                                  "from value.osse_forecast_file or value.grid.forecast_variable")),
}


def osse_from_scenario(scenario, gps) -> OsseField:
    """The OSSE field the scenario's ``value.osse_source`` names, over ground points ``gps``."""
    src = scenario.value.osse_source
    if src not in OSSE_SOURCES:
        raise OsseError(f"value.osse_source '{src}': unknown (known: {', '.join(sorted(OSSE_SOURCES))})")
    field = OSSE_SOURCES[src][0](scenario, gps)
    rank = field_rank_figures(field.values, field.slot_s)
    rank["osse_resolution_min"] = field.slot_s / 60.0
    # the transient field's decorrelation, measured on its drawing step (finer than a long slot)
    rank["decorrelation_min"] = field.meta.get("decorrelation_min", rank["transiency_min"])
    rank["flash_floods"] = field.meta.get("flash_floods")
    rank["rel_change_by_slot_lag"] = relative_change_by_lag(field.values)
    field.meta["rank"] = rank
    return field
