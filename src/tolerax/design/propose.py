"""Tolerance proposals on a scene: the cheapest nominal clearances/backlash and tolerance zones
whose pointing outputs meet their requirements.

`propose_design(problem, solver, *, check)` takes three values: the problem
(`tolerax.design.spec.ToleranceProblem`: objective, requirements with their constraint models,
statistic, zones, cost model), the design method (`tolerax.design.solvers`: `Sequential` by
default, or the augmented Lagrangian on optax) and the Monte Carlo check of a yield
(`tolerax.design.check.Check`). It answers infeasible first, runs the solve rounds
(`tolerax.design.rounds`), draws the optimum on whole ISO grades and measures its noise band (`tolerax.design.finish`) and
returns a `DesignReport` that says whether its answer is a proposal (`tolerax.design.outcome`).
"""

import dataclasses
import functools

import numpy as np

from ..eta import human_seconds, rough_wall
from .check import Check, as_requirement, model_off
from .cost import grade_of
from .finish import TIGHTER_GRADES, drawn_missed, drawn_on_grades, noise_band, noise_verdict, twin_problem
from .features import design_names, lost_motion_weights
from .fidelity import check_fidelity
from .objectives import PointingObjective
from .outcome import SETTLED_STEPS, diagnose, tightest_reach
from .phases import Phases
from .rounds import ROUND_STEP, _secant_rescue, _solve_and_check
from .sequential import sequential_design
from .solvers import AbstractDesignMethod, Sequential
from .spec import SCATTER_SHARE, Auto, Combined, Secants, ToleranceProblem, combine, with_model
from .subproblem import objective_value_and_gradient
from .probe import PROBE_UNITS, scatter_share
from .surface import secant_standard_error
from .types import Design
# The problem and the report live in their own modules; importable from here too (public paths users call).
from .problem import DesignProblem, FromLowerLimit, OnHalfWidth, RobustPointing, design_problem, feature_sizes  # noqa: F401
from .report import DesignReport, JitterRequirement, RequirementOutcome  # noqa: F401
from .requirements import Requirement, as_requirements, resolved  # noqa: F401

DEFAULT_CHECK = Check()  # `propose_design`'s check where none is named: a yield's; a MeanPlusKStd problem has none


