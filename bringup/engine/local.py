"""The local engine: drives participants in one process with an in-memory bus (docs/design.md section 2).

It applies the lockstep rules of msgs_json/envelope.py exactly, so a local run is the reference a
ROS run must match:

1. ``start(t0)`` of every participant; its emits form the inbox of step 0.
2. At step k every participant's ``step(t_k, inbox)`` is called once, in list order; ``inbox`` holds
   the envelopes emitted during step k-1 (or by ``start`` for k = 0) on the topics it subscribes
   to, sorted by ``(t_ns, source, seq)``. Nothing emitted in step k is seen before step k+1. An
   event-driven participant is called only when its inbox is not empty or its wakeup is due
   (contract ``must_step``, applied inline).
3. The next step comes from the contract's step rule (bringup/engine/contract.py ``next_step_ns``):
   the earliest wakeup, at most ``max_step_ns`` ahead, never past the horizon, at least 1 ns on;
   the last step is at ``horizon_ns``, then ``finish(horizon_ns)`` is called once and its emits are
   recorded (delivered to no one).
4. ``seq`` is a per-source counter from 0 in emission order.

Every participant is a managed node (bringup/engine/lifecycle.py, the ROS 2 life cycle the ROS
engine's nodes have): the engine configures (the participant's ``configure()``, if it has one) and
activates each one, in list order, before any ``start``; deactivates each after ``finish``; and,
with ``release`` (the default of :meth:`LocalEngine.run`), cleans each up (its ``close()``, if it
has one: e.g. a satellite's bundle store) and shuts it down, so a run ends with every participant
``finalized``. A caller that still needs the participants' resources after the run (the
`constellation run` command closes the stores side by side while the recorder finishes) passes
``release=False`` and calls :meth:`LocalEngine.release` itself. A transition that fails is an
:class:`EngineError` naming the participant and the transition.

What a participant returns and emits is checked by the contract module (the ROS host uses the same
checks): a violation, or an exception in a participant, is an :class:`EngineError` that names the
participant and the call.

Usage::

    res = run_local(participants, horizon_ns=sc.horizon_ns, max_step_ns=10**10,
                    sink=bag.write_envelope,            # stream (else res.envelopes holds them all)
                    sink_many=bag.write_envelopes,      # optional: each step's list in one call
                    on_step=bag.write_clock,            # called with t_k before each step
                    progress=print, progress_interval_s=1.0)
    res.steps, res.wall_s, res.real_time_factor, res.counts_by_topic

Every emitted envelope goes to ``sink`` (or into ``res.envelopes``) in the order it is delivered:
per step, sorted by ``(t_ns, source, seq)``; ``sink_many`` (e.g. BagWriter.write_envelopes), when
given, gets each step's list in one call instead, same order. Per-step overhead is a few microseconds plus
O(messages): routing is a precomputed topic -> subscribers table. ``Progress.in_flight`` is the sum
of the participants' last ``StepResult.in_flight`` (None when none reports one).

Oracle: tests/unit/test_local_engine.py drives toy participants whose behaviour is known by hand
(echo, ping-pong, timer) and checks each rule: next-step delivery, ordering, wakeup choice, max step,
at-least-1-ns advance, finish, seq numbering, bad emits rejected, determinism across runs;
tests/unit/test_contract.py checks that its errors are the ROS host's, word for word.
"""

from __future__ import annotations

import gc
import heapq
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from operator import attrgetter

from bringup.engine.contract import (
    ContractError,
    EngineError,
    check_emits,
    check_names,
    check_result,
    check_subscriptions,
    failed,
    is_event_driven,
)
from bringup.engine.lifecycle import Lifecycle, LifecycleError
from msgs_json.envelope import Envelope, Participant

__all__ = ["ContractError", "EngineError", "LocalEngine", "Progress", "RunResult", "run_local"]


