"""Tolerance design as constrained optimisation on optax: cheapest bands that meet a requirement.

Design variables $x = (\\text{nominal}, \\text{band})$, one of each per feature (m). The problem is

$$\\min_x\\ C(\\text{band}) \\quad\\text{s.t.}\\quad g(x) = f(x) - R \\le 0,\\qquad l \\le x \\le u,$$

with $C$ a cost model (`tolerax._cost`), $f$ the user's objective (pointing error, arcsec) and $R$
the requirement. It is solved by the augmented Lagrangian of Powell, Hestenes and Rockafellar for
an inequality constraint (Nocedal and Wright, *Numerical Optimization*, 2nd ed., §17.4):

$$L_\\rho(x, \\lambda) = \\hat C(x) + \\tfrac{\\rho}{2}\\max(0, \\lambda/\\rho + \\hat g(x))^2 -
\\tfrac{\\lambda^2}{2\\rho},$$

with $\\hat C = C/C(x_0)$ and $\\hat g = f/R - 1$ made dimensionless, so that one penalty and one
learning rate suit any cost unit and any requirement. Each outer iteration minimises $L_\\rho$ over
the box with a fixed number of steps of an optax optimiser (Adam with a cosine-decayed learning
rate by default), projecting onto the box after every step (`optax.projections.projection_box`);
then $\\lambda \\leftarrow \\max(0, \\lambda + \\rho\\hat g)$, and $\\rho$ grows by `penalty_growth`
whenever the violation $|\\max(\\hat g, -\\lambda/\\rho)|$ did not at least halve.

The optimiser works in box coordinates $z = (x - l)/(u - l) \\in [0, 1]$, so that a learning rate
means "a fraction of the allowed range" whatever the units. A feature with $l = u$ is fixed.

A continuation parameter (typically a smoothing width of the physics) is passed to the objective
and may follow a schedule over outer iterations, so that early iterations see a smooth objective
and later ones the sharp one.
"""

import dataclasses
import functools
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array, ArrayLike, Float
from .. import _validate as V
from .cost import AbstractCostModel, IsoGrade
from .loop import AbstractDesignSolver, ConstrainedDesign, solve_design
# The shared types live in `types`; importable from here too (public paths users call).
from .types import Design, Features, History, OptimisationResult, optimality_residual, realise, robust  # noqa: F401


class _Problem(eqx.Module):
    """The arrays of one problem (dynamic under jit): box, sizes and the scales that make the
    cost and the constraint dimensionless."""

    lower: Design
    span: Design
    size_mm: Float[Array, " n"]
    requirement: Float[Array, ""]
    cost_scale: Float[Array, ""]

    def to_x(self, z: Design) -> Design:
        return jax.tree.map(lambda lo, s, zz: lo + s * zz, self.lower, self.span, z)


def _augmented_lagrangian(z, multiplier, penalty, problem, draws, continuation, objective, cost_model):
    x = problem.to_x(z)
    g = objective(x, draws, continuation) / problem.requirement - 1.0
    shifted = jnp.maximum(multiplier / penalty + g, 0.0)
    cost = cost_model.total(x.band, problem.size_mm) / problem.cost_scale
    return cost + 0.5 * penalty * shifted**2 - 0.5 * multiplier**2 / penalty