def propose_design(
    problem: ToleranceProblem,
    solver: AbstractDesignMethod | None = None,
    *,
    check: Check | None = DEFAULT_CHECK,
    progress: bool = False,
    callback=None,
    **deprecated,
) -> DesignReport:
    """Propose nominal clearances/backlash and tolerance zones for `problem` (a
    `ToleranceProblem`: its objective's scene, requirements, statistic, zones and cost model) that
    meet its requirements at the lowest cost.

    The solver varies, per feature, the lower limit $l$ of the tolerance zone (the smallest
    clearance or backlash a part may have) and its half-width $b$; the zone is $[l, l + 2b]$, the
    nominal $l + b$ (`FromLowerLimit`). Only the bands cost; the lower limits may not go below
    the zones' `min_clearance`, the functional minimum (thermal growth over the orbit's
    temperature swing, the lubricant film, no jamming) — without it the optimum would be a
    zero-clearance nominal.

    Infeasible first: before optimising, the objective is evaluated at the tightest designs the
    bounds allow (every band and lower limit at its smallest, and on the bounds the baseline's
    sensitivities say lower each output: `tolerax.design.outcome.tightest`). Where both miss a
    requirement no design within the bounds meets it: the report is that design's, `status`
    `"infeasible"`, with the requirement that would be met, and no solver runs.

    Each requirement is linearised by its constraint model (`Requirement(model=...)`, default
    `Auto()`: tangent slopes, finished on secants over units where they stall; for an output
    measured at the start to scatter from unit to unit (over units drawn within the starting
    zones more than `SCATTER_SHARE` of its variance lies off a line in the features: the jitter
    of a rattling stage), a response surface refitted as the design moves; models fitted over
    units also solve a twin design, the noise band: the fit the design rests on (its last response
    surface, over the same box, or its secants) on another set of units, the design solved
    again on it from where it is, against the requirements it was solved for; where
    the two costs differ by more than the requirements' tolerances resolve, the status is
    `"noise-limited"`, and a requirement on `Auto()` is designed again on twice the units, up to
    `AUTO_MAX_UNITS`, the report saying so). The continuous optimum is then drawn on whole ISO grades
    (`round_to_grades`), checked again where there is a check, and tightened by up to
    `TIGHTER_GRADES` grades where it misses.

    **Arguments:**

    - `problem`: the `ToleranceProblem`.
    - `solver`: the design method, a value carrying its smoothing-width continuation, budget and
      step: `Sequential()` (default) or `AugmentedLagrangian()` (`tolerax.design.solvers`; one
      requirement on tangents), or one's own `AbstractDesignMethod`.
    - `check`: the Monte Carlo check of a yield design and its re-solves (`Check(units=200,
      rounds=3)`, the default; `None`: no check). A `MeanPlusKStd` problem has no check. Its
      units are a `monte_carlo` run: `Check(backend=..., chunk_size=..., out=...)` runs them on
      a process pool or a Dask cluster, and keeps them to be read back by a design run again.
    - `progress`: a progress bar over the solver's iterations and the checks' units, and one
      line per phase (surface fit, solve, checks, twin, drawn design) with the time since the
      start, on stderr (`tolerax.design.phases`; a callable takes the lines instead). Before
      they start, the surface fits say a rough time (their units at `tolerax.eta.rough_wall`'s
      pace), the solve its budget of gradients at the pace of the compiled evaluations so far,
      and each later check the last one's time.
    - `callback`: `callback(gradients, x, cost, objective)` after every gradient evaluation
      (`Sequential`; `x.nominal` holds the lower limits).
    - `**deprecated`: the former signature, `propose_design(pointing, requirement, widths=...,
      method=..., yield_=..., ...)`, still works for one release with a `DeprecationWarning`
      (`tolerax.design.legacy` says what each keyword became).

    **Returns:** a `DesignReport`.
    """
    if not isinstance(problem, ToleranceProblem):
        from .legacy import from_legacy

        requirement = deprecated.pop("requirement", None) if solver is None else solver  # the former second argument
        problem, solver, check = from_legacy(problem, requirement, check, deprecated)
    elif deprecated:
        raise TypeError(f"propose_design: unexpected keyword(s) {', '.join(sorted(deprecated))}: with a ToleranceProblem the options "
                        "are solver=, check=, progress= and callback= (the problem's own parts: ToleranceProblem's fields).")
    solver = Sequential() if solver is None else solver
    if not isinstance(solver, AbstractDesignMethod):
        raise TypeError(f"propose_design: solver must be a design method, Sequential(), AugmentedLagrangian() or SLSQP() (or "
                        f"one's own AbstractDesignMethod), got {solver!r}.")
    yield_ = problem.yield_
    if yield_ is None:
        if check is not None and check is not DEFAULT_CHECK:
            raise ValueError("propose_design: a check needs a yield requirement (statistic=Yield(...)), the thing it checks.")
        check = None
    if check is not None and not isinstance(check, Check):
        raise TypeError(f"propose_design: check must be a Check(...) or None, got {check!r}.")
    if check is not None and not solver.restarts:
        raise ValueError(f"propose_design: a yield's Monte Carlo check re-solves from the design, which {type(solver).__name__} does "
                         "not: use Sequential(), or check=None.")
    pointing = problem.objective
    say = Phases(progress)
    # What the objective computes and the fidelity each requirement is read at, before anything
    # is simulated (Auto()'s probe).
    given = _given(problem)
    proxy_notes = tuple(check_fidelity(pointing.scene, given, allow_proxy=problem.allow_proxy))
    requirements_, combined = _requirements(problem, solver, say, given)
    proxy_notes += _auto_notes(requirements_)
    options = problem.zones.options() | problem.statistic_options() | combined.options | dict(
        cost_model=problem.cost, output=requirements_[0].output if len(requirements_) == 1 else tuple(r.output for r in requirements_))
    if combined.surface is not None:
        box = options["surface_box"]
        say(f"fitting the response surface: {options['secant_units']} simulated units over [{box[0] * 1e6:.3g}, "
            f"{box[1] * 1e6:.3g}] um" + _rough_units(pointing, options["secant_units"], combined.surface.rounds) + " ...")
    built = design_problem(pointing, **options)
    width = solver.width
    say("the starting design's outputs and slopes ...")
    baseline, slopes = _value_and_sensitivity(built, built.x0, width)
    if combined.secants and any(r.tol is None for r in requirements_):
        say(f"the secant fit's standard error at the start ({options['secant_units']} units) ...")
    requirements, tol = np.asarray([r.limit for r in requirements_], dtype=float), _tolerances(requirements_, built, width)
    checked, twin_costs, notes = [], None, proxy_notes  # checked: (result, its checks: one per requirement, the requirements it was solved for)
    evaluate = _memoised_values(width)
    say("infeasible first: the tightest designs the bounds allow ...")
    since, made = say.elapsed(), evaluate.made
    out_of_reach = _tightest_first(evaluate, built, slopes, requirements, tol)
    # s per evaluation of the compiled objective (two designs asked for; one where they coincide)
    pace = (say.elapsed() - since) / (evaluate.made - made) if evaluate.made > made else None
    if out_of_reach is not None:
        # Infeasible first: the tightest designs the bounds allow miss a requirement, so no design
        # within them meets it; no solver is run. The report is that design's, evaluated.
        result = sequential_design(
            built.objective, built.features, requirement=as_requirement(requirements), lower=built.lower, upper=built.upper,
            draws=built.draws, x0=out_of_reach, cost_model=built.cost_model, width=width, max_iterations=0, tol=tuple(tol),
            zone_upper=built.zone_upper)
        targets = requirements
        notes += ("Answered before optimising: the tightest designs the bounds allow (every band and lower limit at its smallest, "
                  "and on the bounds the baseline's sensitivities say lower each output) already miss the requirement, so no "
                  "design within the bounds meets it; the optimiser was not run.",)
    else:
        rounds = None if combined.surface is None else (int(combined.surface.rounds), combined.surface.width,
                                                        combined.options.get("secant_reach"))
        say(f"solving ({type(solver).__name__}, smoothing widths {', '.join(f'{w:g}' for w in solver.widths)} m)"
            + _how_long(solver, pace, check) + " ...")
        built, result, checked, zoomed = _solve_and_check(built, requirements, tol, solver, check, progress, callback, rounds=rounds,
                                                          say=say)
        notes += zoomed
        stalled = bool(result.stalled is not None and result.stalled)
        off = bool(checked) and model_off(checked[-1][1], requirements)
        if (stalled or off) and combined.rescue and solver.fitted:
            # Auto(): the tangents' own measurement (a stall, or a check that finds their linear
            # model off: `model_off`) moves the design on to secants.
            why = "stalled" if stalled else "read a linear model the check found off by more than half the requirement"
            rebuild = lambda **more: design_problem(pointing, **(options | more))  # noqa: E731
            say(f"the tangent slopes {why}: finishing on secant slopes over units of the zone ...")
            built, result, checked, rescue = _secant_rescue(rebuild, built, result, checked, requirements, tol, solver, check,
                                                            progress, callback, say, why)
            notes += rescue
        targets = checked[-1][2] if checked else requirements  # the (shifted) requirements the returned design was solved for
        if combined.twin:
            # The noise band: the fit the design rests on (its last surface, or its secants) on
            # another set of units, the design solved again on it from where it is, against the
            # requirements it was solved for (a check's shift included).
            seed = int(options.get("secant_seed", 1)) + 1
            say(f"the noise band: the design's fit again on another set of units (seed {seed}), solved again from the design ...")
            rebuild = lambda **more: design_problem(pointing, **(options | more))  # noqa: E731
            twin_costs = noise_band(lambda s: twin_problem(rebuild, built, s, options.get("surface_box")), result, seed,
                                    lambda p: solver.solve(p, as_requirement(targets), tol, progress=progress,
                                                           **(dict(x0=result.x, step=ROUND_STEP) if solver.restarts else {})))
    what = "" if yield_ is None else f" ({yield_:.1%} quantile)"
    status, diagnosis = diagnose(
        objective=result.objective, requirement=targets, tol=tol, converged=bool(result.converged),
        iterations=int(np.asarray(result.history.steps)[-1]), labels=[r.name + what for r in requirements_],
        evaluate=functools.partial(evaluate, built), lower=built.lower,
        upper=built.upper, sensitivity=np.asarray(result.sensitivity.nominal) / requirements[:, None],
        checks=checked[-1][1] if checked else (), yield_=yield_, noisy=built.gradient_noise is not None,
        bounds_text=" (the zones' min_clearance and band_range; a scene file's [tolerances])",
        stalled=bool(result.stalled is not None and result.stalled), solver=solver, settled=_settled(result))
    outcomes = _outcomes(requirements_, result, baseline, targets, tol, checked)
    if twin_costs is not None and status == "converged":
        status, diagnosis = noise_verdict(twin_costs, outcomes, options.get("secant_units"), surface=combined.surface is not None)
        more = _on_more_units(problem, options.get("secant_units"), requirements_) if status == "noise-limited" else None
        if more is not None:
            # Auto(): the measurement (two sets of units that disagree on the design) moves the
            # model on to twice the units (again while noise-limited, up to AUTO_MAX_UNITS); the
            # report is the last design's, these costs in its notes.
            units = int(options["secant_units"])
            say(f"noise-limited on {units} units (costs {twin_costs[0]:.4g} and {twin_costs[1]:.4g}): the design again on "
                f"{2 * units} units (Auto) ...")
            again = propose_design(more, solver, check=check, progress=progress, callback=callback)
            return dataclasses.replace(again, notes=(
                f"On {units} units the design was noise-limited (costs {twin_costs[0]:.4g} and {twin_costs[1]:.4g} with two sets "
                f"of units): Auto() solved it again on {2 * units} units.",) + again.notes)
    # Every solver's result carries one row of sensitivities per requirement, what the rounding reads.
    band = np.asarray(result.x.band)
    grade = np.asarray(grade_of(band * 2, built.features.size_mm))
    drawn_check = None if check is None or status != "converged" else check
    say("the design on whole ISO grades" + (f", checked on {drawn_check.units} units (up to {TIGHTER_GRADES + 1} designs, "
                                            f"each a check{say.at_pace('check').replace(', about', ': about')})"
                                            if drawn_check else "") + " ...")
    drawable = drawn_on_grades(built, result, grade, outcomes, targets, requirements, yield_, drawn_check, width, progress)
    if status == "converged" and not drawable.met:
        # One proposal: what the drawing carries is the answer, so a continuous optimum whose
        # whole grades miss is not a proposal.
        status, diagnosis = "check missed", drawn_missed(drawable, yield_)
    features, x0 = built.features, built.x0
    say(f"done: {status}.")
    return DesignReport(
        names=features.names, nominal=np.asarray(result.x.nominal) + band, band=band,
        grade=grade, feature_cost=np.asarray(result.feature_cost), cost=float(result.cost),
        baseline=(np.asarray(x0.nominal + x0.band), np.asarray(x0.band), float(built.cost_model.total(x0.band, features.size_mm)),
                  outcomes[0].baseline),
        result=result, outcomes=outcomes, yield_=yield_, lost_motion=np.asarray(lost_motion_weights(pointing.scene)),
        fixed=_fixed_names(problem.zones.fixed), status=status, diagnosis=diagnosis,
        noise_band=None if twin_costs is None else twin_costs[:2], notes=notes, cost_unit=built.cost_model.unit,
        grade_range=built.cost_model.grade_range, drawable=drawable,
    )


