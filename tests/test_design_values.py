"""The design as values (`tolerax.design.spec`, `tolerax.design.solvers`, `Check`):
`propose_design(problem, solver, *, check, ...)` takes few options; a new design method is one
class with no edit to the loop or to `propose_design`; the defaults reach the recipes that
verified (the jitter's response surface); the former signature still gives the former answer
for one release, with a warning naming what replaces each keyword."""

import dataclasses
import inspect
from typing import ClassVar
import warnings

import numpy as np
import pytest

import tolerax as tx
from tolerax.design import legacy, propose as _propose
from tolerax.design.loop import ConstrainedDesign, solve_design

import _responses as R
from test_solvers import PenaltyAdam

SLOPES = np.array([4.0e6, 8.0e6, 0.5e6, 2.0e6])  # arcsec/m


def test_propose_design_takes_at_most_five_keyword_options():
    """The problem, the solver and the check are values; what is left are at most five options
    (the former keywords only through `**deprecated`), and no string selects a method."""
    params = inspect.signature(tx.propose_design).parameters
    options = [p for p in params.values() if p.default is not inspect.Parameter.empty]
    assert len(options) <= 5 and [p.name for p in options] == ["solver", "check", "progress", "callback"]
    assert [p.name for p in params.values() if p.kind is inspect.Parameter.VAR_KEYWORD] == ["deprecated"]
    assert not any(isinstance(p.default, str) for p in params.values())
    # Its answer is small data: one outcome per requirement, none of them copied flat onto the report.
    fields = {f.name for f in dataclasses.fields(tx.DesignReport)}
    assert "outcomes" in fields and len(fields) <= 19
    assert not fields & {"objective", "requirement", "constraint_active", "multiplier", "sensitivity", "checks", "jitter",
                         "solved_for"}


def test_the_library_is_modules_of_at_most_500_lines_without_run_history():
    """The library's modules stay readable (at most 500 lines each) and carry no run history:
    no link to a benchmark's result file or an archive (the claims live in benchmarks/README.md)."""
    import pathlib
    import re

    src = pathlib.Path(tx.__file__).parent
    long = {str(p.relative_to(src)): n for p in src.rglob("*.py") if (n := len(p.read_text().splitlines())) > 500}
    assert not long, f"modules over 500 lines: {long}"
    linked = [f"{p.relative_to(src)}:{k + 1}" for p in src.rglob("*.py")
              for k, line in enumerate(p.read_text().splitlines()) if re.search(r"results/|archive/", line)]
    assert not linked, f"src/ links run results: {linked}"


@dataclasses.dataclass(frozen=True)
class PenaltyMethod(tx.AbstractDesignMethod):
    """A design method of one's own: tests/test_solvers.py's projected Adam on a quadratic
    penalty, at one smoothing width, run by the one design loop (`solve_design`)."""

    widths: tuple = (1e-6,)
    steps: int = 40
    several = False
    fitted = False
    restarts = False

    def solve(self, problem, requirement, tol, *, x0=None, step=None, progress=False, callback=None):
        constrained = ConstrainedDesign(problem.objective, problem.features, requirement, tol, problem.lower, problem.upper,
                                        problem.cost_model, problem.draws, self.widths[-1])
        return solve_design(constrained, PenaltyAdam(), problem.x0 if x0 is None else x0, max_steps=self.steps, progress=progress)


