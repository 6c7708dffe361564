"""Tolerance proposals on a scene: the cheapest nominal clearances/backlash and tolerance bands
whose pointing outputs meet their requirements.

`propose_design` ties together the scene's design vector (`tolerax.design.features`), its
requirements (`tolerax.design.requirements`), the problem over manufactured units
(`tolerax.design.problem`), the ISO 286-anchored cost model (`tolerax.design.cost`), an
optimiser (`sequential_design` by default, or the augmented Lagrangian on optax), the Monte
Carlo checks of a yield (`tolerax.design.reliability`), and returns a `DesignReport` that says
whether its answer is a proposal (`tolerax.design.outcome`).
"""


import dataclasses
import functools

import jax
import jax.numpy as jnp
import numpy as np
import optax
from .cost import grade_of
from .features import design_names, lost_motion_weights
from .objectives import AbstractObjective
from .drawable import round_to_grades
from .fidelity import check_fidelity
from .outcome import diagnose, tightest_reach
from .loop import tolerance_worth
from .optimise import optimise_design
from .check import yield_check
from .surface import secant_standard_error
from .rounds import _as_requirement, _secant_rescue, _solve_and_check
from .sequential import sequential_design
from .subproblem import objective_value_and_gradient
from .types import Design
# The problem and the report live in their own modules; importable from here too (public paths users call).
from .problem import DesignProblem, FromLowerLimit, OnHalfWidth, RobustPointing, design_problem, feature_sizes  # noqa: F401
from .report import DesignReport, JitterRequirement, RequirementOutcome  # noqa: F401
from .requirements import Requirement, as_requirements  # noqa: F401


