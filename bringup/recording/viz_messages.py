"""Visualisation messages recorded with every run, no rclpy.

Pure functions returning rosbags typestore messages (``bringup.recording.bag.TYPESTORE``), ready for
``BagWriter.write_msg``:

* ``navsat_fix(r_ecef_km, t_ns)`` -> sensor_msgs/msg/NavSatFix of the sub-satellite point
  (WGS-84 geodetic latitude/longitude [deg], altitude [m]); Foxglove's Map panel draws it.
* ``constellation_markers(sat_names, r_ecef_km, t_ns, gp_ecef_km=, gp_values=, links=)`` ->
  visualization_msgs/msg/MarkerArray in the one fixed frame ``earth`` (ECEF), in metres (REP 103):
  the Earth (WGS-84 ellipsoid), satellites (SPHERE_LIST, 150 km) with name labels, ground points
  (CUBE_LIST, 8 km) coloured by value (blue low -> red high), live ISL links (LINE_LIST, 20 km
  wide). Markers keep fixed (ns, id) so each message replaces the last. Metres at Earth scale are
  fine for Foxglove's 3D panel, which renders in 32-bit floats: the README's Foxglove paragraph has
  the figures (float32 spacing 0.5 m at 7,000 km; the shipped layout's near/far planes), checked by
  tests/unit/test_viz.py.
* ``viz_messages(...)`` -> [(topic, msgtype, msg)] for one instant: one fix per satellite on
  ``/<sat>/fix`` plus the MarkerArray on ``/viz/constellation``.
* ``viz_cdr(...)`` -> [(topic, msgtype, cdr)]: the same messages' CDR written directly (constant
  runs of bytes packed once, positions/colours packed with struct/numpy, the fixes' geodetic
  conversion done for all satellites in one numpy call) - the bytes ``TYPESTORE.serialize_cdr`` gives
  for ``viz_messages``, without building message objects; ``write_viz(bag, ...)`` records them with
  ``bag.write_raw``.

Header stamps are the ``t_ns`` the builders are given; :func:`write_viz` gives them the bag's UTC
instant (its epoch + t_ns, the same as /clock and the log time, bringup/recording/bag.py).

The sub-satellite point is the WGS-84 geodetic conversion of the orbit core
(:func:`orbit_clock.frames.ecef_to_geodetic`, checked in tests/unit/test_orbit_frames.py).

Oracle (tests/unit/test_viz.py): the messages serialize with rosbags and decode with
mcap-ros2-support; fix fields and marker geometry checked against the inputs (positions in metres,
links joining the right satellites, colour ramp monotone). tests/unit/test_viz_fast.py: ``viz_cdr``
bytes equal rosbags' serialization of ``viz_messages`` frame by frame (links none/one/duplicated,
with/without ground points and labels), the vectorised fixes equal ``navsat_fix`` row by row, and a
bag written by ``write_viz`` holds those bytes.
"""

from __future__ import annotations

import struct
from collections.abc import Sequence
from typing import Any

import numpy as np

from bringup.recording.bag import TYPESTORE
from msgs_json.topics import VIZ_MARKERS, fix_topic
from orbit_clock.frames import WGS84_A_KM, WGS84_B_KM, ecef_to_geodetic

__all__ = [
    "FRAME",
    "MARKERS_TYPE",
    "M_PER_KM",
    "NAVSAT_TYPE",
    "constellation_markers",
    "constellation_markers_cdr",
    "navsat_fix",
    "navsat_fixes_cdr",
    "value_color",
    "viz_cdr",
    "viz_messages",
    "write_viz",
]

