"""bringup.analysis.figures: every figure writes a non-empty PNG and carries the data it was given."""

from __future__ import annotations

import numpy as np
import pytest
from matplotlib.collections import PolyCollection

from bringup.analysis import figures as plots
from bringup.analysis.figures import PlotError
from orbit_clock.contact_plan import Contact, ContactPlan

PNG_MAGIC = b"\x89PNG\r\n\x1a\n"


def _is_png(p):
    data = p.read_bytes()
    return data[:8] == PNG_MAGIC and len(data) > 5000


def _by_gid(fig, prefix):
    return [a for ax in fig.axes for a in ax.findobj() if (a.get_gid() or "").startswith(prefix)]


REGIONS = [dict(name="Dhaka", lat_deg=23.8, lon_deg=90.4, size_km=80.0),
           dict(name="London", lat_deg=51.5, lon_deg=-0.13, size_km=80.0)]


def _tracks():
    t = np.linspace(0, 6000, 300)
    out = {}
    for p in (1, 2):
        for s in (1, 2):
            ph = 2 * np.pi * (t / 5928 + s / 8)
            out[f"sat_{p}{s}"] = (80 * np.sin(ph), (60 * p + np.degrees(ph) - t / 240) % 360 - 180)
    return out


def test_ground_tracks(tmp_path):
    tr = _tracks()
    fig = plots.figure_ground_tracks(tr, REGIONS, [dict(name="svalbard", lat_deg=78.2, lon_deg=15.4)])
    lines = {a.get_gid(): a for a in _by_gid(fig, "track:")}
    assert set(lines) == {f"track:{n}" for n in tr}
    y = lines["track:sat_11"].get_ydata()
    assert np.array_equal(y[np.isfinite(y)], tr["sat_11"][0])      # same points, NaN only at dateline breaks
    assert np.isnan(y).sum() >= 1
    assert len(_by_gid(fig, "region:")) == 2 and len(_by_gid(fig, "station:")) == 1
    p = plots.plot_ground_tracks(tmp_path / "gt.png", tr, REGIONS)
    assert p == tmp_path / "gt.png" and _is_png(p)
    with pytest.raises(PlotError, match="no satellite tracks"):
        plots.figure_ground_tracks({})


def test_value_snapshot_from_osse(tmp_path, paper_scenario):
    from ground_station import osse_from_scenario
    from orbit_clock import ground_points

    gps = ground_points(paper_scenario)
    field = osse_from_scenario(paper_scenario, gps)
    p = plots.plot_osse_snapshot(tmp_path / "osse.png", field, slot=8)
    assert _is_png(p)
    fig = plots.figure_value_snapshot(field.lat_deg, field.lon_deg, field.region_index, field.snapshot(8),
                                      field.region_names)
    colls = [c for c in _by_gid(fig, "snapshot:") if isinstance(c, PolyCollection)]
    assert len(colls) == 5
    london = [c for c in colls if c.get_gid() == "snapshot:London"][0]
    assert np.array_equal(np.asarray(london.get_array()), field.snapshot(8)[field.region_gps("London")])
    with pytest.raises(PlotError, match="slot 99"):
        plots.plot_osse_snapshot(tmp_path / "x.png", field, slot=99)


def test_observation_gantt(tmp_path):
    rng = np.random.default_rng(3)
    obs = [dict(sat=f"sat_{1 + i % 2}{1 + i % 3}", t_ns=int(rng.uniform(0, 6 * 3600) * 1e9),
                region=["Dhaka", "London", "Rio"][i % 3]) for i in range(60)]
    fig = plots.figure_observation_gantt(obs)
    marks = {a.get_gid(): a for a in _by_gid(fig, "gantt:")}
    assert set(marks) == {"gantt:Dhaka", "gantt:London", "gantt:Rio"}
    assert sum(len(m.get_offsets()) for m in marks.values()) == 60
    assert _is_png(plots.plot_observation_gantt(tmp_path / "g.png", obs))
    with pytest.raises(PlotError, match="region 'Rio' is not in region_names"):
        plots.figure_observation_gantt(obs, region_names=["Dhaka", "London"])


def test_contact_timeline_paper_plan(tmp_path, paper_inputs):
    from orbit_clock.contact_plan_io import read_contact_plan

    plan = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000.0)
    fig = plots.figure_contact_timeline(plan)
    bars = _by_gid(fig, "pair:")
    assert len(bars) == len(plan.pairs())
    assert _is_png(plots.plot_contact_timeline(tmp_path / "cp.png", plan))


