"""Build the ROS 2 interface packages the Jazzy wheels on PyPI lack (tf2_msgs) and pip-install them.

The ``ros-jazzy-*`` wheels (ros-jazzy-common-interfaces) bring geometry_msgs, sensor_msgs,
visualization_msgs and diagnostic_msgs, but no ``tf2_msgs``, so no rclpy node of a plain pip install
can publish ``/tf``. The wheels do bring ROS's own interface generators (rosidl_generator_c/py,
rosidl_typesupport_c/fastrtps_c/introspection_c, rosidl_generator_type_description) with their
templates, headers and libraries. This script runs those generators on
``scripts/ros_interfaces/tf2_msgs`` (TFMessage: ``geometry_msgs/TransformStamped[] transforms``, as in
ROS 2 Jazzy's geometry2) and compiles what colcon + CMake would, with the C and C++ compilers alone:

  libtf2_msgs__rosidl_generator_c.so            message struct, init/fini/copy, type hash/description
  libtf2_msgs__rosidl_typesupport_fastrtps_c.so CDR (de)serialisation for rmw_fastrtps_cpp
  libtf2_msgs__rosidl_typesupport_introspection_c.so
  libtf2_msgs__rosidl_typesupport_c.so          the dispatcher rclpy asks (finds the two above)
  libtf2_msgs__rosidl_generator_py.so           Python <-> C conversion
  tf2_msgs/tf2_msgs_s__rosidl_typesupport_*.so  the Python extension modules

and packs them as a wheel (``agile-dtn-tf2-msgs``; libraries under the venv's ``lib/`` like the
Jazzy wheels', the .idl/.msg/type description under ``share/tf2_msgs``) that pip installs, so
``pip uninstall agile-dtn-tf2-msgs`` removes it again. Idempotent: it does nothing when
``tf2_msgs.msg.TFMessage`` already imports (``--force`` rebuilds).

Needs a C and a C++ compiler (``CC``/``CXX``, default cc/c++) and the Python headers; without them it
exits 1 with one line saying what is missing (scripts/setup.sh then warns that live /tf is off).

How we know it is right (tests/ros/test_tf2_msgs.py): a TFMessage published by one rclpy context
reaches another over DDS; the type hash the graph reports is ROS 2 Jazzy's own for
tf2_msgs/msg/TFMessage (RIHS01_e369d0f0..., as ``ros2 topic info -v /tf`` prints on Jazzy); rosbags
(an independent serializer) reads our CDR as the same message and we read its.
"""

from __future__ import annotations

import argparse
import base64
import hashlib
import logging
import os
import shutil
import subprocess
import sys
import sysconfig
import tempfile
import time
import zipfile
from pathlib import Path

HERE = Path(__file__).resolve().parent
PACKAGE = "tf2_msgs"
SOURCE = HERE / "ros_interfaces" / PACKAGE
DIST = "agile_dtn_tf2_msgs"
VERSION = "0.36.0"
TYPESUPPORTS = ("c", "fastrtps_c", "introspection_c")


class BuildError(RuntimeError):
    pass


def _run(cmd: list[str], cwd: Path) -> None:
    r = subprocess.run(cmd, check=False, cwd=cwd, capture_output=True, text=True)
    if r.returncode != 0:
        tail = (r.stderr or r.stdout).strip().splitlines()[-5:]
        raise BuildError(f"{cmd[0]} failed ({' '.join(cmd[:2])} ...): " + " | ".join(tail))


def generate(work: Path) -> Path:
    """Run the rosidl generators into ``work/gen/<generator>/tf2_msgs``; returns ``work/gen``."""
    # the generators find their templates through the ament index of the venv (the wheels' share/)
    os.environ["AMENT_PREFIX_PATH"] = sys.prefix
    # the wheels register rosidl_cli's entry points twice (egg-info and dist-info); it warns, harmlessly
    logging.getLogger("rosidl_cli.entry_points").setLevel(logging.ERROR)
    from rosidl_cli.command.hash.api import generate_type_hashes
    from rosidl_generator_c.cli import GenerateC
    from rosidl_generator_py.cli import GeneratePython
    from rosidl_typesupport_c.cli import GenerateCTypesupport
    from rosidl_typesupport_fastrtps_c.cli import GenerateFastRTPSCTypesupport
    from rosidl_typesupport_introspection_c.cli import GenerateIntrospectionCTypesupport

    src = work / "src"
    shutil.copytree(SOURCE, src / PACKAGE)
    share = str(Path(sys.prefix) / "share")
    files = [f"{src / PACKAGE}:msg/TFMessage.idl"]
    gen = work / "gen"
    td = generate_type_hashes(package_name=PACKAGE, interface_files=files, include_paths=[share],
                              output_path=gen / "type_description")
    GenerateC("c").generate(PACKAGE, files, [share], gen / "c" / PACKAGE, type_description_files=td)
    # GeneratePython's default typesupports come from the ament index; name ours explicitly
    GeneratePython("py", typesupport_implementations=[f"rosidl_typesupport_{t}" for t in TYPESUPPORTS]
                   ).generate(PACKAGE, files, [share], gen / "py" / PACKAGE)
    GenerateCTypesupport("typesupport_c").generate(PACKAGE, files, [share], gen / "typesupport_c" / PACKAGE)
    GenerateFastRTPSCTypesupport("typesupport_fastrtps_c").generate(
        PACKAGE, files, [share], gen / "typesupport_fastrtps_c" / PACKAGE)
    GenerateIntrospectionCTypesupport("typesupport_introspection_c").generate(
        PACKAGE, files, [share], gen / "typesupport_introspection_c" / PACKAGE)
    return gen