def test_scipy_slsqp_is_a_solver_value_and_finds_the_same_optimum(monkeypatch):
    """`tx.SLSQP` (SciPy's SLSQP with the exact gradients, the reference a method is raced
    against) through `propose_design`: on closed-form units whose RMS and peak are linear in the
    zones, one requirement and two at once, the same cost as the sequential method's to 1 %
    (two methods, one optimum), each constraint met within its tolerance by the objective
    evaluated again, and SciPy's multipliers the shadow prices the sequential method reports (to
    5 %; from the stationarity condition where SciPy gives none)."""
    scene = R.scan_scene()
    weights = 0.5 * np.asarray(tx.lost_motion_weights(scene))
    line = R.Line(scene, 1000.0, weights, 100e-6)
    built = _propose.design_problem(line, n_draws=2)
    requirement = 0.5 * float(built.value(width=1e-6))
    problem = tx.ToleranceProblem(line, requirement, tx.MeanPlusKStd(units=2))
    ref = tx.propose_design(problem, tx.SLSQP(widths=(1e-6,)))
    ours = tx.propose_design(problem, tx.Sequential(widths=(1e-6,)))
    assert ref.status == ours.status == "converged", ref.diagnosis
    assert ref.cost == pytest.approx(ours.cost, rel=0.01)
    assert float(built.value(ref.result.x, 1e-6)) <= requirement * 1.01
    assert float(ref.result.multiplier[0]) == pytest.approx(float(ours.result.multiplier[0]), rel=0.05)
    two = R.Line(scene, [900.0, 2000.0], [weights, 2 * weights], 100e-6, names=("pointing_rms", "pointing_peak"))
    both = tx.ToleranceProblem(two, [tx.Requirement("pointing_rms", 600.0), tx.Requirement("pointing_peak", 1500.0)],
                               tx.MeanPlusKStd(units=2))
    ref, ours = tx.propose_design(both, tx.SLSQP(widths=(1e-6,))), tx.propose_design(both, tx.Sequential(widths=(1e-6,)))
    assert ref.cost == pytest.approx(ours.cost, rel=0.01) and ref.status == "converged", ref.diagnosis
    assert all(o.objective <= o.requirement.limit * 1.01 for o in ref.outcomes)
    # The peak's gradient is twice the RMS's (parallel): it is slack at the optimum (1400 < 1500),
    # so its price is 0 and the RMS's carries the cost (a fit over both once priced the peak).
    assert float(ref.outcomes[1].objective) == pytest.approx(1400.0, rel=1e-6) and float(ours.result.multiplier[1]) == 0.0
    np.testing.assert_allclose(ref.result.multiplier, ours.result.multiplier, rtol=0.05, atol=1e-6 * np.max(ours.result.multiplier))
    assert ref.result.history.objective.shape == (1, 2) and ref.result.history.multiplier.shape == (1, 2)
    # An older SciPy returns no multipliers: they come from the stationarity condition instead.
    import scipy.optimize

    plain = scipy.optimize.minimize

    def without_multipliers(*args, **kwargs):
        found = plain(*args, **kwargs)
        del found["multipliers"]
        return found

    monkeypatch.setattr(scipy.optimize, "minimize", without_multipliers)
    again = tx.propose_design(both, tx.SLSQP(widths=(1e-6,)))
    np.testing.assert_allclose(again.result.multiplier, ref.result.multiplier, rtol=1e-3, atol=1e-6 * np.max(ours.result.multiplier))
    with pytest.raises(ValueError, match="max_iterations must be >= 1"):
        tx.SLSQP(max_iterations=0)


def test_the_mean_plus_k_std_gradient_is_a_diffrax_adjoint_not_a_string():
    """`MeanPlusKStd(adjoint=...)` takes diffrax's own adjoints: forward mode (`None`, the
    default, or `diffrax.ForwardMode()`) and checkpointed reverse mode give the same design on a
    closed-form unit (one gradient, two ways to take it); the former string warns and maps to
    them; anything else is refused naming what to give."""
    import diffrax

    line = R.Line(R.scan_scene(), 1000.0, 0.5 * np.asarray(tx.lost_motion_weights(R.scan_scene())), 100e-6)
    requirement = 0.5 * float(_propose.design_problem(line, n_draws=2).value(width=1e-6))

    def design(statistic):
        return tx.propose_design(tx.ToleranceProblem(line, requirement, statistic), tx.Sequential(widths=(1e-6,)))

    forward, reverse = design(tx.MeanPlusKStd(units=2)), design(tx.MeanPlusKStd(units=2, adjoint=diffrax.RecursiveCheckpointAdjoint()))
    assert forward.status == reverse.status == "converged"
    np.testing.assert_allclose(reverse.band, forward.band, rtol=1e-9)
    with pytest.warns(DeprecationWarning, match="adjoint="):
        old = tx.MeanPlusKStd(units=2, gradient="reverse")
    assert isinstance(old.adjoint, diffrax.RecursiveCheckpointAdjoint) and old.gradient is None
    with pytest.warns(DeprecationWarning):
        assert tx.MeanPlusKStd(1.0, 2, None, "forward").adjoint is None  # the former fourth place
    with pytest.raises(ValueError, match="'forward' or 'reverse'.*diffrax.ForwardMode"):
        tx.MeanPlusKStd(adjoint="checkpointed")
    with pytest.raises(TypeError, match="must be a diffrax adjoint"):
        tx.MeanPlusKStd(adjoint=diffrax.RecursiveCheckpointAdjoint)  # the class, not an adjoint
    with pytest.warns(DeprecationWarning, match="design_problem"):  # the builder's former keyword too
        built = _propose.design_problem(line, n_draws=2, gradient="reverse")
    assert isinstance(built.objective.objective.adjoint, diffrax.RecursiveCheckpointAdjoint)
    with pytest.raises(TypeError, match="RobustPointing: adjoint must be a diffrax adjoint"):
        _propose.design_problem(line, n_draws=2, adjoint="reverse")


