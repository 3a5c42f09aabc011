"""A run on a globe: a CZML document (Cesium's time-dynamic scene format) from a run's bag alone.

CZML (Cesium Language, https://github.com/AnalyticalGraphicsInc/czml-writer/wiki/CZML-Guide) is a JSON
array of packets; the first is the document with the scene clock, each other one an entity. The
packets are made with czml3 (pydantic models of the CZML packets) from what the bag recorded, on the
scenario's UTC clock (the bag's log times are UTC, bringup/recording/bag.py):

* the document's clock spans the bag, from its first to its last message (epoch + t);
* a satellite per ``/<sat>/fix`` topic (sensor_msgs/NavSatFix: WGS-84 latitude, longitude, altitude
  of the sub-satellite point at every visualisation frame), its position sampled in
  cartographic degrees and interpolated (Lagrange, degree 5), with a point, a label and its orbit's
  trail;
* a ground station per ``/tf_static`` transform ``earth`` -> ``gs_*`` (ECEF metres);
* a look per executed observation (``/<sat>/observations``): the instrument footprint (an ellipse
  of the footprint's diameter on the ground point) coloured by the recorded value with the bag's own
  colour ramp (bringup/recording/viz_messages.py ``value_color``: blue low, red high), shown from
  the look for one OSSE slot (``--look-s``, 900 s); the ground point's position is the bag's
  ground-point marker (``/viz/constellation``, namespace ``ground_points``: every GP in index order);
* a link per pair of nodes while in contact (``/orbit/contacts`` windows, ISL yellow, ground cyan),
  drawn between the two entities' positions, shown over the union of the pair's windows;
* a bundle transfer per sender and next hop (``/<sat>/dtn/events`` "forwarded"), a red line shown
  for ``--transfer-s`` (2 s) from each hand-over.

Entity ids: ``sat/<name>``, ``gs/<name>``, ``look/<sat>/<gp>/<t_ns>``, ``link/<a>/<b>``,
``xfer/<from>/<to>``. :func:`czml_counts` gives how many of each a bag yields, so a viewer's entity
count can be checked against the bag.

How we know it is right: tests/unit/test_czml.py (a local run's bag: the document parses as JSON,
every entity of each kind is there with the bag's counts, the clock spans the bag's UTC times, a
satellite's sampled positions equal its NavSatFix fixes, a look sits on its ground point);
tests/browser/test_globe.py (marker ``browser``: CesiumJS itself, in headless Chromium, loads the
document and reports the same entity count and clock span).
"""

from __future__ import annotations

import datetime as dt
from collections import defaultdict
from pathlib import Path

import numpy as np
from czml3 import Document, Packet
from czml3.enums import InterpolationAlgorithms
from czml3.properties import (
    Clock,
    Color,
    Ellipse,
    Label,
    Material,
    Point,
    Polyline,
    PolylineMaterial,
    Position,
    PositionList,
    SolidColorMaterial,
)
from czml3.properties import (
    Path as CzPath,
)
from czml3.types import TimeInterval, TimeIntervalCollection

from bringup.errors import UserError
from bringup.recording.bag import BagReader
from bringup.recording.viz_messages import value_color
from msgs_json import codec
from msgs_json.topics import CONTACTS, TF_STATIC, VIZ_MARKERS
from orbit_clock.frames import ecef_to_geodetic

__all__ = ["CzmlInputs", "czml_counts", "czml_document", "read_czml_inputs"]

_NS = 1_000_000_000
_FIX = "sensor_msgs/msg/NavSatFix"


class CzmlInputs:
    """What the document is made of, read from a bag (module docstring)."""

    def __init__(self) -> None:
        self.epoch_ns = 0
        self.start_ns = 0
        self.end_ns = 0
        self.fixes: dict[str, list[tuple[int, float, float, float]]] = defaultdict(list)  # t_ns, lon, lat, alt_m
        self.stations: dict[str, tuple[float, float, float]] = {}  # name -> ECEF [m]
        self.gp_ecef_m: np.ndarray | None = None
        self.looks: list[tuple[str, int, int, float]] = []  # sat, gp, t_ns, recorded value
        self.windows: dict[tuple[str, str], list[tuple[int, int, str]]] = defaultdict(list)  # (a, b) -> start, end, kind
        self.forwards: dict[tuple[str, str], list[int]] = defaultdict(list)  # (from, to) -> t_ns


