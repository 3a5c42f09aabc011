"""Regions drawn as shapes: bounding boxes and (Multi)Polygons in lon/lat, cut into ground points.

A shape region is a GeoJSON (RFC 7946) Polygon or MultiPolygon in WGS-84 longitude/latitude degrees
(its coordinates as the scenario key ``polygon_deg`` holds them: a list of polygons, each a list of
rings, the first the outer one, each ring a closed list of ``[lon, lat]``), or a bounding box
``bbox_deg = [west, south, east, north]`` (RFC 7946 section 5; west > east crosses the antimeridian,
section 5.2). Edges are straight in lon/lat (RFC 7946 section 3.1.1), which is what shapely's
containment (the GEOS library) tests.

How the GPs are laid out (equal-area): the shape is mapped with the ellipsoidal sinusoidal projection
centred on its central meridian lon0 (Snyder, "Map Projections - A Working Manual", USGS PP 1395,
section 30), ``y = M(lat)`` the WGS-84 meridian arc from the equator and ``x = N(lat) cos(lat)
(lon - lon0)`` with N the prime-vertical radius. The projection is equal-area, so a square grid of
side ``spacing_km`` in (x, y) gives every GP ``spacing_km^2`` of ground: rows are parallels exactly
``spacing_km`` apart along the meridian, and along every row the GPs are ``spacing_km`` apart along
the parallel (as the squares of orbit_clock/ground_points.py, whose grid this is for a small square).
The grid is centred on the shape's projected bounding box the way the squares are (centres at
``(k + 0.5) * spacing - n * spacing / 2`` from its middle), and a candidate is a GP when shapely says
the shape contains it (points on the boundary are not inside). Row 0 is the northernmost candidate
row and column 0 the westernmost candidate column; GP order is row-major, north to south, west to east.

Limits, refused with one line (:class:`RegionShapeError`, or the text of :func:`shape_problem`):
a shape reaching beyond +-85 deg latitude (polar caps are not representable as lon/lat rings and the
rows' circumference vanishes there); one polygon spanning more than 180 deg of longitude (a ring that
crosses the antimeridian must be split at +-180 as RFC 7946 section 3.1.9 asks; the parts of a split
MultiPolygon are then put side by side, 170..180 with -180..-170, and gridded as one shape); a region
spanning more than 180 deg of longitude in all; self-intersecting or otherwise invalid polygons
(shapely's ``explain_validity`` names where), empty or zero-area shapes; a shape too small or thin to
hold one GP at the spacing.

How we know it is right (tests/unit/test_region_shapes.py): against shapely's own containment on a
dense sample of the polygon (a concave polygon with a hole, and a MultiPolygon split at the
antimeridian), every GP lies inside and every sample point inside lies within a cell diagonal of a
GP; the GP count times ``spacing^2`` matches the polygon's geodesic area (an independent equal-area
figure: the polygon's area on the authalic sphere by the spherical excess of its densified edges) to
a few percent; neighbours in a row and in a column are ``spacing_km`` apart (chord on the ellipsoid);
the meridian arc against scipy's quadrature of its integral; and every bad shape gives one line.
"""

from __future__ import annotations

import math

import numpy as np

from orbit_clock.frames import WGS84_A_KM, WGS84_E2

__all__ = ["MAX_ABS_LAT_DEG", "RegionShapeError", "bbox_polygon", "meridian_arc_km", "shape_area_km2",
           "shape_grid", "shape_problem"]

MAX_ABS_LAT_DEG = 85.0
MAX_CANDIDATES = 20_000_000  # grid points tested for containment in one region (~0.5 GiB of arrays)


class RegionShapeError(ValueError):
    """A shape region that cannot be gridded; the message is one line naming the region."""


# --------------------------------------------------------------------------------------------
# The ellipsoidal sinusoidal projection
# --------------------------------------------------------------------------------------------
_E2, _E4, _E6 = WGS84_E2, WGS84_E2 ** 2, WGS84_E2 ** 3
_M0 = 1 - _E2 / 4 - 3 * _E4 / 64 - 5 * _E6 / 256
_M2 = 3 * _E2 / 8 + 3 * _E4 / 32 + 45 * _E6 / 1024
_M4 = 15 * _E4 / 256 + 45 * _E6 / 1024
_M6 = 35 * _E6 / 3072


def meridian_arc_km(lat_deg) -> np.ndarray:
    """WGS-84 meridian arc from the equator to ``lat_deg`` [km] (Snyder eq. 3-21; error < 1 mm)."""
    p = np.deg2rad(np.asarray(lat_deg, dtype=np.float64))
    return WGS84_A_KM * (_M0 * p - _M2 * np.sin(2 * p) + _M4 * np.sin(4 * p) - _M6 * np.sin(6 * p))


