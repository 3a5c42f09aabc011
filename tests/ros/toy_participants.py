"""Toy lockstep participants for the ROS-engine tests and bench (no rclpy).

Their output depends on exactly what they received, in which order and at which step (a CRC of
their inbox goes into every message they emit), so any lost, duplicated, late or reordered
envelope changes the trace. Emit stamps lie before the step time on purpose, so the engine cannot
split steps by stamp alone.

* :class:`Ping` / :class:`Pong`: ping wakes every 7.3 s and emits on /toy/ping (JSON text); pong
  answers each ping on /toy/pong one step later; ping counts the answers.
* :class:`Counter` ``c<i>``: wakes at its own irregular period, emits on /toy/count/c<i> (text)
  and every third time a blob on /toy/blob (bytes); reads its ring neighbour's count topic and the
  blobs; greets on /toy/hello in start() and reports in finish().
* :class:`Listener` (event-driven, msgs_json/envelope.py rule 1): reads /toy/ping and wakes itself
  every 13 s; it is called only for an inbox or at its wakeup, and reports in finish how often and
  when it was called (role ``pingpong`` hosts it beside ping and pong).
* :class:`Staller`: a counter that stops answering (sleeps, once, ``sleep_s``: an hour by default)
  once sim time passes ``stall_at_ns`` (negative: in its start, the lockstep's step 0).
* :class:`Breaker`: a counter that breaks the engine contract one way (:data:`BREAKS`) once sim
  time reaches ``at_ns`` (``spec.extra["break"] = {"role": ..., "kind": ..., "at_ns": ...}``).

``make(spec, role)`` is the run-spec factory: role ``pingpong`` hosts ping and pong in one process,
role ``c<i>`` hosts counter i (``spec.extra["n_counters"]`` counters in the ring;
``blob_every`` (0: no blobs) and ``period_s`` tune the counters;
``spec.extra["stall"] = {"role": ..., "at_ns": ..., "sleep_s": ...}`` makes one a Staller; ``spec.extra["linger"] = role``
makes that role's process ignore SIGTERM and not exit after its run). ``all_participants``
returns fresh instances of every role's participants, for the local engine reference run.
``slow_prepare`` is a run-spec prepare hook that makes chosen processes slow to get ready.
"""

from __future__ import annotations

import json
import time
import zlib

from msgs_json.envelope import Emit, Envelope, StepResult

S = 1_000_000_000


def _crc(inbox: list[Envelope]) -> int:
    text = "|".join(f"{e.t_ns},{e.source},{e.seq},{e.topic},{e.data!r}" for e in inbox)
    return zlib.crc32(text.encode())