def _fixed_names(fixed) -> tuple:
    """The fixed features' names (`Zones.fixed`: names, a mapping or a `Tolerances`)."""
    names = getattr(fixed, "names", None)
    return tuple(names if names is not None else fixed)


def _value_and_sensitivity(problem, x, width):
    """`(values, sensitivity)` of the design objective at `x` (`Design(lower limit, band)`, m) and
    smoothing `width` (m): each requirement's value (m,) and its derivative over the lower
    limits (m, n; output unit per m), from the program the optimiser differentiates."""
    value, gradient = objective_value_and_gradient(problem.objective, x, problem.draws, width)
    return np.atleast_1d(np.asarray(value, dtype=float)), np.atleast_2d(np.asarray(gradient.nominal, dtype=float))


def _memoised_values(width):
    """`evaluate(problem, x)`: the objective's values at `x` (`Design`, m) and smoothing `width`
    (m) through the program the optimiser differentiates (`_value_and_sensitivity`), each design
    evaluated once per problem: the tightest designs are asked for before optimising
    (`_tightest_first`) and again by `diagnose` where a design misses."""
    memo = {}

    def evaluate(problem, x):
        key = (id(problem), np.asarray(x.nominal).tobytes(), np.asarray(x.band).tobytes())
        if key not in memo:  # the problem is kept with its values: its id is not reused while the memo lives
            memo[key] = (problem, _value_and_sensitivity(problem, x, width)[0])
            evaluate.made += 1
        return memo[key][1]

    evaluate.made = 0  # evaluations made (not read back from the memo)
    return evaluate


