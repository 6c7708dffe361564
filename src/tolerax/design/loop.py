"""One design problem, one loop, any solver.

The problem, the solver and the loop are three things (as in optimistix: `optx.minimise(fn,
solver, y0)`):

- `ConstrainedDesign`: what is solved: minimise the cost of the bands subject to each
  constraint $f_j(x) \\le R_j$ over a box, $x = $ `Design(lower limit, band)` (m).
- a solver: a final subclass of `AbstractDesignSolver` with `init`, `step`, `terminate` and
  `postprocess`, whose state is its own. `SequentialSolver` (`tolerax.design.sequential`: a
  trust-region step as an optax transformation) and `AugmentedLagrangianSolver`
  (`tolerax.design.optimise`: `optax.adam` on the augmented Lagrangian) are the two built in.
- `solve_design(problem, solver, x0)`: the loop that runs any of them, with a progress bar and
  a callback, and returns an `OptimisationResult`.

A new solver is one class (`tests/test_solvers.py` writes one in a few lines and races it on
problems with known optima).
"""

import abc
import dataclasses
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import tqdm

from .cost import AbstractCostModel
from .types import Design, Features, History, OptimisationResult


@dataclasses.dataclass(frozen=True)
class ConstrainedDesign:
    """$\\min_x \\sum_i c_i(b_i)$ s.t. $f_j(x) \\le R_j$ ($j = 1..m$), lower $\\le x \\le$ upper.

    - `objective(x, draws, width)`: the constraints' values $f$ (a scalar for one, a vector of
      m), differentiable in `x` (`Design(lower limit, band)`, m).
    - `features`: names and sizes (mm) of the n features; `cost_model`: the cost of the bands.
    - `requirements` (m,): $R_j$; `tol` (m,): relative tolerances (a constraint within
      $R_j(1 \\pm$ tol$)$ is met and active).
    - `lower`, `upper` (`Design`, m): the box; equal bounds hold a variable fixed.
    - `draws`: passed to the objective unchanged; `width`: the smoothing width (m) passed to it.
    - `gradient_noise(x, width) -> (m, 2n)` (optional): standard errors of the constraints'
      gradients where they are estimates (secant fits), for the convergence test.
    - `zone_upper` (n,) (optional, m): each zone's upper edge $l + 2b$ at most this: with the
      box's lower limits, the zones held inside a box where the constraints' model holds (a
      response surface's, `Surface(rounds=...)`); a coupled bound a box on
      $(l, b)$ cannot express.
    """

    objective: Callable
    features: Features
    requirements: np.ndarray
    tol: np.ndarray
    lower: Design
    upper: Design
    cost_model: AbstractCostModel
    draws: Any = None
    width: Any = None
    gradient_noise: Callable | None = None
    zone_upper: Any = None

    def __post_init__(self):
        requirements = np.atleast_1d(np.asarray(self.requirements, dtype=float))
        if requirements.ndim != 1 or not np.all(requirements > 0):
            raise ValueError(f"ConstrainedDesign: one or more requirements > 0 (arcsec), got {self.requirements!r}.")
        tol = np.asarray(self.tol, dtype=float)
        if tol.ndim > 1 or tol.size not in (1, requirements.size) or not np.all((tol > 0) & (tol < 1)):
            raise ValueError(f"ConstrainedDesign: tol must be in (0, 1), one value or one per requirement ({requirements.size}), "
                             f"got {self.tol!r}.")
        object.__setattr__(self, "requirements", requirements)
        object.__setattr__(self, "tol", np.broadcast_to(tol, requirements.shape).copy())

    @property
    def m(self) -> int:
        """The number of constraints."""
        return self.requirements.shape[0]


class AbstractDesignSolver(eqx.Module):
    """A solver of a `ConstrainedDesign`, run by `solve_design`. Its state is any object it
    chooses; the loop only passes it along.

    - `init(problem, x0) -> state`: from the starting design `x0` (`Design`, within the box).
    - `step(problem, state) -> state`: one iteration.
    - `terminate(problem, state) -> bool`: stop now (converged, or nothing more to do).
    - `postprocess(problem, state) -> OptimisationResult`: the answer.
    - `last(problem, state) -> (x, cost, objective, evaluations)`: the design the last step
      evaluated, for the progress bar and the callback (`objective` an array (m,), one entry
      per constraint, however many).
    """

    @abc.abstractmethod
    def init(self, problem: ConstrainedDesign, x0: Design) -> Any:
        raise NotImplementedError

    @abc.abstractmethod
    def step(self, problem: ConstrainedDesign, state: Any) -> Any:
        raise NotImplementedError

    @abc.abstractmethod
    def terminate(self, problem: ConstrainedDesign, state: Any) -> bool:
        raise NotImplementedError

    @abc.abstractmethod
    def postprocess(self, problem: ConstrainedDesign, state: Any) -> OptimisationResult:
        raise NotImplementedError

    @abc.abstractmethod
    def last(self, problem: ConstrainedDesign, state: Any) -> tuple[Design, float, Any, int]:
        """`(x, cost, objective, evaluations)` of the design the last step evaluated."""
        raise NotImplementedError