def propose_design(
    pointing: AbstractObjective,
    requirement: float,
    *,
    widths=(1e-6, 1e-7),
    max_outer: int | None = None,
    inner_steps: int = 10,
    learning_rate: float = 0.1,
    method: str = "sequential",
    progress: bool = False,
    callback=None,
    check_units: int | None = None,
    max_checks: int = 3,
    check_key=None,
    jitter: float | None = None,
    noise_band: bool | None = None,
    allow_proxy: bool = False,
    surface_rounds: int = 4,
    **problem,
) -> DesignReport:
    """Propose nominal clearances/backlash and tolerance bands for `pointing.scene` that meet
    `requirement` (arcsec, on `statistic` of `output` over `n_draws` manufactured units) at the
    lowest cost.

    The optimiser varies, per feature, the lower limit $l$ of the tolerance zone (the smallest
    clearance or backlash a part may have) and its half-width $b$; the zone is $[l, l + 2b]$, the
    nominal $l + b$ (`FromLowerLimit`). Only the bands cost; the lower limits may not go below
    `min_clearance`, the functional minimum (thermal growth over the orbit's temperature swing,
    the lubricant film, no jamming) — without it the optimum would be a zero-clearance nominal.

    Infeasible first: before optimising, the objective is evaluated at the tightest designs the
    bounds allow (every band and lower limit at its smallest, and on the bounds the baseline's
    sensitivities say lower each output: `tolerax.design.outcome.tightest`). Where both miss a
    requirement no design within the bounds meets it: the report is that design's, `status`
    `"infeasible"`, with the requirement that would be met, and no optimiser runs.

    **Arguments:**

    - `pointing`: the `PointingObjective` (scene, horizon, window), or any `AbstractObjective`
      (a closed-form model of the outputs); its scene's current design is the starting nominal.
    - `requirement`: what the design must meet: a number (the limit of `output`, by default
      the RMS pointing error, arcsec), a `Requirement` (an output and its limit), or a
      sequence of them (each met on its own at the problem's statistic or yield; e.g.
      `[Requirement("pointing_rms", 700), Requirement("pointing_peak", 2500)]`).
    - `widths`: smoothing widths (m), wide to narrow; the proposal is judged at the last. The
      sequential method solves at each in turn from the last design; the augmented Lagrangian
      takes one value per outer iteration, the last repeated. A wide first width makes the
      sequential method robust to its start: the contacts make the narrow objective rough far
      from the optimum.
    - `method`: `"sequential"` (default: `sequential_design`, the linearised problem solved
      exactly at each iterate in a trust region, once per width of `widths`, each from the last
      one's design; at most `max_outer` gradients per width, default 20; where the tangent
      slopes stall (the trust region collapses on a rough response), the last width is solved
      again from there on secant slopes over units, `_secant_rescue`, and the report's `notes`
      say so; `inner_steps` and `learning_rate` unused) or `"augmented-lagrangian"` (`optimise_design`: Adam on the
      augmented Lagrangian, on optax, with the `widths` continuation; `max_outer` outer
      iterations, default 6, of `inner_steps` steps at `learning_rate`).
      `benchmarks/design_comparison.py` races the two, SciPy's SLSQP, a calibrated
      stack-up and derivative-free search.
    - `progress`: a progress bar over the optimiser's iterations.
    - `callback`: `method="sequential"` only: `callback(gradients, x, cost, objective)` after
      every gradient evaluation (`sequential_design`; `x.nominal` holds the lower limits).
    - `check_units`, `max_checks`, `check_key`: with a yield requirement (`yield_`), the
      proposal is checked on `check_units` fresh simulated units (default 200; 0: no check;
      `yield_check`, units from `check_key`, default `jax.random.key(1)`) and, where the linear
      model under- or over-reads their `yield_` quantile by more than 1 % of `requirement` and
      twice the check's standard error, the requirement the optimiser sees is shifted by the
      difference and the design solved again from where it was, at most `max_checks` checks
      (`method="sequential"` only).
    - `noise_band` (default: where a requirement is fitted by secants): solve the design again
      with an independent set of secant units (`secant_seed` + 1) and report both costs
      (`DesignReport.noise_band`). Where they differ by more than the requirements' tolerances
      resolve (the larger of 1 % of the cost and $\\sum_j \\lambda_j\\,\\text{tol}_j R_j$),
      the fitted slopes' noise decides the design: the status is `"noise-limited"`.
    - `jitter` (arcsec, optional): a pointing-stability requirement beside the lost-motion one:
      the `yield_` quantile of `pointing_jitter` (the RMS of the pointing error above
      `pointing.jitter_cutoff` Hz over the window; set `PointingObjective(jitter_cutoff=...)`)
      at most `jitter`. Needs `yield_`. Both metrics are linearised by secants over
      `secant_units` units of the zone (default max(16, 2 x features + 2); jitter tangents are
      not its slopes: rattle is chaotic and a tangent grows exponentially with the horizon), from the same
      solves (their quantiles include the fits' residual scatter, `scatter=True`, unless
      `scatter=False` is given), so at the pointing objective's fidelity: give a planetary one (lumped jitter does
      not predict the planetary stage's unit by unit). The jitter's tolerance is twice its fit's standard error at the start
      (`secant_standard_error`, at least 1 %, at most 50 %); the optimiser is told the slopes'
      noise (`DesignProblem.gradient_noise`); each check simulates both metrics on the same
      units and may shift either requirement. The report's `jitter` holds that part.
    - A pointing objective with a life whose wear rate has a `spread` (`MissionLife(spread=...)`,
      a scene's `[life] spread`): every requirement is linearised by secants over units that
      each draw their rate, the line carrying the rate and the quantile drawing it
      (`LinearisedYield`, uncertain inputs), so that the design meets its yield over the rate's
      band, not at one estimate.
    - `surface_rounds` (with `surface_box`): at most this many response surfaces, each after the
      first fitted over a box about the zones the last one's design gave (each middle +- 1.5
      half-widths, or +- `secant_reach` where wider) and the design solved again on it from
      there, held inside that box (a line is trusted where it was fitted), until the boxes
      settle (moving them would move each output by at most its requirement's tolerance along
      the surface's slopes); then the checks, whose re-solves stay in the last box. A surface over
      the whole bounds finds where the requirement can be met but reads the quantile where the
      design lands with the bounds' average misfit; the last surface is fitted over that
      design's own units.
      1: the one surface over `surface_box`. The report's `notes` list the boxes.
    - `allow_proxy`: design requirements whose output the scene's joints do not read as the
      full stage does (a jitter requirement on a lumped or mass-scaled joint:
      `tolerax.design.fidelity`) instead of refusing them; the report's `notes` say so.
    - `**problem`: the problem's options, as `design_problem` takes them: the starting band
      or starting zones (`start`, a `Tolerances`, e.g. `SceneFile.tolerances()`), functional
      minima, band range, manufactured units, robust statistic or `yield_`, cost model,
      gradient mode, `fixed` features (names, half-widths or a `Tolerances`).

    **Returns:** a `DesignReport`.
    """
    if method not in ("augmented-lagrangian", "sequential"):
        raise ValueError(f"propose_design: method must be 'augmented-lagrangian' or 'sequential', got {method!r}.")
    if callback is not None and method != "sequential":
        raise ValueError("propose_design: callback is supported by method='sequential' only.")
    yield_ = problem.get("yield_")
    problem_fixed = tuple(problem.get("fixed", ()))
    check_units = (200 if yield_ is not None else 0) if check_units is None else int(check_units)
    if check_units and yield_ is None:
        raise ValueError("propose_design: check_units needs a yield requirement (yield_=...), the thing it checks.")
    if check_units and method != "sequential":
        raise ValueError("propose_design: a yield requirement's Monte Carlo check needs method='sequential' (or check_units=0).")
    if max_outer is None:
        max_outer = 20 if method == "sequential" else 6
    if int(surface_rounds) < 1:
        raise ValueError(f"propose_design: surface_rounds must be >= 1 (1: one response surface), got {surface_rounds!r}.")
    requirements_, options = _requirements_and_options(pointing, requirement, jitter, method, yield_, problem)
    proxy_notes = tuple(check_fidelity(pointing.scene, requirements_, allow_proxy=allow_proxy))
    problem = design_problem(pointing, **options)
    widths = tuple(float(w) for w in widths)
    baseline, slopes = _value_and_sensitivity(problem, problem.x0, widths[-1])
    requirements, tol = np.asarray([r.limit for r in requirements_], dtype=float), _tolerances(requirements_, problem, widths[-1])
    checked, twin_costs, notes = [], None, proxy_notes  # checked: (result, its checks: one per requirement, the requirements it was solved for)
    evaluate = _memoised_values(widths[-1])
    out_of_reach = _tightest_first(evaluate, problem, slopes, requirements, tol)
    if out_of_reach is not None:
        # Infeasible first: the tightest designs the bounds allow miss a requirement, so no design
        # within them meets it; the optimiser is not run. The report is that design's, evaluated.
        result = sequential_design(
            problem.objective, problem.features, requirement=_as_requirement(requirements), lower=problem.lower, upper=problem.upper,
            draws=problem.draws, x0=out_of_reach, cost_model=problem.cost_model, width=widths[-1], max_iterations=0, tol=tuple(tol),
            zone_upper=problem.zone_upper)
        targets = requirements
        notes += ("Answered before optimising: the tightest designs the bounds allow (every band and lower limit at its smallest, "
                  "and on the bounds the baseline's sensitivities say lower each output) already miss the requirement, so no "
                  "design within the bounds meets it; the optimiser was not run.",)
    elif method == "sequential":
        key = jax.random.key(1) if check_key is None else check_key
        rounds = None if options.get("surface_box") is None else (int(surface_rounds), options.get("surface_width"),
                                                                   options.get("secant_reach"))
        problem, result, checked, zoomed = _solve_and_check(problem, requirements, tol, widths, max_outer, progress, callback,
                                                            check_units, max_checks, key, rounds=rounds)
        notes += zoomed
        if bool(result.stalled) and options.get("secant_units") is None:
            problem, result, checked, rescue = _secant_rescue(pointing, options, problem, result, checked, requirements, tol, widths,
                                                      max_outer, progress, callback, check_units, max_checks, key)
            notes += rescue
        targets = checked[-1][2] if checked else requirements  # the (shifted) requirements the returned design was solved for
        if noise_band if noise_band is not None else any(r.secants for r in requirements_):
            seed = int(options.get("secant_seed", 1)) + 1
            twin = design_problem(pointing, **(options | {"secant_seed": seed}))
            _, other, _, _ = _solve_and_check(twin, requirements, tol, widths, max_outer, progress, None, check_units, max_checks, key,
                                              rounds=rounds)
            twin_costs = (float(result.cost), float(other.cost), seed)
    else:
        schedule = lambda i: jnp.asarray(widths)[jnp.minimum(i, len(widths) - 1)]  # noqa: E731
        result = optimise_design(
            problem.objective, problem.features, requirement=float(requirements[0]), lower=problem.lower, upper=problem.upper,
            draws=problem.draws, x0=problem.x0, cost_model=problem.cost_model, optimiser=optax.adam(learning_rate),
            continuation=schedule, max_outer=max_outer, inner_steps=inner_steps, tol=1e-3, progress=progress,
        )
        targets = requirements
    what = "" if yield_ is None else f" ({yield_:.1%} quantile)"
    status, diagnosis = diagnose(
        objective=result.objective, requirement=targets, tol=tol, converged=bool(result.converged),
        iterations=int(np.asarray(result.history.steps)[-1]), labels=[r.name + what for r in requirements_],
        evaluate=functools.partial(evaluate, problem), lower=problem.lower,
        upper=problem.upper, sensitivity=np.atleast_2d(np.asarray(result.sensitivity.nominal)) / requirements[:, None],
        checks=checked[-1][1] if checked else (), yield_=yield_, noisy=problem.gradient_noise is not None,
        bounds_text=" (min_clearance and band_range; a scene file's [tolerances])", stalled=bool(result.stalled is not None and result.stalled))
    outcomes = _outcomes(requirements_, result, baseline, targets, tol, checked)
    if twin_costs is not None and status == "converged":
        status, diagnosis = _noise_verdict(twin_costs, outcomes, options.get("secant_units"), bool(other.converged))
    drawable = None
    first, band = outcomes[0], np.asarray(result.x.band)
    grade = np.asarray(grade_of(band * 2, problem.features.size_mm))
    if method == "sequential":
        drawable = _drawable(problem, result, grade, outcomes, targets, requirements, yield_, check_units if status == "converged" else 0,
                             widths, jax.random.key(2) if check_key is None else jax.random.fold_in(check_key, 1))
        if status == "converged" and not drawable.met:
            # One proposal: what the drawing carries is the answer, so a continuous optimum whose
            # whole grades miss is not a proposal.
            status, diagnosis = "check missed", _drawable_missed(drawable, yield_)
    jitter_outcome = next((o for o in outcomes if o.requirement.output == "pointing_jitter"), None)
    features, x0 = problem.features, problem.x0
    return DesignReport(
        names=features.names, nominal=np.asarray(result.x.nominal) + band, band=band,
        grade=grade, feature_cost=np.asarray(result.feature_cost), cost=float(result.cost),
        objective=first.objective, requirement=first.requirement.limit, constraint_active=first.constraint_active,
        multiplier=first.multiplier, sensitivity=first.sensitivity,
        baseline=(np.asarray(x0.nominal + x0.band), np.asarray(x0.band), float(problem.cost_model.total(x0.band, features.size_mm)),
                  first.baseline),
        result=result, yield_=yield_, checks=first.checks, lost_motion=np.asarray(lost_motion_weights(pointing.scene)),
        fixed=tuple(problem_fixed), jitter=None if jitter_outcome is None else JitterRequirement.of(jitter_outcome, getattr(pointing, "jitter_cutoff", None)),
        solved_for=first.target if method == "sequential" else None, status=status, diagnosis=diagnosis, outcomes=outcomes,
        noise_band=None if twin_costs is None else twin_costs[:2], notes=notes, cost_unit=problem.cost_model.unit,
        grade_range=problem.cost_model.grade_range, drawable=drawable,
    )


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
        return memo[key][1]

    return evaluate


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


