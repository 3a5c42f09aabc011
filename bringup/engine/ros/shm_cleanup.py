"""Remove the FastDDS shared-memory files in /dev/shm that no live process holds.

FastDDS's shared-memory transport (on in every ROS process here: rmw_fastrtps adds it for
``ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST``, whatever the XML profile or FASTDDS_BUILTIN_TRANSPORTS
say - measured) keeps, per participant, a segment ``fastrtps_<hex>`` (+ ``_el`` lock file) and a port
queue ``fastrtps_port<N>`` (+ ``_el`` and a mutex ``sem.fastrtps_port<N>_mutex``). A process that
leaves without destroying its participant - our node processes do, on purpose (bringup/engine/ros/host.py:
FastDDS 2.14 can deadlock there), and every SIGKILL in the fault tests - leaves them behind.

What hangs a later run (seen in CI, diagnosed with ``py-spy dump --native``): a process killed while
FastDDS was creating its port leaves ``fastrtps_port<N>`` empty (0 bytes). Participants take the
shared-memory ports 7000, 7001, ... in turn, and the next one to reach N opens that file with boost's
``open_or_create``, which spins forever waiting for the dead creator to initialise it: that process
never comes up and the clock reports "hosts not ready". Only removing the file ends it.

:func:`remove_unheld` removes a file group (a segment with its lock, or a port with its lock and
mutex) only when no member is mapped or open by any live process (read from /proc/*/maps and
/proc/*/fd), so files of runs still going stay. Removing a port's queue but not its mutex left
inconsistent state in an earlier attempt: groups go whole or not at all. A live participant always
holds its files (the descriptor from creation, then the mapping; a lock file stays open), so files of
runs still going stay. The launcher runs it before every run (bringup/engine/ros/launcher.py), the test session
at its start (tests/conftest.py); by hand: ``python -m bringup.engine.ros.shm_cleanup``.

How we know it is right: tests/unit/test_shm_cleanup.py builds groups in a temporary folder, holds
some (an open descriptor, a mapping) and checks that exactly the unheld groups go;
tests/ros/test_launcher.py plants empty port files where a run's participants look first and the run
completes (it hung until the test's timeout without the launcher's cleanup).
"""

from __future__ import annotations

import os
import re
from pathlib import Path

__all__ = ["SHM_DIR", "fastdds_groups", "held_names", "remove_unheld"]

SHM_DIR = Path("/dev/shm")
_SEG = re.compile(r"^fastrtps_([0-9a-f]+)(_el)?$")
_PORT = re.compile(r"^(?:sem\.)?fastrtps_port(\d+)(?:_el|_mutex)?$")


def fastdds_groups(names) -> dict[str, set[str]]:
    """FastDDS file names grouped by what they belong to (``seg:<hex>`` or ``port:<N>``)."""
    groups: dict[str, set[str]] = {}
    for n in names:
        m = _PORT.match(n)
        if m:
            groups.setdefault(f"port:{m.group(1)}", set()).add(n)
            continue
        m = _SEG.match(n)
        if m:
            groups.setdefault(f"seg:{m.group(1)}", set()).add(n)
    return groups


def held_names(folder: Path = SHM_DIR) -> set[str]:
    """Names in ``folder`` that a live process has mapped or open."""
    prefix = str(folder).rstrip("/") + "/"
    held: set[str] = set()
    for pid in os.listdir("/proc"):
        if not pid.isdigit():
            continue
        try:
            with open(f"/proc/{pid}/maps") as fh:
                for line in fh:
                    i = line.find(prefix)
                    if i >= 0:
                        held.add(line[i + len(prefix):].split(" ")[0].rstrip("\n"))
            fd_dir = f"/proc/{pid}/fd"
            for fd in os.listdir(fd_dir):
                try:
                    target = os.readlink(f"{fd_dir}/{fd}")
                except OSError:
                    continue
                if target.startswith(prefix):
                    held.add(target[len(prefix):].split(" ")[0])
        except OSError:  # the process left, or is not ours to read
            continue
    return held


def remove_unheld(folder: Path = SHM_DIR) -> list[str]:
    """Remove every FastDDS file group in ``folder`` with no member held; returns the names removed."""
    folder = Path(folder)
    try:
        names = os.listdir(folder)
    except OSError:
        return []
    groups = fastdds_groups(names)
    if not groups:
        return []
    held = held_names(folder)
    removed = []
    for members in groups.values():
        if members & held:
            continue
        for n in sorted(members):
            try:
                (folder / n).unlink()
                removed.append(n)
            except OSError:
                pass
    return removed


if __name__ == "__main__":
    gone = remove_unheld()
    print(f"removed {len(gone)} FastDDS shared-memory files no live process holds from {SHM_DIR}")