FRAME = "earth"
M_PER_KM = 1000.0  # markers are in metres (REP 103)
NAVSAT_TYPE = "sensor_msgs/msg/NavSatFix"
MARKERS_TYPE = "visualization_msgs/msg/MarkerArray"
_T = TYPESTORE.types
# marker sizes [m]: satellites 150 km spheres, ISL lines 20 km wide, ground points 8 km cubes,
# labels 250 km high (readable from the layout's 45,000 km camera distance)
_SAT_SCALE = (150e3, 150e3, 150e3)
_ISL_SCALE = (20e3, 0.0, 0.0)
_GP_SCALE = (8e3, 8e3, 8e3)
_LABEL_SCALE = (0.0, 0.0, 250e3)
_Marker = _T["visualization_msgs/msg/Marker"]


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
    return _T["geometry_msgs/msg/Point"](x=float(v[0]) * M_PER_KM, y=float(v[1]) * M_PER_KM, z=float(v[2]) * M_PER_KM)


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


def _link_ends(sat_names, links) -> list[int]:
    """Satellite indices of each ISL's two ends, links sorted and deduplicated (either direction)."""
    idx = {n: i for i, n in enumerate(sat_names)}
    ends: list[int] = []
    for a, b in sorted({tuple(sorted(p)) for p in links}):
        if a not in idx or b not in idx:
            raise ValueError(f"constellation_markers: link {a}-{b} names an unknown satellite")
        ends += [idx[a], idx[b]]
    return ends


