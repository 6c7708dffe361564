"""Tolerance design by sequential linearisation: a calibrated stack-up rebuilt at every iterate,
solved exactly, inside a trust region.

The problem (`ConstrainedDesign`) has the design variables read as `FromLowerLimit` does:
per feature the lower limit $l$ of the tolerance zone (free of cost) and the half-width $b$ of
the band (whose cost $c_i(b_i)$ is separable and non-increasing),

$$\\min_{l, b}\\ \\sum_i c_i(b_i) \\quad\\text{s.t.}\\quad f(l, b) \\le R,\\qquad
(l, b) \\in [\\text{lower}, \\text{upper}].$$

On the lost-motion part of a pointing budget $f$ is close to linear in $(l, b)$: a stack-up.
Each iteration evaluates $f$ and its gradient once at the iterate $x_k$ and solves the
linearised problem exactly,

$$\\min\\ \\sum_i c_i(b_i)\\quad\\text{s.t.}\\quad f_k + a\\cdot(l - l_k) + d\\cdot(b - b_k) \\le R,$$

over the box intersected with a trust region $|z - z_k| \\le \\Delta$ in box coordinates. The
subproblem is separable, so its Lagrangian dual is one-dimensional: for a multiplier
$\\lambda \\ge 0$ each lower limit sits on the bound that lowers $f$ (it costs nothing) and each
band solves $c_i'(b_i) + \\lambda d_i = 0$ in its interval; the linearised constraint is then
monotone in $\\lambda$, whose root is found by bisection (`optimistix.Bisection`), as is each
band. A step is kept when the objective at the trial point does not exceed the requirement by
more than the linear model predicted (or lowers the violation); the trust region grows when the
model predicted the objective well and shrinks when it did not, so the method still converges
where the response bends (contact onset, clipping at zero clearance).

It stops, converged, with the constraint met to `tol` (active, or inactive with every band at
its widest) and one of: the design stopped moving (a step cut short by the trust region does
not count: that says the region collapsed); the first-order optimality residual below
`optimality_tol`; or the cost stationary (changed by less than `cost_tol` relative over the
last two kept steps, SLSQP's test, or by less than the requirements' own tolerances are worth)
with the *bands* at a KKT point (their residual, the lower
limits held, below `band_tol`). The last test exists because the lower limits carry no cost:
their optimality condition is $\\partial f/\\partial l = 0$, and on an objective rough at small
scales (impacts at a narrow smoothing width) that derivative is noise: the iterates move such
a lower limit about and the full residual stays above its tolerance while the cost has
stopped changing. Where the constraints' gradients are estimates (slopes fitted over
a few units of a chaotic response: the jitter), the bands' test may also pass within two
standard errors of them (`gradient_noise`). Otherwise the run ends on its budget, reported not
converged, with the cheapest iterate on the requirement.

The step is an optax transformation (`trust_region_step`: `optax.GradientTransformationExtraArgs`
whose `update` takes the constraints' `value`, `grad` and `value_fn` as extra arguments, as
optax's line searches do, and keeps the trust region and the multipliers in its state), run by
`SequentialSolver` in the one design loop (`tolerax.design.loop.solve_design`), projected onto
the box by `optax.projections.projection_box`. Inside it the linearised subproblem is solved
exactly, not by gradient steps: it is separable with a few linear constraints (a
one-dimensional dual by bisection for one, SLSQP on a problem without simulations for several:
`tolerax.design.subproblem`), and each iterate's simulation is the expensive part.
"""

import dataclasses
from collections.abc import Callable
from typing import Any, NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import optax

from .cost import AbstractCostModel
from .loop import AbstractDesignSolver, ConstrainedDesign, make_result, solve_design, tolerance_worth
from .subproblem import (_cost_and_gradient, _cost_gradient, _subproblem, _subproblem_many, _value_and_grad, _value_and_jacobian,
                         linearised_minimiser)
from .types import Design, Features, OptimisationResult, counted_rows, optimality_residual

MIN_RADIUS = 1e-4  # the trust region's smallest half-width (a fraction of each variable's range)
STALL_STEPS = 4  # rejected steps in a row at MIN_RADIUS that end a run as stalled

