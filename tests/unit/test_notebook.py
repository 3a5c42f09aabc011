"""The example notebook (docs/api/example.ipynb) runs from top to bottom without an error (nbclient, a
fresh kernel of this interpreter); its cells assert what they show (a drawn CGR route's arrival, the
bag's observations equal to the report's count, the report rebuilt from the bag)."""

from __future__ import annotations

import os
from pathlib import Path

import nbformat
from nbclient import NotebookClient

REPO = Path(__file__).resolve().parents[2]


def test_example_notebook_executes(tmp_path):
    nb = nbformat.read(REPO / "docs" / "api" / "example.ipynb", as_version=4)
    env_path = os.pathsep.join([str(REPO), os.environ.get("PYTHONPATH", "")])
    os.environ["PYTHONPATH"] = env_path
    NotebookClient(nb, timeout=600, kernel_name="python3", resources={"metadata": {"path": str(tmp_path)}}).execute()
    outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
    assert not [o for o in outputs if o.get("output_type") == "error"]
    assert "B 2 52.001" in "".join(o.get("text", "") for o in outputs)
