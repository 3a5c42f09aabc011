"""Tasking requests: an operator's target (lat, lon, priority, deadline) as a new GP of interest.

A ``task`` command (sat_node/operations/commands.py) carries ``args`` = ``{"lat_deg", "lon_deg",
"priority", "by_ns"}``. The satellite that executes it maps the target to the nearest ground point
(GP) of its own grid (the scenario's regions cut at ``regions.gp_spacing_km``; the satellite holds
the same grid as every planner) when one lies within ``gp_spacing_km`` of it (else the command is
rejected ``no_target`` and counted), and keeps it in its :class:`TaskBook`. From then on, until the
deadline ``by_ns`` or until it learns of an observation of that GP made after the command was
issued (its own look, or one a delivered bundle tells of), the GP is one of its **GPs of
interest**: in every plan it makes, its believed absolute value at that GP is raised to
:data:`TASK_VALUE` of the priority for the DP grid times up to the deadline (the value is a floor:
a GP already worth more keeps its value). Eq. 1 then applies as to any GP (the value halves with
each earlier known look, zero within ``revisit_zero_s`` of one).

In joint planning (sat_node/scheduler/planner.py ``Planner.group``) the satellite plans its
neighbours from what it knows; the tasked GP is its own to take, so in the instances it builds for
its partners that GP is worth 0 until the deadline (the task is reserved for it: the joint dive
would otherwise give it to a partner that looks first and never received the task).

The planner learns of a task ONLY through the delivered, authenticated command: the overlay
(:class:`TaskOverlay`) is built from the satellite's own TaskBook, which only
``OnboardOperations._on_command`` fills.

Priorities: 1 (most urgent) to 3; :data:`TASK_VALUE` = 1024, 512, 256 - the OSSE value scale is
1..256 (ground_station/osse.py), so priority 3 is worth as much as the most valuable flooded GP and
priority 1 four times more. A scaling the study does not give: a stated choice, reported, not tuned.

How we know it is right (tests/unit/test_operations_tasking.py): the nearest GP against a brute-force
haversine scan of the grid; the overlay on a hand-built value matrix (owner: floor to the deadline,
partners: zero, after the deadline unchanged); a task fulfilled by an observation after issue and
not by one before; a satellite that received the command plans the target and an identical one that
did not never does (the peek test). Whole runs on both engines: tests/system/test_operations_tasking_run.py.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

__all__ = ["PRIORITIES", "TASK_VALUE", "Task", "TaskBook", "TaskOverlay", "nearest_gp"]

#: priority -> the believed absolute value of the tasked GP until the deadline (module docstring)
TASK_VALUE = {1: 1024.0, 2: 512.0, 3: 256.0}
PRIORITIES = tuple(TASK_VALUE)
_EARTH_KM = 6371.0088  # mean radius (IUGG) for the great-circle distance to the nearest GP
_NS = 1_000_000_000


def nearest_gp(lat_deg: np.ndarray, lon_deg: np.ndarray, lat: float, lon: float) -> tuple[int, float]:
    """(index, great-circle distance [km]) of the ground point nearest to (lat, lon) [deg]: the
    haversine formula on a sphere of the Earth's mean radius."""
    la, lo = np.radians(np.asarray(lat_deg, float)), np.radians(np.asarray(lon_deg, float))
    p, q = math.radians(lat), math.radians(lon)
    h = np.sin((la - p) / 2) ** 2 + np.cos(la) * math.cos(p) * np.sin((lo - q) / 2) ** 2
    d = 2 * _EARTH_KM * np.arcsin(np.sqrt(np.clip(h, 0.0, 1.0)))
    i = int(np.argmin(d))
    return i, float(d[i])


@dataclass
class Task:
    """One executed tasking request: the command, the GP it maps to, its priority and deadline, and
    the first known observation of the GP after issue (``done_ns``, ``done_by``; None: open)."""

    command_id: str
    gp: int
    priority: int
    by_ns: int
    issued_ns: int
    executed_ns: int
    done_ns: int | None = None
    done_by: str = ""


class TaskBook:
    """A satellite's tasks (picklable: the checkpoint holds it)."""

    def __init__(self) -> None:
        self.tasks: list[Task] = []

    def add(self, task: Task) -> None:
        self.tasks.append(task)

    def observed(self, gp: int, t_ns: int, src: str) -> None:
        """An observation of ``gp`` at ``t_ns`` by ``src`` became known: it fulfils the open tasks of
        that GP issued at or before it (and not past their deadline)."""
        for k in self.tasks:
            if k.gp == gp and k.done_ns is None and k.issued_ns <= t_ns <= k.by_ns:
                k.done_ns, k.done_by = t_ns, src

    def open_at(self, t_ns: int) -> list[Task]:
        return [k for k in self.tasks if k.done_ns is None and k.by_ns >= t_ns]

    def overlay(self, owner: str, t_ns: int) -> TaskOverlay | None:
        """The planner's view of the open tasks at ``t_ns`` (None: no open task)."""
        live = self.open_at(t_ns)
        if not live:
            return None
        best: dict[int, tuple[float, float]] = {}  # gp -> (value, deadline s): the highest priority wins
        for k in live:
            v, by_s = TASK_VALUE[k.priority], k.by_ns / _NS
            old = best.get(k.gp)
            if old is None or (v, by_s) > old:
                best[k.gp] = (v, by_s)
        gps = np.array(sorted(best), dtype=np.int64)
        return TaskOverlay(owner, gps, np.array([best[g][0] for g in gps]), np.array([best[g][1] for g in gps]))


@dataclass(frozen=True)
class TaskOverlay:
    """The tasked GPs as the planner applies them (module docstring): ``gps`` (sorted), their
    ``value`` and deadline ``by_s`` [s since the epoch]; ``owner`` the satellite whose task they are."""

    owner: str
    gps: np.ndarray
    value: np.ndarray
    by_s: np.ndarray

    @property
    def last_by_s(self) -> float:
        return float(self.by_s.max())

    def apply(self, sat: str, gp_ids: np.ndarray, times_s: np.ndarray, absval: np.ndarray) -> np.ndarray:
        """``absval`` ((T, G) or (G,) over ``times_s`` x ``gp_ids``) with the tasks applied for an
        instance of ``sat``: a floor of the task's value at the owner's, 0 at a partner's, at the
        times up to the deadline; the same array when no tasked GP is among ``gp_ids``."""
        gp_ids = np.asarray(gp_ids, np.int64)
        times_s = np.asarray(times_s, np.float64)
        pos = np.searchsorted(self.gps, gp_ids)
        pos = np.minimum(pos, len(self.gps) - 1)
        cols = np.flatnonzero(self.gps[pos] == gp_ids)
        if len(cols) == 0:
            return absval
        out = np.array(np.broadcast_to(absval, (len(times_s), len(gp_ids))), dtype=np.float64)
        for j in cols:
            k = pos[j]
            rows = times_s <= self.by_s[k]
            if sat == self.owner:
                out[rows, j] = np.maximum(out[rows, j], self.value[k])
            else:
                out[rows, j] = 0.0
        return out
