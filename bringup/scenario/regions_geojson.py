"""Regions from a GeoJSON file (RFC 7946): what ``regions.geojson_file`` and ``--regions`` read.

Accepted: a FeatureCollection, a single Feature, or a bare Polygon / MultiPolygon geometry, in WGS-84
longitude/latitude degrees (GeoJSON's only coordinate system since RFC 7946; a legacy ``crs`` member
naming anything but CRS84 / EPSG:4326 is refused). Each feature becomes one region holding its
Polygon or MultiPolygon as ``polygon_deg`` (a Polygon is a MultiPolygon of one), named from its
``name`` property (else ``<file stem>_<n>``, n counting features from 1), with ``source`` naming the
file and feature for later errors. Other geometry types, null geometries, empty collections, bad
coordinates, self-intersections (orbit_clock/region_shapes.py ``shape_problem``) are refused with one
line naming the file and the feature. ``--regions W,S,E,N`` makes one bounding-box region instead.

How we know it is right: tests/unit/test_region_shapes.py reads FeatureCollections, Features and bare
geometries written by the test, and checks one line (file and feature) for each kind of bad file.
"""

from __future__ import annotations

import json
from pathlib import Path

from msgs_json.text_input import TextInputError, read_text
from orbit_clock.region_shapes import MAX_ABS_LAT_DEG, shape_problem

__all__ = ["MAX_GEOJSON_BYTES", "GeoJsonError", "bbox_problem", "bbox_region", "read_geojson_regions", "regions_arg"]

MAX_GEOJSON_BYTES = 64 * 2 ** 20
_CRS84 = ("urn:ogc:def:crs:OGC:1.3:CRS84", "urn:ogc:def:crs:OGC::CRS84", "EPSG:4326", "urn:ogc:def:crs:EPSG::4326")


class GeoJsonError(ValueError):
    """A GeoJSON regions file that cannot be used; one line naming the file and the feature."""


def _feature_name(props, stem: str, k: int) -> str:
    name = props.get("name") if isinstance(props, dict) else None
    return name.strip() if isinstance(name, str) and name.strip() else f"{stem}_{k + 1}"


def read_geojson_regions(path: str | Path) -> list[dict]:
    """The file's features as scenario region tables: ``{name, polygon_deg, source}``."""
    p = Path(path)
    if not p.is_file():
        raise GeoJsonError(f"{p}: GeoJSON regions file not found")
    try:
        doc = json.loads(read_text(p, "GeoJSON regions file", MAX_GEOJSON_BYTES))
    except TextInputError as exc:
        raise GeoJsonError(str(exc)) from None
    except (json.JSONDecodeError, RecursionError) as exc:
        raise GeoJsonError(f"{p}: not valid JSON: {' '.join(str(exc).split())[:200]}") from None
    if not isinstance(doc, dict) or not isinstance(doc.get("type"), str):
        raise GeoJsonError(f"{p}: not a GeoJSON object (no 'type')")
    crs = doc.get("crs")
    if crs is not None:
        name = crs.get("properties", {}).get("name") if isinstance(crs, dict) else None
        if name not in _CRS84:
            raise GeoJsonError(f"{p}: coordinates in {name or crs!r}: only WGS-84 lon/lat (CRS84, RFC 7946) is "
                               "supported; reproject the file (e.g. ogr2ogr -t_srs EPSG:4326)")
    kind = doc["type"]
    if kind == "FeatureCollection":
        feats = doc.get("features")
        if not isinstance(feats, list):
            raise GeoJsonError(f"{p}: FeatureCollection has no 'features' list")
        if not feats:
            raise GeoJsonError(f"{p}: FeatureCollection has no features (empty)")
    elif kind == "Feature":
        feats = [doc]
    elif kind in ("Polygon", "MultiPolygon"):
        feats = [{"type": "Feature", "geometry": doc, "properties": {}}]
    else:
        raise GeoJsonError(f"{p}: GeoJSON type '{kind}': expected a FeatureCollection, Feature, Polygon or "
                           "MultiPolygon")
    out = []
    for k, f in enumerate(feats):
        props = f.get("properties") if isinstance(f, dict) else None
        name = _feature_name(props, p.stem, k)
        where = f"{p}: feature {k} '{name}'"
        if not isinstance(f, dict) or f.get("type") != "Feature":
            raise GeoJsonError(f"{where}: not a GeoJSON Feature")
        geom = f.get("geometry")
        if not isinstance(geom, dict):
            raise GeoJsonError(f"{where}: no geometry (null)")
        gtype, coords = geom.get("type"), geom.get("coordinates")
        if gtype not in ("Polygon", "MultiPolygon"):
            raise GeoJsonError(f"{where}: geometry is a {gtype}: only Polygon and MultiPolygon make regions")
        if not isinstance(coords, list) or not coords:
            raise GeoJsonError(f"{where}: empty {gtype} (no coordinates)")
        polys = [coords] if gtype == "Polygon" else coords
        bad = shape_problem(polys)
        if bad:
            raise GeoJsonError(f"{where}: {bad}")
        polygon_deg = [[[[float(v) for v in pos[:2]] for pos in ring] for ring in poly] for poly in polys]
        out.append({"name": name, "polygon_deg": polygon_deg, "source": f"{p.name} feature {k}"})
    return out


def bbox_region(text: str) -> dict | None:
    """``W,S,E,N`` (degrees) as a bounding-box region table named ``bbox``; None when ``text`` is not
    four comma-separated numbers. Raises GeoJsonError for four numbers that make no box."""
    parts = text.split(",")
    if len(parts) != 4:
        return None
    try:
        w, s, e, n = (float(x) for x in parts)
    except ValueError:
        return None
    problem = bbox_problem([w, s, e, n])
    if problem:
        raise GeoJsonError(f"--regions {text}: {problem}")
    return {"name": "bbox", "bbox_deg": [w, s, e, n]}


def bbox_problem(b) -> str | None:
    """What is wrong with ``[west, south, east, north]`` (None: nothing)."""
    w, s, e, n = b
    if not all(-180.0 <= x <= 180.0 for x in (w, e)) or not all(-90.0 <= x <= 90.0 for x in (s, n)):
        return f"[west, south, east, north] = {list(b)}: longitudes must be in -180..180, latitudes in -90..90"
    if not s < n:
        return f"[west, south, east, north] = {list(b)}: south must be below north"
    if w == e:
        return f"[west, south, east, north] = {list(b)}: west equals east (no width)"
    if max(abs(s), abs(n)) > MAX_ABS_LAT_DEG:
        return f"[west, south, east, north] = {list(b)}: beyond +-{MAX_ABS_LAT_DEG:g} deg latitude (polar regions " \
               "are not supported)"
    if (e - w) % 360.0 > 180.0:
        return f"[west, south, east, north] = {list(b)}: spans more than 180 deg of longitude"
    return None


def regions_arg(text: str) -> list[dict]:
    """``--regions``: a GeoJSON file's regions, or one box from ``W,S,E,N``."""
    box = bbox_region(text)
    return [box] if box is not None else read_geojson_regions(Path(text).expanduser().resolve())
