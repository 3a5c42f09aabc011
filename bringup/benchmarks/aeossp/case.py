"""Read one ``aeossp_standard`` case folder into typed objects.

The format is the benchmark's public case contract (its README, "Case Inputs"): ``mission.yaml``
(horizon, action/geometry/resource grids), ``satellites.yaml`` (TLEs, sensor type, attitude and
resource models) and ``tasks.yaml`` (point targets with release/due times, required duration,
sensor type and weight). Every problem is one :class:`~bringup.errors.UserError` line naming the
file and the entry (``tasks.yaml: tasks[3] (task_0004): due_time before release_time``).

Also the solution JSON (``{"actions": [...]}``): :func:`read_solution` / :func:`write_solution`.

Checked by tests/unit/test_aeossp_case.py.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

import yaml
from sgp4.api import Satrec

from bringup.errors import UserError

__all__ = ["Action", "Case", "Mission", "Satellite", "Task", "iso_z", "read_case", "read_solution",
           "write_solution"]


@dataclass(frozen=True)
class Mission:
    case_id: str
    start: datetime
    end: datetime
    action_step_s: int
    geometry_step_s: int
    resource_step_s: int

    @property
    def horizon_s(self) -> int:
        return round((self.end - self.start).total_seconds())

    def offset_s(self, t: datetime) -> float:
        return (t - self.start).total_seconds()


@dataclass(frozen=True)
class Satellite:
    sat_id: str
    tle1: str
    tle2: str
    sensor: str
    max_rate_deg_s: float
    max_acc_deg_s2: float
    settle_s: float
    max_off_nadir_deg: float
    capacity_wh: float
    initial_wh: float
    idle_w: float
    imaging_w: float
    slew_w: float
    charge_w: float

    def satrec(self) -> Satrec:
        return Satrec.twoline2rv(self.tle1, self.tle2)


@dataclass(frozen=True)
class Task:
    task_id: str
    lat_deg: float
    lon_deg: float
    alt_m: float
    release_s: int      # offsets from the horizon start
    due_s: int
    duration_s: int
    sensor: str
    weight: float


@dataclass(frozen=True)
class Case:
    mission: Mission
    satellites: tuple[Satellite, ...]
    tasks: tuple[Task, ...]

    def sat(self, sat_id: str) -> Satellite:
        return self._sats[sat_id]

    def task(self, task_id: str) -> Task:
        return self._tasks[task_id]

    def __post_init__(self):
        object.__setattr__(self, "_sats", {s.sat_id: s for s in self.satellites})
        object.__setattr__(self, "_tasks", {t.task_id: t for t in self.tasks})


@dataclass(frozen=True)
class Action:
    """One observation: satellite, task, start and end as whole seconds from the horizon start."""
    sat_id: str
    task_id: str
    start_s: int
    end_s: int


def iso_z(t: datetime) -> str:
    return t.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%SZ")


def _time(value, where: str) -> datetime:
    if isinstance(value, datetime):
        t = value
    elif isinstance(value, str):
        try:
            t = datetime.fromisoformat(value)
        except ValueError:
            raise UserError(f"{where}: not an ISO 8601 time: {value!r}") from None
    else:
        raise UserError(f"{where}: not an ISO 8601 time: {value!r}")
    if t.tzinfo is None:
        raise UserError(f"{where}: time without a time zone (UTC 'Z' expected): {value!r}")
    return t.astimezone(UTC)


def _num(d: dict, key: str, where: str, *, positive=False, nonneg=False) -> float:
    if key not in d:
        raise UserError(f"{where}: missing {key}")
    v = d[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise UserError(f"{where}: {key} is not a number: {v!r}")
    v = float(v)
    if not math.isfinite(v):
        raise UserError(f"{where}: {key} is not finite")
    if positive and v <= 0:
        raise UserError(f"{where}: {key} must be > 0, got {v:g}")
    if nonneg and v < 0:
        raise UserError(f"{where}: {key} must be >= 0, got {v:g}")
    return v


def _map(d, key: str, where: str) -> dict:
    v = d.get(key) if isinstance(d, dict) else None
    if not isinstance(v, dict):
        raise UserError(f"{where}: missing mapping {key}")
    return v


def _str(d: dict, key: str, where: str) -> str:
    v = d.get(key)
    if not isinstance(v, str) or not v:
        raise UserError(f"{where}: missing {key}")
    return v


def _load(path: Path, top: str):
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise UserError(f"{path}: no such file (an aeossp case folder holds mission.yaml, satellites.yaml, "
                        "tasks.yaml)") from None
    except OSError as exc:
        raise UserError(f"{path}: {exc.strerror or exc}") from None
    try:
        doc = yaml.load(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
    except yaml.YAMLError as exc:
        mark = getattr(exc, "problem_mark", None)
        line = f" line {mark.line + 1}" if mark is not None else ""
        raise UserError(f"{path}:{line} not valid YAML ({getattr(exc, 'problem', None) or 'parse error'})") from None
    if not isinstance(doc, dict) or top not in doc:
        raise UserError(f"{path}: expected a mapping with a top-level '{top}'")
    return doc[top]


def _aligned(seconds: float, step: int, where: str, what: str) -> int:
    n = round(seconds)
    if abs(seconds - n) > 1e-9 or n % step:
        raise UserError(f"{where}: {what} is not on the {step}-s action grid")
    return int(n)


def _mission(path: Path) -> Mission:
    m = _load(path, "mission")
    where = path.name
    if not isinstance(m, dict):
        raise UserError(f"{where}: 'mission' is not a mapping")
    start = _time(m.get("horizon_start"), f"{where}: horizon_start")
    end = _time(m.get("horizon_end"), f"{where}: horizon_end")
    if end <= start:
        raise UserError(f"{where}: horizon_end is not after horizon_start")
    steps = {}
    for key in ("action_time_step_s", "geometry_sample_step_s", "resource_sample_step_s"):
        v = _num(m, key, where, positive=True)
        if v != int(v):
            raise UserError(f"{where}: {key} must be a whole number of seconds")
        if (end - start).total_seconds() % v:
            raise UserError(f"{where}: the horizon is not a multiple of {key}={v:g}")
        steps[key] = int(v)
    return Mission(str(m.get("case_id", path.parent.name)), start, end, steps["action_time_step_s"],
                   steps["geometry_sample_step_s"], steps["resource_sample_step_s"])


def _entries(entries: list, path: Path, kind: str, id_key: str):
    """(where, entry, id) of each entry of a list of mappings with unique ``id_key`` values; one-line
    UserError naming the entry that is not a mapping or repeats an id."""
    seen: set[str] = set()
    for i, e in enumerate(entries):
        where = f"{path.name}: {kind}[{i}]"
        if not isinstance(e, dict):
            raise UserError(f"{where}: not a mapping")
        eid = _str(e, id_key, where)
        where = f"{where} ({eid})"
        if eid in seen:
            raise UserError(f"{where}: duplicate {id_key}")
        seen.add(eid)
        yield where, e, eid


def _satellites(path: Path) -> tuple[Satellite, ...]:
    entries = _load(path, "satellites")
    if not isinstance(entries, list) or not entries:
        raise UserError(f"{path.name}: 'satellites' must be a non-empty list")
    out = []
    for where, s, sid in _entries(entries, path, "satellites", "satellite_id"):
        l1, l2 = _str(s, "tle_line1", where), _str(s, "tle_line2", where)
        try:
            rec = Satrec.twoline2rv(l1, l2)
        except Exception as exc:  # noqa: BLE001 - sgp4 raises ValueError/IndexError on a bad line
            raise UserError(f"{where}: bad TLE ({exc})") from None
        if rec.error:
            raise UserError(f"{where}: bad TLE (sgp4 error {rec.error})")
        sensor = _str(_map(s, "sensor", where), "sensor_type", where)
        att, res = _map(s, "attitude_model", where), _map(s, "resource_model", where)
        sat = Satellite(
            sid, l1, l2, sensor,
            _num(att, "max_slew_velocity_deg_per_s", where, positive=True),
            _num(att, "max_slew_acceleration_deg_per_s2", where, positive=True),
            _num(att, "settling_time_s", where, nonneg=True),
            _num(att, "max_off_nadir_deg", where, positive=True),
            _num(res, "battery_capacity_wh", where, positive=True),
            _num(res, "initial_battery_wh", where, nonneg=True),
            _num(res, "idle_power_w", where, nonneg=True),
            _num(res, "imaging_power_w", where, nonneg=True),
            _num(res, "slew_power_w", where, nonneg=True),
            _num(res, "sunlit_charge_power_w", where, nonneg=True))
        if sat.initial_wh > sat.capacity_wh:
            raise UserError(f"{where}: initial_battery_wh exceeds battery_capacity_wh")
        out.append(sat)
    return tuple(out)


def _tasks(path: Path, mission: Mission) -> tuple[Task, ...]:
    entries = _load(path, "tasks")
    if not isinstance(entries, list):
        raise UserError(f"{path.name}: 'tasks' must be a list")
    out = []
    step = mission.action_step_s
    for where, t, tid in _entries(entries, path, "tasks", "task_id"):
        lat = _num(t, "latitude_deg", where)
        lon = _num(t, "longitude_deg", where)
        if not -90 <= lat <= 90 or not -180 <= lon <= 360:
            raise UserError(f"{where}: latitude/longitude out of range ({lat:g}, {lon:g})")
        rel = _aligned(mission.offset_s(_time(t.get("release_time"), f"{where}: release_time")), step, where,
                       "release_time")
        due = _aligned(mission.offset_s(_time(t.get("due_time"), f"{where}: due_time")), step, where, "due_time")
        dur = _aligned(_num(t, "required_duration_s", where, positive=True), step, where, "required_duration_s")
        if due <= rel:
            raise UserError(f"{where}: due_time is not after release_time")
        out.append(Task(tid, lat, lon, _num(t, "altitude_m", where), rel, due, dur,
                        _str(t, "required_sensor_type", where), _num(t, "weight", where, nonneg=True)))
    return tuple(out)


def read_case(case_dir: str | Path) -> Case:
    """The case in ``case_dir``; a :class:`UserError` line for anything malformed."""
    d = Path(case_dir)
    if not d.is_dir():
        raise UserError(f"{d}: not a folder (an aeossp case folder holds mission.yaml, satellites.yaml, tasks.yaml)")
    mission = _mission(d / "mission.yaml")
    return Case(mission, _satellites(d / "satellites.yaml"), _tasks(d / "tasks.yaml", mission))


def read_solution(path: str | Path, case: Case) -> list[Action]:
    """A solution JSON as actions; structure errors (unknown ids, bad times, types) are one line.

    Times must be whole seconds; times off the action grid or outside the horizon are kept and
    judged by :func:`bringup.benchmarks.aeossp.check.check`.
    """
    p = Path(path)
    try:
        doc = json.loads(p.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise UserError(f"{p}: no such file") from None
    except (OSError, ValueError) as exc:
        raise UserError(f"{p}: not a JSON solution ({exc})") from None
    acts = doc.get("actions") if isinstance(doc, dict) else None
    if not isinstance(acts, list):
        raise UserError(f"{p}: expected an object with an 'actions' list")
    out = []
    for i, a in enumerate(acts):
        where = f"{p.name}: actions[{i}]"
        if not isinstance(a, dict):
            raise UserError(f"{where}: not an object")
        if a.get("type") != "observation":
            raise UserError(f"{where}: unsupported action type {a.get('type')!r}")
        sid, tid = a.get("satellite_id"), a.get("task_id")
        if sid not in case._sats:
            raise UserError(f"{where}: unknown satellite_id {sid!r}")
        if tid not in case._tasks:
            raise UserError(f"{where}: unknown task_id {tid!r}")
        s = case.mission.offset_s(_time(a.get("start_time"), f"{where}: start_time"))
        e = case.mission.offset_s(_time(a.get("end_time"), f"{where}: end_time"))
        if s != int(s) or e != int(e):
            raise UserError(f"{where}: times must be whole seconds")
        out.append(Action(sid, tid, int(s), int(e)))
    return out


def write_solution(path: str | Path, case: Case, actions: list[Action]) -> None:
    from datetime import timedelta

    t0 = case.mission.start
    doc = {"actions": [
        {"type": "observation", "satellite_id": a.sat_id, "task_id": a.task_id,
         "start_time": iso_z(t0 + timedelta(seconds=a.start_s)), "end_time": iso_z(t0 + timedelta(seconds=a.end_s))}
        for a in sorted(actions, key=lambda a: (a.sat_id, a.start_s))]}
    try:
        Path(path).write_text(json.dumps(doc, indent=1) + "\n", encoding="utf-8")
    except OSError as exc:
        from bringup.errors import os_error_line
        raise UserError(os_error_line(exc)) from None