def compile_all(gen: Path, out: Path) -> tuple[list[Path], list[Path]]:
    """Compile the generated sources; returns (shared libraries, Python extension modules)."""
    prefix = Path(sys.prefix)
    py_inc = Path(sysconfig.get_paths()["include"])
    if not (py_inc / "Python.h").exists():
        raise BuildError(f"no Python headers ({py_inc}/Python.h missing; on Debian: apt-get install python3-dev)")
    import numpy
    cc = os.environ.get("CC", "cc")
    cxx = os.environ.get("CXX", "c++")
    for c in (cc, cxx):
        if shutil.which(c) is None:
            raise BuildError(f"no compiler {c!r} on PATH (set CC/CXX, or on Debian: apt-get install gcc g++)")
    inc = [f"-I{gen / d}" for d in ("c", "typesupport_fastrtps_c", "typesupport_introspection_c")]
    inc += [f"-I{prefix / 'include'}"] + [f"-I{d}" for d in sorted((prefix / "include").iterdir()) if d.is_dir()]
    inc += [f"-I{py_inc}", f"-I{numpy.get_include()}"]
    libdir = out / "lib"
    libdir.mkdir(parents=True)
    link = [f"-L{prefix / 'lib'}", f"-L{libdir}", "-Wl,-rpath,$ORIGIN"]
    msg = gen / "c" / PACKAGE / "msg"
    p = PACKAGE
    libs = [
        (cc, [*sorted((msg / "detail").glob("*.c"))], f"lib{p}__rosidl_generator_c.so",
         ["-lgeometry_msgs__rosidl_generator_c", "-lrosidl_runtime_c", "-lrcutils"]),
        (cxx, [*sorted((gen / "typesupport_fastrtps_c" / p / "msg" / "detail").glob("*.cpp"))],
         f"lib{p}__rosidl_typesupport_fastrtps_c.so",
         [f"-l{p}__rosidl_generator_c", "-lgeometry_msgs__rosidl_typesupport_fastrtps_c",
          "-lgeometry_msgs__rosidl_generator_c", "-lrosidl_typesupport_fastrtps_c",
          "-lrosidl_typesupport_fastrtps_cpp", "-lrosidl_runtime_c", "-lfastcdr", "-lrmw", "-lrcutils"]),
        (cc, [*sorted((gen / "typesupport_introspection_c" / p / "msg" / "detail").glob("*.c"))],
         f"lib{p}__rosidl_typesupport_introspection_c.so",
         [f"-l{p}__rosidl_generator_c", "-lgeometry_msgs__rosidl_typesupport_introspection_c",
          "-lrosidl_typesupport_introspection_c", "-lrosidl_runtime_c"]),
        (cxx, [*sorted((gen / "typesupport_c" / p / "msg").glob("*.cpp"))], f"lib{p}__rosidl_typesupport_c.so",
         [f"-l{p}__rosidl_generator_c", "-lrosidl_typesupport_c", "-lrosidl_runtime_c", "-lrcpputils", "-lrcutils"]),
        (cc, [gen / "py" / p / "msg" / "_tf_message_s.c"], f"lib{p}__rosidl_generator_py.so",
         [f"-l{p}__rosidl_generator_c", f"-l{p}__rosidl_typesupport_c", "-lgeometry_msgs__rosidl_generator_py",
          "-lgeometry_msgs__rosidl_generator_c", "-lrosidl_runtime_c", "-lrcutils"]),
    ]
    built = []
    for compiler, sources, name, deps in libs:
        if not sources:
            raise BuildError(f"the generators made no sources for {name}")
        std = ["-std=c++17"] if compiler == cxx else []
        _run([compiler, "-shared", "-fPIC", "-O2", *std, *inc, *map(str, sources), "-o", str(libdir / name),
              *link, *deps], gen)
        built.append(libdir / name)
    ext_dir = out / "py" / p
    ext_dir.mkdir(parents=True)
    suffix = sysconfig.get_config_var("EXT_SUFFIX")
    exts = []
    for ts in TYPESUPPORTS:
        target = ext_dir / f"{p}_s__rosidl_typesupport_{ts}{suffix}"
        _run([cc, "-shared", "-fPIC", "-O2", *inc, str(gen / "py" / p / f"_{p}_s.ep.rosidl_typesupport_{ts}.c"),
              "-o", str(target), f"-L{prefix / 'lib'}", f"-L{libdir}", "-Wl,-rpath,$ORIGIN/../../../..",
              f"-l{p}__rosidl_generator_py", f"-l{p}__rosidl_typesupport_{ts}", f"-l{p}__rosidl_generator_c",
              "-lrosidl_runtime_c"], gen)
        exts.append(target)
    return built, exts