def _settled(result):
    """The relative spread of the cost over the last `SETTLED_STEPS` accepted steps at the last
    smoothing width (`diagnose`), or `None` where there are fewer. A rejected step repeats the
    cost of the row before it, so only the rows whose cost changed count: a run of rejections (a
    shrinking trust region, where more iterations may still find a step) is not a settled cost."""
    history = result.history
    last = np.asarray(history.continuation) == np.asarray(history.continuation)[-1]
    costs = np.asarray(history.cost)[last]
    moved = costs[np.concatenate([[True], np.diff(costs) != 0])][-SETTLED_STEPS:]
    if moved.size < SETTLED_STEPS or not np.all(np.isfinite(moved)) or moved.min() <= 0:
        return None
    return float((moved.max() - moved.min()) / moved.min())


def _how_long(solver, pace, check) -> str:
    """The solve's time said before it: its solver's budget (`most_gradients`) at `pace` (s
    each: the infeasible-first evaluations', compiled; `None`: not measured), and the check's
    units. The first solve's budget: a check's re-solves, a surface's rounds and a twin design
    add their own."""
    most = solver.most_gradients()
    said = "" if most is None else f"; the first solve's budget {most} gradients" + (
        "" if pace is None else f", about {human_seconds(most * pace)} at the {pace:.2g} s each the infeasible-first "
                                "evaluations took")
    if check is not None:
        said += f"; then a Monte Carlo check of {int(check.units)} fresh units (at most {int(check.rounds)} rounds)"
    return said