@eqx.filter_jit
def _outer_iteration(z, multiplier, penalty, problem, draws, continuation, objective, cost_model, optimiser, steps):
    """One augmented-Lagrangian iteration: `steps` projected optimiser steps on $L_\\rho$ from `z`,
    then the multiplier update, and the objective, cost and their gradients at the new point."""
    lagrangian = functools.partial(
        _augmented_lagrangian,
        multiplier=multiplier,
        penalty=penalty,
        problem=problem,
        draws=draws,
        continuation=continuation,
        objective=objective,
        cost_model=cost_model,
    )
    zeros, ones = jax.tree.map(jnp.zeros_like, z), jax.tree.map(jnp.ones_like, z)

    def step(carry, _):
        z, state = carry
        value, grad = jax.value_and_grad(lagrangian)(z)
        updates, state = optimiser.update(grad, state, z, value=value, grad=grad, value_fn=lagrangian)
        z = optax.projections.projection_box(optax.apply_updates(z, updates), zeros, ones)
        return (z, state), None

    with jax.named_scope("inner_minimisation"):
        (z, _), _ = jax.lax.scan(step, (z, optimiser.init(z)), None, length=steps)

    x = problem.to_x(z)
    f, sensitivity = jax.value_and_grad(lambda xx: objective(xx, draws, continuation))(x)
    feature_cost, cost_vjp = jax.vjp(lambda xx: cost_model(xx.band, problem.size_mm), x)
    (cost_gradient,) = cost_vjp(jnp.ones_like(feature_cost))
    g = f / problem.requirement - 1.0
    violation = jnp.maximum(g, -multiplier / penalty)
    new_multiplier = jnp.maximum(multiplier + penalty * g, 0.0)
    return z, new_multiplier, violation, f, feature_cost, sensitivity, cost_gradient


@functools.cache
def default_optimiser(learning_rate: float = 0.05, inner_steps: int = 300) -> optax.GradientTransformation:
    """Adam with its learning rate (fraction of each variable's range per step) decayed to 0 over
    one inner minimisation by a cosine, so that each inner run settles instead of hovering at the
    size of its last step. Cached: the same arguments give the same object, which the jitted
    iteration needs to avoid retracing."""
    return optax.adam(optax.cosine_decay_schedule(learning_rate, inner_steps))


# Cached so that wrapping the same plain transformation twice gives the same (static) object.
_with_extra_args = functools.cache(optax.with_extra_args_support)


def _reject(names, what: str, field: str, bad, text: Callable[[int], str]) -> None:
    """Raise naming the first flagged entry, its feature and what it must be."""
    if np.any(bad):
        k = int(np.argmax(bad))
        raise ValueError(f"optimise_design: {what}.{field}[{k}] (feature {names[k]!r}) {text(k)}.")


def _check_inputs(features, requirement, lower, upper, x0, draws) -> None:
    if not isinstance(features, Features):
        raise TypeError(f"optimise_design: features must be a Features, got {type(features).__name__}.")
    names = features.names
    requirement = V.real("optimise_design", "requirement", requirement, "arcsec")
    if not (np.isfinite(requirement) and requirement > 0):
        raise ValueError(f"optimise_design: requirement must be finite and > 0 (arcsec), got {float(requirement)}.")
    designs = {"lower": lower, "upper": upper} | ({} if x0 is None else {"x0": x0})
    for what, design in designs.items():
        if not isinstance(design, Design):
            raise TypeError(f"optimise_design: {what} must be a Design, got {type(design).__name__}.")
        for field in ("nominal", "band"):
            value = np.asarray(getattr(design, field))
            if value.shape != (len(names),):
                raise ValueError(f"optimise_design: {what}.{field} must have shape ({len(names)},), got {value.shape}.")
            _reject(names, what, field, ~np.isfinite(value), lambda k: f"must be finite (m), got {value[k]}")
    pairs = [("lower", "upper")] + ([("lower", "x0"), ("x0", "upper")] if x0 is not None else [])
    for low, high in pairs:
        for field in ("nominal", "band"):
            lo, hi = np.asarray(getattr(designs[low], field)), np.asarray(getattr(designs[high], field))
            _reject(names, low, field, lo > hi, lambda k: f"= {lo[k]:g} m must be <= {high}.{field}[{k}] = {hi[k]:g} m")
    band = np.asarray(lower.band)
    _reject(names, "lower", "band", band < 0, lambda k: f"must be >= 0 (m), got {band[k]:g}")
    for k, leaf in enumerate(jax.tree.leaves(draws)):
        if eqx.is_array(leaf) and not np.all(np.isfinite(np.asarray(leaf))):
            raise ValueError(f"optimise_design: draws (leaf {k}) contains NaN or inf.")


