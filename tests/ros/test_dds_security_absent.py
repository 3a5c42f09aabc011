"""The FastDDS in the Jazzy wheels has no DDS Security plugins, so SROS2 cannot be used here.

Why the project authenticates its run traffic itself (msgs_json/auth.py): this checks the fact
the README states, and fails the day a wheel ships the plugins (then SROS2 becomes an option).

Oracles: the shipped libfastrtps holds none of the DDS Security builtin plugin names
(``builtin.PKI-DH`` authentication, ``builtin.AES-GCM-GMAC`` cryptography, ``builtin.Access-Permissions``
access control; what ``strings ... | grep PKI-DH`` looks for); and turning security on the ROS way
(ROS_SECURITY_ENABLE=true with a keystore enclave, strategy Enforce or Permissive) makes node
creation fail with the middleware's message that this FastDDS was built without the security libraries.
"""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

pytestmark = [pytest.mark.ros, pytest.mark.timeout(120)]

_PROBE = """
import rclpy
rclpy.init(args=["--ros-args", "--enclave", "/probe"])
try:
    rclpy.create_node("security_probe")
    print("NODE CREATED")
except Exception as exc:
    print("FAILED:", " ".join(str(exc).split()))
"""


def test_shipped_fastdds_has_no_security_plugins():
    libs = sorted(Path(sys.prefix, "lib").glob("libfastrtps.so.*.*.*"))
    assert libs, f"no libfastrtps under {sys.prefix}/lib"
    data = libs[-1].read_bytes()
    for name in (b"PKI-DH", b"AES-GCM-GMAC", b"Access-Permissions"):
        assert name not in data, f"{libs[-1].name} holds {name!r}: DDS Security may be built in now"
    # the ROS middleware layer knows it: this is the line it fails with (the next test)
    rmw = Path(sys.prefix, "lib", "librmw_fastrtps_shared_cpp.so").read_bytes()
    assert b"This Fast DDS version doesn't have the security libraries" in rmw


@pytest.mark.parametrize("strategy", ["Enforce", "Permissive"])
def test_ros_security_env_fails_to_create_a_node(tmp_path, monkeypatch, strategy):
    enclave = tmp_path / "keystore" / "enclaves" / "probe"
    enclave.mkdir(parents=True)
    for f in ("identity_ca.cert.pem", "cert.pem", "key.pem", "permissions_ca.cert.pem", "governance.p7s",
              "permissions.p7s"):
        (enclave / f).write_text("placeholder: node creation fails before any file is parsed\n")
    from bringup.engine.ros.launcher import child_env, lease_domain_id

    with lease_domain_id() as lease:
        env = child_env(lease.domain_id)
        env.update(ROS_SECURITY_ENABLE="true", ROS_SECURITY_STRATEGY=strategy,
                   ROS_SECURITY_KEYSTORE=str(tmp_path / "keystore"))
        r = subprocess.run([sys.executable, "-c", _PROBE], env=env, capture_output=True, text=True, timeout=90,
                           check=False)
    assert "NODE CREATED" not in r.stdout, r.stdout
    assert "This Fast DDS version doesn't have the security libraries" in r.stdout, (r.stdout, r.stderr[-2000:])