def test_contact_timeline_title_counts_the_whole_plan(paper_inputs):
    """A plan cut to its busiest rows still says how big it is (the title once counted the drawn rows)."""
    from orbit_clock.contact_plan_io import read_contact_plan

    plan = read_contact_plan(paper_inputs / "contact_plan_3p_8s.csv", rate_bps=1000.0)
    n_pairs = len(plan.pairs())
    windows = sum(len(plots._merge([(c.start_s, c.end_s) for c in plan
                                    if tuple(sorted((c.src, c.dst))) == p])) for p in
                  {tuple(sorted((c.src, c.dst))) for c in plan})
    fig = plots.figure_contact_timeline(plan, max_rows=10)
    assert len(_by_gid(fig, "pair:")) == 10
    title = fig.axes[0].get_title()
    assert f"{n_pairs} node pairs, {windows} windows (10 pairs with the most contact time drawn)" in title


def test_contact_timeline_merges_directions():
    plan = ContactPlan([Contact(0, 600, "sat_11", "sat_12", 1e3, 0.01), Contact(0, 600, "sat_12", "sat_11", 1e3, 0.01),
                        Contact(500, 900, "sat_11", "sat_12", 1e3, 0.01),
                        Contact(3600, 4200, "sat_11", "gs_svalbard", 1e6, 0.005)])
    fig = plots.figure_contact_timeline(plan)
    bars = {a.get_gid(): a for a in _by_gid(fig, "pair:")}
    assert set(bars) == {"pair:sat_11-sat_12", "pair:gs_svalbard-sat_11"}
    assert len(bars["pair:sat_11-sat_12"].get_paths()) == 1           # [0, 900] s merged into one bar
    with pytest.raises(PlotError, match="no contacts"):
        plots.figure_contact_timeline(ContactPlan([]))


def test_value_over_time(tmp_path):
    rng = np.random.default_rng(1)
    series = {m: (rng.uniform(0, 21600, n), rng.integers(1, 256, n)) for m, n in
              (("distributed", 400), ("centralized", 300), ("nonagile", 30))}
    fig = plots.figure_value_over_time(series, horizon_s=21600)
    lines = {a.get_gid(): a for a in _by_gid(fig, "mode:")}
    assert set(lines) == {"mode:distributed", "mode:centralized", "mode:nonagile"}
    y = lines["mode:centralized"].get_ydata()
    assert y[-1] == pytest.approx(series["centralized"][1].sum()) and np.all(np.diff(y) >= 0)
    assert _is_png(plots.plot_value_over_time(tmp_path / "v.png", series, horizon_s=21600))
    with pytest.raises(PlotError, match="'x' has 2 times but 3 values"):
        plots.figure_value_over_time({"x": ([0, 1], [1, 2, 3])})


def test_latency_vs_gaps(tmp_path):
    rng = np.random.default_rng(2)
    lat = {p: list(rng.lognormal(np.log(10 if p <= 6 else 120), 0.6, 40)) for p in range(1, 12)}
    gap = {p: list(rng.lognormal(np.log(300 * p), 0.4, 25)) for p in range(1, 14)}
    fig = plots.figure_latency_vs_gaps(lat, gap, before_fraction_by_priority={p: 0.9 for p in range(1, 12)})
    assert fig._box_counts == {"latency": 11, "gap": 13}
    assert len(_by_gid(fig, "box:latency")) == 11 and len(_by_gid(fig, "box:gap")) == 13
    assert _is_png(plots.plot_latency_vs_gaps(tmp_path / "l.png", lat, gap))
    with pytest.raises(PlotError, match="every priority is empty"):
        plots.figure_latency_vs_gaps({1: []}, {})


