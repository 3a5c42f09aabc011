"""MkDocs hooks: the pages generated from the code, added to the site at build time.

``reference/configuration.md`` and ``reference/cli.md`` come from bringup/cli/reference.py (the
scenario schema and the argument parsers), and ``changelog.md`` is the repository's CHANGELOG.md, so
none of them can drift from what they describe. Checked by tests/unit/test_docs_site.py.
"""

from __future__ import annotations

from pathlib import Path

from mkdocs.structure.files import File


def on_files(files, config):
    from bringup.cli.reference import cli_reference_md, config_reference_md

    root = Path(config["config_file_path"]).resolve().parent
    pages = {
        "reference/configuration.md": config_reference_md(),
        "reference/cli.md": cli_reference_md(),
        "changelog.md": (root / "CHANGELOG.md").read_text(encoding="utf-8"),
    }
    for uri, text in pages.items():
        files.append(File.generated(config, uri, content=text))
    return files
