"""No file in the repository names a document or source file that is not in the repository.

Three checks over every file git tracks (text files only):

* a path into the repository's own folders (``docs/design.md``, a test file,
  ``bringup/scenario/toml/paper.toml``...) names a file or folder that exists;
* a bare document name written in capitals (``README.md``, ``CHANGELOG.md``) exists at the top or
  beside the file naming it, and nothing points outside the repository (``../shared``);
* every relative Markdown link in README.md and docs/ resolves, and a "docs/design.md section N"
  names a section the page has.

Output files a run writes (``report.md``, ``compare.md`` in a run folder) are not documents of the
repository and are not checked.
"""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

REPO = Path(__file__).resolve().parents[2]
TOP = ("docs", "tests", "bringup", "sat_node", "orbit_clock", "msgs_json", "dtn_router", "ground_station",
       "scripts", "bench", "docker", ".ci")
PATH_RE = re.compile(r"(?<![\w./-])((?:{})/[\w./-]*[\w/])".format("|".join(re.escape(t) for t in TOP)))
CAPS_DOC_RE = re.compile(r"(?<![\w./-])([A-Z][A-Z0-9_]+\.md)\b")
MD_LINK_RE = re.compile(r"\]\(([^)\s]+)\)")
SECTION_RE = re.compile(r"docs/design\.md,? sections? (\d+)")
# pages the documentation build generates from the code (docs/hooks.py), relative to docs/
GENERATED_PAGES = {"reference/configuration.md", "reference/cli.md", "changelog.md"}
SKIP_SUFFIXES = {".png", ".svg", ".pdf", ".mcap", ".npz", ".gz", ".whl", ".sqlite", ".bin"}


def _tracked() -> list[Path]:
    out = subprocess.run(["git", "ls-files", "-z"], cwd=REPO, capture_output=True, check=True).stdout
    files = [REPO / p for p in out.decode().split("\0") if p]
    return [f for f in files if f.is_file() and f.suffix not in SKIP_SUFFIXES and "node_modules" not in f.parts]


def _text(f: Path) -> str | None:
    try:
        return f.read_text(encoding="utf-8")
    except UnicodeDecodeError:
        return None


def test_paths_into_the_repository_exist():
    missing = []
    for f in _tracked():
        s = _text(f)
        if s is None or f == Path(__file__):
            continue
        for m in PATH_RE.finditer(s):
            p = m.group(1).rstrip(".")
            if s[m.end():m.end() + 1] in "*{<" or "/NAME" in p or "XXX" in p:
                continue  # a pattern, not a path
            if not (REPO / p).exists():
                missing.append(f"{f.relative_to(REPO)}: {p}")
    assert not missing, "paths to files that do not exist:\n" + "\n".join(sorted(set(missing)))


def test_no_reference_outside_the_repository():
    bad = []
    for f in _tracked():
        s = _text(f)
        if s is None or f == Path(__file__):
            continue
        if "../shared" in s or "/work/shared" in s:
            bad.append(f"{f.relative_to(REPO)}: ../shared")
        for m in CAPS_DOC_RE.finditer(s):
            name = m.group(1)
            if not ((REPO / name).exists() or (f.parent / name).exists()):
                bad.append(f"{f.relative_to(REPO)}: {name}")
    assert not bad, "documents named that are not in the repository:\n" + "\n".join(sorted(set(bad)))


def test_markdown_links_and_design_sections_resolve():
    design = (REPO / "docs" / "design.md").read_text()
    sections = set(re.findall(r"^## (\d+)\.", design, flags=re.MULTILINE))
    bad = []
    docs = [REPO / "README.md", *sorted((REPO / "docs").rglob("*.md"))]
    for f in docs:
        for m in MD_LINK_RE.finditer(f.read_text()):
            target = m.group(1)
            if re.match(r"^[a-z]+:", target) or target.startswith("#"):
                continue
            path = target.split("#", 1)[0]
            generated = (f.parent / path).resolve().relative_to(REPO / "docs").as_posix() \
                if (f.parent / path).resolve().is_relative_to(REPO / "docs") else None
            if path and not (f.parent / path).exists() and generated not in GENERATED_PAGES:
                bad.append(f"{f.relative_to(REPO)}: link {target}")
    for f in _tracked():
        s = _text(f)
        if s is None:
            continue
        for m in SECTION_RE.finditer(s):
            if m.group(1) not in sections:
                bad.append(f"{f.relative_to(REPO)}: docs/design.md section {m.group(1)}")
    assert not bad, "\n".join(sorted(set(bad)))