@dataclass(frozen=True, slots=True)
class Progress:
    """What the progress callback receives."""

    t_ns: int
    horizon_ns: int
    steps: int
    envelopes: int
    wall_s: float
    in_flight: int | None = None

    @property
    def real_time_factor(self) -> float:
        return (self.t_ns / 1e9) / self.wall_s if self.wall_s > 0 else float("inf")

    @property
    def fraction(self) -> float:
        return self.t_ns / self.horizon_ns if self.horizon_ns else 1.0


@dataclass
class RunResult:
    steps: int
    t0_ns: int
    horizon_ns: int
    wall_s: float
    envelopes: list[Envelope] = field(default_factory=list)  # empty when a sink was given
    counts_by_topic: dict[str, int] = field(default_factory=dict)

    @property
    def real_time_factor(self) -> float:
        sim_s = (self.horizon_ns - self.t0_ns) / 1e9
        return sim_s / self.wall_s if self.wall_s > 0 else float("inf")


_KEY = attrgetter("t_ns", "source", "seq")
# a named tuple made from its fields at once: what ``Envelope(...)`` does without its Python-level
# __new__ (~1.1 M envelopes per 1000-satellite half hour; tests/unit/test_speed_paths.py checks equality)
_new = tuple.__new__


class LocalEngine:
    """Deterministic lockstep driver for a fixed list of participants (see the module docstring)."""

    def __init__(
        self,
        participants: Sequence[Participant],
        *,
        horizon_ns: int,
        max_step_ns: int,
        t0_ns: int = 0,
        sink: Callable[[Envelope], None] | None = None,
        sink_many: Callable[[list[Envelope]], None] | None = None,
        on_step: Callable[[int], None] | None = None,
        progress: Callable[[Progress], None] | None = None,
        progress_interval_s: float = 1.0,
    ):
        if not (0 <= t0_ns <= horizon_ns):
            raise EngineError(f"local engine: need 0 <= t0_ns <= horizon_ns, got {t0_ns}, {horizon_ns}")
        if max_step_ns < 1:
            raise EngineError(f"local engine: max_step_ns must be >= 1, got {max_step_ns}")
        names = check_names(participants)
        self.participants = list(participants)
        self.horizon_ns = int(horizon_ns)
        self.max_step_ns = int(max_step_ns)
        self.t0_ns = int(t0_ns)
        self.sink = sink
        # each step's envelopes in one call, in the same order (~440k envelopes per paper run:
        # one Python call each otherwise)
        self._sink_many = sink_many
        self.on_step = on_step
        self.progress = progress
        self.progress_interval_s = progress_interval_s
        # topic -> indices of subscribers (list order), fixed for the run
        self._subs: dict[str, list[int]] = {}
        for i, p in enumerate(self.participants):
            for topic in check_subscriptions(p.name, p.subscriptions()):
                self._subs.setdefault(topic, []).append(i)
        self._seq: dict[str, int] = {n: 0 for n in names}
        self.counts_by_topic: dict[str, int] = {}
        # each participant's managed-node state machine (bringup/engine/lifecycle.py)
        self.lifecycles = [Lifecycle(p.name, _hooks(p)) for p in self.participants]

    def _transition(self, label: str, lifecycles=None) -> None:
        for lc in self.lifecycles if lifecycles is None else lifecycles:
            try:
                lc.change(label)
            except LifecycleError as exc:
                raise EngineError(f"local engine: {exc}") from None

    def release(self, workers: int = 1) -> None:
        """Clean up (the participants' ``close()``) and shut down every participant: each ends
        ``finalized``. ``workers`` > 1: that many participants at a time (their stores close side by side)."""
        if workers <= 1:
            self._transition("cleanup")
            self._transition("shutdown")
            return
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(max_workers=workers, thread_name_prefix="release") as ex:
            for f in [ex.submit(self._transition, "cleanup", [lc]) for lc in self.lifecycles]:
                f.result()
        self._transition("shutdown")

    # -- helpers -----------------------------------------------------------------------------------
    def _stamp(self, name: str, emits, t_max_ns: int, where: str) -> list[Envelope]:
        """Turn a participant's emits into envelopes (seq assigned), checked by the contract."""
        emits = check_emits(name, emits, t_max_ns, where)
        out = []
        append = out.append
        seq = self._seq[name]
        counts = self.counts_by_topic
        get = counts.get
        for e in emits:
            topic = e.topic
            append(_new(Envelope, (e.t_ns, name, seq, topic, e.data)))
            seq += 1
            counts[topic] = get(topic, 0) + 1
        self._seq[name] = seq
        return out

    # -- the loop ----------------------------------------------------------------------------------
    def run(self, release: bool = True) -> RunResult:
        """Configure and activate every participant, run the steps, deactivate them; with
        ``release`` also clean them up and shut them down (:meth:`release`)."""
        self._transition("configure")
        self._transition("activate")
        res = self._run_gc()
        self._transition("deactivate")
        if release:
            self.release()
        return res

    def _run_gc(self) -> RunResult:
        # The loop allocates millions of short-lived objects (envelopes, events, bundles) next to a
        # large long-lived heap (world, numba, participants): with the default thresholds the cyclic
        # collector keeps re-scanning that heap. Freeze what exists now and collect the young
        # generation less often; nothing in the run depends on when cyclic garbage is freed.
        gc.collect()
        gc.freeze()
        thresholds = gc.get_threshold()
        gc.set_threshold(50_000, 50, 1000)
        try:
            return self._run()
        finally:
            gc.set_threshold(*thresholds)
            gc.unfreeze()

    def _run(self) -> RunResult:
        ps = self.participants
        n = len(ps)
        subs_get = self._subs.get
        sink = self.sink
        keep: list[Envelope] = []
        emit_out = sink if sink is not None else keep.append
        sink_many = self._sink_many
        on_step = self.on_step
        progress = self.progress
        horizon = self.horizon_ns
        max_step = self.max_step_ns
        wall0 = time.perf_counter()
        next_report = wall0 + self.progress_interval_s
        n_env = 0

        def call(i: int, fn, where: str, t_ns: int):
            try:
                return fn(t_ns)
            except EngineError:
                raise
            except Exception as exc:
                raise failed(ps[i].name, where, exc) from exc

        names = [p.name for p in ps]
        range_n = range(n)
        steps_fn = [p.step for p in ps]
        driven = [is_event_driven(p) for p in ps]
        # Event-driven participants are called only for an inbox or a due wakeup: they are looked up
        # (receivers of the step's envelopes, a heap of wakeups) instead of visited one by one.
        always = [i for i in range(n) if not driven[i]]
        any_driven = len(always) < n
        due: list[tuple[int, int]] = []  # (wakeup, index) of event-driven participants; stale entries skipped
        # the wakeup each event-driven participant has an entry for in ``due`` (None: none live): a
        # participant called for its inbox mostly returns the wakeup it already had, which is not
        # pushed again (the heap stays small and holds few stale entries)
        queued: list[int | None] = [None] * n
        # start
        t = self.t0_ns
        pending: list[Envelope] = []
        wake: list[int | None] = [None] * n
        flight: list[int | None] = [None] * n
        for i, p in enumerate(ps):
            where = f"start at {t}"
            r = check_result(p.name, call(i, p.start, where, t), where)
            pending.extend(self._stamp(p.name, r.emits, t, where))
            wake[i] = r.next_wakeup_ns
            flight[i] = r.in_flight
            if driven[i] and r.next_wakeup_ns is not None:
                heapq.heappush(due, (r.next_wakeup_ns, i))
                queued[i] = r.next_wakeup_ns

        steps = 0
        heappop, heappush = heapq.heappop, heapq.heappush
        while True:
            # deliver what was emitted in the previous step: participant index -> its inbox (only
            # the receivers have one)
            inboxes: dict[int, list[Envelope]] = {}
            if pending:
                pending.sort(key=_KEY)
                if sink_many is not None:
                    sink_many(pending)
                else:
                    for env in pending:
                        emit_out(env)
                for env in pending:
                    for i in subs_get(env.topic, ()):
                        box = inboxes.get(i)
                        if box is None:
                            inboxes[i] = [env]
                        else:
                            box.append(env)
                n_env += len(pending)
                pending = []
            if on_step is not None:
                on_step(t)
            i = 0
            where = f"step at {t}"
            order = range_n
            if any_driven:
                called = set(always)
                called.update(inboxes)
                while due and due[0][0] <= t:
                    w, j = heappop(due)
                    if wake[j] == w:
                        called.add(j)
                    if queued[j] == w:
                        queued[j] = None
                order = sorted(called)
            try:
                for i in order:
                    box = inboxes.get(i)
                    if box is None:
                        if driven[i]:
                            w = wake[i]
                            if w is None or w > t:
                                continue  # an event-driven participant with nothing this step (contract rule 1)
                        box = []
                    r = steps_fn[i](t, box)
                    check_result(names[i], r, where)
                    if r.emits:
                        pending.extend(self._stamp(names[i], r.emits, t, where))
                    w = r.next_wakeup_ns
                    if w is not None and driven[i] and queued[i] != w:
                        heappush(due, (w, i))
                        queued[i] = w
                    wake[i] = w
                    flight[i] = r.in_flight
            except EngineError:
                raise
            except Exception as exc:
                raise failed(names[i], where, exc) from exc
            steps += 1
            if progress is not None:
                now = time.perf_counter()
                if now >= next_report:
                    next_report = now + self.progress_interval_s
                    progress(Progress(t, horizon, steps, n_env, now - wall0, _sum(flight)))
            if t >= horizon:
                break
            # the step rule (contract next_step_ns) over every wakeup: the event-driven participants'
            # are the live entries of ``due`` (an entry is live while it is its participant's wakeup;
            # stale ones are dropped here, and the participant is then known to have none queued),
            # the others' are read one by one
            nxt = min(t + max_step, horizon)
            while due:
                w, j = due[0]
                if wake[j] != w:
                    heappop(due)
                    if queued[j] == w:
                        queued[j] = None
                    continue
                nxt = min(nxt, w)
                break
            for j in always:
                w = wake[j]
                if w is not None and w < nxt:
                    nxt = w
            t = nxt if nxt > t else t + 1

        # finish: emits recorded, delivered to no one (the last step's emits too)
        for i, p in enumerate(ps):
            where = f"finish at {horizon}"
            pending.extend(self._stamp(p.name, call(i, p.finish, where, horizon), horizon, where))
        pending.sort(key=_KEY)
        if sink_many is not None:
            sink_many(pending)
        else:
            for env in pending:
                emit_out(env)
        n_env += len(pending)
        wall = time.perf_counter() - wall0
        if progress is not None:
            progress(Progress(horizon, horizon, steps, n_env, wall, _sum(flight)))
        return RunResult(steps, self.t0_ns, horizon, wall, keep, dict(self.counts_by_topic))


def _hooks(p) -> dict:
    """A participant's own life-cycle hooks: ``configure()`` and ``close()`` (cleanup), when it has them."""
    hooks = {}
    if callable(getattr(p, "configure", None)):
        hooks["configure"] = p.configure
    if callable(getattr(p, "close", None)):
        hooks["cleanup"] = p.close
    return hooks


def _sum(values: list[int | None]) -> int | None:
    """Sum of the numbers given, None when there are none."""
    got = [v for v in values if v is not None]
    return sum(got) if got else None


def run_local(participants: Sequence[Participant], **kw) -> RunResult:
    """``LocalEngine(participants, **kw).run()``."""
    return LocalEngine(participants, **kw).run()
