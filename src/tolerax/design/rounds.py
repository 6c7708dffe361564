"""The solve rounds `propose_design` runs: the sequential optimiser continued from wide to narrow
smoothing widths (`_sequential_continuation`), the Monte Carlo check and re-solve of a yield
design against a shifted requirement (SORA: `_solve_and_check`), response-surface rounds that
refit where the design leaves the surface's box (`_surface_rounds`), and the secant rescue of a
tangent design that stalled (`_secant_rescue`). Each returns an `OptimisationResult` whose history
chains its rounds (`_chain`).
"""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

from .check import yield_check
from .outcome import MODEL_OFF
from .problem import DesignProblem, design_problem
from .sequential import sequential_design
from .types import Design


def _sequential_continuation(problem: DesignProblem, requirement, widths, max_iterations, progress, callback=None, x0=None, trust=0.5,
                             tol=0.01):
    """`sequential_design` once per smoothing width, wide to narrow, each started from the
    last design with a smaller trust region (a wide width smooths the contact onsets that make
    a narrow width's gradients unreliable far from the optimum); one result whose history runs
    over all of them. Where the slopes are fitted over units, the optimiser is told their
    noise (`DesignProblem.gradient_noise`)."""
    results, x = [], problem.x0 if x0 is None else x0
    for k, width in enumerate(widths):
        done = sum(int(np.asarray(r.history.steps)[-1]) for r in results)  # gradients before this width
        result = sequential_design(
            problem.objective, problem.features, requirement=requirement, lower=problem.lower, upper=problem.upper,
            draws=problem.draws, x0=x, cost_model=problem.cost_model, width=width, max_iterations=max_iterations,
            trust_region=trust if k == 0 else 0.1, progress=progress, tol=tol, gradient_noise=problem.gradient_noise,
            callback=None if callback is None else (lambda i, *rest, done=done: callback(done + i, *rest)),
            zone_upper=problem.zone_upper,
        )
        results.append(result)
        x = result.x
    return _chain(results)


def _chain(results):
    """The last of successive `OptimisationResult`s (each started from the one before) with one
    history over all of them: its gradient counts run on, its `iteration` indexes the whole."""
    offset = sum(len(np.asarray(r.history.cost)) for r in results[:-1])
    steps = np.cumsum([int(np.asarray(r.history.steps)[-1]) for r in results])
    history = jax.tree.map(lambda *h: jnp.concatenate(h), *[r.history for r in results])
    counts = np.concatenate([np.asarray(r.history.steps) + (steps[i - 1] if i else 0) for i, r in enumerate(results)])
    history = eqx.tree_at(lambda h: h.steps, history, jnp.asarray(counts, dtype=float))
    last = results[-1]
    return eqx.tree_at(lambda r: (r.history, r.iteration), last, (history, last.iteration + offset))


def _cheapest_accepted(costs, quantiles, requirement, tol=0.01):
    """Index of the cheapest design whose simulated quantile met `requirement` to `tol` (each
    of them, with several requirements: `quantiles` one array per design), or `None` where none
    did."""
    ok = [k for k, q in enumerate(quantiles) if np.all(np.asarray(q) <= np.asarray(requirement) * (1 + np.asarray(tol)))]
    return min(ok, key=lambda k: costs[k]) if ok else None


def _secant_rescue(pointing, options, problem, result, checked, requirements, tol, widths, max_outer, progress, callback, check_units,
                   max_checks, key):
    """Where the tangent-slope design stalled (its trust region collapsed: the response is
    rough at the judging width), solve the last width again from the stalled design with the
    slopes fitted by secants over units of the zone (`design_problem(secant_units=...)`, as
    many as the jitter's default): what the stall's diagnosis advises, done once. Returns
    `(problem, result, checked)`: the secant solve's where it converged, or where it met its
    requirements at a lower cost (its history continuing the stalled one's); else the tangent
    solve's; and a note saying what was done."""
    units = max(16, 2 * len(problem.features.names) + 2)
    secant = design_problem(pointing, **(options | {"secant_units": units}))
    _, again, again_checked, _ = _solve_and_check(secant, requirements, tol, widths[-1:], max_outer, progress, callback, check_units,
                                                  max_checks, key, x0=result.x, trust=0.1)
    met = np.all(np.atleast_1d(np.asarray(again.objective, dtype=float)) <= requirements * (1 + tol))
    note = (f"The tangent slopes stalled at the {widths[-1]:.2g} m width after {int(np.asarray(result.history.steps)[-1])} "
            f"gradients; the design was finished from there on secant slopes over {units} units of the zone "
            f"({'converged' if bool(again.converged) else 'not converged'}).")
    if bool(again.converged) or (met and float(again.cost) < float(result.cost)):
        return secant, _chain([result, again]), again_checked, (note,)
    return problem, result, checked, (note + " The tangent design is kept.",)


def _as_requirement(requirements):
    """The requirements (m,) as the optimisers and `yield_check` take them: a float for one, a
    tuple of m floats for several."""
    return float(requirements[0]) if len(requirements) == 1 else tuple(float(v) for v in requirements)


ZONE_ROOM = 1.5  # a surface round's box: the last design's zone middle +- this many half-widths (or secant_reach)