def test_a_design_method_of_one_s_own_runs_through_propose_design(capsys):
    """`PenaltyMethod` (above) through `propose_design`, unchanged: on a closed-form unit whose
    RMS is linear in the zones, the proposal meets a requirement half the baseline's (to the
    penalty's 1 %, the objective evaluated again independently) at the same cost as the built-in
    sequential method's to 2 % (two methods, one optimum); a yield's check, which re-solves, is
    refused for a method that does not re-solve. With `progress`, each phase is said as it
    starts, with the time since the design began."""
    line = R.Line(R.scan_scene(), 1000.0, 0.5 * np.asarray(tx.lost_motion_weights(R.scan_scene())), 100e-6)
    problem = tx.ToleranceProblem(line, 1.0, tx.MeanPlusKStd(units=2))
    built = _propose.design_problem(line, n_draws=2)
    requirement = 0.5 * float(built.value(width=1e-6))
    problem = dataclasses.replace(problem, requirements=requirement)
    mine = tx.propose_design(problem, PenaltyMethod())
    capsys.readouterr()
    ours = tx.propose_design(problem, tx.Sequential(widths=(1e-6,)), progress=True)
    said = [line for line in capsys.readouterr().err.splitlines() if line.startswith("propose_design [")]
    assert said[0].startswith("propose_design [0:0") and "the starting design's outputs" in said[0]
    assert any("infeasible first" in line for line in said) and said[-1].endswith(f"done: {ours.status}.")
    # Before the solve, how long it may take: its budget at the pace of the compiled evaluations.
    assert any("solving (Sequential" in line and "the first solve's budget 20 gradients, about " in line for line in said), said
    # A response surface's fits, before the first: its units at the rough pace of the scene's runs.
    pointing = tx.load_scene("scan-azimuth-planetary").objective(jitter_cutoff=20.0)
    one = tx.eta.rough_wall(pointing.scene, pointing.duration, pointing.integrator)
    assert _propose._rough_units(pointing, 64, 6) == (f", roughly {tx.eta.human_seconds(64 * one)} on one core plus "
                                                      "compilation (up to 6 such fits)")
    assert _propose._rough_units(line, 64, 6) == ""  # a closed form: no scene run to time
    again = float(built.value(mine.result.x, 1e-6))
    assert again == pytest.approx(mine.outcomes[0].objective, rel=1e-9) and again <= requirement * 1.01
    assert mine.cost == pytest.approx(ours.cost, rel=0.02) and ours.status == "converged"
    # The status is data (an enum, like diffrax's RESULTS) that is also its string.
    assert ours.status is tx.DesignStatus.CONVERGED and f"{ours.status}" == "converged" and ours.accepted
    assert dataclasses.replace(ours, status="infeasible").status is tx.DesignStatus.INFEASIBLE
    with pytest.raises(ValueError, match="'maybe' is not a valid DesignStatus"):
        dataclasses.replace(ours, status="maybe")
    with pytest.raises(ValueError, match="re-solves from the design"):
        tx.propose_design(dataclasses.replace(problem, statistic=tx.Yield(0.99)), PenaltyMethod())


def test_the_defaults_reach_the_recipes_that_verified():
    """With no model named (`Auto()`): the RMS alone on tangents, finished on secants where they
    stall; beside a jitter that scatters from unit to unit, both fitted on the jitter's
    response-surface recipe (64 units with their scatter, the jitter's line on its logarithm,
    boxes from the functional minimum to 100 um, six rounds, a twin solve); a model named on a
    requirement is kept."""
    # The jitter's scatter (0.5 arcsec) against its trend over the starting zone (its slopes
    # times +-10 um: under 0.1 arcsec): Auto()'s measurement reads a share near 1.
    pointing = R.Line(R.scan_scene(), [900.0, 2.0], [SLOPES, SLOPES * 1e-3], 60e-6, names=("pointing_rms", "pointing_jitter"),
                      jitter_cutoff=20.0, sigma=[0.0, 0.5])
    alone, combined = _propose._requirements(tx.ToleranceProblem(pointing, 700.0), tx.Sequential())
    assert isinstance(alone[0].model, tx.Auto) and combined.options == {} and combined.rescue and not combined.twin
    both = [tx.Requirement("pointing_rms", 700.0), tx.Requirement("pointing_jitter", 0.2)]
    found, combined = _propose._requirements(tx.ToleranceProblem(pointing, both, tx.Yield(0.9), tx.Zones(min_clearance=8e-6)),
                                             tx.Sequential())
    shares = [r.model.share for r in found]
    assert shares[0] < 1e-6 and shares[1] > 0.5, shares  # a line carries the RMS exactly; the jitter is scatter
    assert combined.secants and combined.twin and not combined.rescue and combined.surface.rounds == 6
    assert combined.options["secant_units"] == 64 and combined.options["scatter"]
    assert combined.options["log_outputs"] == ("pointing_jitter",) and combined.options["surface_box"] == (8e-6, 100e-6)
    assert [r.secants for r in found] == [True, True] and [r.log_fit for r in found] == [False, True]
    named = [tx.Requirement("pointing_rms", 700.0, model=tx.Secants(units=20)), tx.Requirement("pointing_jitter", 0.2,
                                                                                            model=tx.Secants(units=24, log=True))]
    _, combined = _propose._requirements(tx.ToleranceProblem(pointing, named, tx.Yield(0.9)), tx.Sequential())
    assert combined.surface is None and combined.options["secant_units"] == 24
    with pytest.raises(ValueError, match="AugmentedLagrangian takes tangent slopes only"):
        _propose._requirements(tx.ToleranceProblem(pointing, both, tx.Yield(0.9)), tx.AugmentedLagrangian())


