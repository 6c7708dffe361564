"""The studies notebook executes end to end at its small size (what CI can afford)."""

import pathlib

import nbformat
from nbclient import NotebookClient

NOTEBOOKS = pathlib.Path(__file__).resolve().parent.parent / "notebooks"


def test_paper_studies_notebook_executes(monkeypatch):
    monkeypatch.setenv("TOLERAX_STUDY_SIZE", "small")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(NOTEBOOKS / "paper_studies.ipynb", as_version=4)
    client = NotebookClient(nb, timeout=1200, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOKS)}})
    client.execute()
    outputs = "".join(
        o.get("text", "") for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])
    )
    assert "speed: 2 scenes" in outputs  # ran the small size
    assert "claims agree" in outputs  # and the conclusions table read the committed results
