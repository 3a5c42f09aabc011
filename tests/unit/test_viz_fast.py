"""The direct CDR writer of bringup/recording/viz_messages.py (write_viz's path) against rosbags' own serializer.

Oracle: ``TYPESTORE.serialize_cdr`` of the message objects the plain builders make
(``viz_messages``, ``navsat_fix``) is the reference; every frame's bytes must equal it exactly
(empty and odd-length link lists, with and without the ground-point marker and labels, stamps
with and without nanoseconds), and a bag written by ``write_viz`` reads back as those bytes.
"""

from __future__ import annotations

import numpy as np
import pytest

from bringup.recording.bag import TYPESTORE, BagReader, BagWriter
from bringup.recording.viz_messages import (
    MARKERS_TYPE,
    NAVSAT_TYPE,
    constellation_markers_cdr,
    navsat_fix,
    navsat_fixes_cdr,
    viz_cdr,
    viz_messages,
    write_viz,
)

NAMES = ["sat_11", "sat_12", "sat_21", "sat_22", "sat_31"]


def _frames():
    rng = np.random.default_rng(11)
    gp = rng.normal(size=(9, 3)) * 6400.0
    link_sets = [[], [("sat_12", "sat_11")], [("sat_12", "sat_11"), ("sat_11", "sat_12"), ("sat_31", "sat_22")]]
    for k in range(12):
        u = rng.normal(size=(len(NAMES), 3))
        r = u / np.linalg.norm(u, axis=1)[:, None] * rng.uniform(6600.0, 8400.0, (len(NAMES), 1))
        kw = {"links": link_sets[k % 3]}
        if k % 2:
            vals = rng.integers(0, 257, len(gp)).astype(float)
            vals[0] = 0.0  # grey
            kw.update(gp_ecef_km=gp, gp_values=vals)
        if k % 4 == 3:
            kw["labels"] = False
        t_ns = int(rng.integers(0, 10**13)) if k % 5 else k * 10**9
        yield r, t_ns, kw


def test_fast_bytes_equal_rosbags_serialization():
    n = 0
    for r, t_ns, kw in _frames():
        plain = [(t, ty, TYPESTORE.serialize_cdr(m, ty)) for t, ty, m in viz_messages(NAMES, r, t_ns, **kw)]
        fast = viz_cdr(NAMES, r, t_ns, **kw)
        assert [(t, ty) for t, ty, _ in fast] == [(t, ty) for t, ty, _ in plain]
        for (_, ty, a), (_, _, b) in zip(plain, fast):
            assert b == a, ty
            n += 1
        # and the bytes decode to the message the plain builder made
        ma = TYPESTORE.deserialize_cdr(fast[-1][2], MARKERS_TYPE)
        assert len(ma.markers) == 3 + ("gp_ecef_km" in kw) + (len(NAMES) if kw.get("labels", True) else 0)
    assert n == 12 * (len(NAMES) + 1)


def test_fixes_vectorised_equal_one_by_one():
    # the fast path converts all satellites in one numpy call; each row must give navsat_fix's bits
    rng = np.random.default_rng(5)
    u = rng.normal(size=(40, 3))
    r = u / np.linalg.norm(u, axis=1)[:, None] * rng.uniform(6400.0, 8400.0, (40, 1))
    r[0] = [0.0, 0.0, 7000.0]  # over the pole
    fast = navsat_fixes_cdr(r, 123_456_789_012)
    assert fast == [TYPESTORE.serialize_cdr(navsat_fix(v, 123_456_789_012), NAVSAT_TYPE) for v in r]


def test_fast_path_checks_its_input():
    r = np.full((len(NAMES), 3), 7000.0)
    with pytest.raises(ValueError, match="unknown satellite"):
        viz_cdr(NAMES, r, 0, links=[("sat_11", "sat_99")])
    with pytest.raises(ValueError, match="5 names but 2 positions"):
        viz_cdr(NAMES, r[:2], 0)
    with pytest.raises(ValueError, match="3 ground points but 2 values"):
        constellation_markers_cdr(NAMES, r, 0, gp_ecef_km=np.ones((3, 3)), gp_values=[1, 2])


def test_write_viz_bag_holds_plain_bytes(tmp_path):
    frames = list(_frames())[:4]
    with BagWriter(tmp_path / "bag") as bag:
        for r, t_ns, kw in frames:
            assert write_viz(bag, NAMES, r, t_ns, **kw) == len(NAMES) + 1
    want = sorted((t_ns, t, TYPESTORE.serialize_cdr(m, ty))
                  for r, t_ns, kw in frames for t, ty, m in viz_messages(NAMES, r, t_ns, **kw))
    got = sorted((m.log_time_ns, m.topic, bytes(m.cdr)) for m in BagReader(tmp_path / "bag").messages())
    assert got == want


def test_link_ends_on_indices_equal_the_name_pairs():
    """viz_messages.link_ends_indexed (the feed's path) against _link_ends (the name pairs, the path it
    replaces) on drawn link lists: both directions, repeats, names whose string order is not their
    index order; and the marker bytes made from either are the same."""
    from bringup.recording.viz_messages import _link_ends, link_ends_indexed, name_ranks

    rng = np.random.default_rng(5)
    names = ["sat_n900", "sat_12", "sat_0002_0001", "sat_11", "sat_n25", "sat_0001_0040", "sat_31"]
    rank, by_rank = name_ranks(names)
    for k in range(200):
        m = int(rng.integers(0, 40))
        a = rng.integers(0, len(names), m)
        b = (a + rng.integers(1, len(names), m)) % len(names)
        want = _link_ends(names, [(names[i], names[j]) for i, j in zip(a.tolist(), b.tolist())])
        got = link_ends_indexed(rank, by_rank, a, b)
        assert got.tolist() == want
        if k < 20:
            r = rng.normal(size=(len(names), 3)) * 7000.0
            pairs = [(names[i], names[j]) for i, j in zip(a.tolist(), b.tolist())]
            assert constellation_markers_cdr(names, r, 5 * 10**9 + k, link_ends=got) == \
                constellation_markers_cdr(names, r, 5 * 10**9 + k, links=pairs)


def test_viz_feed_frames_from_indices_equal_those_from_name_pairs(paper_scenario):
    """A world's VizFeed (link_ends on arrays) writes the bytes it writes from the name pairs."""
    from bringup.recording.viz_feed import VizFeed
    from bringup.scenario.world import World

    world = World.build(paper_scenario.with_overrides(sats=48, planes=4, hours=0.2))
    fast, pairs = VizFeed(world, period_s=60.0), VizFeed(world, period_s=60.0)
    assert fast._ab is not None
    pairs._ab = None
    links = 0
    for t in range(0, 720, 60):
        a, b = fast.frame(t * 10**9, t * 10**9), pairs.frame(t * 10**9, t * 10**9)
        assert a == b and a
        links += len(fast.links_at(float(t)))
    assert links > 100
