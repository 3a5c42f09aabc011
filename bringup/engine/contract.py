"""The engine contract: what a participant may give an engine, and how the next step is chosen.

A participant (msgs_json/envelope.py) is driven in lockstep by one of two engines: the local engine
(bringup/engine/local.py, one process) and the ROS engine (bringup/engine/ros/host.py runs the
participants, bringup/engine/ros/clock_node.py chooses the steps). Both check what a participant
gives them with the functions of this module and choose the next step with :func:`next_step_ns`,
so a participant that breaks the contract fails the same way under either engine, with one line
that names it and the call (``<name> step at <t_ns>: ...``).

The rules checked here:

* names: every participant has a non-empty string name, unique in the run;
* subscriptions: a list of topic names, each a string that starts with ``/``;
* ``start(t0)`` and ``step(t_k, inbox)`` return a :class:`StepResult`; ``finish(horizon)`` returns a
  list of :class:`Emit`;
* every emit is an :class:`Emit` whose topic is a string that starts with ``/``, whose data is
  ``str`` (a msgs_json text) or ``bytes`` (a bundle), and whose ``t_ns`` is an ``int`` in
  ``[0, t_k]``: nothing is emitted stamped in the future (``[0, t0]`` in start, ``[0, horizon]`` in
  finish);
* ``next_wakeup_ns`` is ``None`` (no need to be woken) or an ``int >= 0``; a wakeup at or before
  ``t_k`` asks for the very next step;
* ``in_flight`` is ``None`` or an ``int >= 0``: how many items the participant holds to emit later
  (the ISL medium's bundle copies still travelling). Engines show the sum in their progress; it
  changes nothing in the run.
* the step rule: ``t_{k+1} = max(t_k + 1, min(next wakeups of step k, t_k + max_step, horizon))``;
  the last step is at the horizon.
* ``live_state(t_ns)``, optional (the ROS engine asks every visualisation period): ``None`` or a
  :class:`LiveState` whose position is ``None`` or three finite numbers [km], whose values map
  non-empty strings to int, float or str, whose level is 0, 1 or 2 and whose message is a string;
* who is called: every participant at every step, except an event-driven one (``event_driven``
  attribute True), called only when its inbox is not empty or its standing wakeup is due
  (:func:`is_event_driven`, :func:`must_step`); a participant not called keeps its last wakeup and
  ``in_flight``.

``bool`` is not accepted where an ``int`` is (it is one in Python, never meant as a time).
Exceptions raised by a participant become an :class:`EngineError` naming it (:func:`failed`).

How we know it is right: tests/unit/test_contract.py breaks each rule under the local engine and
under the ROS engine's host and checks the two errors are the same line; tests/ros/test_lockstep.py
runs a participant that breaks the contract under the real ROS engine and finds that line in the
run's error.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

from msgs_json.envelope import Emit, LiveState, StepResult

__all__ = ["ContractError", "EngineError", "check_emits", "check_live_state", "check_names", "check_result",
           "check_subscriptions", "failed", "is_event_driven", "must_step", "next_step_ns"]


class EngineError(ValueError):
    """A participant failed or broke the contract; the message names it and the call."""


class ContractError(EngineError):
    """A participant gave an engine something the contract does not allow (module docstring)."""


def check_names(participants: Sequence) -> list[str]:
    """The participants' names, checked: non-empty strings, unique in the run."""
    names = [getattr(p, "name", None) for p in participants]
    if not names or not all(isinstance(n, str) and n for n in names) or len(set(names)) != len(names):
        raise ContractError(f"participant names must be unique non-empty strings, got {names}")
    return names


def check_subscriptions(name: str, topics) -> list[str]:
    """``subscriptions()`` of ``name``, checked: topic names that start with ``/`` (duplicates dropped)."""
    if isinstance(topics, (str, bytes)) or not isinstance(topics, Iterable):
        raise ContractError(f"{name} subscriptions: expected a list of topic names, got {type(topics).__name__}")
    out = list(dict.fromkeys(topics))
    for t in out:
        if type(t) is not str or not t.startswith("/"):
            raise ContractError(f"{name} subscriptions: topic {t!r} is not a name starting with '/'")
    return out


def check_result(name: str, r, where: str) -> StepResult:
    """What ``start``/``step`` returned, checked (``where``: ``start at T`` / ``step at T``)."""
    if type(r) is StepResult:  # the common case, checked in a few attribute reads (every step of every participant)
        w = r.next_wakeup_ns
        n = r.in_flight
        if (w is None or (type(w) is int and w >= 0)) and (n is None or (type(n) is int and n >= 0)):
            return r
    elif not isinstance(r, StepResult):
        raise ContractError(f"{name} {where}: returned {type(r).__name__}, expected StepResult")
    w = r.next_wakeup_ns
    if w is not None and (type(w) is not int or w < 0):
        raise ContractError(f"{name} {where}: next_wakeup_ns must be an int >= 0 or None, got {w!r}")
    n = r.in_flight
    if n is not None and (type(n) is not int or n < 0):
        raise ContractError(f"{name} {where}: in_flight must be an int >= 0 or None, got {n!r}")
    return r