def read_czml_inputs(bag_path: str | Path) -> CzmlInputs:
    """One pass over the topics the document needs; a bag without them is one line naming what lacks."""
    inp = CzmlInputs()
    with BagReader(bag_path) as bag:
        inp.epoch_ns = bag.epoch_ns
        inp.start_ns, inp.end_ns = bag.start_ns, bag.end_ns
        names = [t.topic for t in bag.topics()]
        fix_topics = [t for t in names if t.endswith("/fix")]
        wanted = {*fix_topics, TF_STATIC, VIZ_MARKERS}
        for topic, t_ns, msg in bag.typed(sorted(wanted & set(names))):
            if topic.endswith("/fix"):
                inp.fixes[topic.rsplit("/", 2)[-2]].append((t_ns, float(msg.longitude), float(msg.latitude),
                                                            float(msg.altitude)))
            elif topic == TF_STATIC:
                for tf in msg.transforms:
                    if tf.child_frame_id.startswith("gs_"):
                        tr = tf.transform.translation
                        inp.stations[tf.child_frame_id] = (float(tr.x), float(tr.y), float(tr.z))
            elif inp.gp_ecef_m is None:
                for m in msg.markers:
                    if m.ns == "ground_points":
                        inp.gp_ecef_m = np.array([(p.x, p.y, p.z) for p in m.points], dtype=np.float64)
        if not inp.fixes:
            raise UserError(f"bag {bag.path}: no /<sat>/fix topics (a bag of a run records them): no satellites "
                            "to draw")
        env_topics = [t for t in names if t.endswith(("/observations", "/dtn/events")) or t == CONTACTS]
        for env in bag.envelopes(env_topics):
            msg = codec.decode(env.topic, env.data)
            if env.topic.endswith("/observations"):
                inp.looks.append((msg.sat, int(msg.gp), int(msg.t_ns), float(msg.recorded_value)))
            elif env.topic == CONTACTS:
                if msg.event == "open":
                    a, b = sorted((msg.src, msg.dst))
                    inp.windows[(a, b)].append((int(msg.start_ns), int(msg.end_ns), msg.kind))
            elif type(msg).__name__ == "BundleForwarded":
                inp.forwards[(msg.sat, msg.next_hop)].append(int(msg.t_ns))
    if inp.looks and inp.gp_ecef_m is None:
        raise UserError(f"bag {bag_path}: observations but no ground-point marker on {VIZ_MARKERS}: cannot place "
                        "the looks")
    return inp