def name_ranks(sat_names: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """(rank, by_rank) of the names: ``rank[i]`` is name i's place in string order, ``by_rank[k]``
    the index of the k-th name in that order (what :func:`link_ends_indexed` needs)."""
    by_rank = np.array(sorted(range(len(sat_names)), key=list(sat_names).__getitem__), dtype=np.int64)
    rank = np.empty_like(by_rank)
    rank[by_rank] = np.arange(len(by_rank), dtype=np.int64)
    return rank, by_rank


def link_ends_indexed(rank: np.ndarray, by_rank: np.ndarray, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """:func:`_link_ends` of the links (a[k], b[k]) given as satellite indices into names whose
    :func:`name_ranks` are ``rank``, ``by_rank``: the same list, made on arrays. A link is its two
    ends in string order (the lower name first, as ``tuple(sorted(pair))``), coded lower rank x n +
    higher rank; the sorted distinct codes are the sorted distinct pairs (tests/unit/test_viz_fast.py
    against _link_ends on drawn link lists)."""
    n = len(rank)
    ra, rb = rank[np.asarray(a, dtype=np.int64)], rank[np.asarray(b, dtype=np.int64)]
    codes = np.unique(np.minimum(ra, rb) * n + np.maximum(ra, rb))
    ends = np.empty(2 * len(codes), dtype=np.int64)
    ends[0::2] = by_rank[codes // n]
    ends[1::2] = by_rank[codes % n]
    return ends


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
    """MarkerArray (frame ``earth``, metres): Earth, satellites, ground points, ISL links.

    r_ecef_km: (N, 3) satellite positions [km], in ``sat_names`` order; gp_ecef_km: (M, 3) [km] with
    gp_values (M,) (value 1..256; 0 = nothing left to see); links: pairs of satellite names now in
    contact (each drawn once, whatever the direction)."""
    r = np.asarray(r_ecef_km, dtype=float).reshape(-1, 3)
    if len(r) != len(sat_names):
        raise ValueError(f"constellation_markers: {len(sat_names)} names but {len(r)} positions")
    C = _T["std_msgs/msg/ColorRGBA"]
    M = _Marker
    earth_d = 2 * WGS84_A_KM * M_PER_KM
    markers = [
        _marker(t_ns, "earth", 0, M.SPHERE, scale=(earth_d, earth_d, 2 * WGS84_B_KM * M_PER_KM),
                color=C(r=0.15, g=0.3, b=0.6, a=0.6)),
        _marker(t_ns, "satellites", 0, M.SPHERE_LIST, scale=_SAT_SCALE,
                color=C(r=1.0, g=1.0, b=1.0, a=1.0), points=[_point(v) for v in r]),
    ]
    pts = [_point(r[i]) for i in _link_ends(sat_names, links)]
    markers.append(_marker(t_ns, "isl", 0, M.LINE_LIST, scale=_ISL_SCALE,
                           color=C(r=1.0, g=0.85, b=0.1, a=0.9), points=pts))
    if gp_ecef_km is not None:
        g = np.asarray(gp_ecef_km, dtype=float).reshape(-1, 3)
        vals = np.zeros(len(g)) if gp_values is None else np.asarray(gp_values, dtype=float)
        if len(vals) != len(g):
            raise ValueError(f"constellation_markers: {len(g)} ground points but {len(vals)} values")
        markers.append(_marker(t_ns, "ground_points", 0, M.CUBE_LIST, scale=_GP_SCALE,
                               color=C(r=1.0, g=1.0, b=1.0, a=1.0), points=_gp_points(g),
                               colors=[value_color(v, value_max) for v in vals]))
    if labels:
        for i, name in enumerate(sat_names):
            p = r[i] * M_PER_KM * 1.04
            markers.append(_marker(t_ns, "labels", i, M.TEXT_VIEW_FACING, scale=_LABEL_SCALE,
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


# --- fast path: the same CDR bytes written directly ----------------------------------------------------
# rosbags' serializer walks message objects field by field in Python; a frame is ~30 markers (labels,
# ~25 fields each, most never changing) and one fix per satellite. The functions below emit the CDR
# (OMG XCDR1 little endian, as ROS 2 rmw and rosbags: primitives aligned to their size from the end
# of the 4-byte encapsulation header, strings as uint32 length incl. NUL + bytes + NUL, sequences as
# uint32 count + elements) directly, with the constant runs of bytes packed once. Same bytes as
# TYPESTORE.serialize_cdr of the builders above (tests/unit/test_viz_fast.py, and a paper run's viz
# messages hashed before/after the change).
_CDR_HDR = b"\x00\x01\x00\x00"
_ST_II = struct.Struct("<iI")
_ST_U32 = struct.Struct("<I")
_ST_3D = struct.Struct("<3d")
_ST_4F = struct.Struct("<4f")
_ST_LLA = struct.Struct("<3d")
_ZERO9 = bytes(72)


def _cdr_str(b: bytearray, s: bytes) -> None:
    """Append a CDR string (aligned to 4) to ``b``; ``s`` without its NUL."""
    b += bytes(-(len(b) - 4) % 4)
    b += _ST_U32.pack(len(s) + 1)
    b += s
    b += b"\x00"


def _fix_parts() -> tuple[bytes, bytes, bytes]:
    b = bytearray(_CDR_HDR)
    head = bytes(b)
    b += _ST_II.pack(0, 0)
    n0 = len(b)
    _cdr_str(b, FRAME.encode())
    b += b"\x00"  # status.status int8
    b += bytes(-(len(b) - 4) % 2)
    b += b"\x00\x00"  # status.service uint16
    b += bytes(-(len(b) - 4) % 8)
    mid = bytes(b[n0:])
    return head, mid, _ZERO9 + b"\x00"


_FIX_HEAD, _FIX_MID, _FIX_TAIL = _fix_parts()
_FRAME_B = FRAME.encode()


def _marker_cdr(b: bytearray, sec: int, nsec: int, ns: bytes, mid: int, mtype: int, position, scale,
                color: bytes, points: bytes = b"", npoints: int = 0, colors: bytes = b"", ncolors: int = 0,
                text: bytes = b"") -> None:
    """Append one visualization_msgs/Marker (the fields :func:`_marker` sets) to ``b``."""
    b += bytes(-(len(b) - 4) % 4)
    b += _ST_II.pack(sec, nsec)
    _cdr_str(b, _FRAME_B)
    _cdr_str(b, ns)
    b += bytes(-(len(b) - 4) % 4)
    b += struct.pack("<iii", mid, mtype, 0)
    b += bytes(-(len(b) - 4) % 8)
    b += _ST_3D.pack(*position)
    b += _QUAT_ID
    b += _ST_3D.pack(*scale)
    b += color  # 4 float32, offset multiple of 8 here
    b += _LIFETIME_LOCKED  # lifetime (0, 0), frame_locked False
    b += bytes(-(len(b) - 4) % 4)
    b += _ST_U32.pack(npoints)
    if npoints:
        b += bytes(-(len(b) - 4) % 8)
        b += points
    b += bytes(-(len(b) - 4) % 4)
    b += _ST_U32.pack(ncolors)
    b += colors
    _cdr_str(b, b"")  # texture_resource
    b += bytes(-(len(b) - 4) % 4)
    b += _ST_II.pack(0, 0)  # texture.header.stamp
    _cdr_str(b, _FRAME_B)  # texture.header.frame_id
    _cdr_str(b, b"")  # texture.format
    b += bytes(-(len(b) - 4) % 4)
    b += b"\x00\x00\x00\x00\x00\x00\x00\x00"  # texture.data [], uv_coordinates []
    _cdr_str(b, text)
    _cdr_str(b, b"")  # mesh_resource
    _cdr_str(b, b"")  # mesh_file.filename
    b += bytes(-(len(b) - 4) % 4)
    b += b"\x00\x00\x00\x00\x00"  # mesh_file.data [], mesh_use_embedded_materials False


_QUAT_ID = struct.pack("<4d", 0.0, 0.0, 0.0, 1.0)
_LIFETIME_LOCKED = struct.pack("<iI?", 0, 0, False)
_COLOR_BYTES: dict = {}


def _color_bytes(value: float, vmax: float, alpha: float = 0.9) -> bytes:
    key = (float(value), vmax, alpha)
    c = _COLOR_BYTES.get(key)
    if c is None:
        if len(_COLOR_BYTES) > 65536:
            _COLOR_BYTES.clear()
        v = value_color(value, vmax, alpha)
        c = _COLOR_BYTES[key] = _ST_4F.pack(v.r, v.g, v.b, v.a)
    return c


def _points_bytes(r_km: np.ndarray) -> bytes:
    """(K, 3) km -> K geometry_msgs/Point in metres (the same product as :func:`_point`)."""
    return np.ascontiguousarray(r_km * M_PER_KM, dtype="<f8").tobytes()


_GP_BYTES: dict = {}


def _gp_points_bytes(g: np.ndarray) -> bytes:
    key = g.tobytes()
    pts = _GP_BYTES.get(key)
    if pts is None:
        _GP_BYTES.clear()
        pts = _GP_BYTES[key] = _points_bytes(g)
    return pts


_C_EARTH = _ST_4F.pack(0.15, 0.3, 0.6, 0.6)
_C_WHITE = _ST_4F.pack(1.0, 1.0, 1.0, 1.0)
_C_ISL = _ST_4F.pack(1.0, 0.85, 0.1, 0.9)
_ORIGIN = (0.0, 0.0, 0.0)


def constellation_markers_cdr(sat_names: Sequence[str], r_ecef_km, t_ns: int, *, gp_ecef_km=None,
                              gp_values=None, links: Sequence[tuple[str, str]] = (), value_max: float = 256.0,
                              labels: bool = True, link_ends: np.ndarray | None = None) -> bytes:
    """CDR of :func:`constellation_markers` (same arguments, same checks), without message objects.
    ``link_ends``: the links as :func:`link_ends_indexed` gives them, instead of ``links``."""
    r = np.asarray(r_ecef_km, dtype=float).reshape(-1, 3)
    if len(r) != len(sat_names):
        raise ValueError(f"constellation_markers: {len(sat_names)} names but {len(r)} positions")
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    M = _Marker
    ends = _link_ends(sat_names, links) if link_ends is None else link_ends
    gp = None
    if gp_ecef_km is not None:
        g = np.asarray(gp_ecef_km, dtype=float).reshape(-1, 3)
        vals = np.zeros(len(g)) if gp_values is None else np.asarray(gp_values, dtype=float)
        if len(vals) != len(g):
            raise ValueError(f"constellation_markers: {len(g)} ground points but {len(vals)} values")
        gp = (g, vals)
    n_markers = 3 + (gp is not None) + (len(sat_names) if labels else 0)
    b = bytearray(_CDR_HDR)
    b += _ST_U32.pack(n_markers)
    earth_d = 2 * WGS84_A_KM * M_PER_KM
    _marker_cdr(b, sec, nsec, b"earth", 0, M.SPHERE, _ORIGIN, (earth_d, earth_d, 2 * WGS84_B_KM * M_PER_KM), _C_EARTH)
    _marker_cdr(b, sec, nsec, b"satellites", 0, M.SPHERE_LIST, _ORIGIN, _SAT_SCALE, _C_WHITE,
                points=_points_bytes(r), npoints=len(r))
    _marker_cdr(b, sec, nsec, b"isl", 0, M.LINE_LIST, _ORIGIN, _ISL_SCALE, _C_ISL,
                points=_points_bytes(r[ends]) if len(ends) else b"", npoints=len(ends))
    if gp is not None:
        g, vals = gp
        cols = b"".join([_color_bytes(v, value_max) for v in vals.tolist()])
        _marker_cdr(b, sec, nsec, b"ground_points", 0, M.CUBE_LIST, _ORIGIN, _GP_SCALE, _C_WHITE,
                    points=_gp_points_bytes(g), npoints=len(g), colors=cols, ncolors=len(g))
    if labels:
        lp = (r * M_PER_KM * 1.04).tolist()
        for i, name in enumerate(sat_names):
            _marker_cdr(b, sec, nsec, b"labels", i, M.TEXT_VIEW_FACING, lp[i], _LABEL_SCALE, _C_WHITE,
                        text=name.encode())
    return bytes(b)


def navsat_fixes_cdr(r_ecef_km, t_ns: int) -> list[bytes]:
    """CDR of :func:`navsat_fix` for each row of ``r_ecef_km`` (frame ``earth``)."""
    r = np.asarray(r_ecef_km, dtype=float).reshape(-1, 3)
    sec, nsec = divmod(int(t_ns), 1_000_000_000)
    # one vectorised conversion: numpy's element loops give each row the bits the one-row call gives
    # (tests/unit/test_viz_fast.py compares with navsat_fix row by row)
    lat, lon, alt_km = ecef_to_geodetic(r)
    stamp = _ST_II.pack(sec, nsec)
    head, mid, tail = _FIX_HEAD, _FIX_MID, _FIX_TAIL
    pack = _ST_LLA.pack
    return [b"".join((head, stamp, mid, pack(a, o, h * 1000.0), tail))
            for a, o, h in zip(lat.tolist(), lon.tolist(), alt_km.tolist())]


def viz_cdr(sat_names: Sequence[str], r_ecef_km, t_ns: int, **markers_kw) -> list[tuple[str, str, bytes]]:
    """:func:`viz_messages` as (topic, msgtype, CDR bytes), the bytes TYPESTORE.serialize_cdr gives."""
    r = np.asarray(r_ecef_km, dtype=float).reshape(-1, 3)
    if len(r) != len(sat_names):
        raise ValueError(f"constellation_markers: {len(sat_names)} names but {len(r)} positions")
    out: list[tuple[str, str, bytes]] = [
        (fix_topic(n), NAVSAT_TYPE, c) for n, c in zip(sat_names, navsat_fixes_cdr(r, t_ns))
    ]
    out.append((VIZ_MARKERS, MARKERS_TYPE, constellation_markers_cdr(sat_names, r, t_ns, **markers_kw)))
    return out


def write_viz(bag, sat_names: Sequence[str], r_ecef_km, t_ns: int, **markers_kw) -> int:
    """Write :func:`viz_messages` (as :func:`viz_cdr` bytes) to a BagWriter at log time ``t_ns``,
    stamped with the bag's instant ``bag.epoch_ns + t_ns``; returns how many."""
    msgs = viz_cdr(sat_names, r_ecef_km, getattr(bag, "epoch_ns", 0) + t_ns, **markers_kw)
    for topic, msgtype, cdr in msgs:
        bag.write_raw(topic, msgtype, cdr, t_ns)
    return len(msgs)
