"""The design notebooks execute end to end at their small size (what CI can afford) and print
numbers that make sense (the physics notebooks: test_notebooks_physics.py)."""

import re

from _notebooks import NOTEBOOKS, execute as _execute

# The claims the conclusions cell of paper_studies.ipynb defines, one `claim(...)` each: speed 7
# (Figs. 5/6 for each driven joint, Fig. 6, Figs. 17-18, Fig. 19, Fig. 20, Figs. 12/13 vs 20),
# radial clearance 2 (Figs. 7/8, each joint), clearance grid 1 (Tables 4-5), backlash 2
# (Figs. 10-11, speed error and torsional vibration), coupling 2 (Table 7, each joint), coupling
# grid 1 (Figs. 15-16).
N_CLAIMS = 15
# One table per horizon of the committed full-size rows: 3 s (metrics over 2-3 s) and 20 s (10-20 s).
HORIZONS = ("3 s", "20 s")
_SUMMARY = re.compile(r"^At (\d+ s) \(.*\): (\d+) of (\d+) claims agree$", re.MULTILINE)


def _claims_tables(text):
    """{horizon: ((N, M) of its "N of M" line, its claim lines "- [verdict] ...")} of printed
    conclusions: each table is its summary line and the claim lines up to the next summary."""
    tables, current = {}, None
    for line in text.splitlines():
        match = _SUMMARY.match(line)
        if match:
            current = match.group(1)
            assert current not in tables, f"two tables for {current}"
            tables[current] = ((int(match.group(2)), int(match.group(3))), [])
        elif line.startswith("- [") and current is not None:
            tables[current][1].append(line)
    return tables


def test_paper_studies_notebook_executes(monkeypatch):
    cell_outputs = _execute(monkeypatch, "paper_studies.ipynb", "TOLERAX_STUDY_SIZE")
    outputs = "".join(cell_outputs)
    assert "speed: 2 scenes" in outputs  # ran the small size
    # The conclusions read the committed full-size results at each horizon and hold every claim:
    # none skipped for missing results, one row per claim, and "N of M" counts those rows.
    (conclusions,) = [text for text in cell_outputs if _SUMMARY.search(text)]
    tables = _claims_tables(conclusions)
    assert tuple(tables) == HORIZONS
    for horizon, ((n_agree, n_claims), rows) in tables.items():
        assert n_claims == N_CLAIMS, horizon
        assert not any(row.startswith("- [not run]") for row in rows), rows
        verdicts = [row.split("]")[0] + "]" for row in rows]
        assert len(rows) == n_claims and set(verdicts) <= {"- [agree]", "- [differ]"}, rows
        assert verdicts.count("- [agree]") == n_agree
    # ... and they are the tables recorded in results/claims.md (its output, copied verbatim):
    # regenerated results must come with their recorded claims.
    recorded = (NOTEBOOKS / "results" / "claims.md").read_text()
    assert tables == _claims_tables(recorded)
    (changed,) = re.findall(r"^Verdicts that change between 3 s and 20 s: \d+ of \d+$", conclusions, re.MULTILINE)
    assert changed in recorded.splitlines()


def test_design_and_yield_notebook_executes(monkeypatch):
    outputs = "".join(_execute(monkeypatch, "design_and_yield.ipynb", "TOLERAX_NOTEBOOK_SIZE"))
    assert "small ('azimuth" in outputs  # ran the small size
    assert "4 of 4 samples used" in outputs  # the Monte Carlo ran every unit
    # the proposal's table, headed by whether it is a proposal (at the small size the optimiser's
    # budget may end before it converges: then the best design reached, said first)
    assert "Proposed design" in outputs or "**Not a proposal:" in outputs