def _rough_units(pointing, units: int, rounds: int) -> str:
    """The surface fits' time said before the first: `units` simulations at `rough_wall`'s pace
    (a scene's objective only; an order of magnitude, not a bound), up to `rounds` fits."""
    one = rough_wall(pointing.scene, pointing.duration, pointing.integrator) if isinstance(pointing, PointingObjective) else None
    return "" if one is None else (f", roughly {human_seconds(max(units * one, 1.0))} on one core plus compilation"
                                   + (f" (up to {rounds} such fits)" if rounds > 1 else ""))


def _tightest_first(evaluate, problem, slopes, requirements, tol):
    """Infeasible first (before any optimising): the objective at the tightest designs the
    bounds allow (`tightest_reach`: every band and lower limit at its smallest; and on the bounds
    the baseline's sensitivities `slopes` (m, n) say lower the outputs), two evaluations of
    `evaluate(problem, x)`. Returns the one nearer to meeting every requirement where both miss
    one (to its relative tolerance `tol`): no design within the bounds meets it (the test
    `diagnose` makes after a design); else `None`."""
    tried, values = tightest_reach(functools.partial(evaluate, problem), problem.lower, problem.upper, slopes / requirements[:, None])
    if np.all(np.min(values, axis=0) <= requirements * (1 + tol)):
        return None
    return tried[int(np.argmin(np.max(values / requirements, axis=1)))]


AUTO_MAX_UNITS = 128  # Auto() moves a noise-limited design on to twice its units while that stays within this


def _on_more_units(problem: ToleranceProblem, units, measured=()) -> ToleranceProblem | None:
    """`problem` with each requirement on `Auto()` (its default) that is fitted over units
    moved to `Auto(units=2 x units)`, where that stays within `AUTO_MAX_UNITS`; `None` where no
    requirement is (a model named by the user is kept as named). `measured`: the requirements
    as `_requirements` gave them (in the problem's order): every `Auto` keeps its measured
    `share`, moved or not, so the design on more units does not measure again."""
    if units is None or 2 * int(units) > AUTO_MAX_UNITS:
        return None
    requirements = as_requirements(problem.requirements)
    shares = [m.model.share if isinstance(m.model, Auto) else None for m in measured] or [None] * len(requirements)

    def moved_model(r):  # its model resolved once (with_model replaces the requirement: a flagged one warns each time)
        model = with_model(r).model
        if not isinstance(model, Auto):
            return None
        return dataclasses.replace(model, units=2 * int(units)) if model.resolve(r).fitted else None

    def kept_share(r, share):  # an Auto() requirement not moved keeps its measurement too (else the probe runs again)
        model = with_model(r).model
        return r if share is None or not isinstance(model, Auto) else dataclasses.replace(r, model=dataclasses.replace(model, share=share))

    measured_ = [kept_share(r, share) for r, share in zip(requirements, shares)]
    moved = tuple(r if (m := moved_model(r)) is None else dataclasses.replace(r, model=m) for r in measured_)
    if all(a is b or a == b for a, b in zip(moved, measured_)):
        return None  # nothing moved on to more units
    return dataclasses.replace(problem, requirements=moved)


