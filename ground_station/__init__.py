"""Ground segment: the OSSE value forecast (synthetic or from a file) and the centralized mode's
ground scheduler (ground_segment.py; Nag et al., section 5).

Front door (no rclpy): ``osse_from_scenario(scenario, gps) -> OsseField``.
"""

from ground_station.osse import (
    VALUE_MAX,
    VALUE_MIN,
    GroundPointArrays,
    OsseError,
    OsseField,
    SyntheticParams,
    as_ground_point_arrays,
    synthetic_field,
)
from ground_station.osse_io import load_value_grid, read_grid, write_value_grid
from ground_station.osse_sources import OSSE_SOURCES, osse_from_scenario

__all__ = [
    "OSSE_SOURCES",
    "VALUE_MAX",
    "VALUE_MIN",
    "GroundPointArrays",
    "OsseError",
    "OsseField",
    "SyntheticParams",
    "as_ground_point_arrays",
    "load_value_grid",
    "osse_from_scenario",
    "read_grid",
    "synthetic_field",
    "write_value_grid",
]