# Importable from here too (their older home).
__all__ = ["SequentialSolver", "TrustRegionState", "sequential_design", "trust_region_step", "_subproblem", "_subproblem_many"]


def _optimality(dc, z, grad, f, requirements, tol, lo, hi, n, bands_only=False, se=None) -> float:
    """`optimality_residual` at box point `z` (flat lower limits then bands) with the cost's
    gradient over the bands `dc` (n,) and the gradients `grad` (m, 2n) of the constraints values
    `f`: over those `counted_rows` counts (the active ones, to `tol`); `bands_only`: over the
    bands, the lower limits held where they are; `se` (m, 2n): the gradients' standard errors
    (the residual within their noise)."""
    dc = np.concatenate([np.zeros(n), dc])
    keep = slice(n, None) if bands_only else slice(None)
    rows = counted_rows(f >= requirements * (1 - tol))
    return optimality_residual(dc[keep], grad[rows][:, keep], (z <= lo)[keep], (z >= hi)[keep],
                               None if se is None else se[rows][:, keep])


class _Flat:
    """A `ConstrainedDesign` in flat coordinates $z$ = (lower limits, bands) (m, shape (2n,)):
    its box, the constraints' values and gradients, the cost and the exact linearised
    subproblem. Built once per solve (it holds the gradient-noise cache)."""

    def __init__(self, problem: ConstrainedDesign):
        self.problem, self.n, self.m = problem, len(problem.features.names), problem.m
        self.lo = np.concatenate([np.asarray(problem.lower.nominal), np.asarray(problem.lower.band)])
        self.hi = np.concatenate([np.asarray(problem.upper.nominal), np.asarray(problem.upper.band)])
        self.span = np.where(self.hi > self.lo, self.hi - self.lo, 1.0)
        self.width = None if problem.width is None else jnp.asarray(problem.width, dtype=float)
        self.zone = None if problem.zone_upper is None else np.asarray(problem.zone_upper, dtype=float)
        self._noise = {}

    def held(self, z) -> np.ndarray:
        """The box's upper corner with, where a zone's upper edge is on `zone_upper`, its lower
        limit's and band's entries at `z` (held there, as by a bound: for the optimality tests)."""
        if self.zone is None:
            return self.hi
        on = z[: self.n] + 2.0 * z[self.n :] >= self.zone - 1e-7 * self.span[self.n :]
        return np.where(np.concatenate([on, on]), np.minimum(self.hi, z), self.hi)

    def design(self, z) -> Design:
        return Design(z[: self.n], z[self.n :])

    def evaluate(self, z):
        """`(f, grad)`: the constraints' values (m,) and gradients (m, 2n) at `z`."""
        p, x = self.problem, self.design(z)
        f, g = (_value_and_grad if self.m == 1 else _value_and_jacobian)(p.objective, x, p.draws, self.width)
        rows = [np.asarray(part, dtype=float).reshape(self.m, self.n) for part in (g.nominal, g.band)]
        return np.asarray(f, dtype=float).reshape(self.m), np.concatenate(rows, axis=1)

    def cost(self, z) -> float:
        return float(_cost_and_gradient(self.problem.cost_model, self.problem.features.size_mm, jnp.asarray(z[self.n :]))[0])

    def cost_gradient(self, z) -> np.ndarray:
        """$\\partial C/\\partial z$ (cost/m): zero over the lower limits."""
        return np.concatenate([np.zeros(self.n), _cost_gradient(self.problem.cost_model, self.problem.features.size_mm, z[self.n :])])

    def noise(self, z) -> np.ndarray:
        """The constraints' gradient standard errors (m, 2n) at `z`: one batch of simulations per point."""
        key = z.tobytes()
        if key not in self._noise:
            raw = self.problem.gradient_noise(self.design(z), self.width)
            self._noise[key] = np.asarray(raw, dtype=float).reshape(self.m, 2 * self.n)
        return self._noise[key]

    def subproblem(self, z, f, grad, box_lo, box_hi):
        """The exact minimiser of the linearised problem in `[box_lo, box_hi]`: `(trial z,
        multipliers (m,), predicted f (m,))`; a multiplier is inf where even the tightest design
        there misses its linearised constraint."""
        n, p = self.n, self.problem
        l, b, lam, f_pred = linearised_minimiser(p.cost_model, p.features.size_mm, f, grad[:, :n], grad[:, n:], z[:n], z[n:],
                                                 (box_lo[:n], box_hi[:n]), (box_lo[n:], box_hi[n:]), p.requirements, self.zone)
        trial = np.clip(np.concatenate([np.asarray(l), np.asarray(b)]), self.lo, self.hi)
        return trial, lam, f_pred  # (m,) each, as `linearised_minimiser` returns them