def _utc(inp: CzmlInputs, t_ns: int) -> dt.datetime:
    return dt.datetime.fromtimestamp(0, dt.UTC) + dt.timedelta(microseconds=(inp.epoch_ns + t_ns) // 1000)


def _merge(intervals: list[tuple[int, int]]) -> list[tuple[int, int]]:
    out: list[list[int]] = []
    for a, b in sorted(intervals):
        if out and a <= out[-1][1]:
            out[-1][1] = max(out[-1][1], b)
        else:
            out.append([a, b])
    return [(a, b) for a, b in out]


def _availability(inp: CzmlInputs, intervals: list[tuple[int, int]]) -> TimeIntervalCollection:
    return TimeIntervalCollection(values=[TimeInterval(start=_utc(inp, a), end=_utc(inp, b))
                                          for a, b in _merge(intervals)])


def _rgba(c) -> Color:
    """A std_msgs/ColorRGBA (0..1 floats) as CZML's 0..255 rgba."""
    return Color(rgba=[round(255 * float(x)) for x in (c.r, c.g, c.b, c.a)])


def _node_ref(node: str) -> str:
    return f"gs/{node}" if node.startswith("gs_") else f"sat/{node}"


def czml_counts(inp: CzmlInputs) -> dict[str, int]:
    """How many entities of each kind the document holds (module docstring)."""
    known = set(inp.fixes) | set(inp.stations)
    return {"satellites": len(inp.fixes), "stations": len(inp.stations), "looks": len(inp.looks),
            "links": sum(1 for (a, b) in inp.windows if a in known and b in known),
            "transfers": sum(1 for (a, b) in inp.forwards if a in known and b in known)}


def czml_document(inp: CzmlInputs, *, footprint_km: float = 8.0, look_s: float = 900.0,
                  transfer_s: float = 2.0, name: str = "run") -> Document:
    """The CZML document (module docstring)."""
    if not (footprint_km > 0 and look_s > 0 and transfer_s > 0):
        raise UserError("czml: --footprint-km, --look-s and --transfer-s must be > 0")
    start, end = _utc(inp, inp.start_ns), _utc(inp, max(inp.end_ns, inp.start_ns + _NS))
    packets = [Packet(id="document", name=name, version="1.0",
                      clock=Clock(interval=TimeInterval(start=start, end=end), currentTime=start, multiplier=60))]
    t0 = inp.start_ns
    for sat, rows in sorted(inp.fixes.items()):
        rows.sort()
        samples: list[float] = []
        for t_ns, lon, lat, alt in rows:
            samples += [(t_ns - t0) / _NS, lon, lat, alt]
        packets.append(Packet(
            id=f"sat/{sat}", name=sat,
            availability=TimeInterval(start=_utc(inp, rows[0][0]), end=end),
            position=Position(epoch=start, cartographicDegrees=samples,
                              interpolationAlgorithm=InterpolationAlgorithms.LAGRANGE, interpolationDegree=5),
            point=Point(pixelSize=7, color=Color(rgba=[255, 255, 255, 255])),
            label=Label(text=sat, scale=0.5, pixelOffset={"cartesian2": [0, -14]}),
            path=CzPath(width=1, leadTime=0, trailTime=5400, resolution=60,
                        material=PolylineMaterial(solidColor=SolidColorMaterial(color=Color(rgba=[120, 180, 255, 160])))),
        ))
    for gs, xyz in sorted(inp.stations.items()):
        packets.append(Packet(id=f"gs/{gs}", name=gs, position=Position(cartesian=list(xyz)),
                              point=Point(pixelSize=9, color=Color(rgba=[0, 220, 220, 255])),
                              label=Label(text=gs.removeprefix("gs_"), scale=0.5, pixelOffset={"cartesian2": [0, 14]})))
    look_ns = round(look_s * _NS)
    for sat, gp, t_ns, value in inp.looks:
        if not 0 <= gp < len(inp.gp_ecef_m):
            raise UserError(f"czml: an observation of GP {gp} by {sat} at {t_ns} ns: no such ground point in the "
                            f"bag's marker ({len(inp.gp_ecef_m)} GPs)")
        lat, lon, _ = ecef_to_geodetic(inp.gp_ecef_m[gp] / 1000.0)
        color = _rgba(value_color(value))
        packets.append(Packet(
            id=f"look/{sat}/{gp}/{t_ns}", name=f"{sat} looks at GP {gp}",
            description=f"{sat} at t = {t_ns / _NS:.1f} s: recorded value {value:g}",
            availability=TimeInterval(start=_utc(inp, t_ns), end=_utc(inp, t_ns + look_ns)),
            position=Position(cartographicDegrees=[float(lon), float(lat), 0.0]),
            ellipse=Ellipse(semiMajorAxis=footprint_km * 500.0, semiMinorAxis=footprint_km * 500.0,
                            material=Material(solidColor=SolidColorMaterial(color=color))),
        ))
    known = set(inp.fixes) | set(inp.stations)
    for (a, b), wins in sorted(inp.windows.items()):
        if a not in known or b not in known:
            continue
        ground = any(k == "ground" for _, _, k in wins)
        packets.append(Packet(
            id=f"link/{a}/{b}", name=f"{a} - {b}",
            availability=_availability(inp, [(s, e) for s, e, _ in wins]),
            polyline=Polyline(positions=PositionList(references=[f"{_node_ref(a)}#position", f"{_node_ref(b)}#position"]),
                              width=1.5, arcType="NONE",
                              material=PolylineMaterial(solidColor=SolidColorMaterial(
                                  color=Color(rgba=[0, 220, 220, 200] if ground else [255, 215, 30, 200])))),
        ))
    xfer_ns = round(transfer_s * _NS)
    for (a, b), times in sorted(inp.forwards.items()):
        if a not in known or b not in known:
            continue
        packets.append(Packet(
            id=f"xfer/{a}/{b}", name=f"bundles {a} -> {b}",
            availability=_availability(inp, [(t, t + xfer_ns) for t in times]),
            polyline=Polyline(positions=PositionList(references=[f"{_node_ref(a)}#position", f"{_node_ref(b)}#position"]),
                              width=3, arcType="NONE",
                              material=PolylineMaterial(solidColor=SolidColorMaterial(color=Color(rgba=[255, 40, 40, 230])))),
        ))
    return Document(packets=packets)