def optimise_design(
    objective: Callable[[Design, Any, Float[Array, ""]], Float[Array, ""]],
    features: Features,
    *,
    requirement: ArrayLike,
    lower: Design,
    upper: Design,
    draws: Any = None,
    x0: Design | None = None,
    cost_model: AbstractCostModel | None = None,
    optimiser: optax.GradientTransformation | None = None,
    continuation: optax.Schedule | ArrayLike = 0.0,
    max_outer: int = 30,
    inner_steps: int = 300,
    penalty: float = 10.0,
    penalty_growth: float = 4.0,
    max_penalty: float = 1e6,
    tol: float = 1e-6,
    active_tol: float = 1e-3,
    progress: bool = False,
) -> OptimisationResult:
    """Cheapest tolerance design whose objective meets `requirement` (module docstring).

    **Arguments:**

    - `objective`: `objective(x, draws, continuation) -> f` (arcsec, scalar), differentiable in
      `x` (a `Design`); e.g. `robust` of the pointing error over `realise(x, draws)`. Pass the same
      function (or an `eqx.Module` whose arrays may change) on every call to reuse the compiled
      iteration.
    - `features`: `Features` (names, sizes) of the `n` design features.
    - `requirement`: $R$ (arcsec), finite and $> 0$.
    - `lower`, `upper`: bounds (`Design`, m), finite, `lower <= upper`, `lower.band >= 0`; a
      variable with equal bounds is held fixed.
    - `draws`: passed unchanged to the objective (e.g. standardised draws, `(n_draws, n)`).
    - `x0`: starting design within the bounds; the middle of the box by default.
    - `cost_model`: an `AbstractCostModel`; `IsoGrade()` by default.
    - `optimiser`: any optax `GradientTransformation` on box coordinates in $[0, 1]$, re-initialised
      each outer iteration; `default_optimiser(0.05, inner_steps)` by default.
    - `continuation`: a constant or an optax schedule of the outer iteration number, passed to the
      objective (e.g. `optax.exponential_decay(1e-6, 1, 0.5, end_value=1e-8)` for a smoothing
      width in m).
    - `max_outer`, `inner_steps`: outer iterations (at most) and optimiser steps per iteration.
    - `penalty`, `penalty_growth`, `max_penalty`: initial $\\rho$, its growth factor, its cap.
    - `tol`: convergence on the violation $|\\max(\\hat g, -\\lambda/\\rho)|$ and on the change of
      $z$ (infinity norm) between outer iterations.
    - `active_tol`: the requirement counts as active when $f \\ge R(1 - $`active_tol`$)$.
    - `progress`: a progress bar (tqdm, on stderr) over outer iterations, showing the cost and
      the objective after each; the first iteration includes compilation.

    **Returns:**

    An `OptimisationResult`. Raises `ValueError` naming the argument on bad input, and
    `RuntimeError` if the objective returns NaN or inf during the optimisation.
    """
    cost_model = IsoGrade() if cost_model is None else cost_model
    optimiser = default_optimiser(0.05, inner_steps) if optimiser is None else optimiser
    _check_inputs(features, requirement, lower, upper, x0, draws)
    x0 = jax.tree.map(lambda lo, hi: 0.5 * (lo + hi), lower, upper) if x0 is None else x0
    if not (penalty > 0 and penalty_growth >= 1 and max_penalty >= penalty and inner_steps >= 1 and max_outer >= 1):
        raise ValueError(
            "optimise_design: need penalty > 0, penalty_growth >= 1, max_penalty >= penalty, inner_steps >= 1, "
            f"max_outer >= 1; got {penalty}, {penalty_growth}, {max_penalty}, {inner_steps}, {max_outer}."
        )
    if not 0.0 <= active_tol < 1.0:
        raise ValueError(f"optimise_design: active_tol must be in [0, 1), got {active_tol!r}.")
    # The problem's tolerance is the activity tolerance here (> 0 there: 0 reads as exact).
    problem = ConstrainedDesign(objective, features, requirement, max(float(active_tol), 1e-300), lower, upper, cost_model, draws)
    solver = AugmentedLagrangianSolver(optimiser, continuation, int(max_outer), int(inner_steps), float(penalty), float(penalty_growth),
                                       float(max_penalty), float(tol))
    return solve_design(problem, solver, x0, max_steps=max_outer, progress=progress, first_callback=False)