class TrustRegionState(NamedTuple):
    """The state of `trust_region_step`: the trust region's half-width `radius` (a fraction of
    each variable's range), the subproblem's `multipliers` at the kept point, the last kept
    step (`previous`, box fractions, or None), the constraints' `value` and `grad` at the point
    the last update returned, and what that update did: the `trial` point and its values,
    whether it was `accepted`, how far it `moved` (box fraction) and whether the trust region
    `limited` it; `evaluations` of the constraints so far."""

    radius: float
    multipliers: np.ndarray
    previous: np.ndarray | None
    value: np.ndarray | None
    grad: np.ndarray | None
    trial: np.ndarray | None
    trial_value: np.ndarray | None
    trial_multipliers: np.ndarray | None
    accepted: bool
    moved: float
    limited: bool
    evaluations: int


def trust_region_step(flat: _Flat, trust_region: float = 0.5) -> optax.GradientTransformationExtraArgs:
    """The sequential method's step as an optax transformation on the flat design $z$.

    `update(updates, state, params, *, value, grad, value_fn)`: `params` the current point,
    `value` (m,) and `grad` (m, 2n) the constraints there, `value_fn(z) -> (value, grad)` to
    evaluate a trial point (a simulation); `updates` (the cost's gradient) is not needed: the
    subproblem is solved with the cost model itself. It solves the linearised subproblem in the
    trust region, evaluates the trial point once, keeps it (returns `trial - params`) or not
    (returns zeros), and updates the region: doubled (at most the whole box) where the linear
    model predicted the constraints to within a quarter of their change, else quartered; halved
    to the step's length where a kept step turns back on the last (the constraint's curvature
    makes the iterates zig-zag along it). A constraint clear of its requirement in both model
    and simulation (by more than its tolerance) neither rejects a step nor shrinks the region,
    whatever its model's error. The new point's `value` and `grad` are in the state
    (`TrustRegionState`), so the caller evaluates nothing twice."""
    p = flat.problem
    R, tol, lo, hi, span = p.requirements, p.tol, flat.lo, flat.hi, flat.span

    def init(params):
        return TrustRegionState(float(trust_region), np.zeros(p.m), None, None, None, None, None, None, False, 0.0, False, 0)

    def update(updates, state, params=None, *, value, grad, value_fn, **extra):
        z, f = np.asarray(params, dtype=float), np.asarray(value, dtype=float)
        radius = state.radius
        box_lo, box_hi = np.maximum(lo, z - radius * span), np.minimum(hi, z + radius * span)
        trial, lam, f_pred = flat.subproblem(z, f, np.asarray(grad), box_lo, box_hi)
        f_trial, grad_trial = value_fn(trial)
        model_error = np.abs(f_trial - f_pred)
        change = np.maximum(np.abs(f_pred - f), tol * R)
        violation, violation_trial = np.maximum(f - R, 0.0), np.maximum(f_trial - R, 0.0)
        clear = np.maximum(f_trial, f_pred) < R * (1 - tol)
        model_error = np.where(clear, 0.0, model_error)
        accept = bool(np.all(violation_trial <= np.maximum(violation, tol * R)) or np.all(model_error <= 0.5 * change))
        step = (trial - z) / span
        moved = float(np.max(np.abs(step)))
        # A step stopped by the trust region, not by the box or the model's own optimum: a small
        # one says the region collapsed, not that the design converged.
        inner = (box_lo > lo) | (box_hi < hi)
        limited = bool(np.any(inner & ((trial <= box_lo + 1e-12 * span) | (trial >= box_hi - 1e-12 * span)) & (np.abs(step) > 0)))
        radius = min(2.0 * radius, 1.0) if np.all(model_error <= 0.25 * change) else max(0.25 * radius, MIN_RADIUS)
        if accept and state.previous is not None and np.dot(step, state.previous) < 0:
            radius = min(radius, max(0.5 * moved, 1e-6))
        new = TrustRegionState(
            radius, lam if accept else state.multipliers, step if accept else state.previous,
            f_trial if accept else f, grad_trial if accept else np.asarray(grad), trial, f_trial, lam, accept, moved, limited,
            state.evaluations + 1)
        return (trial - z) if accept else np.zeros_like(z), new

    return optax.GradientTransformationExtraArgs(init, update)


