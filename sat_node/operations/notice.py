"""Mode notices: a satellite tells its neighbours over the DTN that it stops (or resumes) imaging.

A notice is a bundle payload of compact JSON whose first key is ``"notice"`` (an observation's
inference payload, sat_node/inference.py, starts with ``"src"``, so one look at the first bytes
tells them apart): ``{"notice":"mode","src":SAT,"mode":MODE,"imaging":BOOL,"t_ns":T}``. It is sent
at priority 1 to every other satellite of the constellation when the satellite's imaging ability
changes (sat_node/operations/modes.py ``imaging_allowed``). A satellite that receives one keeps the
newest notice per source (by ``t_ns``) and leaves the satellites that do not image out of its joint
plans (sat_node/scheduler/planner.py ``partners``): it learns this only from the bundle, never
from the other satellite's state.

Oracle: tests/unit/test_operations_modes.py round-trips notices and rejects malformed ones with
one line naming the field; tests/system/test_operations_faults.py sees the neighbours replan.
"""

from __future__ import annotations

import json
from dataclasses import dataclass

from sat_node.operations.modes import MODES

__all__ = ["ModeNotice", "decode_notice", "encode_notice", "is_notice"]

_PREFIX = b'{"notice":'


@dataclass(frozen=True)
class ModeNotice:
    src: str
    mode: str
    imaging: bool
    t_ns: int


def encode_notice(n: ModeNotice) -> bytes:
    return json.dumps({"notice": "mode", "src": n.src, "mode": n.mode, "imaging": bool(n.imaging),
                       "t_ns": int(n.t_ns)}, separators=(",", ":")).encode()


def is_notice(payload: bytes) -> bool:
    return payload[:len(_PREFIX)] == _PREFIX


def decode_notice(payload: bytes) -> ModeNotice:
    """A notice from a payload; ValueError naming the field when it is not one."""
    try:
        d = json.loads(payload)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ValueError(f"mode notice: not JSON ({exc})") from None
    if not isinstance(d, dict) or d.get("notice") != "mode":
        raise ValueError("mode notice: not a mode notice object")
    src, mode, imaging, t_ns = d.get("src"), d.get("mode"), d.get("imaging"), d.get("t_ns")
    if not isinstance(src, str) or not src:
        raise ValueError(f"mode notice: bad 'src' ({src!r})")
    if mode not in MODES:
        raise ValueError(f"mode notice: bad 'mode' ({mode!r})")
    if not isinstance(imaging, bool):
        raise ValueError(f"mode notice: bad 'imaging' ({imaging!r})")
    if isinstance(t_ns, bool) or not isinstance(t_ns, int) or t_ns < 0:
        raise ValueError(f"mode notice: bad 't_ns' ({t_ns!r})")
    return ModeNotice(src, mode, imaging, t_ns)