@dataclasses.dataclass
class _LagrangianState:
    """`AugmentedLagrangianSolver`'s state: box coordinates `z`, multiplier and penalty, the
    last violation, one history row per outer iteration, the cheapest iterate that met the
    requirement at the final continuation value, the last iteration's outputs."""

    box: _Problem
    z: Design
    multiplier: Array
    rho: Array
    previous_violation: float = np.inf
    rows: list = dataclasses.field(default_factory=list)
    best: tuple | None = None
    converged: bool = False
    last: tuple | None = None  # (f, feature_cost, sensitivity, cost_gradient)


class AugmentedLagrangianSolver(AbstractDesignSolver):
    """The augmented Lagrangian of the module docstring as a solver of the one design loop
    (`solve_design`): each step is one outer iteration, `inner_steps` projected steps of the
    optax `optimiser` on $L_\\rho$ (one compiled program), then the multiplier and penalty
    updates. One constraint; its `tol` in the problem is the activity tolerance (`active_tol`).

    - `optimiser`: an optax `GradientTransformation` on box coordinates in $[0, 1]$.
    - `continuation`: a constant or an optax schedule of the outer iteration (the width passed
      to the objective); `max_outer`: the iterations the schedule is laid over (its last value
      is the one the answer is judged at).
    - `inner_steps`, `penalty`, `penalty_growth`, `max_penalty`, `tol`: as `optimise_design`.
    """

    optimiser: optax.GradientTransformation
    continuation: Any = 0.0
    max_outer: int = 30
    inner_steps: int = 300
    penalty: float = 10.0
    penalty_growth: float = 4.0
    max_penalty: float = 1e6
    tol: float = 1e-6

    def schedule(self, i):
        return self.continuation(i) if callable(self.continuation) else self.continuation

    def init(self, problem, x0):
        if problem.m != 1:
            raise ValueError(f"AugmentedLagrangianSolver: one requirement, got {problem.m}.")
        lower, upper, features = problem.lower, problem.upper, problem.features
        span = jax.tree.map(lambda lo, hi: hi - lo, lower, upper)
        z = jax.tree.map(lambda x, lo, s: (x - lo) / jnp.where(s > 0, s, 1.0), x0, lower, span)
        cost_scale = problem.cost_model.total(x0.band, features.size_mm)
        if not (np.isfinite(cost_scale) and cost_scale > 0):
            raise ValueError(f"optimise_design: cost_model gives a total cost {float(cost_scale)} at x0; need finite, > 0.")
        box = _Problem(lower, span, features.size_mm, jnp.asarray(problem.requirements[0], dtype=float), cost_scale)
        return _LagrangianState(box, z, jnp.asarray(0.0, dtype=float), jnp.asarray(self.penalty, dtype=float))

    def step(self, problem, state):
        iteration, box = len(state.rows), state.box
        value = jnp.asarray(self.schedule(iteration), dtype=float)
        z_new, multiplier_new, violation, f, feature_cost, sensitivity, cost_gradient = _outer_iteration(
            state.z, state.multiplier, state.rho, box, problem.draws, value, problem.objective, problem.cost_model,
            _with_extra_args(self.optimiser), self.inner_steps)
        if not (np.isfinite(f) and all(np.all(np.isfinite(leaf)) for leaf in jax.tree.leaves(z_new))):
            raise RuntimeError(f"optimise_design: the objective returned {float(f)} (or a non-finite gradient) at outer "
                               f"iteration {iteration}, continuation {float(value)}.")
        change = max(float(jnp.max(jnp.abs(a - b))) for a, b in zip(jax.tree.leaves(z_new), jax.tree.leaves(state.z)))
        state.z, state.multiplier, violation = z_new, multiplier_new, float(violation)
        to_arcsec = box.cost_scale / box.requirement  # dimensionless multiplier -> cost per arcsec
        row = (jnp.sum(feature_cost), f, f - box.requirement, state.multiplier * to_arcsec, state.rho, value)
        state.rows.append(tuple(float(v) for v in row) + ((iteration + 1) * self.inner_steps,))
        state.last = (f, feature_cost, sensitivity, cost_gradient)
        # The objective is noisy at the scale of an optimiser step (rattle), so the iterates
        # oscillate about the constraint instead of settling on it; the answer is the cheapest
        # iterate that met the requirement at the final continuation value (if any did).
        final_value = float(self.schedule(self.max_outer - 1))
        if self._meets(problem, state.rows[-1][1]) and float(value) == final_value and (state.best is None or state.rows[-1][0] < state.best[0]):
            state.best = (state.rows[-1][0], iteration, state.z, f, feature_cost, sensitivity, cost_gradient, state.multiplier)
        settled = float(self.schedule(iteration + 1)) == float(value)
        if abs(violation) <= self.tol and change <= self.tol and settled:
            state.converged = True
        elif abs(violation) > 0.5 * abs(state.previous_violation):
            state.rho = jnp.minimum(state.rho * self.penalty_growth, self.max_penalty)
        state.previous_violation = violation
        return state

    def _meets(self, problem, f) -> bool:
        return f <= float(problem.requirements[0]) * (1.0 + self.tol)  # within the violation tolerance

    def terminate(self, problem, state):
        return state.converged

    def last(self, problem, state):
        x = state.box.to_x(state.z)
        return x, state.rows[-1][0], np.atleast_1d(state.rows[-1][1]), len(state.rows)

    def postprocess(self, problem, state):
        rows, z, box, multiplier = state.rows, state.z, state.box, state.multiplier
        f, feature_cost, sensitivity, cost_gradient = state.last
        chosen = len(rows) - 1
        if state.best is not None and (not self._meets(problem, rows[-1][1]) or state.best[0] < rows[-1][0]):
            _, chosen, z, f, feature_cost, sensitivity, cost_gradient, multiplier = state.best
        return OptimisationResult(
            x=box.to_x(z),
            features=problem.features,
            cost=jnp.sum(feature_cost),
            feature_cost=feature_cost,
            # One entry (and one sensitivity row) per requirement, as every solver's result.
            objective=jnp.atleast_1d(f),
            constraint=jnp.atleast_1d(f - box.requirement),
            multiplier=jnp.atleast_1d(multiplier * box.cost_scale / box.requirement),
            constraint_active=jnp.atleast_1d(f >= box.requirement * (1.0 - float(problem.tol[0]))),
            at_lower=jax.tree.map(lambda zz: zz <= 1e-9, z),
            at_upper=jax.tree.map(lambda zz, s: (zz >= 1.0 - 1e-9) | (s == 0), z, box.span),
            sensitivity=jax.tree.map(lambda s: jnp.reshape(s, (1, -1)), sensitivity),
            cost_gradient=cost_gradient,
            converged=jnp.asarray(state.converged),
            iteration=jnp.asarray(chosen),
            history=History(*(jnp.asarray(column, dtype=float).reshape((-1, 1) if k in (1, 2, 3) else (-1,))
                              for k, column in enumerate(zip(*rows)))),
        )