@dataclasses.dataclass
class _SequentialState:
    """`SequentialSolver`'s state: the flat problem, the current point `z` and its constraints
    `f`, `grad`, the transformation's state, the cost after every kept step, one history row per
    step, the cheapest iterate on the requirements, and whether it converged."""

    flat: _Flat
    transformation: Any
    z: np.ndarray
    f: np.ndarray
    grad: np.ndarray
    opt_state: TrustRegionState
    kept: list
    rows: list = dataclasses.field(default_factory=list)
    best: tuple | None = None
    converged: bool = False
    rejected: int = 0  # steps rejected in a row at the smallest trust region


def _row(problem, cost, f, multipliers, evaluations) -> tuple:
    """One `History` row: cost, objective, constraint (objective - requirement), multiplier
    (each an array, one entry per requirement), penalty (NaN: the method has none),
    continuation (the smoothing width, NaN without one) and the evaluations so far."""
    width = np.nan if problem.width is None else float(problem.width)
    f = np.asarray(f, dtype=float)
    return (cost, f, f - problem.requirements, np.asarray(multipliers, dtype=float), np.nan, width, evaluations)


class SequentialSolver(AbstractDesignSolver):
    """Sequential linearisation in a trust region (the module docstring), as a solver of the one
    design loop (`solve_design`).

    - `trust_region`: the starting trust region's half-width, a fraction of each variable's range.
    - `step_tol`: the design has stopped moving when no variable moves by more than this fraction
      of its range (a step cut short by the trust region does not count).
    - `optimality_tol`: or the first-order optimality residual is below this.
    - `cost_tol`, `band_tol`: or the cost changed by less than `cost_tol` (relative), or by less
      than moving each requirement within its tolerance is worth ($\\sum_j \\lambda_j\\,
      \\text{tol}_j R_j$), over the last two kept steps, with the bands' residual (lower limits
      held; within two standard errors of estimated gradients, where the problem gives
      `gradient_noise`) below `band_tol`. Where the design then met its requirements to their
      tolerance but not to a tenth of it, the cheapest iterate within that tenth is returned
      instead if it costs no more than the tolerance is worth.
    """

    trust_region: float = 0.5
    step_tol: float = 1e-3
    optimality_tol: float = 1e-3
    cost_tol: float = 1e-3
    band_tol: float = 1e-2

    def init(self, problem, x0):
        flat = _Flat(problem)
        z = np.clip(np.concatenate([np.asarray(x0.nominal), np.asarray(x0.band)]), flat.lo, flat.hi)
        f, grad = flat.evaluate(z)
        transformation = trust_region_step(flat, self.trust_region)
        opt_state = transformation.init(z)._replace(value=f, grad=grad, evaluations=1, trial=z, trial_value=f)
        return _SequentialState(flat, transformation, z, f, grad, opt_state, [flat.cost(z)])

    def step(self, problem, state):
        flat, R, tol = state.flat, problem.requirements, problem.tol
        cost_gradient = flat.cost_gradient(state.z)
        tried_at = state.opt_state.radius  # the region this step was tried in
        updates, opt = state.transformation.update(cost_gradient, state.opt_state, state.z, value=state.f, grad=state.grad,
                                                   value_fn=flat.evaluate)
        z = np.asarray(optax.projections.projection_box(optax.apply_updates(state.z, updates), flat.lo, flat.hi))
        cost = flat.cost(opt.trial if opt.accepted else state.z)
        if opt.accepted:
            z = opt.trial  # exactly the point evaluated (the projection of a point in the box is itself)
            state.kept.append(cost)
        state.rejected = 0 if opt.accepted or tried_at > MIN_RADIUS else state.rejected + 1
        state.z, state.f, state.grad, state.opt_state = z, opt.value, opt.grad, opt
        f, n = state.f, flat.n
        state.rows.append(_row(problem, cost, f, opt.multipliers, opt.evaluations))
        if np.all(f <= R * (1 + 0.1 * tol)) and (state.best is None or state.rows[-1][0] <= state.best[0]):
            state.best = (state.rows[-1][0], len(state.rows) - 1, z, f, state.grad, opt.multipliers)
        met, active = bool(np.all(f <= R * (1 + tol))), bool(np.any(f >= R * (1 - tol)))
        widest = bool(np.all(z[n:] >= flat.hi[n:] - self.step_tol * flat.span[n:]))
        kept = state.kept
        # Stationary: the cost moved by less than `cost_tol`; or by less than what moving each
        # requirement within its own tolerance is worth (multiplier x tol x R: the constraints
        # are held only to that, so cost changes below it are not resolved by the problem). The
        # returned design is then the cheapest on its requirements to a tenth of their
        # tolerance where one is worth as much (`postprocess`).
        spread = max(kept[-3:]) - min(kept[-3:]) if len(kept) >= 3 else np.inf
        stationary = spread <= self.cost_tol * kept[-1] or spread <= tolerance_worth(opt.multipliers, tol, R)
        if opt.accepted and met and (active or widest):
            dc = _cost_gradient(problem.cost_model, problem.features.size_mm, z[n:])
            args = (dc, z, state.grad, f, R, tol, flat.lo, flat.held(z), n)
            state.converged = bool(
                (opt.moved <= self.step_tol and not opt.limited)
                or _optimality(*args) <= self.optimality_tol
                or (stationary and _optimality(*args, bands_only=True) <= self.band_tol)
                or (stationary and problem.gradient_noise is not None
                    and _optimality(*args, bands_only=True, se=flat.noise(z)) <= self.band_tol))
        return state

    def terminate(self, problem, state):
        return state.converged or self.stalled(state)

    def stalled(self, state) -> bool:
        """The trust region collapsed: `STALL_STEPS` steps rejected in a row with the region at its
        smallest. The linear model does not predict the response even over tiny steps (rough
        at this smoothing width, or noisy); more iterations would not move the design."""
        return state.rejected >= STALL_STEPS

    def last(self, problem, state):
        opt, flat = state.opt_state, state.flat
        f = opt.trial_value
        return flat.design(opt.trial), flat.cost(opt.trial), np.asarray(f), opt.evaluations

    def postprocess(self, problem, state):
        flat, n = state.flat, state.flat.n
        rows, z, f, grad, lam = state.rows, state.z, state.f, state.grad, state.opt_state.multipliers
        R, tol = problem.requirements, problem.tol
        if not rows:  # no step taken (`max_steps=0`): the start, evaluated, is the history's one row
            rows = [_row(problem, flat.cost(z), f, np.zeros_like(f), state.opt_state.evaluations)]
        chosen = len(rows) - 1
        # A converged design met to `tol` but over its requirements by more than a tenth of it
        # gives way to the cheapest iterate within that tenth where the two costs differ by no
        # more than the tolerance is worth (the problem does not resolve them): one answer on
        # the requirement, whichever stopping test passed.
        on_requirement = bool(np.all(f <= R * (1 + 0.1 * tol)))
        resolved = tolerance_worth(lam, tol, R)
        if state.best is not None and (not state.converged or state.best[0] < rows[-1][0]
                                       or (not on_requirement and state.best[0] <= rows[-1][0] + resolved)):
            # The cheapest iterate on the requirement (to a tenth of `tol`), unless the converged one
            # is cheaper (met to `tol`): on a rough objective a run that ends on its budget can wander
            # past cheaper designs it had already found.
            _, chosen, z, f, grad, lam = state.best
        rows_of = lambda g: Design(g[:, :n], g[:, n:])  # noqa: E731
        result = make_result(problem, flat.design(z), f, rows_of(grad), lam, converged=state.converged, iteration=chosen, rows=rows,
                             sensitivity_se=None if problem.gradient_noise is None else rows_of(flat.noise(z)))
        return eqx.tree_at(lambda r: r.stalled, result, jnp.asarray(self.stalled(state) and not state.converged),
                           is_leaf=lambda v: v is None)