def _lat_of_arc(m_km: np.ndarray) -> np.ndarray:
    """Inverse of meridian_arc_km by Newton's method on the meridian radius of curvature [deg]."""
    m_km = np.asarray(m_km, dtype=np.float64)
    p = m_km / (WGS84_A_KM * _M0)
    for _ in range(6):
        s2 = np.sin(p) ** 2
        rho = WGS84_A_KM * (1 - _E2) / (1 - _E2 * s2) ** 1.5
        p = p - (meridian_arc_km(np.rad2deg(p)) - m_km) / rho
    return np.rad2deg(p)


def _parallel_radius_km(lat_deg) -> np.ndarray:
    """N(lat) cos(lat): the radius of the parallel at ``lat_deg`` [km]."""
    p = np.deg2rad(np.asarray(lat_deg, dtype=np.float64))
    return WGS84_A_KM * np.cos(p) / np.sqrt(1 - _E2 * np.sin(p) ** 2)


# --------------------------------------------------------------------------------------------
# Checking shapes
# --------------------------------------------------------------------------------------------
def bbox_polygon(bbox_deg) -> list:
    """``[west, south, east, north]`` as MultiPolygon coordinates: one rectangle, or two split at
    +-180 when the box crosses the antimeridian (west > east, RFC 7946 section 5.2)."""
    w, s, e, n = (float(v) for v in bbox_deg)

    def rect(a, b):
        return [[[a, s], [b, s], [b, n], [a, n], [a, s]]]

    return [rect(w, e)] if w <= e else [rect(w, 180.0), rect(-180.0, e)]


def _ring_problem(ring, where: str) -> str | None:
    if not isinstance(ring, (list, tuple)) or len(ring) < 4:
        n = len(ring) if isinstance(ring, (list, tuple)) else 0
        return f"{where}: a ring needs at least 4 positions (closed: the last repeats the first), got {n}"
    for k, pos in enumerate(ring):
        if (not isinstance(pos, (list, tuple)) or len(pos) < 2
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in pos)):
            return f"{where}, position {k}: expected [lon, lat] numbers, got {pos!r}"[:300]
        lon, lat = float(pos[0]), float(pos[1])
        if not (math.isfinite(lon) and math.isfinite(lat)):
            return f"{where}, position {k}: coordinates must be finite, got {pos!r}"
        if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
            return (f"{where}, position {k}: [{lon:g}, {lat:g}] is not [lon, lat] in degrees (lon -180..180, "
                    f"lat -90..90; GeoJSON puts longitude first)")
        if abs(lat) > MAX_ABS_LAT_DEG:
            return (f"{where}, position {k}: latitude {lat:g} is beyond +-{MAX_ABS_LAT_DEG:g} deg (polar regions "
                    f"are not supported)")
    if [float(v) for v in ring[0][:2]] != [float(v) for v in ring[-1][:2]]:
        return f"{where}: ring is not closed (its last position must repeat its first)"
    return None


def shape_problem(polygon_deg) -> str | None:
    """What is wrong with MultiPolygon coordinates (None: nothing), as one phrase naming the polygon,
    ring and position: structure, coordinates, latitude limit, antimeridian, emptiness, validity."""
    if not isinstance(polygon_deg, (list, tuple)) or not polygon_deg:
        return "empty shape (no polygon)"
    from shapely import Polygon
    from shapely.validation import explain_validity

    spans = []
    for i, poly in enumerate(polygon_deg):
        where = f"polygon {i}" if len(polygon_deg) > 1 else "polygon"
        if not isinstance(poly, (list, tuple)) or not poly:
            return f"{where}: empty (no ring)"
        for j, ring in enumerate(poly):
            bad = _ring_problem(ring, f"{where}, ring {j}")
            if bad:
                return bad
        lons = [float(p[0]) for p in poly[0]]
        span = max(lons) - min(lons)
        if span > 180.0:
            return (f"{where}: spans {span:g} deg of longitude ({min(lons):g}..{max(lons):g}); a shape crossing "
                    f"the antimeridian must be split at +-180 into a MultiPolygon (RFC 7946 section 3.1.9)")
        spans.append((min(lons), max(lons)))
        shp = Polygon(poly[0], poly[1:])
        if not shp.is_valid:
            return f"{where}: invalid polygon: {explain_validity(shp)}"
        if shp.area <= 0:
            return f"{where}: has no area"
    if len(polygon_deg) > 1:
        from shapely import MultiPolygon

        mp = MultiPolygon([Polygon(p[0], p[1:]) for p in polygon_deg])
        if not mp.is_valid:
            return f"invalid MultiPolygon (its polygons overlap?): {explain_validity(mp)}"
        if _unwrap_shift(spans) is None:
            return ("spans more than 180 deg of longitude in all (either way round the antimeridian): split it "
                    "into regions")
    return None


def _unwrap_shift(spans: list[tuple[float, float]]) -> list[float] | None:
    """Per polygon, 0 or 360 added to its longitudes so the region spans at most 180 deg (None: no way)."""
    lo, hi = min(s[0] for s in spans), max(s[1] for s in spans)
    if hi - lo <= 180.0:
        return [0.0] * len(spans)
    shift = [360.0 if s[1] <= 0.0 else 0.0 for s in spans]
    lo2 = min(s[0] + d for s, d in zip(spans, shift, strict=True))
    hi2 = max(s[1] + d for s, d in zip(spans, shift, strict=True))
    return shift if hi2 - lo2 <= 180.0 else None