TIGHTER_GRADES = 2  # how many grades below the continuous ones the drawable design is rounded from, at most


def _drawable(problem, result, grade, outcomes, targets, requirements, yield_, check_units, widths, key):
    """The proposal as drawn: the continuous design on whole ISO grades (`round_to_grades`,
    from its grades `grade`, with its linear model against what it was solved for), checked on
    `check_units` simulated units against the requirements where there is a yield. Where it
    misses (its check short of the yield, or its linear model over a requirement), tighter
    grades are tried: rounded from every continuous grade one lower, then two (`TIGHTER_GRADES`),
    each checked on the same units; the first that meets is returned, else the last tried, its
    `tightened` saying how far."""
    size, lower, upper = np.asarray(problem.features.size_mm), problem.lower, problem.upper
    band, limit = np.asarray(result.x.band, dtype=float), np.asarray(result.x.nominal, dtype=float)
    given = np.asarray(lower.band) == np.asarray(upper.band)
    fixed = tuple(n for n, g in zip(problem.features.names, given) if g)
    for shift in range(TIGHTER_GRADES + 1):
        d = round_to_grades(problem.features.names, size, limit, band, np.asarray(grade, dtype=float) - shift,
                            [o.objective for o in outcomes], targets, np.atleast_2d(np.asarray(result.sensitivity.band)),
                            lambda b: np.asarray(problem.cost_model(jnp.asarray(b), jnp.asarray(size))),
                            band_range=(np.asarray(lower.band), np.asarray(upper.band)), fixed=fixed,
                            pressure_angle=problem.features.pressure_angle)
        d = dataclasses.replace(d, tightened=shift)
        if yield_ is not None and check_units:
            got = yield_check(problem.objective.objective, Design(d.nominal, d.band), _as_requirement(requirements), check_units,
                              key, widths[-1])
            d = dataclasses.replace(d, checks=got if requirements.shape[0] > 1 else (got,))
        if d.met:
            return d
    return d


