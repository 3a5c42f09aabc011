"""Run spec: the JSON file every process of a ROS-engine run is started with.

``constellation node --run-spec FILE --role ROLE`` reads it (bringup/cli/node.py); the launcher
(bringup/engine/ros/launcher.py) writes it. It names the scenario (path or name, with overrides: the named options and the ``--set`` texts under ``"set"``), mode, seed,
the roles (one OS process each, besides the ``clock`` role; ``groups`` may give a process several
participant roles) and a participant factory as a dotted path ``"module:function"``;
``function(spec, role) -> list[Participant]`` returns the participants one process role hosts, so
tests can plug in toy participants.
``keys_file`` names the run's keys (bringup/engine/keys.py; written by the launcher, mode 0600) and
``domain_id`` the run's ROS_DOMAIN_ID.
An optional ``prepare`` hook (same form) readies what processes need before they report ready
(the scenario's: bringup/scenario/participants.py prepare, the satellites' numba kernels).
ROS naming: ``namespace`` is pushed in front of every participant node's namespace (as launch's
PushRosNamespace), ``ros_args`` are ROS arguments every node process gets (``-r`` remaps, ...;
bringup/engine/ros/naming.py); :meth:`RunSpec.parameters` are the run settings every participant
node declares, :meth:`RunSpec.live_period_s` how often hosts publish live state.

Oracle: round trip (write -> read is identity) and one-line errors on bad files
(tests/ros/test_launcher.py).
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import Any

import msgspec

from bringup.engine.keys import RunKeys
from bringup.engine.ros.naming import check_namespace
from bringup.errors import UserError
from bringup.scenario.config import load_scenario
from bringup.scenario.overrides import apply_sets

__all__ = ["MAX_DOMAIN_ID", "CLOCK_ROLE", "RunSpec", "load_factory"]

#: the largest ROS_DOMAIN_ID a run may use: DDS (RTPS) ports are 7400 + 250 x domain + offsets, and
#: 232 is the last domain whose ports stay below 65536. A run that leases an id takes one of 1..101,
#: whose ports lie below Linux's ephemeral range (32768 on); a chosen one may be anything in 0..232.
MAX_DOMAIN_ID = 232
CLOCK_ROLE = "clock"


class RunSpec(msgspec.Struct, kw_only=True, forbid_unknown_fields=True):
    factory: str
    roles: list[str]
    scenario: str | None = None
    overrides: dict[str, Any] = {}
    mode: str = "distributed"
    seed: int | None = None
    # Explicit lockstep bounds; None = from the scenario (horizon, lockstep_max_step_s).
    horizon_ns: int | None = None
    max_step_ns: int | None = None
    t0_ns: int = 0
    # Pacing: None = as fast as possible, else sim seconds per wall second.
    real_time_factor: float | None = None
    # A host that does not ack a step within this wall time is reported by name.
    ack_timeout_s: float = 10.0
    # Before step 0 the clock waits this long (wall s) for every host to be ready, naming the ones
    # it waits for every few seconds; None = as long as it takes (hosts then wait for the first step
    # without bound too; the launcher still ends the run when a process dies). Hosts also bound their
    # publishers' discovery by it (60 s when None).
    startup_timeout_s: float | None = 60.0
    # "module:function" run before the run's processes say they are ready: ``function(spec, role)``,
    # once by the launcher with role None before it starts any process (e.g. compile numba kernels
    # into the cache), then in each host process with its role (load them); None = nothing to do.
    prepare: str | None = None
    # Crash/restart: > 0 = the clock waits this long (wall s) for a silent host to come
    # back, the launcher restarts a host that died (at most max_restarts times per role), and hosts
    # checkpoint every step into state_dir (or their participant's own store).
    restart_wait_s: float = 0.0
    max_restarts: int = 0
    state_dir: str | None = None
    bag_dir: str | None = None
    progress_period_s: float = 0.5
    # process role -> the participant roles it hosts (given to the factory one by one); a process
    # role not listed hosts itself
    groups: dict[str, list[str]] = {}
    # The run's keys (bringup/engine/keys.py): an owner-only file with the run key every envelope is
    # authenticated with and the satellites' BPSec key; the launcher writes one when this is None.
    keys_file: str | None = None
    # The run's ROS_DOMAIN_ID (the launcher writes it here; informative: the processes get it in
    # their environment).
    domain_id: int | None = None
    # pushed in front of every participant node's namespace ("" = none; e.g. "/fleet")
    namespace: str = ""
    # ROS arguments for every node process (global in its rclpy context), e.g. ["-r", "sat_12:__ns:=/x/sat_12"]
    ros_args: list[str] = []
    extra: dict[str, Any] = {}

    def members(self, role: str) -> list[str]:
        """The participant roles process ``role`` hosts."""
        return list(self.groups.get(role, [role]))

    def to_file(self, path: Path) -> None:
        path.write_bytes(msgspec.json.format(msgspec.json.encode(self), indent=2))

    @classmethod
    def from_file(cls, path: Path) -> RunSpec:
        try:
            spec = msgspec.json.decode(Path(path).read_bytes(), type=cls)
        except FileNotFoundError:
            raise UserError(f"run spec {path}: no such file") from None
        except (msgspec.DecodeError, msgspec.ValidationError) as exc:
            raise UserError(f"run spec {path}: {exc}") from None
        spec.check(str(path))
        return spec

    def check(self, where: str = "run spec") -> None:
        if not self.roles:
            raise UserError(f"{where}: 'roles' is empty")
        if CLOCK_ROLE in self.roles or len(set(self.roles)) != len(self.roles):
            raise UserError(f"{where}: 'roles' must be unique and must not contain '{CLOCK_ROLE}'")
        if ":" not in self.factory:
            raise UserError(f"{where}: 'factory' must be 'module:function', got {self.factory!r}")
        if self.restart_wait_s < 0 or self.max_restarts < 0:
            raise UserError(f"{where}: 'restart_wait_s' and 'max_restarts' must be >= 0")
        if self.real_time_factor is not None and self.real_time_factor <= 0:
            raise UserError(f"{where}: 'real_time_factor' must be > 0")
        if self.startup_timeout_s is not None and not self.startup_timeout_s > 0:
            raise UserError(f"{where}: 'startup_timeout_s' must be > 0 or null")
        unknown = [g for g in self.groups if g not in self.roles]
        if unknown:
            raise UserError(f"{where}: 'groups' names {unknown[0]!r}, which is not one of the roles")
        hosted = [m for g in self.groups.values() for m in g]
        if len(set(hosted)) != len(hosted) or any(not g for g in self.groups.values()):
            raise UserError(f"{where}: 'groups' must list each participant once, in non-empty groups")
        if self.prepare is not None and ":" not in self.prepare:
            raise UserError(f"{where}: 'prepare' must be 'module:function', got {self.prepare!r}")
        try:
            check_namespace(self.namespace)
        except ValueError as exc:
            raise UserError(f"{where}: 'namespace': {exc}") from None
        if not all(isinstance(a, str) for a in self.ros_args) or "--ros-args" in self.ros_args:
            raise UserError(f"{where}: 'ros_args' must be ROS arguments (strings) without '--ros-args'")

    def keys(self) -> RunKeys:
        """The run's keys, read from ``keys_file`` (one-line UserError when there is none)."""
        if not self.keys_file:
            raise UserError("run spec: no keys_file (the launcher writes the run's keys and names them here)")
        return RunKeys.read(Path(self.keys_file))

    def load_scenario(self):
        """The scenario with overrides (None when the spec names none, e.g. toy runs)."""
        if self.scenario is None:
            return None

        sc = load_scenario(self.scenario).with_catalogue(self.overrides.get("tle") or (), self.overrides.get("omm") or ())
        keys = ("sats", "planes", "hours", "seed", "knowledge", "transiency_min", "gp_spacing_km",
                "joint_planning", "joint_max_partners", "forwarding", "viz_period_s", "regions", "epoch_utc")
        ov = {k: self.overrides.get(k) for k in keys}
        if self.seed is not None:
            ov["seed"] = self.seed
        if any(v is not None for v in ov.values()):
            sc = sc.with_overrides(**ov)
        # ``--set KEY=VALUE`` texts, after the named overrides as on the command line
        # (bringup/cli/common.py scenario_from_args)
        return apply_sets(sc, self.overrides.get("set") or [])

    def epoch_ns(self) -> int:
        """The scenario epoch in Unix ns: the clock of the run's bag and /clock (bringup/recording/bag.py);
        0 when the spec names no scenario (toy runs)."""
        sc = self.load_scenario()
        return 0 if sc is None else sc.epoch_ns

    def live_period_s(self) -> float | None:
        """Sim seconds between two live publications of the hosts (the scenario's ``[viz]
        period_s``); None when the spec names no scenario (toy runs: nothing to show)."""
        sc = self.load_scenario()
        return None if sc is None else float(sc.viz.period_s)

    def parameters(self, role: str, process: str | None = None) -> dict[str, Any]:
        """The run settings the participant node ``role`` declares (read-only ROS parameters):
        ``run.*`` (role, the OS process hosting it, mode, engine, seed, UTC epoch, horizon, step
        bound, pacing, namespace) and,
        with a scenario, its scalar settings by section (``scheduler.replan_period_s``,
        ``isl.rate_bps``, ...; lists of numbers as arrays, tables of tables left out)."""
        horizon, max_step = self.bounds_ns()
        out: dict[str, Any] = {"run.role": role, "run.process": process or role, "run.mode": self.mode, "run.engine": "ros",
                               "run.horizon_s": horizon / 1e9, "run.max_step_s": max_step / 1e9,
                               "run.real_time_factor": float(self.real_time_factor or 0.0),
                               "run.namespace": self.namespace, "run.epoch_ns": self.epoch_ns()}
        sc = self.load_scenario()
        if sc is not None:
            out["run.scenario"] = sc.name
            out["run.seed"] = int(sc.scenario.seed)
            out["run.epoch_utc"] = sc.epoch_iso
            for section, table in msgspec.to_builtins(sc).items():
                if isinstance(table, dict):
                    for k, v in table.items():
                        p = _parameter_value(v)
                        if p is not None:
                            out[f"{section}.{k}"] = p
        return out

    def bounds_ns(self) -> tuple[int, int]:
        """(horizon_ns, max_step_ns): explicit values, else the scenario's."""
        horizon, max_step = self.horizon_ns, self.max_step_ns
        if horizon is None or max_step is None:
            sc = self.load_scenario()
            if sc is None:
                raise UserError("run spec: give horizon_ns and max_step_ns, or a scenario")
            horizon = sc.horizon_ns if horizon is None else horizon
            max_step = int(round(sc.scenario.lockstep_max_step_s * 1e9)) if max_step is None else max_step
        return int(horizon), int(max_step)


def _parameter_value(v):
    """``v`` as a ROS parameter value (bool, int, float, str, or a non-empty list of one of them), or None."""
    if isinstance(v, (bool, int, float, str)):
        return v
    if isinstance(v, list) and v:
        for kind in (bool, int, float, str):
            if all(type(x) is kind for x in v):
                return list(v)
        if all(isinstance(x, (int, float)) and not isinstance(x, bool) for x in v):
            return [float(x) for x in v]
    return None


def load_factory(dotted: str):
    """Import ``"module:function"``; one-line UserError when it is not there."""
    mod_name, _, fn_name = dotted.partition(":")
    try:
        mod = importlib.import_module(mod_name)
    except ImportError as exc:
        raise UserError(f"participant factory {dotted!r}: cannot import {mod_name}: {exc}") from None
    fn = getattr(mod, fn_name, None)
    if not callable(fn):
        raise UserError(f"participant factory {dotted!r}: {mod_name} has no function {fn_name}")
    return fn
