"""The operations part of a satellite's flight software (sat_node/satellite.py SatelliteLogic mixes it in).

What it does at each step, on the satellite's own state only: the mode rules on its telemetry
(sat_node/operations/modes.py; injected faults set the hardware bits the telemetry reads), what a
mode change does (the plan dropped, the safe attitude, the mode notice to the neighbours,
sat_node/operations/notice.py), neighbours' notices received over the DTN, and operator commands
uplinked by the ground gateway or relayed over the ISLs (sat_node/operations/commands.py), among
them tasking requests (sat_node/operations/tasking.py: the target joins the GPs the planner values),
and the acknowledgement of each command event to the ground (CommandAck on /ground/acks at the
first moment in one of the satellite's own ground contacts).

Oracle: tests/unit/test_operations_satellite.py (one satellite stepped by hand),
tests/unit/test_operations_tasking.py (a task executed, the peek test),
tests/system/test_operations_faults.py, tests/system/test_operations_commands_run.py and
tests/system/test_operations_tasking_run.py (whole runs, both engines; acks inside the ground contacts).
"""

from __future__ import annotations

import dataclasses

import numpy as np

from msgs_json import codec
from msgs_json import schemas as S
from msgs_json import topics as T
from msgs_json.envelope import Emit
from sat_node.acs import angle_between_deg, nadir_unit, unit_vectors
from sat_node.operations.commands import CommandRejected, target_of
from sat_node.operations.controller import Operations
from sat_node.operations.modes import MODES, SAFE, Fault, FaultSchedule, Limits, Telemetry
from sat_node.operations.notice import ModeNotice, encode_notice
from sat_node.operations.tasking import Task, nearest_gp

__all__ = ["OnboardOperations", "operations_for"]

_NS = 1_000_000_000


