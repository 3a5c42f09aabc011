"""FastDDS shared-memory cleanup (bringup/engine/ros/shm_cleanup.py): only groups no live process holds go, and
they go whole. Oracle: groups made by hand in a temporary folder, held through this process's own
descriptors and mappings (which /proc shows like any other process's)."""

import mmap
import os

from bringup.engine.ros.shm_cleanup import fastdds_groups, held_names, remove_unheld

PORT_A = ["fastrtps_port7000", "fastrtps_port7000_el", "sem.fastrtps_port7000_mutex"]
PORT_B = ["fastrtps_port12911", "fastrtps_port12911_el", "sem.fastrtps_port12911_mutex"]
SEG_A = ["fastrtps_0a1b2c3d4e5f6071", "fastrtps_0a1b2c3d4e5f6071_el"]
SEG_B = ["fastrtps_ffee000011112222", "fastrtps_ffee000011112222_el"]
OTHER = ["lttng-ust-wait-6", "sem.aavyrU", "fastrtps_notours.txt"]


def _make(folder, names):
    for n in names:
        (folder / n).write_bytes(b"\0" * 4096)


def test_groups():
    g = fastdds_groups(PORT_A + SEG_A + OTHER)
    assert g == {"port:7000": set(PORT_A), "seg:0a1b2c3d4e5f6071": set(SEG_A)}


def test_only_unheld_groups_go_and_whole(tmp_path):
    _make(tmp_path, PORT_A + PORT_B + SEG_A + SEG_B + OTHER)
    # hold port B through its mutex only (mapped, as a named semaphore is), segment B through its lock
    fd_m = os.open(tmp_path / PORT_B[2], os.O_RDWR)
    mm = mmap.mmap(fd_m, 4096)
    os.close(fd_m)
    fd_l = os.open(tmp_path / SEG_B[1], os.O_RDONLY)
    try:
        held = held_names(tmp_path)
        assert PORT_B[2] in held and SEG_B[1] in held and PORT_A[0] not in held
        removed = remove_unheld(tmp_path)
        assert sorted(removed) == sorted(PORT_A + SEG_A)
        assert sorted(os.listdir(tmp_path)) == sorted(PORT_B + SEG_B + OTHER)
    finally:
        mm.close()
        os.close(fd_l)
    # released: now they go too, and what is not FastDDS's stays
    assert sorted(remove_unheld(tmp_path)) == sorted(PORT_B + SEG_B)
    assert sorted(os.listdir(tmp_path)) == sorted(OTHER)


def test_missing_folder_is_nothing(tmp_path):
    assert remove_unheld(tmp_path / "absent") == []
