"""Ground points (GPs): each scenario region (a city centre and a square side, or a drawn shape) cut into a grid.

A region of side ``size_km`` at spacing ``spacing_km`` holds n x n points, n = round(size/spacing)
(paper: the GPs Nyquist-sample the 8 km footprint, Nag et al. 2019, section 5: 80 km / 4 km =
20 x 20 = 400 GPs per region, 2000 for the 5 cities). Point centres sit at (k + 0.5) * spacing - size/2 km north/east of the region
centre, converted to geodetic lat/lon with the WGS-84 meridian radius of curvature at the centre (rows) and
the prime-vertical radius at each row's latitude (columns), so neighbours are spacing_km apart to
0.1 % (rows are parallels: columns converge by cos(lat) only across rows, < 1 % over 80 km). GPs lie on the
ellipsoid (height 0). Regions drawn as shapes (a bounding box or a GeoJSON Polygon / MultiPolygon, the
scenario's ``bbox_deg`` / ``polygon_deg``) are gridded by orbit_clock/region_shapes.py on an equal-area
grid at the same spacing; their centre is the direction of their GPs' mean and their half diagonal the
farthest GP from it.

Global GP id 0..n-1: region order of the scenario, then row (north to south), then column (west to
east). ``GroundPoints.region_names[region_index[g]]`` is the region of GP g.

How we know it is right: tests/unit/test_orbit_propagation.py checks the paper's counts (400 per
region, 2000 in all), that neighbours are ``spacing_km`` apart (chord on the ellipsoid, to 0.1 %),
the region's extent and the id order; tests/unit/test_region_shapes.py the shapes.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from orbit_clock.frames import (
    WGS84_A_KM,
    WGS84_B_KM,
    WGS84_E2,
    ecef_to_geodetic,
    geodetic_to_ecef_km,
    up_unit,
)

__all__ = ["GroundPoints", "ground_points", "region_grid"]


@dataclass(frozen=True)
class GroundPoints:
    """Arrays of length n (one row per GP id) plus the region names."""

    region_names: list[str]
    region_index: np.ndarray  # (n,) int
    row: np.ndarray  # (n,) int, 0 = northernmost
    col: np.ndarray  # (n,) int, 0 = westernmost
    lat_deg: np.ndarray
    lon_deg: np.ndarray
    ecef_km: np.ndarray  # (n, 3)
    region_center_lat_deg: np.ndarray  # (n_regions,)
    region_center_lon_deg: np.ndarray
    region_half_diag_km: np.ndarray  # (n_regions,) farthest GP from the centre [km]
    # (n_regions,) side of the square about the centre that the synthetic field spreads over [km]:
    # a square's size_km; a shape's sqrt(2) x its half diagonal
    region_size_km: np.ndarray | None = None

    def __len__(self) -> int:
        return int(self.lat_deg.size)

    @property
    def ids(self) -> np.ndarray:
        return np.arange(len(self))

    @property
    def up(self) -> np.ndarray:
        return up_unit(self.lat_deg, self.lon_deg)

    def region_id(self, region) -> int:
        """Region index from a name or an index."""
        if isinstance(region, (int, np.integer)):
            if not 0 <= region < len(self.region_names):
                raise ValueError(f"region index {region}: out of range 0..{len(self.region_names) - 1}")
            return int(region)
        try:
            return self.region_names.index(region)
        except ValueError:
            raise ValueError(f"region {region!r}: not one of {self.region_names}") from None

    def in_region(self, region) -> np.ndarray:
        """GP ids of a region (by name or index), in id order."""
        return np.flatnonzero(self.region_index == self.region_id(region))


def region_grid(lat_deg: float, lon_deg: float, size_km: float, spacing_km: float):
    """(lat_deg, lon_deg, row, col) arrays of one region's grid, row-major north->south, west->east."""
    if spacing_km <= 0 or size_km <= 0:
        raise ValueError(f"region grid: size_km={size_km} and spacing_km={spacing_km} must be > 0")
    n = max(1, round(size_km / spacing_km))
    off_km = (np.arange(n) + 0.5) * spacing_km - n * spacing_km / 2.0
    lat0 = np.deg2rad(lat_deg)
    s2 = np.sin(lat0) ** 2
    r_meridian_km = WGS84_A_KM * (1 - WGS84_E2) / (1 - WGS84_E2 * s2) ** 1.5
    north_km = off_km[::-1]  # row 0 northernmost
    rows, cols = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    lat = lat_deg + np.rad2deg(north_km[rows] / r_meridian_km)
    # east-west offsets at each row's own latitude, so every row keeps spacing_km between columns
    lat_r = np.deg2rad(lat)
    r_prime_row_km = WGS84_A_KM / np.sqrt(1 - WGS84_E2 * np.sin(lat_r) ** 2)
    lon = lon_deg + np.rad2deg(off_km[cols] / (r_prime_row_km * np.cos(lat_r)))
    lon = (lon + 180.0) % 360.0 - 180.0
    return lat.ravel(), lon.ravel(), rows.ravel(), cols.ravel()