def _drawable_missed(d, yield_) -> str:
    """The diagnosis of a converged design whose drawable twin (whole grades) misses: by a check
    short of the yield where one is, else by its linear model."""
    missed = [c for c in d.checks if c.interval[1] < c.q]
    if not missed:
        return ("The continuous optimum meets the requirements, but on whole ISO grades (what a drawing carries) the linear "
                "model says it misses: " + ", ".join(f"{float(o):.4g} against {float(r):.4g}" for o, r in zip(d.objective, d.limit))
                + ". To change it: a wider band range (band_range), or a looser requirement.")
    c = missed[0]
    return (f"The continuous optimum meets the requirements, but its design on whole ISO grades (what a drawing carries), "
            f"rounded from up to {d.tightened} grade(s) below the continuous ones after its checks, does not: {c.text()}, against "
            f"{yield_:.1%} asked. To change "
            "it: fit the slopes over units (secant_units, --secant-units), more check units (check_units, --check), or a "
            "looser requirement.")


def _noise_verdict(band, outcomes, units, other_converged) -> tuple[str, str]:
    """`(status, diagnosis)` from the costs of the designs found with two independent sets of
    secant units, `band = (this cost, the other's, the other's seed)`: converged where they agree
    to what the requirements' tolerances resolve, else noise-limited."""
    this, that, seed = band
    resolved = max(0.01 * this, tolerance_worth([o.multiplier for o in outcomes], [o.tol for o in outcomes],
                                                [o.requirement.limit for o in outcomes]))
    if abs(this - that) <= resolved and other_converged:
        return "converged", ""
    return "noise-limited", (
        f"Two independent sets of {units} secant units give designs of cost {this:.4g} (this one) and {that:.4g} (secant_seed "
        f"{seed}{'' if other_converged else ', not converged'}): a band of {abs(this - that):.3g}, more than the "
        f"{resolved:.3g} the requirements' tolerances resolve. The fitted slopes' noise, not the mechanism, decides the design. To "
        "change it: more secant units (secant_units, --secant-units), or a looser tolerance on the noisy requirement.")