def tolerance_worth(multipliers, tol, requirements) -> float:
    """The cost that moving each requirement within its tolerance is worth,
    $\\sum_j |\\lambda_j|\\,\\text{tol}_j R_j$ (multipliers in cost per unit of the output; a
    non-finite one, an infeasible subproblem's, counts 0): cost differences below it are not
    resolved by the problem as posed."""
    lam = np.abs(np.asarray(multipliers, dtype=float))
    return float(np.sum(np.where(np.isfinite(lam), lam, 0.0) * np.asarray(tol, dtype=float) * np.asarray(requirements, dtype=float)))


def solve_design(problem: ConstrainedDesign, solver: AbstractDesignSolver, x0: Design, *, max_steps: int, progress: bool = False,
                 callback: Callable[[int, Design, float, Any], None] | None = None, first_callback: bool = True) -> OptimisationResult:
    """Run `solver` on `problem` from `x0` for at most `max_steps` steps: `init`, then `step`
    until `terminate`, then `postprocess`.

    **Arguments:**

    - `problem`: a `ConstrainedDesign`; `solver`: an `AbstractDesignSolver`; `x0`: the start
      (`Design(lower limit, band)`, m).
    - `max_steps`: iterations at most (for the sequential solver, one gradient evaluation each);
      0: the start evaluated and reported, no step taken.
    - `progress`: a tqdm bar over the steps, with the cost and the constraints' values.
    - `callback(evaluations, x, cost, objective)`: after the start's evaluation (if
      `first_callback`) and after every step, with the design that step evaluated (a trial
      point, kept or not).
    """
    if int(max_steps) < 0:
        raise ValueError(f"solve_design: max_steps must be >= 0, got {max_steps!r}.")
    state = solver.init(problem, x0)
    if callback is not None and first_callback:
        callback(*_reordered(solver.last(problem, state)))
    bar = tqdm.tqdm(total=int(max_steps), desc=type(solver).__name__, disable=not progress)
    for _ in range(int(max_steps)):
        state = solver.step(problem, state)
        x, cost, objective, evaluations = solver.last(problem, state)
        if callback is not None:
            callback(evaluations, x, cost, objective)
        bar.update(1)
        bar.set_postfix(cost=f"{cost:.4g}", objective=np.array2string(np.atleast_1d(objective), precision=1),
                        requirement=np.array2string(problem.requirements))
        if solver.terminate(problem, state):
            break
    bar.close()
    return solver.postprocess(problem, state)


def _reordered(last):
    x, cost, objective, evaluations = last
    return evaluations, x, cost, objective


def make_result(problem: ConstrainedDesign, x: Design, f, sensitivity: Design, multiplier, *, converged: bool, iteration: int,
                rows, sensitivity_se: Design | None = None) -> OptimisationResult:
    """The `OptimisationResult` of a solver's answer `x` (`Design(lower limit, band)`, m): the
    constraints' values `f` (m,) and gradients `sensitivity` (a `Design` of rows, arcsec/m)
    there, the multipliers (m,), whether it `converged`, the index of the chosen iterate in
    `rows` (one history row per step: cost, objective, constraint, multiplier, penalty,
    continuation, steps). One entry (and one row) per requirement, however many there are.
    The cost, its gradient and the bounds held are computed here."""
    n, m = len(problem.features.names), problem.m
    f, multiplier = np.asarray(f, dtype=float).reshape(m), np.asarray(multiplier, dtype=float).reshape(m)
    rows_of = lambda d: Design(np.asarray(d.nominal).reshape(m, n), np.asarray(d.band).reshape(m, n))  # noqa: E731
    feature_cost = problem.cost_model(jnp.asarray(x.band), problem.features.size_mm)
    cost_gradient = jax.grad(lambda b: problem.cost_model.total(b, problem.features.size_mm))(jnp.asarray(x.band, dtype=float))
    return OptimisationResult(
        x=x,
        features=problem.features,
        cost=jnp.sum(feature_cost),
        feature_cost=feature_cost,
        objective=jnp.asarray(f),
        constraint=jnp.asarray(f - problem.requirements),
        multiplier=jnp.asarray(multiplier),
        constraint_active=jnp.asarray(f >= problem.requirements * (1 - problem.tol)),
        at_lower=jax.tree.map(lambda v, bound: jnp.asarray(v) <= bound, x, problem.lower),
        at_upper=jax.tree.map(lambda v, bound: jnp.asarray(v) >= bound, x, problem.upper),
        sensitivity=rows_of(sensitivity),
        sensitivity_se=None if sensitivity_se is None else rows_of(sensitivity_se),
        cost_gradient=Design(np.zeros(n), np.asarray(cost_gradient)),
        converged=jnp.asarray(bool(converged)),
        iteration=jnp.asarray(int(iteration)),
        history=History(*(jnp.asarray(np.asarray(col, dtype=float)) for col in zip(*rows))),
    )
