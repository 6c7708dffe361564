"""Every notebook executes end to end at its small size (what CI can afford), and prints numbers
that make sense."""

import pathlib
import re

import nbformat
from nbclient import NotebookClient

NOTEBOOKS = pathlib.Path(__file__).resolve().parent.parent / "notebooks"
# The claims the conclusions cell of paper_studies.ipynb defines, one `claim(...)` each: speed 7
# (Figs. 5/6 for each driven joint, Fig. 6, Figs. 17-18, Fig. 19, Fig. 20, Figs. 12/13 vs 20),
# radial clearance 2 (Figs. 7/8, each joint), clearance grid 1 (Tables 4-5), backlash 2
# (Figs. 10-11, speed error and torsional vibration), coupling 2 (Table 7, each joint), coupling
# grid 1 (Figs. 15-16).
N_CLAIMS = 15
_SUMMARY = re.compile(r"^(\d+) of (\d+) claims agree$", re.MULTILINE)


def _claims_table(text):
    """("N of M" as (N, M), the claim lines "- [verdict] ...") of a printed conclusions table."""
    (summary,) = _SUMMARY.findall(text)
    rows = [line for line in text.splitlines() if line.startswith("- [")]
    return tuple(map(int, summary)), rows


def _execute(monkeypatch, name: str, size_variable: str) -> list[str]:
    """Execute `notebooks/<name>` at its small size; the text output of each code cell."""
    monkeypatch.setenv(size_variable, "small")
    monkeypatch.setenv("MPLBACKEND", "Agg")
    nb = nbformat.read(NOTEBOOKS / name, as_version=4)
    client = NotebookClient(nb, timeout=1200, kernel_name="python3", resources={"metadata": {"path": str(NOTEBOOKS)}})
    client.execute()
    return ["".join(o.get("text", "") for o in c.get("outputs", [])) for c in nb.cells if c.cell_type == "code"]


def test_paper_studies_notebook_executes(monkeypatch):
    cell_outputs = _execute(monkeypatch, "paper_studies.ipynb", "TOLERAX_STUDY_SIZE")
    outputs = "".join(cell_outputs)
    assert "speed: 2 scenes" in outputs  # ran the small size
    # The conclusions table read the committed full-size results and holds every claim: none
    # skipped for missing results, one row per claim, and "N of M" counts those rows.
    (conclusions,) = [text for text in cell_outputs if _SUMMARY.search(text)]
    (n_agree, n_claims), rows = _claims_table(conclusions)
    assert n_claims == N_CLAIMS
    assert not any(row.startswith("- [not run]") for row in rows), rows
    verdicts = [row.split("]")[0] + "]" for row in rows]
    assert len(rows) == n_claims and set(verdicts) <= {"- [agree]", "- [differ]"}, rows
    assert verdicts.count("- [agree]") == n_agree
    # ... and it is the table recorded in results/claims.md (its output, copied verbatim; 3 of 15
    # agree when this was written): regenerated results must come with their recorded claims.
    recorded = _claims_table((NOTEBOOKS / "results" / "claims.md").read_text())
    assert ((n_agree, n_claims), rows) == recorded


def test_design_and_yield_notebook_executes(monkeypatch):
    outputs = "".join(_execute(monkeypatch, "design_and_yield.ipynb", "TOLERAX_NOTEBOOK_SIZE"))
    assert "small ('azimuth" in outputs  # ran the small size
    assert "4 of 4 samples used" in outputs  # the Monte Carlo ran every unit
    assert "Proposed design" in outputs


def _number(pattern: str, text: str) -> float:
    """The number captured by `pattern` in a notebook's printed output (exactly one match)."""
    (value,) = re.findall(pattern, text)
    return float(value)


def test_joint_on_bench_notebook_executes(monkeypatch):
    outputs = "".join(_execute(monkeypatch, "joint_on_bench.ipynb", "TOLERAX_BENCH_SIZE"))
    assert "size small: 0.3 s from rest" in outputs  # ran the small size
    # Lin & Parker's structure for a ring-fixed stage with 3 equally spaced planets: 15 coordinates
    # = 5 distinct rotational modes (one the 0 Hz rigid rotation) + 5 degenerate translational pairs.
    assert "rigid-body mode 0.000 Hz; 5 rotational modes, 5 translational pairs" in outputs
    # The output starts to move only once the motor has taken up lost motion, and the members start
    # centred, so the lag when the pins land is a positive part of the full lost motion, not all of it.
    fraction = _number(r"fraction (-?[\d.]+) of the joint's lost motion", outputs)
    assert 0.2 < fraction < 1.0, fraction
    assert _number(r"peak planet-pin force ([\d.]+) N", outputs) > 0.1  # the pins landed and carry load
    # The simulated single impact against the closed form; 1e-4 is tests/test_contact.py's bar for
    # the smoothed law (1 nm width) against the exact one.
    assert _number(r"largest \|simulated - closed form\| restitution: ([\d.e+-]+)", outputs) < 1e-4


def test_speed_and_error_notebook_executes(monkeypatch):
    outputs = "".join(_execute(monkeypatch, "speed_and_error.ipynb", "TOLERAX_SPEED_SIZE"))
    assert "size small: sweep over 0.03 s" in outputs  # ran the small size
    assert outputs.count("recorded by: python benchmarks/") == 4  # every recorded result names its command
    # The step the 3 s run settled at is the stability limit of the fastest held mode: the estimate
    # from Tsit5's tableau and the linearised joint agrees within what its approximations allow
    # (bearings as springs, the joint alone, mesh damping as modal damping: a factor of 2).
    ratio = _number(r"ratio observed/predicted ([\d.]+)", outputs)
    assert 0.5 < ratio < 2.0, ratio
    # The sweep ran past the pins' landing (an impact inside the window), and tightening rtol from
    # 1e-4 to 1e-6 took more steps and reduced the error against the rtol 1e-10 reference.
    assert _number(r"peak contact force ([\d.]+) N", outputs) > 0.5
    steps = [_number(rf"rtol {r}: [\d.]+ s, (\d+) steps", outputs) for r in ("0.0001", "1e-06")]
    errors = [_number(rf"rtol {r}: .*output angle error \(arcsec\) ([\d.e+-]+),", outputs) for r in ("0.0001", "1e-06")]
    assert steps[1] > steps[0] and errors[1] < errors[0], (steps, errors)