def test_auto_chooses_by_the_scatter_it_measures_not_by_the_output_name():
    """`Auto()` measures, over units drawn within the starting zones, the share of each output's
    variance a line in the features does not carry (`tolerax.design.probe.scatter_share`), and fits the outputs above
    `SCATTER_SHARE` on a response surface: an RMS that scatters from unit to unit gets one, a
    jitter a line carries gets tangents. The share agrees with its closed form; a share given
    is not measured again; a problem without a yield, or for a solver on tangents alone, is not
    measured; the report says what was measured."""
    from tolerax.design.probe import scatter_share
    from tolerax.design.types import Design

    # Closed form: units uniform over middle +- b (b = 10 um) give the line's part a variance
    # sum_i (s_i b)^2 / 3 = 2808 arcsec^2; with sigma = 53 arcsec the share is
    # 53^2 / (53^2 + 2808) = 0.500. 2000 units drawn at random: the ratio of two variance
    # estimates carries a sampling error of ~0.02 here (0.49-0.52 over three keys), so 0.05.
    line = R.Line(R.scan_scene(), [900.0], [SLOPES], 60e-6, sigma=[53.0])
    share = scatter_share(line, ("pointing_rms",), Design(np.full(4, 60e-6), np.full(4, 10e-6)), units=2000)
    assert abs(float(share[0]) - 53.0**2 / (53.0**2 + 2808.0)) < 0.05, share
    with pytest.raises(ValueError, match="too few degrees of freedom"):
        scatter_share(line, ("pointing_rms",), Design(np.full(4, 60e-6), np.full(4, 10e-6)), units=6)

    pointing = R.Line(R.scan_scene(), [900.0, 2.0], [SLOPES * 1e-3, SLOPES], 60e-6, names=("pointing_rms", "pointing_jitter"),
                      jitter_cutoff=20.0, sigma=[30.0, 0.0])
    both = [tx.Requirement("pointing_rms", 950.0), tx.Requirement("pointing_jitter", 400.0)]
    found, combined = _propose._requirements(tx.ToleranceProblem(pointing, both, tx.Yield(0.9)), tx.Sequential())
    assert found[0].model.share > 0.5 and found[1].model.share < 1e-6, [r.model.share for r in found]
    assert isinstance(found[0].model.resolve(found[0]), tx.Surface) and isinstance(found[1].model.resolve(found[1]), tx.Tangents)
    assert combined.surface is not None and combined.options["log_outputs"] == ("pointing_rms",)
    (note,) = _propose._auto_notes(found)
    assert "over 50 units drawn within the starting zones" in note and "pointing_jitter 0.00 (tangents)" in note
    assert f"pointing_rms {found[0].model.share:.2f} (a response surface)" in note
    given = [tx.Requirement("pointing_rms", 950.0, model=tx.Auto(share=0.0))]
    found, combined = _propose._requirements(tx.ToleranceProblem(pointing, given, tx.Yield(0.9)), tx.Sequential())
    assert found[0].model == tx.Auto(share=0.0) and combined.surface is None and combined.rescue
    found, _ = _propose._requirements(tx.ToleranceProblem(pointing, 950.0, tx.MeanPlusKStd(1.0)), tx.Sequential())
    assert found[0].model == tx.Auto() and _propose._auto_notes(found) == ()
    found, _ = _propose._requirements(tx.ToleranceProblem(pointing, 950.0, tx.Yield(0.9)), tx.AugmentedLagrangian())
    assert found[0].model == tx.Auto()  # tangents only: nothing to choose, nothing measured
    with pytest.raises(ValueError, match="share is a fraction"):
        tx.Auto(share=1.5)


