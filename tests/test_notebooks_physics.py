"""The physics notebooks (the joint on its bench, speed and error, a mechanism of one's own, the
mission's life) execute end to end at their small size and print numbers that make sense."""

from _notebooks import execute as _execute, number as _number


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


def test_own_mechanism_notebook_executes(monkeypatch, tmp_path):
    """The engineer's path on a mechanism of their own: scene file -> 99 % design -> proposal.toml
    read back -> verified yield -> trade-off points (small size: the wiring, not the numbers)."""
    monkeypatch.setenv("TOLERAX_OUT", str(tmp_path))
    outputs = "".join(_execute(monkeypatch, "own_mechanism.ipynb", "TOLERAX_OWN_SIZE"))
    assert "small {" in outputs and "reflector mass 12.0 kg" in outputs
    assert "azimuth.carrier_clearance (given) | 60.0 | 8.0 |" in outputs  # the bought-in bearing kept its zone
    assert (tmp_path / "proposal.toml").exists() and "verified yield" in outputs
    assert outputs.count("requirement ") >= 2 and "6 of 6 samples used" in outputs


def test_mission_life_notebook_executes(monkeypatch):
    """Pointing over the mission's life (small size: one life point of a short window): the
    journals and the flanks grew, the end-of-life RMS is read, every lubricant ran, and the
    committed design_life result is quoted."""
    outputs = "".join(_execute(monkeypatch, "mission_life.ipynb", "TOLERAX_LIFE_SIZE"))
    assert "small {" in outputs
    assert _number(r"largest growth ([\d.e+-]+) um \(", outputs) > 0.0
    assert _number(r"end of life: RMS pointing error ([\d.]+) arcsec", outputs) > 0.0
    assert outputs.count("end-of-life RMS") == 3 and "(a run failed)" not in outputs  # one row per lubricant
    assert "beginning and end of life" in outputs


def test_every_notebook_is_stored_with_its_outputs():
    """GitHub shows a notebook's stored outputs: every notebook is committed executed (at the
    size it defaults to), with at least one plot and no error."""
    import nbformat

    from _notebooks import NOTEBOOKS

    for path in sorted(NOTEBOOKS.glob("*.ipynb")):
        nb = nbformat.read(path, as_version=4)
        outputs = [o for c in nb.cells if c.cell_type == "code" for o in c.get("outputs", [])]
        assert all(c.get("execution_count") for c in nb.cells if c.cell_type == "code"), f"{path.name}: a cell not executed"
        assert not [o for o in outputs if o.get("output_type") == "error"], f"{path.name}: stored with an error"
        assert any("image/png" in o.get("data", {}) for o in outputs), f"{path.name}: no stored plot"