def _record_line(arc: str, data: bytes) -> str:
    digest = base64.urlsafe_b64encode(hashlib.sha256(data).digest()).rstrip(b"=").decode()
    return f"{arc},sha256={digest},{len(data)}"


def pack_wheel(gen: Path, libs: list[Path], exts: list[Path], dest: Path) -> Path:
    """A wheel holding the Python package, the libraries (data -> <venv>/lib) and the interface files."""
    tag = sysconfig.get_platform().replace("-", "_").replace(".", "_")
    py = f"cp{sys.version_info.major}{sys.version_info.minor}"
    whl = dest / f"{DIST}-{VERSION}-{py}-{py}-{tag}.whl"
    data = f"{DIST}-{VERSION}.data/data"
    info = f"{DIST}-{VERSION}.dist-info"
    files: dict[str, bytes] = {
        f"{PACKAGE}/__init__.py": b"",
        f"{PACKAGE}/msg/__init__.py": (gen / "py" / PACKAGE / "msg" / "__init__.py").read_bytes(),
        f"{PACKAGE}/msg/_tf_message.py": (gen / "py" / PACKAGE / "msg" / "_tf_message.py").read_bytes(),
    }
    for e in exts:
        files[f"{PACKAGE}/{e.name}"] = e.read_bytes()
    for lib in libs:
        files[f"{data}/lib/{lib.name}"] = lib.read_bytes()
    share = f"{data}/share"
    files[f"{share}/{PACKAGE}/package.xml"] = (SOURCE / "package.xml").read_bytes()
    for f in ("TFMessage.msg", "TFMessage.idl"):
        files[f"{share}/{PACKAGE}/msg/{f}"] = (SOURCE / "msg" / f).read_bytes()
    files[f"{share}/{PACKAGE}/msg/TFMessage.json"] = (gen / "type_description" / "msg" / "TFMessage.json").read_bytes()
    # the ament index entries colcon would install (ros2 tools and rosidl -I find the package by them)
    files[f"{share}/ament_index/resource_index/packages/{PACKAGE}"] = b""
    files[f"{share}/ament_index/resource_index/rosidl_interfaces/{PACKAGE}"] = b"msg/TFMessage.idl\nmsg/TFMessage.msg\n"
    files[f"{info}/METADATA"] = (
        f"Metadata-Version: 2.1\nName: {DIST.replace('_', '-')}\nVersion: {VERSION}\n"
        "Summary: tf2_msgs/msg/TFMessage (ROS 2 Jazzy) generated and compiled locally by "
        "agile-dtn-constellation's scripts/build_ros_interfaces.py\n").encode()
    files[f"{info}/WHEEL"] = (f"Wheel-Version: 1.0\nGenerator: build_ros_interfaces\nRoot-Is-Purelib: false\n"
                              f"Tag: {py}-{py}-{tag}\n").encode()
    record = [_record_line(a, b) for a, b in files.items()] + [f"{info}/RECORD,,"]
    files[f"{info}/RECORD"] = ("\n".join(record) + "\n").encode()
    with zipfile.ZipFile(whl, "w", zipfile.ZIP_DEFLATED) as z:
        for arc, b in files.items():
            zi = zipfile.ZipInfo(arc, date_time=(2000, 1, 1, 12, 0, 0))
            zi.external_attr = (0o755 if arc.endswith(".so") else 0o644) << 16
            zi.compress_type = zipfile.ZIP_DEFLATED
            z.writestr(zi, b)
    return whl


def installed() -> bool:
    r = subprocess.run([sys.executable, "-c", "from tf2_msgs.msg import TFMessage; TFMessage()"],
                       check=False, capture_output=True)
    return r.returncode == 0


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--force", action="store_true", help="rebuild even when tf2_msgs already imports")
    ap.add_argument("--wheel-dir", type=Path, default=None, help="keep the wheel here (default: not kept)")
    args = ap.parse_args(argv)
    if not args.force and installed():
        return 0
    t0 = time.monotonic()
    try:
        with tempfile.TemporaryDirectory(prefix="ros_interfaces_") as tmp:
            work = Path(tmp)
            gen = generate(work)
            libs, exts = compile_all(gen, work / "build")
            dest = args.wheel_dir or work
            dest.mkdir(parents=True, exist_ok=True)
            whl = pack_wheel(gen, libs, exts, dest)
            _run([sys.executable, "-m", "pip", "install", "--quiet", "--no-deps", "--force-reinstall", str(whl)], work)
    except (BuildError, ImportError, OSError) as exc:
        print(f"build_ros_interfaces: tf2_msgs not built: {exc}", file=sys.stderr)
        return 1
    if not installed():
        print("build_ros_interfaces: tf2_msgs built and installed but does not import", file=sys.stderr)
        return 1
    print(f"build_ros_interfaces: tf2_msgs built and installed ({time.monotonic() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