def test_the_former_keywords_map_to_the_values_that_replace_them():
    """`tolerax.design.legacy`: each former keyword lands on its value (the former defaults
    kept: a jitter on plain secants, a given `secant_units` without scatter or twin), with a
    `DeprecationWarning`; an unknown keyword is named."""
    pointing = R.Line(R.scan_scene(), [900.0, 2.0], [SLOPES, SLOPES], 60e-6, names=("pointing_rms", "pointing_jitter"),
                      jitter_cutoff=20.0)
    default = _propose.DEFAULT_CHECK
    with pytest.warns(DeprecationWarning, match="jitter, max_checks, method, surface_box, yield_"):
        problem, solver, check = legacy.from_legacy(pointing, 700.0, default, dict(
            yield_=0.9, jitter=0.2, method="sequential", max_checks=2, surface_box=(5e-6, 90e-6)))
    assert solver == tx.Sequential() and check == tx.Check(200, 2) and problem.statistic == tx.Yield(0.9)
    models = [r.model for r in problem.requirements]
    assert models[1] == tx.Surface(units=None, box=(5e-6, 90e-6), rounds=4, log=False, scatter=True, twin=True)
    with pytest.warns(DeprecationWarning):
        problem, solver, check = legacy.from_legacy(pointing, 700.0, default, dict(secant_units=12, yield_=0.99, check_units=0,
                                                                                   method="augmented-lagrangian", band=5e-6))
    assert problem.requirements[0].model == tx.Secants(units=12, scatter=False, twin=False) and check is None
    assert isinstance(solver, tx.AugmentedLagrangian) and problem.zones == tx.Zones(band=5e-6)
    with pytest.warns(DeprecationWarning, match="gradient, k"):  # the former gradient string: a diffrax adjoint now
        problem, _, _ = legacy.from_legacy(pointing, 700.0, default, dict(gradient="reverse", k=2.0))
    assert problem.statistic.k == 2.0 and type(problem.statistic.adjoint).__name__ == "RecursiveCheckpointAdjoint"
    # A requirement flagged for secants (as a jitter is) takes a surface at the default units.
    with pytest.warns(DeprecationWarning, match=r"secants=\.\.\., log_fit=\.\.\.\) is deprecated .* model=tx\.Secants\(\)"):
        flagged = tx.Requirement("pointing_rms", 700.0, secants=True)
    assert flagged.secants and not flagged.log_fit
    with warnings.catch_warnings():  # the defaults given, or read back and given again, say nothing
        warnings.simplefilter("error")
        jitter = tx.Requirement("pointing_jitter", 0.2, secants=True, log_fit=False)
        dataclasses.replace(jitter, limit=0.3)
    with pytest.warns(DeprecationWarning):
        problem, _, _ = legacy.from_legacy(pointing, flagged, default, dict(yield_=0.9, surface_box=(5e-6, 90e-6)))
    assert problem.requirements[0].model == tx.Surface(units=None, box=(5e-6, 90e-6), rounds=4, log=False)
    with pytest.raises(TypeError, match="unknown keyword.*widthz"):
        legacy.from_legacy(pointing, 700.0, default, dict(widthz=(1e-6,)))
    # A former name on the face: still served, with what replaces it; off the face's list.
    with pytest.warns(DeprecationWarning, match="tolerax.JitterRequirement is deprecated .* report.outcomes"):
        assert tx.JitterRequirement is tx.design.report.JitterRequirement
    assert "JitterRequirement" not in tx.__all__


def test_bad_values_are_named():
    with pytest.raises(ValueError, match="level must be a fraction"):
        tx.Yield(1.5)
    with pytest.raises(ValueError, match="units must be >= 2"):
        tx.Check(units=1)
    with pytest.raises(ValueError, match="widths must be one or more"):
        tx.Sequential(widths=(-1e-6,))
    with pytest.raises(ValueError, match="rounds must be >= 1"):
        tx.Surface(rounds=0)
    with pytest.raises(TypeError, match="statistic must be"):
        tx.ToleranceProblem(None, 1.0, statistic=0.99)
    line = R.Line(R.scan_scene(), 1000.0, SLOPES, 100e-6)
    with pytest.raises(TypeError, match="solver must be a design method"):
        tx.propose_design(tx.ToleranceProblem(line, 500.0), "sequential")
    with pytest.raises(ValueError, match="units must exceed the 4 design features"):
        tx.propose_design(tx.ToleranceProblem(line, tx.Requirement("pointing_rms", 500.0, model=tx.Secants(units=3))))


