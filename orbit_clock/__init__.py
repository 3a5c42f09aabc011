"""orbit_clock: orbital mechanics of the constellation (pure, no rclpy; docs/design.md section 1).

Front door of the pure core: Walker generation, SGP4 propagation, frames, ground points, GP access,
ISL and ground-station contact plans, bundle priority order, contact-plan types. Simulated time is
kept by the engines (bringup/engine), not here.
"""

from orbit_clock.access import (
    AccessWindows,
    access_windows,
    access_windows_bruteforce,
    off_nadir_deg,
    off_nadir_profile,
    visibility_matrix,
)
from orbit_clock.contact_plan import Contact, ContactPlan, canonical_node, node_name, node_number
from orbit_clock.frames import ecef_to_geodetic, elevation_deg, geodetic_to_ecef_km, gmst_rad, teme_to_ecef
from orbit_clock.ground_passes import ground_contact_plan, station_names, station_passes
from orbit_clock.ground_points import GroundPoints, ground_points
from orbit_clock.isl import isl_contact_plan, isl_windows, los_clear, los_clearance_km
from orbit_clock.priority import next_access_s, priority_order
from orbit_clock.propagation import Constellation, PropagationError, build_constellation
from orbit_clock.walker import WalkerElements, walker_elements

__all__ = [
    "AccessWindows",
    "Constellation",
    "Contact",
    "ContactPlan",
    "GroundPoints",
    "PropagationError",
    "WalkerElements",
    "access_windows",
    "access_windows_bruteforce",
    "build_constellation",
    "canonical_node",
    "ecef_to_geodetic",
    "elevation_deg",
    "geodetic_to_ecef_km",
    "gmst_rad",
    "ground_contact_plan",
    "ground_points",
    "isl_contact_plan",
    "isl_windows",
    "los_clear",
    "los_clearance_km",
    "next_access_s",
    "node_name",
    "node_number",
    "off_nadir_deg",
    "off_nadir_profile",
    "priority_order",
    "station_names",
    "station_passes",
    "teme_to_ecef",
    "visibility_matrix",
    "walker_elements",
]