def check_emits(name: str, emits, t_max_ns: int, where: str) -> list:
    """The emits of one call (``StepResult.emits`` or what ``finish`` returned), checked; returns
    them as a list. ``t_max_ns``: the latest stamp allowed (the step's time, t0, or the horizon)."""
    if not emits:
        if emits is None or isinstance(emits, (list, tuple)):
            return []
        raise ContractError(f"{name} {where}: emits must be a list of Emit, got {type(emits).__name__}")
    if type(emits) is not list:
        if isinstance(emits, (str, bytes, Emit)) or not isinstance(emits, Iterable):
            raise ContractError(f"{name} {where}: emits must be a list of Emit, got {type(emits).__name__}")
        emits = list(emits)
    for e in emits:
        if type(e) is not Emit and not isinstance(e, Emit):
            raise ContractError(f"{name} {where}: emitted {type(e).__name__}, expected Emit")
        t = e.t_ns
        if type(t) is not int or t < 0 or t > t_max_ns:
            raise ContractError(f"{name} {where}: emit on {e.topic} at t_ns={t!r} outside [0, {t_max_ns}]")
        td = type(e.data)
        if td is not bytes and td is not str and not isinstance(e.data, (str, bytes)):
            raise ContractError(f"{name} {where}: emit on {e.topic} has {td.__name__} data, expected str or bytes")
        topic = e.topic
        if type(topic) is not str or not topic.startswith("/"):
            raise ContractError(f"{name} {where}: emit topic {topic!r} is not a name starting with '/'")
    return emits


def check_live_state(name: str, s, where: str) -> LiveState | None:
    """What ``live_state`` returned, checked (``where``: ``live_state at T``)."""
    if s is None:
        return None
    if not isinstance(s, LiveState):
        raise ContractError(f"{name} {where}: returned {type(s).__name__}, expected LiveState or None")
    p = s.position_ecef_km
    if p is not None and (not isinstance(p, (tuple, list)) or len(p) != 3
                          or not all(isinstance(x, (int, float)) and math.isfinite(x) for x in p)):
        raise ContractError(f"{name} {where}: position_ecef_km must be None or 3 finite numbers, got {p!r}")
    if not isinstance(s.values, dict):
        raise ContractError(f"{name} {where}: values must be a dict, got {type(s.values).__name__}")
    for k, v in s.values.items():
        if type(k) is not str or not k or not isinstance(v, (int, float, str)):
            raise ContractError(f"{name} {where}: value {k!r}: {v!r} is not a name -> int, float or str")
    if s.level not in (0, 1, 2) or type(s.level) is not int:
        raise ContractError(f"{name} {where}: level must be 0, 1 or 2, got {s.level!r}")
    if not isinstance(s.message, str):
        raise ContractError(f"{name} {where}: message must be a string, got {type(s.message).__name__}")
    return s


def is_event_driven(p) -> bool:
    """True when ``p`` is called only for an inbox or a due wakeup (``p.event_driven is True``)."""
    return getattr(p, "event_driven", False) is True


def must_step(event_driven: bool, has_inbox: bool, wakeup_ns: int | None, t_ns: int) -> bool:
    """Whether a participant is called at the step at ``t_ns`` (``wakeup_ns``: its standing wakeup)."""
    return not event_driven or has_inbox or (wakeup_ns is not None and wakeup_ns <= t_ns)


def failed(name: str, where: str, exc: BaseException) -> EngineError:
    """The error for an exception ``exc`` raised by participant ``name`` in ``where``.

    A stop signal that arrived inside compiled code comes out as another exception with the
    interrupt as its cause (CPython: "SystemError: ... returned a result with an exception set"):
    then the interrupt itself is raised here, so the run is stopped, not failed
    (tests/unit/test_stop_signals.py)."""
    seen, cause = set(), exc
    while cause is not None and id(cause) not in seen:
        if isinstance(cause, KeyboardInterrupt):
            raise cause
        seen.add(id(cause))
        cause = cause.__cause__ or cause.__context__
    return EngineError(f"{name} failed in {where}: {type(exc).__name__}: {exc}")


def next_step_ns(t_ns: int, wakeups: Iterable[int | None], max_step_ns: int, horizon_ns: int) -> int:
    """The step rule: ``max(t + 1, min(wakeups, t + max_step, horizon))`` (``None`` wakeups ignored)."""
    nxt = t_ns + max_step_ns
    if horizon_ns < nxt:
        nxt = horizon_ns
    for w in wakeups:
        if w is not None and w < nxt:
            nxt = w
    return nxt if nxt > t_ns else t_ns + 1