def test_the_command_line_and_scene_files_name_the_same_models(tmp_path, capsys, monkeypatch):
    """`tolerax design --model` and a scene file's `[tolerances] model` name the constraint
    models (`tangents`, `secants`, `surface`, `auto`): the flag over the scene, the scene over
    the default; an unknown one is refused at its line; a model without a yield is refused
    before any work. What reaches `propose_design` is read off the `ToleranceProblem` handed to
    it (the design itself is stopped there)."""
    from tolerax import cli
    from tolerax.design import propose as P

    text = tx.load_scene("scan-azimuth").to_toml().replace("[tolerances]\n", "[tolerances]\nmodel = \"surface\"\n")
    scene = tmp_path / "drive.toml"
    scene.write_text(text)
    seen = []

    checks = []

    def stop(problem, solver=None, **options):
        seen.append((problem, solver))
        checks.append(options.get("check"))
        raise ValueError("stopped here by the test")

    monkeypatch.setattr(P, "propose_design", stop)
    for flags, expected in (([], tx.Surface()), (["--model", "tangents"], tx.Tangents()),
                            (["--model", "secants", "--secant-units", "9"], tx.Secants(units=9))):
        assert cli.main(["design", str(scene), "--requirement", "500", "--yield", "0.99", "--out", str(tmp_path / "o"),
                         *flags]) == 2
        problem, solver = seen[-1]
        assert [r.model for r in problem.requirements] == [expected] and solver == tx.Sequential()
        assert problem.statistic == tx.Yield(0.99) and "stopped here by the test" in capsys.readouterr().err
    # --secant-units alone (no --model): every requirement on the automatic model on K units,
    # whatever its output's name; its measurement then picks, output by output, a response surface
    # on K units (a scattering output) or a line through K units (the others), and unmeasured
    # (here: propose_design, which measures, is stopped) each goes by its output's name.
    scene.write_text(text.replace('model = "surface"\n', ""))
    assert cli.main(["design", str(scene), "--requirement", "500", "--yield", "0.9", "--jitter", "0.3", "--allow-proxy",
                     "--secant-units", "9", "--out", str(tmp_path / "o")]) == 2
    problem, _ = seen[-1]
    assert [r.model for r in problem.requirements] == [tx.Auto(units=9), tx.Auto(units=9)]
    line, surface = tx.Secants(units=9, scatter=False, twin=False), tx.Surface(units=9)
    assert [r.model.resolve(r) for r in problem.requirements] == [line, surface]
    rms, jitter = problem.requirements
    for share, expected in ((0.9, surface), (0.05, line)):  # measured: the share decides, not the name
        assert [dataclasses.replace(r.model, share=share).resolve(r) for r in (rms, jitter)] == [expected, expected]
    assert tx.Auto().resolve(rms) == tx.Tangents() and tx.Auto(share=0.9).resolve(rms) == tx.Surface()
    capsys.readouterr()
    # The solver by name: --solver slsqp is tx.SLSQP() (--outer: its iterations per width); the
    # former --method still names it for one release, and says what replaces it.
    assert cli.main(["design", str(scene), "--requirement", "500", "--solver", "slsqp", "--outer", "50", "--out", str(tmp_path / "o")]) == 2
    assert seen[-1][1] == tx.SLSQP(max_iterations=50) and "stopped here by the test" in capsys.readouterr().err
    assert cli.main(["design", str(scene), "--requirement", "500", "--method", "slsqp", "--outer", "50", "--out", str(tmp_path / "o")]) == 2
    assert seen[-1][1] == tx.SLSQP(max_iterations=50) and "--method is deprecated" in capsys.readouterr().err
    with pytest.raises(SystemExit) as exit_:
        cli.main(["design", str(scene), "--solver", "slsqp", "--method", "sequential", "--out", str(tmp_path / "o")])
    assert exit_.value.code == 2 and "disagree" in capsys.readouterr().err
    with pytest.raises(ValueError, match="units must be >= 2"):
        tx.Auto(units=1)
    # A model per output: a table by output name, the outputs it does not name on Auto(); the
    # same in Python (the scene's problem) and from the command line (--secant-units: its units).
    with_yield = text.replace('model = "surface"', 'model = { pointing_rms = "secants" }\nyield = 0.9\nrequirement = 500.0\n'
                              'require = { pointing_peak = 900.0 }')
    scene.write_text(with_yield)
    assert [r.model for r in tx.load_scene(str(scene)).problem().requirements] == [tx.Secants(), None]
    assert cli.main(["design", str(scene), "--secant-units", "9", "--out", str(tmp_path / "o")]) == 2
    problem, _ = seen[-1]
    assert [r.model for r in problem.requirements] == [tx.Secants(units=9), tx.Auto(units=9)]
    capsys.readouterr()
    for table, where, message in (('{ pointing_rms = "secant" }', "pointing_rms", "model='secant' is unknown"),
                                  ('{ pointing_jiter = "surface" }', "pointing_jiter", "did you mean 'pointing_jitter'")):
        scene.write_text(with_yield.replace('{ pointing_rms = "secants" }', table))
        assert cli.main(["design", str(scene), "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert f"{scene}:27: [tolerances.model] {where}: " in err and message in err, err
    with pytest.raises(SystemExit, match="2"):
        cli.main(["design", "scan-azimuth", "--requirement", "500", "--model", "surface", "--out", str(tmp_path / "o")])
    assert "--model surface needs --yield" in capsys.readouterr().err
    scene.write_text(text.replace('model = "surface"', 'model = "surfaces"'))
    line = text.splitlines().index('model = "surface"') + 1
    assert cli.main(["design", str(scene), "--requirement", "500", "--yield", "0.99", "--out", str(tmp_path / "o")]) == 2
    assert f"{scene}:{line}: [tolerances] model: model='surfaces' is unknown" in capsys.readouterr().err
    # The solver and the check by name in the scene file too ([tolerances] solver, check), the
    # same objects in Python (SceneFile.solver(), check()) and on the command line, whose
    # --solver and --check go over them; check = 0 is none.
    from tolerax.design.check import Check

    named = with_yield.replace("yield = 0.9", 'yield = 0.9\nsolver = "slsqp"\ncheck = { units = 60, rounds = 2 }')
    scene.write_text(named)
    f = tx.load_scene(str(scene))
    assert f.solver() == tx.SLSQP() and f.check() == Check(60, 2)
    assert cli.main(["design", str(scene), "--out", str(tmp_path / "o")]) == 2
    assert seen[-1][1] == tx.SLSQP() and checks[-1] == Check(60, 2)
    assert cli.main(["design", str(scene), "--solver", "sequential", "--check", "30", "--out", str(tmp_path / "o")]) == 2
    assert seen[-1][1] == tx.Sequential() and checks[-1] == Check(30, 2)
    scene.write_text(named.replace("check = { units = 60, rounds = 2 }", "check = 0"))
    assert tx.load_scene(str(scene)).check() is None and cli.main(["design", str(scene), "--out", str(tmp_path / "o")]) == 2
    assert checks[-1] is None and seen[-1][1] == tx.SLSQP()
    assert tx.load_scene("scan-azimuth").solver() == tx.Sequential() and tx.load_scene("scan-azimuth").check() is None  # no yield
    capsys.readouterr()
    for wrong, message in (('solver = "slsqq"', "solver='slsqq' is unknown; use one of ('sequential', 'augmented-lagrangian', "
                                                "'slsqp') (the design solver: tolerax.Sequential, tolerax.AugmentedLagrangian, "
                                                "tolerax.SLSQP) (did you mean 'slsqp'?)"),
                           ('solver = "augmented-lagrangian"', "the augmented Lagrangian takes no yield"),
                           ("check = 1", "must be the units per Monte Carlo check (>= 2)"),
                           ("check = { units = 60, round = 2 }", "round")):
        scene.write_text(named.replace('solver = "slsqp"' if wrong.startswith("solver") else "check = { units = 60, rounds = 2 }",
                                       wrong))
        assert cli.main(["design", str(scene), "--out", str(tmp_path / "o")]) == 2
        err = capsys.readouterr().err
        assert "[tolerances" in err and message in err, err


@dataclasses.dataclass(frozen=True)
class WideSlopes(tx.AbstractConstraintModel):
    """A constraint model of one's own: tangent slopes taken at a wider smoothing width than
    the design is judged at (what `Tangents(slope_width=...)` also does, written anew)."""

    width: float = 1e-5

    def options(self, requirement, n_features):
        return {"slope_width": self.width}


@dataclasses.dataclass(frozen=True)
class TwelveUnits(tx.AbstractConstraintModel):
    """A constraint model of one's own fitted over units: a line through 12 units of the zone
    without the fit's scatter."""

    fitted: ClassVar[bool] = True

    def options(self, requirement, n_features):
        return dict(secant_units=12, scatter=False, secant_reach=None, secant_seed=1, log_outputs=())


def test_a_constraint_model_of_one_s_own_runs_through_propose_design():
    """`WideSlopes` (above), no edit to the loop or to `propose_design`: on a closed-form unit
    whose slopes grow with the smoothing width, its design is the one `Tangents` gives at that
    width (the same linearisation) and not the one tangents at the judging width give. And
    `TwelveUnits`, fitted over units without subclassing `Secants`: the design `Secants` gives on
    the same units, and refused by a solver that takes tangents only (it is known as fitted)."""
    scene = R.scan_scene()
    line = R.Line(scene, 1000.0, 0.5 * np.asarray(tx.lost_motion_weights(scene)), 100e-6,
                  width_slopes=[[0.0, 2e10, 1e10, 0.0]])  # arcsec/m per m of width
    requirement = 0.6 * float(_propose.design_problem(line, yield_=0.99).value(width=1e-6))

    def design(model):
        problem = tx.ToleranceProblem(line, tx.Requirement("pointing_rms", requirement, model=model), tx.Yield(0.99))
        return tx.propose_design(problem, tx.Sequential(widths=(1e-6,)), check=None)

    mine, same, plain = design(WideSlopes()), design(tx.Tangents(slope_width=1e-5)), design(tx.Tangents())
    assert mine.cost == same.cost and np.array_equal(mine.band, same.band)
    assert abs(mine.cost - plain.cost) > 1e-3 * plain.cost
    # A model fitted over units, of one's own (not a Secants subclass): `combine` reads its
    # `fitted` attribute and its options, so it runs through the same secant machinery; on the
    # same units it is the same design as Secants'.
    mine, same = design(TwelveUnits()), design(tx.Secants(units=12, scatter=False, twin=False))
    assert mine.status == same.status and mine.cost == same.cost and np.array_equal(mine.band, same.band)
    with pytest.raises(ValueError, match="takes tangent slopes only"):  # it is known as fitted: refused where slopes are asked
        tx.propose_design(tx.ToleranceProblem(line, tx.Requirement("pointing_rms", requirement, model=TwelveUnits()), tx.Yield(0.99)),
                          tx.AugmentedLagrangian(widths=(1e-6,)), check=None)


def test_auto_moves_a_noise_limited_design_on_to_more_units(monkeypatch):
    """`Auto()` starts on its surface's units and moves on where the measurement says so: on a
    log-linear jitter with a relative scatter of 0.5 (closed form), two sets of 8 units give
    designs of cost 2.30 and 1.41 (the twin: the last surface on the other units), noise-limited; the design is made again on 16 units (the cap
    lowered to 16 here, 128 by default, to keep the test short), the notes say so with both
    costs, and the report is that design's. A model the user names is kept as named."""
    from tolerax.design import propose as P

    slopes, sigma = [2e4, 1.5e4, 1e4, 5e3], 0.5
    requirement = 0.05 * np.exp(sum(slopes) * 25e-6 + 1.3 * sigma)
    response = R.Line(R.scan_scene(), np.log(0.05), [slopes], [5e-6] * 4, names=("pointing_jitter",), log=(True,), sigma=[sigma],
                      jitter_cutoff=20.0)
    problem = tx.ToleranceProblem(response, tx.Requirement("pointing_jitter", requirement, model=tx.Auto(units=8)), tx.Yield(0.9),
                                  tx.Zones(band=20e-6), allow_proxy=True)
    monkeypatch.setattr(P, "AUTO_MAX_UNITS", 16)
    report = tx.propose_design(problem, tx.Sequential(widths=(1e-7,)), check=None)
    moved = [n for n in report.notes if n.startswith("On 8 units the design was noise-limited")]
    assert len(moved) == 1 and "costs 2.302 and 1.413 with two sets of units): Auto() solved it again on 16 units." in moved[0]
    assert report.noise_band is not None and report.noise_band[:2] != (2.30237042176353, 1.413123557019249)
    assert not any(n.startswith("On 16 units") for n in report.notes)  # the cap: no further
    # Which requirements move: those on Auto() fitted over units, to twice the units within the cap.
    assert sum(n.startswith("Auto() measured") for n in report.notes) == 1  # measured once: the move to 16 units keeps it
    again = P._on_more_units(problem, 8)
    assert again.requirements[0].model == tx.Auto(units=16) and P._on_more_units(problem, 16) is None
    measured = (dataclasses.replace(problem.requirements, model=tx.Auto(units=8, share=0.7)),)
    assert P._on_more_units(problem, 8, measured).requirements[0].model == tx.Auto(units=16, share=0.7)
    # A requirement on Auto() that stays on tangents keeps its measurement in the move too (the
    # probe does not run again on more units).
    rms = tx.Requirement("pointing_rms", 700.0)
    both = dataclasses.replace(problem, requirements=(rms, problem.requirements))
    shares = (dataclasses.replace(rms, model=tx.Auto(share=0.01)), dataclasses.replace(problem.requirements, model=tx.Auto(units=8, share=0.7)))
    assert [r.model for r in P._on_more_units(both, 8, shares).requirements] == [tx.Auto(share=0.01), tx.Auto(units=16, share=0.7)]
    named = dataclasses.replace(problem, requirements=(tx.Requirement("pointing_jitter", requirement, model=tx.Surface(units=8)),))
    tangents = dataclasses.replace(problem, requirements=(tx.Requirement("pointing_rms", 700.0),))
    assert P._on_more_units(named, 8) is None and P._on_more_units(tangents, 8) is None