def _surface_rounds(problem, result, rounds, width, reach, requirements, tol, widths, max_outer, progress, callback):
    """`propose_design(surface_rounds=...)`: the response surface fitted again over a box about
    the zones `result`'s design gave (each zone's middle +- `ZONE_ROOM` half-widths, or +-
    `reach` (m) where that is wider; moved up where it would reach below zero) and the design
    solved again on it from there, its zones held inside that box (lower limits at least the
    box's lower edge, `DesignProblem.zone_upper` its upper edge): a line is trusted only where
    it was fitted, and a feature whose fitted slope is noise would otherwise carry its zone
    (free to move: it costs nothing) far outside the box, where the quantile is read off an
    extrapolation.
    Until the boxes settle (moving the box's edges would change each output by at most its
    requirement's tolerance `tol` along the surface's slopes) or `rounds` surfaces were
    fitted. Returns `(problem, trusted, result, notes)`: the problem on the last surface, the
    same held to its box (for re-solves from the design), the design (its history continuing
    `result`'s) and a note listing the boxes."""
    surface = problem.objective.objective.surface
    boxes = [(np.asarray(surface.center - surface.half), np.asarray(surface.center + surface.half))]
    settled, trusted = False, problem
    for _ in range(rounds - 1):
        band = np.asarray(result.x.band, dtype=float)
        middle = np.asarray(result.x.nominal, dtype=float) + band
        half = np.maximum(ZONE_ROOM * band, 0.0 if reach is None else float(reach))
        lo = np.maximum(middle - half, 0.0)
        hi = lo + 2.0 * half
        last_lo, last_hi = boxes[-1]
        inner = problem.objective.objective
        # Settled: moving the box's edges would change each output by no more than its
        # requirement's tolerance along the surface's slopes (a feature the output does not
        # depend on may drift; its box does not matter).
        moved = np.abs(np.asarray(inner.surface.slopes)) @ np.maximum(np.abs(lo - last_lo), np.abs(hi - last_hi))
        if np.all(moved <= tol * np.where(inner.log, 1.0, requirements)):
            settled = True
            break
        problem = problem.refit_surface(lo, hi, width)
        trusted = dataclasses.replace(problem, lower=Design(np.maximum(np.asarray(problem.lower.nominal), lo), problem.lower.band),
                                      zone_upper=hi)
        boxes.append((lo, hi))
        again = _sequential_continuation(trusted, _as_requirement(requirements), widths[-1:], max_outer, progress, callback,
                                         x0=result.x, trust=0.5, tol=tuple(tol))
        result = _chain([result, again])
    if len(boxes) == 1:
        return problem, trusted, result, ()
    text = "; ".join(f"[{', '.join(f'{a * 1e6:.3g}-{b * 1e6:.3g}' for a, b in zip(lo, hi))}] um" for lo, hi in boxes)
    return problem, trusted, result, (
        f"Designed on {len(boxes)} response surfaces, each after the first fitted over a box about the last design's zones "
        f"and the design held inside it ({text}); "
        + ("the boxes settled." if settled else f"the boxes had not settled after {rounds} (surface_rounds)."),)


def _solve_and_check(problem, requirements, tol, widths, max_outer, progress, callback, check_units, max_checks, key, x0=None,
                     trust=0.5, rounds=None):
    """The sequential design with its Monte Carlo checks: `(problem, result, checked, notes)`,
    `checked` one `(result, checks (one per requirement), requirements solved for)` per check,
    the last the returned design's. With `rounds` (`(surface_rounds, surface_width,
    secant_reach)`), first the response surface's rounds (`_surface_rounds`: `problem` is then
    the one on the last surface, `notes` say what was done; re-solves keep the design in that
    surface's box). Where a check finds the linear
    model off by more than its noise (and by less than `MODEL_OFF` of the requirement), the
    requirements are shifted by that (SORA) and the design solved again from where it was. A
    design that misses what it was solved for is not checked."""
    m = requirements.shape[0]
    result = _sequential_continuation(problem, _as_requirement(requirements), widths, max_outer, progress, callback, x0=x0,
                                      trust=trust, tol=tuple(tol))
    notes, trusted = (), problem
    if rounds is not None:
        problem, trusted, result, notes = _surface_rounds(problem, result, *rounds, requirements, tol, widths, max_outer, progress,
                                                          callback)
    target, checked = requirements.copy(), []
    for _ in range(max_checks if check_units else 0):
        if np.any(np.atleast_1d(np.asarray(result.objective, dtype=float)) > target * (1 + tol)):
            break  # the design misses what it was solved for (infeasible, or not converged): nothing to check
        middle = Design(result.x.nominal + result.x.band, result.x.band)
        got = yield_check(problem.objective.objective, middle, _as_requirement(requirements), check_units, key, widths[-1])
        got = got if m > 1 else (got,)
        checked.append((result, got, target.copy()))
        shift = np.array([c.shift for c in got])
        if np.any(np.abs(shift) > MODEL_OFF * requirements):
            break  # the linear model does not hold here: no shift of it would (`diagnose` says so)
        corrected = requirements - shift
        # a shift within the check's own noise (or the method's tolerance) is not one
        noise = np.maximum(tol * requirements, 2.0 * np.array([c.shift_se for c in got]))
        moved = np.abs(corrected - target) > noise
        if not np.all(np.isfinite(corrected)) or not np.any(moved) or len(checked) == max_checks:
            break
        target = np.where(moved, corrected, target)
        again = _sequential_continuation(trusted, _as_requirement(target), widths[-1:], max_outer, progress, callback, x0=result.x,
                                         trust=0.1, tol=tuple(tol))
        result = _chain([result, again])  # its history (gradients) continues the one before
    # The proposal: the cheapest checked design whose simulated quantile met the requirement
    # (to the method's tolerance), else the last one: a re-solve that did not land is not
    # kept over a cheaper design the simulation already accepted.
    k = _cheapest_accepted([float(r.cost) for r, _, _ in checked], [[c.quantile_simulated for c in got] for _, got, _ in checked],
                           requirements, tol)
    if k is not None:
        checked = checked[: k + 1]
        result = checked[-1][0]
    return problem, result, checked, notes