class Ping:
    name = "ping"

    def __init__(self, period_ns: int = 7_300_000_000):
        self.period_ns = period_ns
        self.n = 0
        self.answers = 0

    def subscriptions(self) -> list[str]:
        return ["/toy/pong"]

    def start(self, t0_ns: int) -> StepResult:
        return StepResult([Emit("/toy/hello", json.dumps({"from": self.name}), t0_ns)], t0_ns + self.period_ns)

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        self.answers += len(inbox)
        emits = []
        if t_ns % self.period_ns == 0 or inbox:
            self.n += 1
            emits.append(Emit("/toy/ping", json.dumps({"n": self.n, "crc": _crc(inbox)}), max(0, t_ns - 5)))
        return StepResult(emits, (t_ns // self.period_ns + 1) * self.period_ns)

    def finish(self, t_ns: int) -> list[Emit]:
        return [Emit("/toy/summary", json.dumps({"ping": self.n, "answers": self.answers}), t_ns)]


class Pong:
    name = "pong"

    def subscriptions(self) -> list[str]:
        return ["/toy/ping", "/toy/hello"]

    def start(self, t0_ns: int) -> StepResult:
        return StepResult()

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        emits = [Emit("/toy/pong", json.dumps({"re": e.seq, "crc": _crc(inbox)}), e.t_ns)
                 for e in inbox if e.topic == "/toy/ping"]
        return StepResult(emits, None)

    def finish(self, t_ns: int) -> list[Emit]:
        return []


class Listener:
    name = "listener"
    event_driven = True

    def __init__(self, period_ns: int = 13 * S):
        self.period_ns = period_ns
        self.calls: list[int] = []
        self.heard = 0

    def subscriptions(self) -> list[str]:
        return ["/toy/ping"]

    def start(self, t0_ns: int) -> StepResult:
        return StepResult([], t0_ns + self.period_ns)

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        self.calls.append(t_ns)
        self.heard += len(inbox)
        return StepResult([], (t_ns // self.period_ns + 1) * self.period_ns, len(self.calls))

    def finish(self, t_ns: int) -> list[Emit]:
        body = {"listener_calls": len(self.calls), "at": zlib.crc32(repr(self.calls).encode()), "heard": self.heard}
        return [Emit("/toy/summary", json.dumps(body), t_ns)]


class Counter:
    def __init__(self, i: int, n: int, blob_every: int = 3, period_s: float | None = None):
        self.i, self.n_ring = i, n
        self.name = f"c{i}"
        self.period_ns = (period_s if period_s else 3 + 1.37 * (i % 5)) * S
        self.count = 0
        self.blob_every = blob_every
        self.seen = 0

    def subscriptions(self) -> list[str]:
        blobs = ["/toy/blob"] if self.blob_every else []
        return [f"/toy/count/c{(self.i + 1) % self.n_ring}", *blobs, "/toy/hello"]

    def start(self, t0_ns: int) -> StepResult:
        return StepResult([Emit("/toy/hello", json.dumps({"from": self.name}), t0_ns)], t0_ns + int(self.period_ns))

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        self.seen += len(inbox)
        emits = []
        if inbox or t_ns % int(self.period_ns) == 0:
            self.count += 1
            stamp = max(0, t_ns - 1000 * self.i)
            emits.append(Emit(f"/toy/count/{self.name}", json.dumps({"c": self.count, "crc": _crc(inbox)}), stamp))
            if self.blob_every and self.count % self.blob_every == 0:
                emits.append(Emit("/toy/blob", bytes([self.i % 256]) + _crc(inbox).to_bytes(4, "big"), stamp))
        nxt = (t_ns // int(self.period_ns) + 1) * int(self.period_ns)
        return StepResult(emits, nxt)

    def finish(self, t_ns: int) -> list[Emit]:
        return [Emit("/toy/summary", json.dumps({self.name: self.count, "seen": self.seen}), t_ns)]


class Staller(Counter):
    def __init__(self, i: int, n: int, at_ns: int, sleep_s: float = 3600.0):
        super().__init__(i, n)
        self.at_ns = at_ns
        self.sleep_s = sleep_s
        self.slept = False

    def start(self, t0_ns: int) -> StepResult:
        if self.at_ns < 0:  # slow in the start step (step 0)
            self.slept = True
            time.sleep(self.sleep_s)
        return super().start(t0_ns)

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        if t_ns >= self.at_ns and not self.slept:
            self.slept = True
            time.sleep(self.sleep_s)
        return super().step(t_ns, inbox)


# ways to break the engine contract (bringup/engine/contract.py), each with what the step returns
BREAKS = {
    "negative_wakeup": lambda t: StepResult([], -5),
    "bool_wakeup": lambda t: StepResult([], True),
    "float_wakeup": lambda t: StepResult([], t + 0.5),
    "future_emit": lambda t: StepResult([Emit("/toy/x", "{}", t + 1)], None),
    "negative_stamp": lambda t: StepResult([Emit("/toy/x", "{}", -1)], None),
    "int_data": lambda t: StepResult([Emit("/toy/x", 7, t)], None),
    "relative_topic": lambda t: StepResult([Emit("toy/x", "{}", t)], None),
    "not_an_emit": lambda t: StepResult([("/toy/x", "{}", t)], None),
    "negative_in_flight": lambda t: StepResult([], None, -1),
    "not_a_step_result": lambda t: ([], None),
    "raises": lambda t: {}["missing key"],
}


class Breaker(Counter):
    def __init__(self, i: int, n: int, kind: str, at_ns: int):
        super().__init__(i, n)
        self.kind = kind
        self.at_ns = at_ns

    def step(self, t_ns: int, inbox: list[Envelope]) -> StepResult:
        if t_ns >= self.at_ns:
            return BREAKS[self.kind](t_ns)
        r = super().step(t_ns, inbox)
        r.next_wakeup_ns = min(r.next_wakeup_ns, self.at_ns)  # break at at_ns exactly
        return r


def roles(n_counters: int, pingpong: bool = True) -> list[str]:
    return (["pingpong"] if pingpong else []) + [f"c{i}" for i in range(n_counters)]


def _linger_at_exit() -> None:
    """The host process, once its run is over, neither exits nor reacts to SIGTERM (as hosts blocked
    in FastDDS participant destruction were seen to): only SIGKILL ends it. Replaces the host's
    way out (bringup/engine/ros/host.py exit_now)."""
    import signal

    import bringup.engine.ros.host

    def linger(code: int) -> None:
        signal.signal(signal.SIGTERM, signal.SIG_IGN)
        time.sleep(120)

    bringup.engine.ros.host.exit_now = linger


def make(spec, role: str, host: bool = True) -> list:
    n = int(spec.extra.get("n_counters", 2))
    if host and spec.extra.get("linger") == role:
        _linger_at_exit()
    if role == "pingpong":
        return [Ping(), Pong(), Listener()]
    if role.startswith("c") and role[1:].isdigit():
        i = int(role[1:])
        stall = spec.extra.get("stall")
        if stall and stall.get("role") == role:
            return [Staller(i, n, int(stall["at_ns"]), float(stall.get("sleep_s", 3600.0)))]
        brk = spec.extra.get("break")
        if brk and brk.get("role") == role:
            return [Breaker(i, n, brk["kind"], int(brk["at_ns"]))]
        return [Counter(i, n, int(spec.extra.get("blob_every", 3)), spec.extra.get("period_s"))]
    raise ValueError(f"toy factory: unknown role {role!r}")


def slow_prepare(spec, role: str | None) -> None:
    """Run-spec prepare hook: ``spec.extra["prepare_s"][role]`` seconds of sleep (a slow start; the
    key ``"run"`` is the launcher's once-per-run call); ``spec.extra["prepare_fail"]`` == role: fails."""
    if spec.extra.get("prepare_fail") == (role or "run"):
        raise ValueError(f"toy prepare: {role or 'run'} cannot get ready")
    time.sleep(float(spec.extra.get("prepare_s", {}).get(role or "run", 0.0)))


def all_participants(spec) -> list:
    return [p for r in spec.roles for p in make(spec, r, host=False)]


def make_deferred(spec, role: str) -> list:
    """The counter roles as managed entries built when their node is configured
    (bringup/engine/lifecycle.py Deferred), as the scenario's factory gives them;
    ``spec.extra["fail_configure"] == role``: building it raises (a node that cannot configure)."""
    from bringup.engine.lifecycle import Deferred

    def build():
        if spec.extra.get("fail_configure") == role:
            raise OSError(f"toy: {role} cannot open its store")
        return make(spec, role)[0]

    return [Deferred(role, build)]