def _unwrapped(polygon_deg) -> list[list[np.ndarray]]:
    """The polygons' rings as (n, 2) [lon, lat] arrays, longitudes made contiguous across +-180."""
    rings = [[np.asarray(r, dtype=np.float64)[:, :2] for r in poly] for poly in polygon_deg]
    spans = [(float(p[0][:, 0].min()), float(p[0][:, 0].max())) for p in rings]
    shift = _unwrap_shift(spans)
    if shift is None:
        raise RegionShapeError("shape spans more than 180 deg of longitude")
    for p, d in zip(rings, shift, strict=True):
        for r in p:
            r[:, 0] += d
    return rings


# --------------------------------------------------------------------------------------------
# Gridding
# --------------------------------------------------------------------------------------------
def _projected(rings, lon0: float):
    """(x, y) [km] of ring vertices in the sinusoidal projection about lon0."""
    return (_parallel_radius_km(rings[:, 1]) * np.deg2rad(rings[:, 0] - lon0), meridian_arc_km(rings[:, 1]))


def shape_grid(polygon_deg, spacing_km: float, *, name: str = "region"):
    """(lat_deg, lon_deg, row, col) of the GPs of a shape (module docstring), row-major north->south,
    west->east. Raises RegionShapeError naming ``name`` when the shape holds no GP at this spacing,
    or would need more than MAX_CANDIDATES grid points tested."""
    from shapely import Polygon, contains_xy, prepare

    if not spacing_km > 0:
        raise RegionShapeError(f"{name}: GP spacing must be > 0 km, got {spacing_km}")
    bad = shape_problem(polygon_deg)
    if bad:
        raise RegionShapeError(f"{name}: {bad}")
    rings = _unwrapped(polygon_deg)
    outer = np.concatenate([p[0] for p in rings])
    lon_lo, lon_hi = float(outer[:, 0].min()), float(outer[:, 0].max())
    lat_lo, lat_hi = float(outer[:, 1].min()), float(outer[:, 1].max())
    lon0 = 0.5 * (lon_lo + lon_hi)
    # projected extent: y from the latitudes; x from the widest parallel the shape reaches (edges
    # straight in lon/lat never leave the lon/lat box, and |x| grows with N cos(lat) and |lon - lon0|)
    y_lo, y_hi = float(meridian_arc_km(lat_lo)), float(meridian_arc_km(lat_hi))
    widest = float(_parallel_radius_km(0.0 if lat_lo <= 0.0 <= lat_hi else
                                       min(abs(lat_lo), abs(lat_hi))))
    half_x = widest * math.radians(0.5 * (lon_hi - lon_lo))
    n_rows = max(1, math.ceil((y_hi - y_lo) / spacing_km - 1e-9))
    n_cols = max(1, math.ceil(2.0 * half_x / spacing_km - 1e-9))
    if n_rows * n_cols > MAX_CANDIDATES:
        raise RegionShapeError(f"{name}: {n_rows} x {n_cols} grid points at {spacing_km:g} km to test (over "
                               f"{MAX_CANDIDATES:.3g}); use a larger regions.gp_spacing_km or a smaller shape")
    y_mid = 0.5 * (y_lo + y_hi)
    y = y_mid - ((np.arange(n_rows) + 0.5) * spacing_km - n_rows * spacing_km / 2.0)  # row 0 northernmost
    x = (np.arange(n_cols) + 0.5) * spacing_km - n_cols * spacing_km / 2.0
    lat_rows = _lat_of_arc(y)
    rr, cc = np.meshgrid(np.arange(n_rows), np.arange(n_cols), indexing="ij")
    lat = lat_rows[rr]
    lon = lon0 + np.rad2deg(x[cc] / _parallel_radius_km(lat))
    inside = np.zeros(lat.shape, dtype=bool)
    for p in rings:
        shp = Polygon(p[0], p[1:])
        prepare(shp)
        inside |= contains_xy(shp, lon, lat)
    if not inside.any():
        raise RegionShapeError(f"{name}: too small or thin for one GP at {spacing_km:g} km spacing (no grid point "
                               f"falls inside it); use a smaller regions.gp_spacing_km or a larger shape")
    lon_in = (lon[inside] + 180.0) % 360.0 - 180.0
    return lat[inside], lon_in, rr[inside], cc[inside]


def shape_area_km2(polygon_deg) -> float:
    """Area of a shape [km^2] from its vertices in the equal-area projection (an estimate for sizing:
    edges straight in the projection rather than in lon/lat)."""
    from shapely import Polygon

    rings = _unwrapped(polygon_deg)
    lon0 = 0.5 * (min(float(p[0][:, 0].min()) for p in rings) + max(float(p[0][:, 0].max()) for p in rings))
    area = 0.0
    for p in rings:
        proj = [np.column_stack(_projected(r, lon0)) for r in p]
        area += Polygon(proj[0], proj[1:]).area
    return float(area)
