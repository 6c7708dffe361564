"""What is done to a solved design before it is proposed, as functions on its result.

- `noise_band`: a design whose slopes are fitted over simulated units (secants, a response
  surface) is solved again on another set of units (`twin_problem`), from the design, against
  the requirements it was solved for; `noise_verdict` reads the two costs: where
  they differ by more than the requirements' tolerances resolve, the fitted slopes' noise, not
  the mechanism, decides the design (`"noise-limited"`).
- `drawn_on_grades`: the continuous optimum on whole ISO 286 grades (`round_to_grades`), checked
  on simulated units where the requirement is a yield, and tightened by up to `TIGHTER_GRADES`
  grades where it misses; `drawn_missed` says why a converged design's drawing is not a
  proposal.

`propose_design` calls them after every solve, whatever the solver (the recipe that holds is
the default); each can be called on a result of one's own.
"""

import dataclasses

import jax.numpy as jnp
import numpy as np

from .drawable import DrawableDesign, round_to_grades
from .loop import tolerance_worth
from .types import Design, OptimisationResult

TIGHTER_GRADES = 2  # how many grades below the continuous ones the drawable design is rounded from, at most

__all__ = ["TIGHTER_GRADES", "drawn_missed", "drawn_on_grades", "noise_band", "noise_verdict", "twin_problem"]


def drawn_on_grades(problem, result: OptimisationResult, grade, outcomes, targets, requirements, yield_=None, check=None,
                    width=None, progress=False) -> DrawableDesign:
    """The proposal as drawn: the continuous design `result` of `problem` (`DesignProblem`) on
    whole ISO grades (`round_to_grades`, from its fractional grades `grade` (n,), with its
    linear model: the `outcomes`' linearised outputs and the result's band sensitivities (m, n)
    against the `targets` (m,) it was solved for), checked on `check`'s units
    (`Check.key_for(drawn=True)`, simulated at the scene's own smoothing width against the
    linear model at `width`, m) against the `requirements` (m,) where there is a check and a
    yield `yield_`. Where it misses (its check short of the yield, or its linear model over a
    requirement), tighter grades are tried: rounded from every continuous
    grade one lower, then two (`TIGHTER_GRADES`), each checked on the same units; the first that
    meets is returned, else the last tried, its `tightened` saying how far."""
    size, lower, upper = np.asarray(problem.features.size_mm), problem.lower, problem.upper
    band, limit = np.asarray(result.x.band, dtype=float), np.asarray(result.x.nominal, dtype=float)
    requirements = np.atleast_1d(np.asarray(requirements, dtype=float))
    given = np.asarray(lower.band) == np.asarray(upper.band)
    fixed = tuple(n for n, g in zip(problem.features.names, given) if g)
    for shift in range(TIGHTER_GRADES + 1):
        d = round_to_grades(problem.features.names, size, limit, band, np.asarray(grade, dtype=float) - shift,
                            [o.objective for o in outcomes], targets, np.asarray(result.sensitivity.band),
                            lambda b: np.asarray(problem.cost_model(jnp.asarray(b), jnp.asarray(size))),
                            band_range=(np.asarray(lower.band), np.asarray(upper.band)), fixed=fixed,
                            pressure_angle=problem.features.pressure_angle)
        d = dataclasses.replace(d, tightened=shift)
        if yield_ is not None and check is not None:
            got = check.simulate(problem.objective.objective, Design(d.nominal, d.band), requirements, width, drawn=True,
                                 progress=progress)
            d = dataclasses.replace(d, checks=got)
        if d.met:
            return d
    return d