def test_plot_inputs_equal_separate_reads(tmp_path):
    """bringup/analysis/run_figures.py plot_inputs reads a run's bag once for all figures: its
    observations and bundle events equal what reading each set of topics alone gives (the reads
    run_plots made before), in the same order - here over several chunks, with log times shared
    across satellites and topics, and topics of other kinds in between."""
    import random

    from bringup.analysis.figure5 import bundle_rows, bundle_rows_from_bag
    from bringup.analysis.run_figures import plot_inputs
    from bringup.recording.bag import BagReader, BagWriter
    from msgs_json import codec
    from msgs_json import schemas as S
    from msgs_json.envelope import Envelope

    ns = 1_000_000_000
    rng = random.Random(5)
    sats = [f"sat_{p}{s}" for p in (1, 2, 3) for s in (1, 2, 3)]
    with BagWriter(tmp_path / "bag", chunk_span_ns=60 * ns) as bag:
        seq = 0
        for k in range(600):
            t = k * 10 * ns
            bag.write_clock(t)
            envs = []
            for sat in rng.sample(sats, 4):
                seq += 1
                dst = rng.choice([x for x in sats if x != sat])
                bid = f"{sat}-{seq}"
                envs.append(Envelope(t, sat, seq, f"/{sat}/observations", codec.encode(S.Observation(
                    sat=sat, gp=rng.randrange(50), t_ns=t, assumed_value=1.5, recorded_value=2.0))))
                envs.append(Envelope(t, sat, seq, f"/{sat}/dtn/events", codec.encode(S.BundleCreated(
                    sat=sat, t_ns=t, bundle_id=bid, src=sat, dst=dst, priority=1 + seq % 3, creation_ns=t,
                    gp=rng.randrange(50), obs_t_ns=t, lifetime_ns=900 * ns, size_bits=2000))))
                if rng.random() < 0.7:
                    envs.append(Envelope(t, dst, seq, f"/{dst}/dtn/events", codec.encode(S.BundleDelivered(
                        sat=dst, t_ns=t, bundle_id=bid, src=sat, dst=dst, priority=1 + seq % 3, creation_ns=t,
                        hop_count=1))))
                envs.append(Envelope(t, "router", seq, "/dtn/medium", bytes(rng.randrange(256) for _ in range(300))))
            rng.shuffle(envs)
            bag.write_envelopes(envs)
    with BagReader(tmp_path / "bag") as r:
        topics = [t.topic for t in r.topics()]
        alone_obs = [codec.decode(e.topic, e.data) for e in r.envelopes([t for t in topics if t.endswith("/observations")])]
        alone_events = [codec.decode(e.topic, e.data) for e in r.envelopes([t for t in topics if t.endswith("/dtn/events")])]
    obs, events = plot_inputs(tmp_path / "bag", bundle_events=True)
    assert len(obs) == 2400 and obs == alone_obs
    assert len(events) > 4000 and events == alone_events
    assert bundle_rows(events) == bundle_rows_from_bag(tmp_path / "bag")
    assert plot_inputs(tmp_path / "bag", bundle_events=False) == (alone_obs, [])


def test_vector_formats_beside_the_png(tmp_path):
    """--plot-formats svg,pdf: each figure also as SVG (well-formed XML, an <svg> root) and PDF."""
    import xml.etree.ElementTree as ET

    plan = ContactPlan([Contact(0, 600, "sat_11", "sat_12", 1e3, 0.01)])
    with plots.also_as(("png", "svg", "pdf")):
        png = plots.plot_contact_timeline(tmp_path / "cp.png", plan)
    assert _is_png(png)
    assert ET.parse(tmp_path / "cp.svg").getroot().tag.endswith("svg")
    assert (tmp_path / "cp.pdf").read_bytes().startswith(b"%PDF-")
    plots.plot_contact_timeline(tmp_path / "again.png", plan)  # outside the block: PNG only
    assert not (tmp_path / "again.svg").exists()
    with pytest.raises(PlotError, match="gif"), plots.also_as(("gif",)):
        pass


def test_coastlines_put_cities_on_land(tmp_path):
    """GSHHS crude shorelines (bringup/analysis/coastlines.py): the study's cities on land, open ocean not;
    the ground-track map draws them."""
    from matplotlib.path import Path as MplPath

    from bringup.analysis.coastlines import land_polygons

    polys = [MplPath(xy) for xy in land_polygons()]
    assert len(polys) > 100

    def on_land(lon, lat):
        return any(p.contains_point((lon, lat)) for p in polys)

    cities = {"Dhaka": (90.41, 23.81), "Sydney": (150.9, -33.8), "Dallas": (-96.8, 32.78), "London": (-0.13, 51.51),
              "Rio": (-43.3, -22.85)}
    assert all(on_land(*c) for c in cities.values()), [n for n, c in cities.items() if not on_land(*c)]
    ocean = [(-40.0, 30.0), (-150.0, 0.0), (80.0, -30.0), (160.0, 30.0), (-30.0, -40.0)]
    assert not any(on_land(*o) for o in ocean)
    fig = plots.figure_ground_tracks({"sat_11": ([0.0, 10.0], [0.0, 10.0])})
    assert len(_by_gid(fig, "coastline")) == len(land_polygons())
