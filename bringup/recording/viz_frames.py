"""The run's TF tree (tf2_msgs/msg/TFMessage), no rclpy: ``earth`` and the frames hanging from it.

Frames (REP 103: metres, right-handed; REP 105 names the Earth-fixed root ``earth``):

* ``earth`` - the root: WGS-84 ECEF, the frame of every marker and fix of the run
  (bringup/recording/viz_messages.py);
* ``<sat>`` - one per satellite, on ``/tf`` at every visualisation frame: origin at the satellite,
  axes of its orbit frame (LVLH): +z towards the Earth's centre (nadir), +y against the orbit
  normal r x v, +x = y x z (along the velocity for a circular orbit). v is the Earth-fixed velocity
  (central difference of the ECEF track over 1 s), so +x follows the ground track. It is the frame
  a nadir-pointing bus holds, not the instrument's pointing (that is in ``/<sat>/acs/state``);
* ``gs_<name>`` - one per ground station, on ``/tf_static`` once: origin at the station (WGS-84
  geodetic to ECEF), axes east-north-up (ENU).

``satellite_tf(...)`` / ``station_tf(...)`` build the rosbags messages; ``tf_cdr`` serializes them
(rosbags' typestore knows tf2_msgs; the ROS engine's live /tf sends the same bytes, published raw).

How we know it is right (tests/unit/test_viz_frames.py): each quaternion rotates the frame's unit
axes onto the vectors of the definition above (nadir, velocity, ENU from geodetic formulas),
checked against scipy's Rotation.from_matrix as an independent conversion, over random orbits and
sites, the poles and the quaternion's sign branches; the messages round-trip through rosbags.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from bringup.recording.bag import TYPESTORE
from bringup.recording.viz_messages import FRAME, M_PER_KM
from orbit_clock.frames import geodetic_to_ecef_km

__all__ = ["TF_TYPE", "enu_quaternion", "orbit_frame_quaternions", "rotation_to_quaternion",
           "satellite_tf", "station_tf", "tf_cdr"]

TF_TYPE = "tf2_msgs/msg/TFMessage"
_T = TYPESTORE.types


def rotation_to_quaternion(m: np.ndarray) -> np.ndarray:
    """(..., 3, 3) rotation matrices (columns = the child's axes in the parent) -> (..., 4) x, y, z, w
    with w >= 0. Shepperd's method: the largest of w, x, y, z comes from the diagonal, the other three
    from off-diagonal sums divided by it, so no branch divides by a small number."""
    m = np.asarray(m, dtype=np.float64)
    d0, d1, d2 = m[..., 0, 0], m[..., 1, 1], m[..., 2, 2]
    s01, s02, s12 = m[..., 0, 1] + m[..., 1, 0], m[..., 0, 2] + m[..., 2, 0], m[..., 1, 2] + m[..., 2, 1]
    a10, a02, a21 = m[..., 1, 0] - m[..., 0, 1], m[..., 0, 2] - m[..., 2, 0], m[..., 2, 1] - m[..., 1, 2]

    def branch(diag_sum):  # 4 * the largest component, never 0 for the branch chosen
        f = np.sqrt(np.maximum(1.0 + diag_sum, 0.0)) * 2.0
        return f, np.where(f == 0.0, 1.0, f)

    fw, gw = branch(d0 + d1 + d2)
    fx, gx = branch(d0 - d1 - d2)
    fy, gy = branch(d1 - d0 - d2)
    fz, gz = branch(d2 - d0 - d1)
    cands = [
        np.stack([a21 / gw, a02 / gw, a10 / gw, 0.25 * fw], axis=-1),
        np.stack([0.25 * fx, s01 / gx, s02 / gx, a21 / gx], axis=-1),
        np.stack([s01 / gy, 0.25 * fy, s12 / gy, a02 / gy], axis=-1),
        np.stack([s02 / gz, s12 / gz, 0.25 * fz, a10 / gz], axis=-1),
    ]
    k = np.argmax(np.stack([d0 + d1 + d2, d0, d1, d2], axis=-1), axis=-1)
    q = np.take_along_axis(np.stack(cands, axis=-2), k[..., None, None], axis=-2)[..., 0, :]
    q = q / np.linalg.norm(q, axis=-1, keepdims=True)
    return np.where(q[..., 3:4] < 0, -q, q)


def orbit_frame_quaternions(r_ecef_km, v_ecef_km_s) -> np.ndarray:
    """(N, 4) x, y, z, w of each satellite's orbit frame (module docstring) in ``earth``."""
    r = np.asarray(r_ecef_km, dtype=np.float64).reshape(-1, 3)
    v = np.asarray(v_ecef_km_s, dtype=np.float64).reshape(-1, 3)
    z = -r / np.linalg.norm(r, axis=1, keepdims=True)
    h = np.cross(r, v)
    n = np.linalg.norm(h, axis=1, keepdims=True)
    if (n == 0).any():
        raise ValueError("orbit_frame_quaternions: velocity parallel to the position (no orbit plane)")
    y = -h / n
    x = np.cross(y, z)
    return rotation_to_quaternion(np.stack([x, y, z], axis=-1))


def enu_quaternion(lat_deg: float, lon_deg: float) -> np.ndarray:
    """x, y, z, w of the east-north-up frame at geodetic (lat, lon) in ``earth``."""
    la, lo = np.radians(lat_deg), np.radians(lon_deg)
    east = np.array([-np.sin(lo), np.cos(lo), 0.0])
    north = np.array([-np.sin(la) * np.cos(lo), -np.sin(la) * np.sin(lo), np.cos(la)])
    up = np.array([np.cos(la) * np.cos(lo), np.cos(la) * np.sin(lo), np.sin(la)])
    return rotation_to_quaternion(np.stack([east, north, up], axis=-1))


def _transform(parent: str, child: str, t_ns: int, xyz_m, q):
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    return _T["geometry_msgs/msg/TransformStamped"](
        header=_T["std_msgs/msg/Header"](stamp=_T["builtin_interfaces/msg/Time"](sec=sec, nanosec=nsec),
                                         frame_id=parent),
        child_frame_id=child,
        transform=_T["geometry_msgs/msg/Transform"](
            translation=_T["geometry_msgs/msg/Vector3"](x=float(xyz_m[0]), y=float(xyz_m[1]), z=float(xyz_m[2])),
            rotation=_T["geometry_msgs/msg/Quaternion"](x=float(q[0]), y=float(q[1]), z=float(q[2]), w=float(q[3]))))


def satellite_tf(sat_names: Sequence[str], r_ecef_km, v_ecef_km_s, t_ns: int):
    """TFMessage: ``earth`` -> each satellite's orbit frame at ``t_ns`` (the header stamp)."""
    r = np.asarray(r_ecef_km, dtype=np.float64).reshape(-1, 3)
    if len(r) != len(sat_names):
        raise ValueError(f"satellite_tf: {len(sat_names)} names but {len(r)} positions")
    q = orbit_frame_quaternions(r, v_ecef_km_s)
    rm = r * M_PER_KM
    return _T[TF_TYPE](transforms=[_transform(FRAME, n, t_ns, rm[i], q[i]) for i, n in enumerate(sat_names)])


def station_tf(stations, t_ns: int):
    """TFMessage: ``earth`` -> ``gs_<name>`` (ENU) for each station (objects with name, lat_deg,
    lon_deg, alt_m; the scenario's ``[[ground.stations]]``)."""
    out = []
    for s in stations:
        p = np.asarray(geodetic_to_ecef_km(s.lat_deg, s.lon_deg, s.alt_m / 1000.0), dtype=np.float64) * M_PER_KM
        out.append(_transform(FRAME, f"gs_{s.name}", t_ns, p, enu_quaternion(s.lat_deg, s.lon_deg)))
    return _T[TF_TYPE](transforms=out)


def tf_cdr(msg) -> bytes:
    return bytes(TYPESTORE.serialize_cdr(msg, TF_TYPE))