def sequential_design(
    objective: Callable,
    features: Features,
    *,
    requirement: float | tuple[float, ...],
    lower: Design,
    upper: Design,
    draws,
    x0: Design,
    cost_model: AbstractCostModel,
    width=None,
    max_iterations: int = 20,
    trust_region: float = 0.5,
    tol: float | tuple[float, ...] = 0.01,
    step_tol: float = 1e-3,
    optimality_tol: float = 1e-3,
    cost_tol: float = 1e-3,
    band_tol: float = 1e-2,
    progress: bool = False,
    callback: Callable[[int, Design, float, float], None] | None = None,
    gradient_noise: Callable | None = None,
    zone_upper=None,
) -> OptimisationResult:
    """Cheapest bands meeting `requirement` by sequential linearisation (see the module
    docstring): `solve_design(ConstrainedDesign(...), SequentialSolver(...), x0)`. The design's
    `nominal` field holds the zone's *lower limit* (`FromLowerLimit`'s convention), its `band`
    the half-width; the cost is `cost_model(band, features.size_mm)`.

    **Arguments:**

    - `objective`: `objective(x: Design, draws, width) -> scalar` (arcsec), differentiable; or,
      with m requirements, a vector of m (e.g. a lost-motion metric and a stability metric);
      each constraint is tested as the one-constraint method tests it and a step must pass for all.
    - `features`, `requirement` (arcsec, or one per constraint), `lower`, `upper` (`Design` boxes,
      m), `draws`, `x0` (the start), `cost_model`: the `ConstrainedDesign`; `width` the
      continuation value passed to the objective (e.g. a smoothing width, m), fixed here.
    - `max_iterations`: gradient evaluations at most (one per iteration).
    - `trust_region`, `step_tol`, `optimality_tol`, `cost_tol`, `band_tol`: `SequentialSolver`'s.
    - `tol`: relative tolerance on each constraint ($|f - R| \\le$ `tol`$\\cdot R$ for an active
      one), one value or one per requirement (a noisy constraint's at its estimate's own noise).
    - `progress`: a tqdm bar over iterations.
    - `callback`: called after every gradient evaluation as `callback(evaluations, x, cost,
      objective)` with the design just evaluated (the trial point, kept or not), its cost and
      objective (arcsec; an array with several requirements).
    - `gradient_noise` (optional): `gradient_noise(x, width) -> (m, 2n)` standard errors of the
      constraints' gradients at `x` (arcsec/m; lower limits then bands) where they are
      estimates (`DesignProblem.gradient_noise`); called (one batch of simulations) only when
      the cost has become stationary and the plain tests failed, and once at the returned design.
    - `zone_upper` (n,) (optional, m): each zone's upper edge $l + 2b$ at most this
      (`ConstrainedDesign.zone_upper`; the subproblem is then solved by SLSQP).

    **Returns:** an `OptimisationResult` whose design is the cheapest iterate on the requirement
    (objective $\\le R(1 + $`tol`$/10)$), else the last one (its `history.penalty` is NaN and
    `history.steps` counts gradient evaluations; `multiplier` is the subproblem's $\\lambda$ there).
    With several requirements the objective, constraint, multiplier, activity and the history's
    columns hold one value per constraint and `sensitivity` one row each.
    """
    try:
        problem = ConstrainedDesign(objective, features, requirement, tol, lower, upper, cost_model, draws, width, gradient_noise,
                                    zone_upper)
    except ValueError as err:
        raise ValueError(str(err).replace("ConstrainedDesign", "sequential_design")) from None
    solver = SequentialSolver(trust_region, step_tol, optimality_tol, cost_tol, band_tol)
    return solve_design(problem, solver, x0, max_steps=max_iterations, progress=progress, callback=callback)
