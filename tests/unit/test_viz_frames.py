"""The run's TF tree (bringup/recording/viz_frames.py) against its definition.

Oracles: scipy's Rotation (an independent matrix -> quaternion conversion and rotation), the frame
definitions written out as vectors (nadir = -r/|r|, orbit normal r x v, east/north/up from the
geodetic formulas of orbit_clock.frames), and rosbags reading the TFMessage bytes back; a paper
world's first visualisation frame holds /tf for every satellite and /tf_static for every station.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from bringup.recording.bag import TYPESTORE
from bringup.recording.viz_frames import (
    TF_TYPE,
    enu_quaternion,
    orbit_frame_quaternions,
    rotation_to_quaternion,
    satellite_tf,
    station_tf,
    tf_cdr,
)
from orbit_clock.frames import geodetic_to_ecef_km, up_unit


def _canon(q):
    q = np.asarray(q, dtype=float)
    return np.where(q[..., 3:4] < 0, -q, q)


def test_rotation_to_quaternion_equals_scipy():
    rs = Rotation.random(5000, random_state=7)
    q = rotation_to_quaternion(rs.as_matrix())
    assert np.abs(q - _canon(rs.as_quat())).max() < 1e-12
    assert (q[:, 3] >= 0).all()
    # each of Shepperd's four branches, including the half turns where w = 0
    for ax in np.eye(3):
        for ang in (0.0, 1e-9, np.pi / 2, np.pi - 1e-9, np.pi):
            r = Rotation.from_rotvec(ax * ang)
            got = Rotation.from_quat(rotation_to_quaternion(r.as_matrix()))
            assert np.abs(got.as_matrix() - r.as_matrix()).max() < 1e-12


def test_orbit_frame_axes():
    rng = np.random.default_rng(3)
    r = rng.normal(size=(300, 3))
    r *= (6378.0 + rng.uniform(300, 36000, size=(300, 1))) / np.linalg.norm(r, axis=1, keepdims=True)
    v = rng.normal(size=(300, 3)) * 7.5
    q = orbit_frame_quaternions(r, v)
    rot = Rotation.from_quat(q)
    nadir = -r / np.linalg.norm(r, axis=1, keepdims=True)
    h = np.cross(r, v)
    y = -h / np.linalg.norm(h, axis=1, keepdims=True)
    assert np.abs(rot.apply([0.0, 0.0, 1.0]) - nadir).max() < 1e-12
    assert np.abs(rot.apply([0.0, 1.0, 0.0]) - y).max() < 1e-12
    x = rot.apply([1.0, 0.0, 0.0])
    assert np.abs(x - np.cross(y, nadir)).max() < 1e-12
    # for a circular orbit +x is the velocity
    rc = np.array([[7000.0, 0.0, 0.0]])
    assert np.allclose(Rotation.from_quat(orbit_frame_quaternions(rc, [[0.0, 7.5, 0.0]])).apply([1.0, 0, 0]),
                       [0.0, 1.0, 0.0], atol=1e-15)
    with pytest.raises(ValueError, match="no orbit plane"):
        orbit_frame_quaternions(rc, rc)


@pytest.mark.parametrize("lat,lon", [(78.2298, 15.4078), (-72.0117, 2.535), (0.0, 0.0), (89.9999, -170.0),
                                     (-90.0, 0.0), (45.0, 180.0)])
def test_enu_axes(lat, lon):
    rot = Rotation.from_quat(enu_quaternion(lat, lon))
    up = np.asarray(up_unit(lat, lon), dtype=float).reshape(3)
    assert np.abs(rot.apply([0.0, 0.0, 1.0]) - up).max() < 1e-12
    # east is horizontal and points along increasing longitude
    lo = np.radians(lon)
    assert np.abs(rot.apply([1.0, 0.0, 0.0]) - [-np.sin(lo), np.cos(lo), 0.0]).max() < 1e-12
    north = rot.apply([0.0, 1.0, 0.0])
    assert abs(north @ up) < 1e-12 and (lat == -90.0 or north[2] >= 0)


def test_messages_round_trip_through_rosbags():
    names = ["sat_11", "sat_12"]
    r = np.array([[7088.0, 0.0, 0.0], [0.0, -7088.0, 10.0]])
    v = np.array([[0.0, 7.5, 0.1], [7.5, 0.0, 0.3]])
    msg = TYPESTORE.deserialize_cdr(tf_cdr(satellite_tf(names, r, v, 946727968_250_000_000)), TF_TYPE)
    assert [t.child_frame_id for t in msg.transforms] == names
    assert {t.header.frame_id for t in msg.transforms} == {"earth"}
    assert (msg.transforms[0].header.stamp.sec, msg.transforms[0].header.stamp.nanosec) == (946727968, 250_000_000)
    tr = msg.transforms[1].transform
    assert (tr.translation.x, tr.translation.y, tr.translation.z) == (0.0, -7088e3, 10e3)
    q = orbit_frame_quaternions(r, v)[1]
    assert (tr.rotation.x, tr.rotation.y, tr.rotation.z, tr.rotation.w) == tuple(q)

    class St:
        name, lat_deg, lon_deg, alt_m = "svalbard", 78.2298, 15.4078, 500.0

    st = TYPESTORE.deserialize_cdr(tf_cdr(station_tf([St], 0)), TF_TYPE).transforms[0]
    assert st.child_frame_id == "gs_svalbard"
    p = np.asarray(geodetic_to_ecef_km(78.2298, 15.4078, 0.5), dtype=float).reshape(3) * 1000.0
    assert np.allclose([st.transform.translation.x, st.transform.translation.y, st.transform.translation.z], p,
                       rtol=0, atol=1e-6)


def test_viz_feed_first_frame_has_static_stations(paper_scenario):
    from bringup.recording.viz_feed import VizFeed
    from bringup.scenario.world import World

    world = World.build(paper_scenario.with_overrides(sats=6, hours=0.1))
    feed = VizFeed(world)
    first = feed.frame(0, world.scenario.epoch_ns)
    topics = [t for t, _, _ in first]
    assert topics.count("/tf") == 1 and topics.count("/tf_static") == 1
    static = TYPESTORE.deserialize_cdr({t: c for t, _, c in first}["/tf_static"], TF_TYPE)
    assert [t.child_frame_id for t in static.transforms] == world.station_nodes
    tf = TYPESTORE.deserialize_cdr({t: c for t, _, c in first}["/tf"], TF_TYPE)
    assert [t.child_frame_id for t in tf.transforms] == world.sat_names
    assert feed.frame(10 * 10**9, 0) == []  # not due before the period
    later = [t for t, _, _ in feed.frame(60 * 10**9, 0)]
    assert "/tf" in later and "/tf_static" not in later
