"""`constellation czml BAG --out DIR`: the run on a globe - a CZML document and a CesiumJS page.

Writes ``DIR/run.czml`` (bringup/analysis/czml.py: satellites and their orbits, ground stations,
looks coloured by value, ISL and ground links while in contact, bundle transfers, on the scenario's
UTC clock), ``DIR/index.html`` (a CesiumJS viewer of it; no Cesium ion token: the imagery ships with
CesiumJS) and ``DIR/package.json`` + ``package-lock.json`` (CesiumJS pinned). Viewing needs CesiumJS
from npm once - ``npm ci --prefix DIR`` - and a local web server: ``--serve PORT`` serves DIR on
127.0.0.1 (a browser cannot load the document from a file:// page).

Checked by tests/unit/test_czml.py (the command's files) and tests/browser/test_globe.py (the page in
headless Chromium).
"""

from __future__ import annotations

import functools
import http.server
import importlib.resources
import shutil
from pathlib import Path

from bringup.analysis.czml import czml_counts, czml_document, read_czml_inputs
from bringup.errors import UserError

GLOBE_FILES = ("index.html", "package.json", "package-lock.json")


def add_arguments(p) -> None:
    p.add_argument("bag", type=Path, help="bag directory (metadata.yaml + .mcap) or its .mcap file")
    p.add_argument("--out", type=Path, required=True, help="folder for run.czml, index.html and package.json")
    p.add_argument("--footprint-km", type=float, default=8.0, help="diameter of a look's footprint [km] (default 8)")
    p.add_argument("--look-s", type=float, default=900.0,
                   help="how long a look's footprint stays shown [s] (default 900: one OSSE slot)")
    p.add_argument("--transfer-s", type=float, default=2.0,
                   help="how long a bundle transfer's line stays shown [s] (default 2)")
    p.add_argument("--serve", type=int, default=None, metavar="PORT",
                   help="then serve the folder on http://127.0.0.1:PORT/ until Ctrl-C (needs `npm ci --prefix OUT`)")


def write_globe(bag: Path, out: Path, **kw) -> dict[str, int]:
    """run.czml and the page's files in ``out``; the document's entity counts by kind."""
    inp = read_czml_inputs(bag)
    doc = czml_document(inp, name=str(bag), **kw)
    out.mkdir(parents=True, exist_ok=True)
    tmp = out / ".run.czml.tmp"
    tmp.write_text(doc.dumps(), encoding="utf-8")
    tmp.replace(out / "run.czml")
    src = importlib.resources.files("bringup.analysis") / "globe"
    for name in GLOBE_FILES:
        with importlib.resources.as_file(src / name) as f:
            shutil.copyfile(f, out / name)
    return czml_counts(inp)


def run(args) -> int:
    counts = write_globe(args.bag, args.out, footprint_km=args.footprint_km, look_s=args.look_s,
                         transfer_s=args.transfer_s)
    print(f"czml: {args.out / 'run.czml'}: " + ", ".join(f"{n} {k}" for k, n in counts.items()))
    if args.serve is None:
        print(f"czml: to view it: npm ci --prefix {args.out} && constellation czml {args.bag} --out {args.out} "
              "--serve 8000, then open http://127.0.0.1:8000/")
        return 0
    if not (args.out / "node_modules" / "cesium" / "Build" / "Cesium" / "Cesium.js").is_file():
        raise UserError(f"czml --serve: CesiumJS is not installed in {args.out}: run `npm ci --prefix {args.out}` first")
    handler = functools.partial(http.server.SimpleHTTPRequestHandler, directory=str(args.out))
    with http.server.ThreadingHTTPServer(("127.0.0.1", args.serve), handler) as srv:
        print(f"czml: serving {args.out} on http://127.0.0.1:{srv.server_address[1]}/ (Ctrl-C to stop)", flush=True)
        try:
            srv.serve_forever()
        except KeyboardInterrupt:
            return 130
    return 0