def _measured(problem: ToleranceProblem, requirements, solver, say=None) -> tuple[Requirement, ...]:
    """`requirements` with each one on `Auto()` not yet measured given its output's measured
    `share` (`probe.scatter_share` over `PROBE_UNITS` units of the problem's starting zone, at
    the smoothing width `solver` judges at; one Monte Carlo run for all of them): what
    `Auto` resolves by. Returned as given, unmeasured (`Auto` then goes by the output's name),
    where nothing could follow from it: the statistic is not a yield (nothing is fitted over
    units then), `solver` takes tangent slopes only, or each unit draws an uncertain input (a
    life's wear rate: every requirement is fitted over units anyway)."""
    pending = [r for r in requirements if isinstance(r.model, Auto) and r.model.share is None]
    pointing = problem.objective
    if not pending or problem.yield_ is None or not solver.fitted or pointing.uncertain_inputs:
        return requirements
    outputs = tuple(dict.fromkeys(r.output for r in pending if r.output in pointing.outputs))
    if not outputs:
        return requirements  # refused below, by name
    if say is not None:
        say(f"Auto(): how much of {', '.join(outputs)}'s scatter a line in the features carries, over {PROBE_UNITS} units "
            "drawn within the starting zones ...")
    built = design_problem(pointing, **(problem.zones.options() | problem.statistic_options()))
    x = Design(np.asarray(built.x0.nominal) + np.asarray(built.x0.band), np.asarray(built.x0.band))  # Design(middle, half-width)
    try:
        shares = dict(zip(outputs, (float(v) for v in scatter_share(pointing, outputs, x, solver.width))))
    except ValueError as error:  # too few of the units solved to fit a line: the output's name decides, as unmeasured
        if say is not None:
            say(f"Auto(): not measured ({error}); each output's model by its name")
        return requirements
    return tuple(dataclasses.replace(r, model=dataclasses.replace(r.model, share=shares[r.output]))
                 if r in pending and r.output in shares else r for r in requirements)


def _auto_notes(requirements) -> tuple[str, ...]:
    """The report's line on what `Auto()` measured and chose, per requirement it measured."""
    measured = [(r, r.model) for r in requirements if isinstance(r.model, Auto) and r.model.share is not None]
    if not measured:
        return ()
    parts = [f"{r.output} {m.share:.2f} ({'a response surface' if m.scattering_measured else 'tangents'})" for r, m in measured]
    return (f"Auto() measured, over {PROBE_UNITS} units drawn within the starting zones, the share of each output's variance a "
            f"line in the features does not carry: {', '.join(parts)}; above {SCATTER_SHARE:g} tangents, or a line through one "
            "zone's units, read scatter, and the output is fitted on a response surface over the bounds.",)


def _given(problem: ToleranceProblem) -> tuple[Requirement, ...]:
    """The problem's requirements with their constraint models (`with_model`) and the objective's
    units, each refused (`ValueError`, naming what the objective computes) where the objective
    does not compute its output."""
    pointing = problem.objective
    given = tuple(with_model(dataclasses.replace(r, unit=pointing.units.get(r.output, r.unit)))
                  for r in as_requirements(problem.requirements))
    for r in given:
        if r.output not in pointing.outputs:
            raise ValueError(f"propose_design: the pointing objective does not compute {r.output!r}, the output of the requirement "
                             f"{r.text()}; it computes {', '.join(pointing.outputs)}"
                             + (" (the jitter needs PointingObjective(..., jitter_cutoff=20.0): Hz, the start of the stability band)."
                                if r.output == "pointing_jitter" else "."))
    return given