class OnboardOperations:
    """Mixed into SatelliteLogic: needs its ``name``, ``world``, ``sc``, ``ops``, ``guard``, ``plan``,
    ``target_km``, ``agent``, ``port``, ``mode``, ``plan_version``, ``_expected_ns``, ``_ops_emits``."""

    def _telemetry(self, t_ns: int) -> Telemetry:
        """This step's housekeeping for the mode rules (sat_node/operations/modes.py): the fault bits
        of the ACS and the instrument (injected faults set them), the pointing error of a stuck ACS
        (its frozen boresight against the safe attitude, nadir), the store's occupancy (an injected
        store_full fault reads as full) and how late this step comes after the wake-up asked for."""
        ops = self.ops
        active = ops.faults.active(t_ns)
        stuck = "acs_stuck" in active
        err = 0.0
        if stuck:
            if ops.frozen_target_km is None:  # the boresight freezes where it points now
                pos0 = self.world.constellation.track_ecef_km(self.name, np.array([t_ns / _NS]))[0]
                ops.frozen_target_km = self.target_km if self.target_km is not None else _nadir_point_km(pos0)
            pos = self.world.constellation.track_ecef_km(self.name, np.array([t_ns / _NS]))[0]
            err = float(angle_between_deg(unit_vectors(ops.frozen_target_km - pos)[None, :],
                                          nadir_unit(pos)[None, :])[0])
        else:
            ops.frozen_target_km = None
        if "store_full" in active:
            held = ops.limits.store_max_bundles
        else:
            held = self.agent.held_count() if self.agent is not None else 0
        late = 0.0  # beyond the step bound (a wake-up falls inside the step that covers it)
        bound_ns = int(round(self.sc.scenario.lockstep_max_step_s * _NS))
        if self._expected_ns is not None and t_ns > self._expected_ns + bound_ns:
            late = (t_ns - self._expected_ns - bound_ns) / _NS
        return Telemetry(acs_fault=stuck, instrument_fault="instrument_off" in active, pointing_error_deg=err,
                         store_bundles=held, clock_late_s=late, commanded_safe=ops.commanded_safe)

    def _operations(self, t_ns: int) -> list[Emit]:
        """Apply the mode rules; on a change, the ModeChange message, the plan dropped when imaging
        stops (and the safe attitude in SAFE), a notice to the neighbours when imaging stops or
        resumes, and a replan when it resumes."""
        ops = self.ops
        was_imaging = ops.imaging
        tr = ops.update(t_ns, self._telemetry(t_ns))
        emits: list[Emit] = []
        dropped = 0.0
        if was_imaging and not ops.imaging:
            dropped = float(sum(max(0.0, it.value) for it in self.plan if it.t_ns >= t_ns))
            ops.value_dropped += dropped
            self.plan = []
        if ops.mode == SAFE:
            self.target_km = None  # the safe attitude: nadir
        if tr is not None:
            msg = S.ModeChange(sat=self.name, t_ns=t_ns, mode=tr.mode, previous=tr.previous, reason=tr.reason,
                               imaging=ops.imaging, plan_value_dropped=dropped)
            emits.append(Emit(T.ops_mode_topic(self.name), codec.encode(msg), t_ns))
        if was_imaging != ops.imaging:
            if self.port is not None:
                note = ModeNotice(self.name, ops.mode, ops.imaging, t_ns)
                others = [(n, 1) for n in self.world.sat_names if n != self.name]
                self.port.originate(encode_notice(note), others, t_ns)
            if ops.imaging:  # resumes: plan again now
                if self.mode == "distributed":
                    self.next_replan_ns = t_ns
                elif self.mode == "nonagile":
                    emits += self._plan_nonagile(t_ns)
        return emits

    def _housekeeping(self, t_ns: int) -> Emit:
        """The housekeeping channels now (Housekeeping; sat_node/operations/catalogue.py CHANNELS)."""
        tm = self._telemetry(t_ns)
        c = self.agent.counters if self.agent is not None else {}
        g = self.guard
        msg = S.Housekeeping(sat=self.name, t_ns=t_ns, mode=MODES.index(self.ops.mode),
                             pointing_error_deg=min(180.0, tm.pointing_error_deg), store_bundles=tm.store_bundles,
                             plan_version=self.plan_version, bundles_created=c.get("created", 0),
                             bundles_delivered=c.get("delivered", 0),
                             commands_accepted=g.accepted if g is not None else 0,
                             commands_rejected=sum(g.rejected.values()) if g is not None else 0)
        return Emit(T.ops_hk_topic(self.name), codec.encode(msg), t_ns)

    def _on_notice(self, n: ModeNotice) -> None:
        """A neighbour's mode notice: keep it; when its imaging changed, replan now (the joint plan's
        partners change, sat_node/operations/notice.py)."""
        if n.src == self.name or n.src not in self.world.sat_names:
            raise ValueError(f"mode notice: source {n.src!r} is not another satellite of this run")
        if self.ops.learn_notice(n) and self.mode == "distributed" and self.plan_version:
            self._news_conflict = True

    def _on_uplinked_command(self, up, t_ns: int) -> None:
        """A command the ground gateway uplinked (GroundCommand): this satellite's own, or one to relay as a
        priority-1 bundle to the satellite it names (the name read before authentication: only the
        addressee verifies and executes, sat_node/operations/commands.py)."""
        if up.relay != self.name:
            return
        payload = up.payload.encode()
        target = target_of(payload)
        if target == self.name:
            self._on_command(payload, t_ns)
        elif target in self.world.sat_names and self.port is not None:
            self.port.originate(payload, [(target, 1)], t_ns)
        else:
            why = "no_isl" if target in self.world.sat_names else "no_such_satellite"
            self.guard.rejected[why] = self.guard.rejected.get(why, 0) + 1
            self._command_event(t_ns, "rejected", reason=why)


    def _on_command(self, payload: bytes, t_ns: int) -> None:
        """Check a command (CommandGuard) and execute it: ``mode safe`` sets the commanded-SAFE bit of the
        mode rules (sat_node/operations/modes.py), ``mode nominal`` clears it (a fault's SAFE stays until the
        fault clears), ``set`` changes a limit. Receipt and execution are events (CommandEvent) with the
        latency since issue; a rejection is an event and a counter, and changes nothing else."""
        try:
            c = self.guard.accept(payload, t_ns)
        except CommandRejected as exc:
            c = exc.command
            kw = {"cid": c.id, "kind": c.kind, "issued_ns": c.issued_ns} if c is not None else {}
            self._command_event(t_ns, "rejected", reason=exc.reason, **kw)
            return
        kw = {"cid": c.id, "kind": c.kind, "issued_ns": c.issued_ns}
        self._command_event(t_ns, "received", **kw)
        if c.kind == "task":
            a = c.args
            gps = self.world.gps
            gp, dist_km = nearest_gp(gps.lat_deg, gps.lon_deg, a["lat_deg"], a["lon_deg"])
            if dist_km > self.sc.regions.gp_spacing_km:
                why = "no_target"
                self.guard.rejected[why] = self.guard.rejected.get(why, 0) + 1
                self._command_event(t_ns, "rejected", reason=why, **kw)
                return
            self.tasks.add(Task(c.id, gp, a["priority"], a["by_ns"], c.issued_ns, t_ns))
            kw |= {"gp": gp, "by_ns": a["by_ns"]}
            if self.mode == "distributed" and self.ops.imaging:
                self._news_conflict = True  # plan it in at this step
        elif c.kind == "mode":
            self.ops.commanded_safe = c.args["mode"] == "safe"
        else:
            field = c.args["name"].split(".", 1)[1]
            self.ops.limits = dataclasses.replace(self.ops.limits, **{field: c.args["value"]})
        self._command_event(t_ns, "executed", **kw)

    def _command_event(self, t_ns: int, stage: str, **kw) -> None:
        """Record a command event (CommandEvent) and queue its acknowledgement for the ground: a
        CommandAck at the first time at or after the event in one of this satellite's own ground
        contacts (the world's ground plan), with the latency from the event (none left: not sent,
        counted in ``ops.acks_not_sent``)."""
        e = _command_event(self.name, t_ns, stage, **kw)
        self._ops_emits.append(e)
        slot = _own_contact(self.world.ground_plan.contacts, self.name, t_ns)
        if slot is None or slot[0] > self.sc.horizon_ns:
            self.ops.acks_not_sent += 1
            return
        due, station = slot
        ev = codec.decode(e.topic, e.data)
        ack = S.CommandAck(sat=self.name, station=station, t_ns=due, command_id=ev.command_id, stage=ev.stage,
                           reason=ev.reason, event_ns=t_ns, issued_ns=ev.issued_ns, latency_s=(due - t_ns) / _NS)
        self.ops.acks_queued += 1
        self.ops.acks = [*self.ops.acks, (due, self.ops.acks_queued, ack)]

    def _acks_due(self, t_ns: int) -> list[Emit]:
        """The acknowledgements whose downlink time has come (stamped with it)."""
        due = sorted((a for a in self.ops.acks if a[0] <= t_ns), key=lambda a: a[:2])
        if not due:
            return []
        self.ops.acks = [a for a in self.ops.acks if a[0] > t_ns]
        self.ops.acks_sent += len(due)
        return [Emit(T.GROUND_ACKS, codec.encode(a[2]), a[0]) for a in due]

    def _next_ack_ns(self) -> int | None:
        return min((a[0] for a in self.ops.acks), default=None)


