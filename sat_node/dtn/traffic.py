"""The study's traffic table (../shared/paper_inputs/traffic_case*.csv; Nag et al. 2021's DTN inputs).

One row per executed observation: ``source,time_s,packet_id,region,Sat11..Sat38``; the satellite
columns hold the bundle priority for that destination (-1: not a destination, 0: the source). Each
(row, destination with priority > 0) is one bundle. Items come out in creation order: by time, then
file row, then priority, then destination name.

How we know it is right: the study's README counts (traffic_case4: 7430 bundles; case1: 52413),
checked in tests/unit/test_dtn_des.py.
"""

from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path

from orbit_clock.contact_plan import canonical_node

__all__ = ["TrafficItem", "TrafficError", "read_traffic"]


class TrafficError(ValueError):
    """A traffic file that cannot be read (names the file and line)."""


@dataclass(frozen=True)
class TrafficItem:
    t_s: float
    source: str
    dest: str
    priority: int
    packet_id: str
    region: str
    row: int


def read_traffic(path) -> list[TrafficItem]:
    path = Path(path)
    try:
        fh = open(path, newline="", encoding="utf-8")
    except OSError as exc:
        raise TrafficError(f"{path}: cannot read traffic: {exc.strerror or exc}") from None
    with fh:
        reader = csv.reader(fh)
        header = next(reader, None)
        if not header or header[:4] != ["source", "time_s", "packet_id", "region"] or len(header) < 5:
            raise TrafficError(f"{path}: header must start with source,time_s,packet_id,region then one "
                               f"column per satellite; got {header}")
        dests = [canonical_node(h.strip()) for h in header[4:]]
        out = []
        for line, row in enumerate(reader, start=2):
            if not row:
                continue
            if len(row) != len(header):
                raise TrafficError(f"{path}:{line}: {len(row)} fields, header has {len(header)}")
            try:
                t_s = float(row[1])
                prios = [int(x) for x in row[4:]]
            except ValueError:
                raise TrafficError(f"{path}:{line}: time or a priority is not a number") from None
            src = canonical_node(row[0].strip())
            for d, p in sorted(zip(dests, prios), key=lambda x: (x[1], x[0])):
                if p > 0 and d != src:
                    if p > 15:
                        raise TrafficError(f"{path}:{line}: priority {p} for {d} is outside 1..15")
                    out.append(TrafficItem(t_s, src, d, p, row[2], row[3], line))
    out.sort(key=lambda x: (x.t_s, x.row, x.priority, x.dest))
    return out
