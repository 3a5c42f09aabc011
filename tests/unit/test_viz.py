"""Visualisation builders: fixes and markers against their inputs; the messages decode."""

from __future__ import annotations

import numpy as np
import pytest

from bringup.recording.bag import TYPESTORE, BagReader, BagWriter
from bringup.recording.viz_messages import (
    FRAME,
    MARKERS_TYPE,
    NAVSAT_TYPE,
    SCALE_KM,
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
    assert [(p.x, p.y, p.z) for p in sats.points] == [tuple(v / SCALE_KM) for v in r]
    isl = by_ns["isl"][0]
    assert len(isl.points) == 4  # two distinct links, each drawn once
    ends = {((a.x, a.y, a.z), (b.x, b.y, b.z)) for a, b in zip(isl.points[::2], isl.points[1::2])}
    assert ((7.088, 0, 0), (0, 7.088, 0)) in ends and ((0, 7.088, 0), (0, 0, 7.088)) in ends
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
