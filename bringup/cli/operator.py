"""Live operator requests to a running ROS run: what ``constellation task`` and ``constellation
command`` share (ground_station/operator_requests.py is the gateway's side).

A request is signed under the run's operator key (derived from the run key in ``RUN/run.keys``,
readable by the run's user only), written into ``RUN/operator`` (made by ``constellation run
--live-commands``) and answered by the run's ground gateway at its next step; the answer (the
command ids and the issue time, or a one-line refusal) is printed. Every failure is one line, exit 2.

Checked by tests/unit/test_operator_requests.py (the CLI against a gateway stepped by the test) and
tests/system/test_operator_live.py (a live ROS run).
"""

from __future__ import annotations

import json
import os
import time
from pathlib import Path

from bringup.engine.keys import KEYS_FILE_NAME, RunKeys
from bringup.errors import UserError
from ground_station.operator_requests import OPERATOR_DIR, encode_request, operator_key

__all__ = ["send_request"]


def send_request(out: Path, req: dict, *, wait_s: float = 120.0) -> dict:
    """Send ``req`` to the run in ``out`` and return the gateway's answer (UserError when refused)."""
    out = Path(out)
    if not (out / "run_spec.json").is_file():
        raise UserError(f"{out}: not the folder of a ROS run (no run_spec.json)")
    op_dir = out / OPERATOR_DIR
    if not op_dir.is_dir():
        raise UserError(f"{out}: the run does not take live commands (start it with constellation run "
                        "--engine ros --live-commands)")
    keys = RunKeys.read(out / KEYS_FILE_NAME, env={})  # (one line when the run is over: no keys file)
    name = f"{time.time_ns()}-{os.getpid()}"
    path = op_dir / f"{name}.req"
    try:
        fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL | os.O_NOFOLLOW | os.O_CLOEXEC, 0o600)
    except OSError as exc:
        raise UserError(f"{path}: cannot write the request ({exc.strerror})") from None
    try:
        os.write(fd, encode_request(req, operator_key(keys.run)))
    finally:
        os.close(fd)
    reply = op_dir / f"{name}.reply"
    deadline = time.monotonic() + wait_s
    while time.monotonic() < deadline:
        if reply.is_file():
            ans = json.loads(reply.read_text())
            if not ans.get("ok"):
                raise UserError(f"the run refused the request: {ans.get('error', '?')}")
            return ans
        if not (out / KEYS_FILE_NAME).exists():
            raise UserError(f"{out}: the run ended before it read the request")
        time.sleep(0.2)
    raise UserError(f"{out}: no answer within {wait_s:g} s (the run's ground gateway reads requests at each step)")


def say_answer(kind: str, ans: dict) -> None:
    ids = ans.get("commands") or []
    where = ", ".join(ids) if ids else "none (no ground contact left before the end of the run)"
    print(f"{kind}: issued at {ans['issued_s']:g} s into the run as {where}; it goes up at the next ground "
          "contact (report.json operations.commands.by_command and operations.tasks when the run ends)")
