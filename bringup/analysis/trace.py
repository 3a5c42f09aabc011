"""A run's trace from its bag: what the engine-equivalence, restart and multi-host checks compare.

``observations_from_bag(bag)`` -> sorted [(sat, gp, t_ns)] of every executed observation;
``deliveries_from_bag(bag)`` -> sorted [(bundle_id, receiver, t_ns)] of every bundle delivery;
``looks_from_bag(bag)`` -> sorted [(t_ns, sat, gp, assumed, recorded, info_ns)] (everything a look
says); ``plans_from_bag(bag)`` -> sorted [(planned_ns, sat, version, items)] of every plan a satellite
made or the ground uplinked, items ``((gp, t_ns, value, info_ns), ...)``.
Two runs of the same scenario and seed must give equal traces whatever the engine, the hosts or the
crashes on the way (docs/design.md section 3).

Used as the oracle of tests/system/test_engines_equal.py, tests/faults/test_restart_ros.py and
tests/system/test_knowledge_flow.py.
"""

from __future__ import annotations

from pathlib import Path

from bringup.recording.bag import BagReader
from msgs_json import codec
from msgs_json import schemas as S

__all__ = ["deliveries_from_bag", "looks_from_bag", "observations_from_bag", "plans_from_bag"]


def observations_from_bag(bag: Path) -> list[tuple[str, int, int]]:
    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith("/observations")]
        return sorted((o.sat, o.gp, o.t_ns) for o in (codec.decode(e.topic, e.data) for e in b.envelopes(topics)))


def deliveries_from_bag(bag: Path) -> list[tuple[str, str, int]]:
    out = []
    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith("/dtn/events")]
        for e in b.envelopes(topics):
            m = codec.decode(e.topic, e.data)
            if isinstance(m, S.BundleDelivered):
                out.append((m.bundle_id, m.sat, m.t_ns))
    return sorted(out)


def looks_from_bag(bag: Path) -> list[tuple]:
    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith("/observations")]
        return sorted((o.t_ns, o.sat, o.gp, o.assumed_value, o.recorded_value, o.info_ns)
                      for o in (codec.decode(e.topic, e.data) for e in b.envelopes(topics)))


def plans_from_bag(bag: Path) -> list[tuple]:
    out = []
    with BagReader(bag) as b:
        topics = [t.topic for t in b.topics() if t.topic.endswith("/schedule") or t.topic == "/ground/uplink"]
        for e in b.envelopes(topics):
            m = codec.decode(e.topic, e.data)
            sch = m.schedule if isinstance(m, S.GroundUplink) else m
            out.append((sch.planned_ns, sch.sat, sch.version,
                        tuple((it.gp, it.t_ns, it.value, it.info_ns) for it in sch.items)))
    return sorted(out)