def drawn_missed(d: DrawableDesign, yield_) -> str:
    """The diagnosis of a converged design whose drawable twin (whole grades) misses: by a check
    short of the yield where one is, else by its linear model."""
    missed = [c for c in d.checks if c.missed]
    if not missed:
        return ("The continuous optimum meets the requirements, but on whole ISO grades (what a drawing carries) the linear "
                "model says it misses: " + ", ".join(f"{float(o):.4g} against {float(r):.4g}" for o, r in zip(d.objective, d.limit))
                + ". To change it: a wider band range (Zones(band_range=...)), or a looser requirement.")
    c = missed[0]
    return (f"The continuous optimum meets the requirements, but its design on whole ISO grades (what a drawing carries), "
            f"rounded from up to {d.tightened} grade(s) below the continuous ones after its checks, does not: {c.text()}, against "
            f"{yield_:.1%} asked. To change "
            "it: fit the slopes over units (model=Secants(units=...), --secant-units), more check units (Check(units=...), --check), or a "
            "looser requirement.")


def noise_band(rebuild, result: OptimisationResult, seed: int, solve) -> tuple:
    """The noise band of a design fitted over units: `rebuild(seed)` the same problem on another
    set of units (`secant_seed`), `solve(problem)` its design. Returns `(this cost, the
    other's, seed, whether the other converged)`, what `noise_verdict` reads."""
    other = solve(rebuild(seed))
    return float(result.cost), float(other.cost), int(seed), bool(other.converged)


def twin_problem(rebuild, fitted, seed: int, first_box=None):
    """The problem the noise band solves again (`noise_band`'s `rebuild`): `rebuild(**options)`
    (`design_problem` with the design's options) on another set of units, `secant_seed=seed`.
    Where `fitted` (the problem the design was last solved on) is on a response surface, the
    surface is fitted again on the other units over the same box, and, where that box is a
    later round's (not `first_box`, the first surface's `(lower, upper)`, m), the design held
    inside it as that round held it (`rounds._surface_rounds`): the fit the answer rests on, on
    other units, not the rounds' path to its box again. Secants draw their units about the
    design as it moves: the problem on other units is the twin."""
    surface = getattr(fitted.objective.objective, "surface", None)
    if surface is None:
        return rebuild(secant_seed=seed)
    lo, hi = np.asarray(surface.center - surface.half), np.asarray(surface.center + surface.half)
    twin = rebuild(secant_seed=seed, surface_box=(lo, hi))
    if first_box is not None and np.allclose(lo, first_box[0], rtol=1e-12, atol=0) and np.allclose(hi, first_box[1], rtol=1e-12, atol=0):
        return twin  # the first surface's box: the design was not held inside it
    return dataclasses.replace(twin, lower=Design(np.maximum(np.asarray(twin.lower.nominal), lo), twin.lower.band),
                               zone_upper=hi)


def noise_verdict(band, outcomes, units, other_converged=None, surface: bool = False) -> tuple[str, str]:
    """`(status, diagnosis)` from the costs of the designs found with two independent sets of
    secant units, `band = (this cost, the other's, the other's seed[, whether it converged])`
    (`noise_band`; `other_converged` where the band has three entries): converged where they
    agree to what the requirements' tolerances resolve, else noise-limited. The remedy names
    the model the units fitted (`surface`: a response surface, else secants) on more units."""
    this, that, seed = band[:3]
    other_converged = bool(band[3] if other_converged is None else other_converged)
    resolved = max(0.01 * this, tolerance_worth([o.multiplier for o in outcomes], [o.tol for o in outcomes],
                                                [o.requirement.limit for o in outcomes]))
    if abs(this - that) <= resolved and other_converged:
        return "converged", ""
    return "noise-limited", (
        f"Two independent sets of {units} secant units give designs of cost {this:.4g} (this one) and {that:.4g} (secant_seed "
        f"{seed}{'' if other_converged else ', not converged'}): a band of {abs(this - that):.3g}, more than the "
        f"{resolved:.3g} the requirements' tolerances resolve. The fitted slopes' noise, not the mechanism, decides the design. To "
        f"change it: the same {'response surface' if surface else 'secants'} on more units (the model's units={2 * units}"
        + (f", e.g. Auto(units={2 * units}) for the default" if surface else "")
        + f"; --secant-units {2 * units}, which keeps the model), or a looser tolerance on the noisy requirement.")