def _own_contact(contacts, sat: str, t_ns: int) -> tuple[int, str] | None:
    """(time, station) of the first moment at or after ``t_ns`` inside a ground contact of ``sat``
    (ties: the station that sorts first); None when no contact is left."""
    best = None
    for c in contacts:
        if c.src != sat or not str(c.dst).startswith("gs_"):
            continue
        s, e = int(round(c.start_s * _NS)), int(round(c.end_s * _NS))
        t = max(t_ns, s)
        if t < e and (best is None or (t, c.dst) < best):
            best = (t, c.dst)
    return best


def _nadir_point_km(pos_km: np.ndarray) -> np.ndarray:
    """The sub-satellite point on a spherical Earth (the frozen boresight of an ACS stuck at nadir)."""
    return pos_km / np.linalg.norm(pos_km) * 6371.0


def operations_for(sc, name: str) -> Operations:
    """The operations state of satellite ``name``: its faults of the scenario and the limit checks."""
    faults = [Fault(name, f.kind, round(f.at_s * _NS), round(f.until_s * _NS) if f.until_s else None)
              for f in getattr(sc, "faults", ()) if f.sat == name]
    o = getattr(sc, "operations", None)
    lim = Limits() if o is None else Limits(o.pointing_error_max_deg, o.store_max_bundles, o.clock_late_max_s)
    return Operations(name, FaultSchedule(faults), lim)



def _command_event(sat: str, t_ns: int, stage: str, *, cid: str = "?", kind: str = "", reason: str = "",
                   issued_ns: int = 0, gp: int = -1, by_ns: int = 0) -> Emit:
    lat = max(0.0, (t_ns - issued_ns) / _NS) if issued_ns else 0.0
    msg = S.CommandEvent(sat=sat, t_ns=t_ns, command_id=cid[:64], stage=stage, reason=reason, kind=kind,
                         issued_ns=issued_ns, latency_s=lat, gp=gp, by_ns=by_ns)
    return Emit(T.ops_command_topic(sat), codec.encode(msg), t_ns)
