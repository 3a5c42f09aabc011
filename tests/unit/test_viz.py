"""Visualisation builders: fixes and markers against their inputs; the messages decode."""

from __future__ import annotations

import numpy as np
import pytest

from bringup.recording.bag import TYPESTORE, BagReader, BagWriter
from bringup.recording.viz_messages import (
    FRAME,
    M_PER_KM,
    MARKERS_TYPE,
    NAVSAT_TYPE,
    constellation_markers,
    navsat_fix,
    value_color,
    viz_messages,
    write_viz,
)
from orbit_clock.frames import geodetic_to_ecef_km


def test_navsat_fix_fields():
    r = geodetic_to_ecef_km(23.81, 90.41, 710.0)  # over Dhaka
    fix = navsat_fix(r, 1_500_000_000)
    assert fix.latitude == pytest.approx(23.81) and fix.longitude == pytest.approx(90.41)
    assert fix.altitude == pytest.approx(710_000.0, abs=1e-3)
    assert (fix.header.stamp.sec, fix.header.stamp.nanosec, fix.header.frame_id) == (1, 500_000_000, FRAME)
    back = TYPESTORE.deserialize_cdr(TYPESTORE.serialize_cdr(fix, NAVSAT_TYPE), NAVSAT_TYPE)
    assert back.latitude == fix.latitude


def test_markers_geometry():
    names = ["sat_11", "sat_12", "sat_21"]
    r = np.array([[7088.0, 0, 0], [0, 7088.0, 0], [0, 0, 7088.0]])
    gp = geodetic_to_ecef_km(np.array([0.0, 10.0]), np.array([0.0, 0.0]), np.array([0.0, 0.0]))
    ma = constellation_markers(names, r, 3, gp_ecef_km=gp, gp_values=[0, 256],
                               links=[("sat_12", "sat_11"), ("sat_11", "sat_12"), ("sat_21", "sat_12")])
    by_ns = {}
    for m in ma.markers:
        by_ns.setdefault(m.ns, []).append(m)
        assert m.header.frame_id == FRAME
    sats = by_ns["satellites"][0]
    assert [(p.x, p.y, p.z) for p in sats.points] == [tuple(v * M_PER_KM) for v in r]
    isl = by_ns["isl"][0]
    assert len(isl.points) == 4  # two distinct links, each drawn once
    ends = {((a.x, a.y, a.z), (b.x, b.y, b.z)) for a, b in zip(isl.points[::2], isl.points[1::2])}
    assert ((7.088e6, 0, 0), (0, 7.088e6, 0)) in ends and ((0, 7.088e6, 0), (0, 0, 7.088e6)) in ends
    g = by_ns["ground_points"][0]
    assert len(g.points) == len(g.colors) == 2
    assert g.colors[0].r == g.colors[0].g == g.colors[0].b  # grey: nothing left to see
    assert g.colors[1].r == 1.0 and g.colors[1].b == 0.0  # max value: red
    assert [m.text for m in by_ns["labels"]] == names
    with pytest.raises(ValueError, match="unknown satellite"):
        constellation_markers(names, r, 0, links=[("sat_11", "sat_99")])
    with pytest.raises(ValueError, match="3 names but 2 positions"):
        constellation_markers(names, r[:2], 0)


def test_value_ramp_is_monotone():
    reds = [value_color(v).r for v in range(1, 257, 5)]
    blues = [value_color(v).b for v in range(1, 257, 5)]
    assert reds == sorted(reds) and blues == sorted(blues, reverse=True)


def test_viz_written_to_bag_decodes_with_mcap(tmp_path):
    from mcap.reader import make_reader
    from mcap_ros2.decoder import DecoderFactory

    names = ["sat_11", "sat_12"]
    r = np.array([[7088.0, 0, 0], [0, 7088.0, 0]])
    with BagWriter(tmp_path / "bag") as bag:
        for k in range(3):
            assert write_viz(bag, names, r, k * 10**9, links=[("sat_11", "sat_12")]) == 3
    topics = {t.topic: (t.msgtype, t.count) for t in BagReader(tmp_path / "bag").topics()}
    assert topics == {"/sat_11/fix": (NAVSAT_TYPE, 3), "/sat_12/fix": (NAVSAT_TYPE, 3),
                      "/viz/constellation": (MARKERS_TYPE, 3)}
    with open(next((tmp_path / "bag").glob("*.mcap")), "rb") as f:
        decoded = [(ch.topic, m) for _, ch, _, m in
                   make_reader(f, decoder_factories=[DecoderFactory()]).iter_decoded_messages()]
    fixes = [m for t, m in decoded if t == "/sat_12/fix"]
    assert len(fixes) == 3 and fixes[0].longitude == pytest.approx(90.0)
    ma = next(m for t, m in decoded if t == "/viz/constellation")
    assert {m.ns for m in ma.markers} == {"earth", "satellites", "isl", "labels"}


def test_viz_messages_topics():
    msgs = viz_messages(["sat_11"], [[7000.0, 0, 0]], 0)
    assert [(t, m) for t, m, _ in msgs] == [("/sat_11/fix", NAVSAT_TYPE), ("/viz/constellation", MARKERS_TYPE)]


def test_metres_at_earth_scale_fit_foxglove_float32():
    """Foxglove's 3D panel (three.js/WebGL) holds vertex positions as float32 and has a depth buffer
    (24 bits assumed) between the camera's near and far planes. Markers in metres: the float32
    spacing at the satellites' radius is 0.5 m (GEO: 4 m), nothing a view of the constellation can
    show; the shipped layout's camera sees the whole Earth and the orbits (near < distance - orbit
    radius, far > distance + orbit radius) with a depth step smaller than half a ground-point cube."""
    import json
    from pathlib import Path

    from bringup.recording.viz_messages import _GP_SCALE

    leo = np.array([[7088.0, 123.456789, -4321.0], [-1.0, 7088.0, 0.001]]) * M_PER_KM
    assert np.abs(leo.astype(np.float32).astype(np.float64) - leo).max() <= 0.5
    geo = np.array([[42164.0, 1.0, 2.0]]) * M_PER_KM
    assert np.abs(geo.astype(np.float32).astype(np.float64) - geo).max() <= 4.0
    layout = json.loads((Path(__file__).resolve().parents[2] / "bringup" / "recording"
                         / "foxglove_layout.json").read_text())
    cam = layout["configById"]["3D!constellation"]["cameraState"]
    orbit_m = 7088e3 * 1.1
    assert cam["near"] < cam["distance"] - orbit_m and cam["far"] > cam["distance"] + orbit_m
    # perspective depth step at distance z: z^2 / (near * 2^24)
    far_side = cam["distance"] + 6378e3
    assert far_side**2 / (cam["near"] * 2**24) < _GP_SCALE[0] / 2