def _requirements(problem: ToleranceProblem, solver, say=None, given=None) -> tuple[tuple[Requirement, ...], Combined]:
    """The problem's requirements (`given`, else `_given(problem)`), each with its constraint
    model resolved (an `Auto()` one measured: `_measured`) and its unit the objective's, checked
    against what the solver takes, and their models combined into one linearisation
    (`combine`)."""
    pointing = problem.objective
    requirements_ = _given(problem) if given is None else given
    yield_ = problem.yield_
    n = len(design_names(pointing.scene))
    requirements_ = _measured(problem, requirements_, solver, say)
    if pointing.uncertain_inputs:
        # Each unit draws the life's wear rate (its spread): every requirement is linearised by
        # secants over units that draw it, the line carrying it (LinearisedYield).
        if yield_ is None:
            raise ValueError(f"propose_design: each unit draws {', '.join(pointing.uncertain_inputs)} (the life's spread: the "
                             "wear rate from unit to unit); a design over it needs a yield requirement (statistic=Yield(...)).")
        requirements_ = tuple(r if r.model.resolve(r).fitted else dataclasses.replace(r, model=Secants())
                              for r in requirements_)
        if not all(r.model.resolve(r).options(r, n)["scatter"] for r in requirements_):
            raise ValueError(f"propose_design: each unit draws {', '.join(pointing.uncertain_inputs)} (the life's spread), whose "
                             "secant fits keep the scatter of what neither the features nor the rate explain: leave scatter on.")
    combined = combine(requirements_, n, problem.zones.min_clearance)
    if combined.secants and yield_ is None:
        fitted = next(r for r in requirements_ if r.model.resolve(r).fitted)
        raise ValueError(f"propose_design: the requirement {fitted.text()} needs a yield requirement (statistic=Yield(...)): "
                         f"it is fitted over units of the zone ({type(fitted.model.resolve(fitted)).__name__}: its scatter from unit "
                         "to unit is chaotic, or asked so), which reads a yield; or give it model=Tangents().")
    if combined.secants and not solver.fitted:
        raise ValueError(f"propose_design: {type(solver).__name__} takes tangent slopes only; the requirements here are fitted over "
                         "units (secants or a response surface): use Sequential().")
    if len(requirements_) > 1 and not solver.several:
        raise ValueError(f"propose_design: {type(solver).__name__} meets one requirement; several need Sequential().")
    logs = combined.options.get("log_outputs", ())
    requirements_ = tuple(resolved(r, secants=combined.secants, log_fit=r.output in logs) for r in requirements_)
    return requirements_, combined


def _tolerances(requirements_, problem, width) -> np.ndarray:
    """Each requirement's relative tolerance: its own, else 1 %, or for a secant-fitted output
    twice its fit's standard error at the start (at least 1 %, at most 50 %)."""
    tol = np.asarray([0.01 if r.tol is None else r.tol for r in requirements_], dtype=float)
    if any(r.secants and r.tol is None for r in requirements_):
        # A secant-fitted output scatters about its trend from unit to unit (chaotic rattle), so
        # its fitted value moves by about its standard error from one design to the next for no
        # other reason: a tolerance below twice that makes the optimiser chase noise.
        x0 = problem.x0
        se = np.atleast_1d(secant_standard_error(problem.objective.objective, Design(x0.nominal + x0.band, x0.band), width))
        for k, r in enumerate(requirements_):
            if r.secants and r.tol is None:
                # On the log scale (`log_outputs`) the standard error is already relative.
                relative = float(se[k]) if r.output in problem.objective.objective.log_outputs else float(se[k]) / r.limit
                tol[k] = min(max(0.01, 2.0 * relative), 0.5)
    return tol


def _outcomes(requirements_, result, baseline, targets, tol, checked) -> tuple[RequirementOutcome, ...]:
    """One `RequirementOutcome` per requirement from the optimiser's result. Its sensitivities
    are to (l, b); at fixed band a nominal shift is a shift of l, and at fixed nominal
    d/db = d/db|_l - d/dl."""
    s_limit, s_band = np.asarray(result.sensitivity.nominal), np.asarray(result.sensitivity.band)  # (m, n): a row each
    values = [np.asarray(v, dtype=float) for v in (result.objective, result.multiplier)]
    active = np.asarray(result.constraint_active, dtype=bool)
    return tuple(
        RequirementOutcome(requirement=r, objective=float(values[0][k]), baseline=float(baseline[k]), target=float(targets[k]),
                           tol=float(tol[k]), constraint_active=bool(active[k]), multiplier=float(values[1][k]),
                           sensitivity=Design(s_limit[k], s_band[k] - s_limit[k]), checks=tuple(got[k] for _, got, _ in checked))
        for k, r in enumerate(requirements_))
