"""Visualisation messages recorded with every run (issue 5 "Visualisation topics"), no rclpy.

Pure functions returning rosbags typestore messages (``bringup.recording.TYPESTORE``), ready for
``BagWriter.write_msg``:

* ``navsat_fix(r_ecef_km, t_ns)`` -> sensor_msgs/msg/NavSatFix of the sub-satellite point
  (WGS-84 geodetic latitude/longitude [deg], altitude [m]); Foxglove's Map panel draws it.
* ``constellation_markers(sat_names, r_ecef_km, t_ns, gp_ecef_km=, gp_values=, links=)`` ->
  visualization_msgs/msg/MarkerArray in the one fixed frame ``earth`` (ECEF) scaled to 1000 km
  units (Foxglove renders in 32-bit floats): the Earth (sphere), satellites (SPHERE_LIST) with name
  labels, ground points (CUBE_LIST) coloured by value (blue low -> red high), live ISL links
  (LINE_LIST). Markers keep fixed (ns, id) so each message replaces the last.
* ``viz_messages(...)`` -> [(topic, msgtype, msg)] for one instant: one fix per satellite on
  ``/<sat>/fix`` plus the MarkerArray on ``/viz/constellation``; ``write_viz(bag, ...)`` writes them.

Header stamps are sim time (``t_ns`` since the scenario epoch, as /clock).

Oracle (tests/unit/test_viz.py): geodetic conversion checked against the closed-form forward
transform (geodetic -> ECEF, an independent formula) to < 1 mm and at the equator/poles; the
messages serialize with rosbags and decode with mcap-ros2-support; marker geometry checked
against the inputs (positions / 1000, links joining the right satellites, colour ramp monotone).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from bringup.recording import TYPESTORE
from msgs_json.topics import VIZ_MARKERS, fix_topic

__all__ = [
    "FRAME",
    "MARKERS_TYPE",
    "NAVSAT_TYPE",
    "SCALE_KM",
    "WGS84_A_KM",
    "WGS84_F",
    "constellation_markers",
    "ecef_to_geodetic",
    "geodetic_to_ecef",
    "navsat_fix",
    "value_color",
    "viz_messages",
    "write_viz",
]

FRAME = "earth"
SCALE_KM = 1000.0  # one visualisation unit = 1000 km
WGS84_A_KM = 6378.137
WGS84_F = 1.0 / 298.257223563
_E2 = WGS84_F * (2.0 - WGS84_F)
_B_KM = WGS84_A_KM * (1.0 - WGS84_F)
_EP2 = _E2 / (1.0 - _E2)

NAVSAT_TYPE = "sensor_msgs/msg/NavSatFix"
MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"
_T = TYPESTORE.types
_Marker = _T["visualization_msgs/msg/Marker"]


# --- geodesy -------------------------------------------------------------------------------------------
def geodetic_to_ecef(lat_deg, lon_deg, alt_km):
    """WGS-84 geodetic -> ECEF [km] (closed form)."""
    lat, lon = np.radians(lat_deg), np.radians(lon_deg)
    n = WGS84_A_KM / np.sqrt(1.0 - _E2 * np.sin(lat) ** 2)
    x = (n + alt_km) * np.cos(lat) * np.cos(lon)
    y = (n + alt_km) * np.cos(lat) * np.sin(lon)
    z = (n * (1.0 - _E2) + alt_km) * np.sin(lat)
    return np.stack([x, y, z], axis=-1)


def ecef_to_geodetic(r_ecef_km):
    """ECEF [km] (..., 3) -> (lat_deg, lon_deg, alt_km), Bowring's start plus two fixed-point
    refinements (well below a millimetre from the surface to 2000 km)."""
    r = np.asarray(r_ecef_km, dtype=float)
    x, y, z = r[..., 0], r[..., 1], r[..., 2]
    p = np.hypot(x, y)
    lon = np.arctan2(y, x)
    theta = np.arctan2(z * WGS84_A_KM, p * _B_KM)
    lat = np.arctan2(z + _EP2 * _B_KM * np.sin(theta) ** 3, p - _E2 * WGS84_A_KM * np.cos(theta) ** 3)
    for _ in range(2):  # fixed-point refinement with the pole-stable height formula
        n = WGS84_A_KM / np.sqrt(1.0 - _E2 * np.sin(lat) ** 2)
        alt = p * np.cos(lat) + z * np.sin(lat) - WGS84_A_KM ** 2 / n
        lat = np.arctan2(z, p * (1.0 - _E2 * n / (n + alt)))
    n = WGS84_A_KM / np.sqrt(1.0 - _E2 * np.sin(lat) ** 2)
    sl, cl = np.sin(lat), np.cos(lat)
    alt = p * cl + z * sl - WGS84_A_KM ** 2 / n  # exact for given lat, stable at the poles
    return np.degrees(lat), np.degrees(lon), alt


# --- message builders ------------------------------------------------------------------------------------
def _stamp(t_ns: int):
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return _T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec)


def _header(t_ns: int, frame: str = FRAME):
    return _T["std_msgs/msg/Header"](stamp=_stamp(t_ns), frame_id=frame)


def navsat_fix(r_ecef_km: Sequence[float], t_ns: int, frame_id: str = FRAME):
    """NavSatFix of the sub-satellite point of a satellite at ``r_ecef_km`` [km]."""
    lat, lon, alt_km = ecef_to_geodetic(np.asarray(r_ecef_km, dtype=float))
    status = _T["sensor_msgs/msg/NavSatStatus"](status=0, service=0)
    return _T[NAVSAT_TYPE](
        header=_header(t_ns, frame_id),
        status=status,
        latitude=float(lat),
        longitude=float(lon),
        altitude=float(alt_km) * 1000.0,
        position_covariance=np.zeros(9, dtype=np.float64),
        position_covariance_type=0,
    )


_COLORS: dict = {}
_GP_POINTS: dict = {}


def value_color(value: float, vmax: float = 256.0, alpha: float = 0.9):
    """ColorRGBA on a blue (0) -> green -> red (vmax) ramp; 0 or less is grey. Made once per
    (value, vmax, alpha): message objects are only read when serialized, so equal colours share one."""
    key = (float(value), vmax, alpha)
    c = _COLORS.get(key)
    if c is None:
        if len(_COLORS) > 65536:
            _COLORS.clear()
        c = _COLORS[key] = _value_color(value, vmax, alpha)
    return c


def _value_color(value: float, vmax: float, alpha: float):
    C = _T["std_msgs/msg/ColorRGBA"]
    if not value > 0:
        return C(r=0.5, g=0.5, b=0.5, a=alpha)
    x = min(float(value) / vmax, 1.0)
    return C(r=float(min(1.0, 2 * x)), g=float(1.0 - abs(2 * x - 1.0)), b=float(max(0.0, 1.0 - 2 * x)), a=alpha)


def _point(v):
    return _T["geometry_msgs/msg/Point"](x=float(v[0]) / SCALE_KM, y=float(v[1]) / SCALE_KM, z=float(v[2]) / SCALE_KM)


def _gp_points(g: np.ndarray) -> list:
    """Points of the (static) ground points, made once per distinct array."""
    key = g.tobytes()
    pts = _GP_POINTS.get(key)
    if pts is None:
        _GP_POINTS.clear()
        pts = _GP_POINTS[key] = [_point(v) for v in g]
    return pts


def _marker(t_ns, ns, mid, mtype, *, scale, color, points=(), colors=(), text="", position=(0.0, 0.0, 0.0)):
    G = _T
    pose = G["geometry_msgs/msg/Pose"](
        position=G["geometry_msgs/msg/Point"](x=position[0], y=position[1], z=position[2]),
        orientation=G["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
    )
    return _Marker(
        header=_header(t_ns),
        ns=ns,
        id=mid,
        type=mtype,
        action=0,
        pose=pose,
        scale=G["geometry_msgs/msg/Vector3"](x=scale[0], y=scale[1], z=scale[2]),
        color=color,
        lifetime=G["builtin_interfaces/msg/Duration"](sec=0, nanosec=0),
        frame_locked=False,
        points=list(points),
        colors=list(colors),
        texture_resource="",
        texture=G["sensor_msgs/msg/CompressedImage"](header=_header(0), format="", data=np.zeros(0, np.uint8)),
        uv_coordinates=[],
        text=text,
        mesh_resource="",
        mesh_file=G["visualization_msgs/msg/MeshFile"](filename="", data=np.zeros(0, np.uint8)),
        mesh_use_embedded_materials=False,
    )


def constellation_markers(
    sat_names: Sequence[str],
    r_ecef_km,
    t_ns: int,
    *,
    gp_ecef_km=None,
    gp_values=None,
    links: Sequence[tuple[str, str]] = (),
    value_max: float = 256.0,
    labels: bool = True,
):
    """MarkerArray (frame ``earth``, 1000 km units): Earth, satellites, ground points, ISL links.

    r_ecef_km: (N, 3) satellite positions [km], in ``sat_names`` order; gp_ecef_km: (M, 3) [km] with
    gp_values (M,) (value 1..256; 0 = nothing left to see); links: pairs of satellite names now in
    contact (each drawn once, whatever the direction)."""
    r = np.asarray(r_ecef_km, dtype=float).reshape(-1, 3)
    if len(r) != len(sat_names):
        raise ValueError(f"constellation_markers: {len(sat_names)} names but {len(r)} positions")
    C = _T["std_msgs/msg/ColorRGBA"]
    M = _Marker
    earth_d = 2 * WGS84_A_KM / SCALE_KM
    markers = [
        _marker(t_ns, "earth", 0, M.SPHERE, scale=(earth_d, earth_d, 2 * _B_KM / SCALE_KM),
                color=C(r=0.15, g=0.3, b=0.6, a=0.6)),
        _marker(t_ns, "satellites", 0, M.SPHERE_LIST, scale=(0.15, 0.15, 0.15),
                color=C(r=1.0, g=1.0, b=1.0, a=1.0), points=[_point(v) for v in r]),
    ]
    idx = {n: i for i, n in enumerate(sat_names)}
    pairs = sorted({tuple(sorted(p)) for p in links})
    pts = []
    for a, b in pairs:
        if a not in idx or b not in idx:
            raise ValueError(f"constellation_markers: link {a}-{b} names an unknown satellite")
        pts += [_point(r[idx[a]]), _point(r[idx[b]])]
    markers.append(_marker(t_ns, "isl", 0, M.LINE_LIST, scale=(0.02, 0.0, 0.0),
                           color=C(r=1.0, g=0.85, b=0.1, a=0.9), points=pts))
    if gp_ecef_km is not None:
        g = np.asarray(gp_ecef_km, dtype=float).reshape(-1, 3)
        vals = np.zeros(len(g)) if gp_values is None else np.asarray(gp_values, dtype=float)
        if len(vals) != len(g):
            raise ValueError(f"constellation_markers: {len(g)} ground points but {len(vals)} values")
        markers.append(_marker(t_ns, "ground_points", 0, M.CUBE_LIST, scale=(0.008, 0.008, 0.008),
                               color=C(r=1.0, g=1.0, b=1.0, a=1.0), points=_gp_points(g),
                               colors=[value_color(v, value_max) for v in vals]))
    if labels:
        for i, name in enumerate(sat_names):
            p = r[i] / SCALE_KM * 1.04
            markers.append(_marker(t_ns, "labels", i, M.TEXT_VIEW_FACING, scale=(0.0, 0.0, 0.25),
                                   color=C(r=1.0, g=1.0, b=1.0, a=1.0), text=name,
                                   position=(float(p[0]), float(p[1]), float(p[2]))))
    return _T[MARKERS_TYPE](markers=markers)


def viz_messages(sat_names: Sequence[str], r_ecef_km, t_ns: int, **markers_kw) -> list[tuple[str, str, Any]]:
    """One instant's visualisation: a NavSatFix per satellite and the MarkerArray."""
    r = np.asarray(r_ecef_km, dtype=float).reshape(-1, 3)
    out: list[tuple[str, str, Any]] = [
        (fix_topic(n), NAVSAT_TYPE, navsat_fix(r[i], t_ns)) for i, n in enumerate(sat_names)
    ]
    out.append((VIZ_MARKERS, MARKERS_TYPE, constellation_markers(sat_names, r, t_ns, **markers_kw)))
    return out


def write_viz(bag, sat_names: Sequence[str], r_ecef_km, t_ns: int, **markers_kw) -> int:
    """Write :func:`viz_messages` to a BagWriter at log time ``t_ns``; returns how many."""
    msgs = viz_messages(sat_names, r_ecef_km, t_ns, **markers_kw)
    for topic, msgtype, msg in msgs:
        bag.write_msg(topic, msgtype, msg, t_ns)
    return len(msgs)
