"""The solve rounds `propose_design` runs through its solver (`tolerax.design.solvers`): the
solve and its Monte Carlo check (`_solve_and_check`, the check's loop in `Check.run`),
response-surface rounds that refit where the design leaves the surface's box
(`_surface_rounds`), and the secant rescue of a tangent design that stalled (`_secant_rescue`).
Each returns an `OptimisationResult` whose history chains its rounds (`chain_results`).
"""

import dataclasses

import numpy as np

from .check import as_requirement
from .types import Design, chain_results


def _secant_rescue(rebuild, problem, result, checked, requirements, tol, solver, check, progress, callback, say=None, why="stalled"):
    """Where the tangent-slope design stalled (its trust region collapsed: the response is
    rough at the judging width), or its check found the tangents' linear model off (`why` says
    which), solve the last width again from the design reached with the
    slopes fitted by secants over units of the zone (`rebuild(secant_units=...)`: the problem
    again with that many, as the jitter's default), what the stall's diagnosis advises, done
    once. Returns `(problem, result, checked, notes)`: the secant solve's where it converged,
    or where it met its requirements at a lower cost (its history continuing the stalled
    one's); else the tangent solve's; and a note saying what was done."""
    units = max(16, 2 * len(problem.features.names) + 2)
    secant = rebuild(secant_units=units)
    _, again, again_checked, _ = _solve_and_check(secant, requirements, tol, solver, check, progress, callback, x0=result.x, say=say)
    met = np.all(np.asarray(again.objective, dtype=float) <= requirements * (1 + tol))
    note = (f"The tangent slopes {why} at the {solver.width:.2g} m width after {int(np.asarray(result.history.steps)[-1])} "
            f"gradients; the design was finished from there on secant slopes over {units} units of the zone "
            f"({'converged' if bool(again.converged) else 'not converged'}).")
    if bool(again.converged) or (met and float(again.cost) < float(result.cost)):
        return secant, chain_results([result, again]), again_checked, (note,)
    return problem, result, checked, (note + " The tangent design is kept.",)


ZONE_ROOM = 1.5  # a surface round's box: the last design's zone middle +- this many half-widths (or secant_reach)
ROUND_STEP = 0.5  # a surface round's re-solve: its first step (relative), as a fresh solve's


def _surface_rounds(problem, result, rounds, width, reach, requirements, tol, solver, progress, callback, say=None):
    """A `Surface` model's rounds (at most `rounds` surfaces): the response surface fitted again over a box about
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
        if say is not None:
            say(f"response surface {len(boxes) + 1} (of at most {rounds}): refitted over the last design's zones ...")
        problem = problem.refit_surface(lo, hi, width)
        trusted = dataclasses.replace(problem, lower=Design(np.maximum(np.asarray(problem.lower.nominal), lo), problem.lower.band),
                                      zone_upper=hi)
        boxes.append((lo, hi))
        again = solver.solve(trusted, as_requirement(requirements), tol, x0=result.x, step=ROUND_STEP, progress=progress,
                             callback=callback)
        result = chain_results([result, again])
    if len(boxes) == 1:
        return problem, trusted, result, ()
    text = "; ".join(f"[{', '.join(f'{a * 1e6:.3g}-{b * 1e6:.3g}' for a, b in zip(lo, hi))}] um" for lo, hi in boxes)
    return problem, trusted, result, (
        f"Designed on {len(boxes)} response surfaces, each after the first fitted over a box about the last design's zones "
        f"and the design held inside it ({text}); "
        + ("the boxes settled." if settled else f"the boxes had not settled after {rounds} (Surface(rounds=...))."),)


def _solve_and_check(problem, requirements, tol, solver, check, progress, callback, x0=None, rounds=None, say=None):
    """The design through `solver` with its Monte Carlo `check` (a `Check`, or `None`):
    `(problem, result, checked, notes)`, `checked` one `(result, checks (one per requirement),
    requirements solved for)` per check (`Check.run`), the last the returned design's. From
    `problem.x0` over the solver's widths, or from `x0` at its last. With `rounds` (`(surface
    rounds, surface width (m), secant reach (m))`), first the response surface's rounds (`_surface_rounds`: `problem`
    is then the one on the last surface, `notes` say what was done; re-solves keep the design in
    that surface's box)."""
    result = solver.solve(problem, as_requirement(requirements), tol, x0=x0, progress=progress, callback=callback)
    notes, trusted = (), problem
    if rounds is not None:
        problem, trusted, result, notes = _surface_rounds(problem, result, *rounds, requirements, tol, solver, progress, callback,
                                                          say)
    checked = []
    if check is not None:
        result, checked = check.run(solver, problem, trusted, result, requirements, tol, progress, callback, say)
    return problem, result, checked, notes