def _shape_region(reg, shape, spacing: float):
    """A shape region's grid, centre (lat, lon), half diagonal and size [km]."""
    from orbit_clock.region_shapes import shape_grid

    label = getattr(reg, "label", None) or f"region '{reg.name}'"
    la, lo, r, c = shape_grid(shape, spacing, name=label)
    xyz = geodetic_to_ecef_km(la, lo, 0.0)
    gu = xyz / np.linalg.norm(xyz, axis=1, keepdims=True)
    m = gu.mean(axis=0)
    c_lat, c_lon, _ = ecef_to_geodetic(m / np.linalg.norm(m) * WGS84_A_KM)
    cu = geodetic_to_ecef_km(c_lat, c_lon, 0.0)
    cu = cu / np.linalg.norm(cu)
    half = float(np.max(np.arccos(np.clip(gu @ cu, -1.0, 1.0)))) * WGS84_B_KM + 1e-6
    return (la, lo, r, c), float(c_lat), float(c_lon), half, np.sqrt(2.0) * half + spacing


def ground_points(scenario, spacing_km: float | None = None) -> GroundPoints:
    """The scenario's regions cut at ``spacing_km`` (default scenario.gp_spacing_km). A region whose
    ``shape_deg`` is not None (scenario regions drawn as shapes) is gridded by
    orbit_clock/region_shapes.py; others are squares (lat_deg, lon_deg, size_km)."""
    spacing = float(spacing_km if spacing_km is not None else scenario.gp_spacing_km)
    regions = scenario.regions.list
    lats, lons, rows, cols, ridx, half, c_lat, c_lon, size = [], [], [], [], [], [], [], [], []
    for i, reg in enumerate(regions):
        shape = getattr(reg, "shape_deg", None)
        if shape is not None:
            (la, lo, r, c), cla, clo, h, sz = _shape_region(reg, shape, spacing)
        else:
            la, lo, r, c = region_grid(reg.lat_deg, reg.lon_deg, reg.size_km, spacing)
            cla, clo, sz = reg.lat_deg, reg.lon_deg, reg.size_km
            h = np.sqrt(2.0) * (max(1, round(reg.size_km / spacing)) * spacing) / 2.0
        lats.append(la), lons.append(lo), rows.append(r), cols.append(c)
        ridx.append(np.full(la.size, i))
        half.append(h), c_lat.append(cla), c_lon.append(clo), size.append(sz)
    lat = np.concatenate(lats)
    lon = np.concatenate(lons)
    return GroundPoints(
        region_names=[r.name for r in regions],
        region_index=np.concatenate(ridx),
        row=np.concatenate(rows),
        col=np.concatenate(cols),
        lat_deg=lat,
        lon_deg=lon,
        ecef_km=geodetic_to_ecef_km(lat, lon, 0.0),
        region_center_lat_deg=np.array(c_lat, dtype=np.float64),
        region_center_lon_deg=np.array(c_lon, dtype=np.float64),
        region_half_diag_km=np.array(half),
        region_size_km=np.array(size, dtype=np.float64),
    )
