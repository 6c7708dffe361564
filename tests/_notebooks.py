"""Execute a notebook at its small size and read numbers from its printed output (shared by the
notebook tests, which are split over two files so that pytest-xdist can run them on two workers)."""

import pathlib
import re

import jax
import nbformat
from nbclient import NotebookClient

NOTEBOOKS = pathlib.Path(__file__).resolve().parent.parent / "notebooks"


def execute(monkeypatch, name: str, size_variable: str) -> list[str]:
    """Execute `notebooks/<name>` at its small size; the text output of each code cell."""
    monkeypatch.setenv(size_variable, "small")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    # The kernel compiles into, and reads back from, the test run's compilation cache
    # (tests/conftest.py; none where TOLERAX_TEST_CACHE=off): a program a notebook shares with
    # another notebook or with the tests (the same scene at the same settings, e.g.
    # own_mechanism.ipynb's small size and tests/test_cli.py's own-mechanism designs) compiles
    # once per run. JAX reads these variables when the kernel imports it.
    folder = jax.config.jax_compilation_cache_dir
    if folder:
        monkeypatch.setenv("JAX_COMPILATION_CACHE_DIR", folder)
        monkeypatch.setenv("JAX_PERSISTENT_CACHE_MIN_COMPILE_TIME_SECS", "0")
        monkeypatch.setenv("JAX_PERSISTENT_CACHE_MIN_ENTRY_SIZE_BYTES", "0")
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    client = NotebookClient(nb, timeout=1200, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOKS)}})
    client.execute()
    return ["".join(o.get("text", "") for o in c.get("outputs", [])) for c in nb.cells if c.cell_type == "code"]


def number(pattern: str, text: str) -> float:
    """The number captured by `pattern` in a notebook's printed output (exactly one match)."""
    (value,) = re.findall(pattern, text)
    return float(value)