def _requirements_and_options(pointing, requirement, jitter, method, yield_, options):
    """The requirements (`Requirement`s) of `propose_design`'s arguments, checked against what
    the pointing objective computes and the method, and `design_problem`'s options for them
    (secant units, with their scatter, where a requirement is linearised by secants)."""
    requirements_ = tuple(dataclasses.replace(r, unit=pointing.units.get(r.output, r.unit))
                          for r in as_requirements(requirement, jitter, options.get("output", "pointing_rms")))
    if pointing.uncertain_inputs:
        # Each unit draws the life's wear rate (its spread): every requirement is linearised by
        # secants over units that draw it, the line carrying it (LinearisedYield).
        if yield_ is None or method != "sequential":
            raise ValueError(f"propose_design: each unit draws {', '.join(pointing.uncertain_inputs)} (the life's spread: the "
                             "wear rate from unit to unit); a design over it needs a yield requirement (yield_=..., --yield) "
                             "and method='sequential'.")
        if options.get("scatter") is False:
            raise ValueError(f"propose_design: each unit draws {', '.join(pointing.uncertain_inputs)} (the life's spread), whose "
                             "secant fits keep the scatter of what neither the features nor the rate explain: leave scatter on.")
        requirements_ = tuple(r if r.secants else dataclasses.replace(r, secants=True) for r in requirements_)
    for r in requirements_:
        if r.output not in pointing.outputs:
            raise ValueError(f"propose_design: the pointing objective does not compute {r.output!r}, the output of the requirement "
                             f"{r.text()}; it computes {', '.join(pointing.outputs)}"
                             + (" (the jitter needs PointingObjective(..., jitter_cutoff=20.0): Hz, the start of the stability band)."
                                if r.output == "pointing_jitter" else "."))
        if r.secants and (yield_ is None or method != "sequential"):
            raise ValueError(f"propose_design: the requirement {r.text()} needs a yield requirement (yield_=...) and "
                             "method='sequential': it is linearised by secants over units of the zone, not by tangents (its "
                             "scatter from unit to unit is chaotic).")
    if len(requirements_) > 1 and method != "sequential":
        raise ValueError("propose_design: several requirements need method='sequential'.")
    options = dict(options)
    options["output"] = requirements_[0].output if len(requirements_) == 1 else tuple(r.output for r in requirements_)
    if any(r.secants for r in requirements_):
        if options.get("secant_units") is None:
            options["secant_units"] = max(16, 2 * len(design_names(pointing.scene)) + 2)
        options.setdefault("scatter", True)
        options.setdefault("log_outputs", tuple(r.output for r in requirements_ if r.secants and r.log_fit))
    return requirements_, options


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
    s_limit, s_band = np.atleast_2d(np.asarray(result.sensitivity.nominal)), np.atleast_2d(np.asarray(result.sensitivity.band))
    values = [np.atleast_1d(np.asarray(v, dtype=float)) for v in (result.objective, result.multiplier)]
    active = np.atleast_1d(np.asarray(result.constraint_active, dtype=bool))
    return tuple(
        RequirementOutcome(requirement=r, objective=float(values[0][k]), baseline=float(baseline[k]), target=float(targets[k]),
                           tol=float(tol[k]), constraint_active=bool(active[k]), multiplier=float(values[1][k]),
                           sensitivity=Design(s_limit[k], s_band[k] - s_limit[k]), checks=tuple(got[k] for _, got, _ in checked))
        for k, r in enumerate(requirements_))
