"""Design solvers as values: each carries its own continuation (smoothing widths, m), budget and
step, and answers one call, `solve`, so that `propose_design`, its Monte Carlo check and its
response-surface rounds re-solve through whichever solver was given.

- `Sequential` (default): the linearised problem solved exactly at each iterate inside a trust
  region (`sequential_design`), once per smoothing width, wide to narrow, each from the last
  width's design.
- `AugmentedLagrangian`: Adam on the augmented Lagrangian (`optimise_design`, on optax), one
  width per outer iteration; one requirement on tangent slopes.
- `SLSQP`: SciPy's sequential least squares programming on the same problem, with the exact
  gradients: the off-the-shelf reference a new method is raced against.

A solver of one's own is a frozen dataclass subclassing `AbstractDesignMethod` with
`solve(problem, requirement, tol, *, x0=None, step=None, progress=False, callback=None)`
returning an `OptimisationResult` (`tests/test_design_values.py` has one: projected Adam on a
quadratic penalty, run by the one design loop, `solve_design`).
"""

import abc
import dataclasses
from typing import ClassVar

import jax
import jax.numpy as jnp
import numpy as np
import optax
import scipy.optimize

from .loop import ConstrainedDesign, make_result
from .optimise import optimise_design
from .problem import DesignProblem
from .sequential import sequential_design
from .types import Design, chain_results


class AbstractDesignMethod(abc.ABC):
    """A design solver (module docstring). `widths` (m, wide to narrow): the smoothing widths
    it continues over; the design is judged at the last. Class attributes: `several` (it meets
    several requirements at once), `fitted` (it takes slopes fitted over units: secants),
    `restarts` (it re-solves from a design: a check's shifted requirement, a surface's rounds),
    `budget` (the name of its field that bounds its iterations, which a diagnosis names)."""

    widths: tuple
    budget: ClassVar[str] = "max_gradients"
    several: ClassVar[bool] = True
    fitted: ClassVar[bool] = True
    restarts: ClassVar[bool] = True

    @abc.abstractmethod
    def solve(self, problem: DesignProblem, requirement, tol, *, x0=None, step=None, progress=False, callback=None):
        """The cheapest design of `problem` (`DesignProblem`) whose objective meets
        `requirement` (a tuple of m floats, one requirement or several) to relative `tol` (one per
        requirement). From `problem.x0` over every width; or, given `x0` (a `Design`: a
        re-solve after the requirement or the problem moved), from there at the last width,
        with `step` (relative, optional) the largest first step. Returns an
        `OptimisationResult`."""

    @property
    def width(self) -> float:
        """The smoothing width (m) the design is judged at: the last."""
        return float(self.widths[-1])

    def most_gradients(self) -> int | None:
        """The most gradient evaluations one solve from the start makes (over every width), for
        the time said before it; `None` where the solver does not bound them in advance."""
        return None


def _widths(widths) -> tuple:
    widths = tuple(float(w) for w in np.atleast_1d(widths))
    if not widths or not all(w > 0 for w in widths):
        raise ValueError(f"design solver: widths must be one or more smoothing widths > 0 (m), wide to narrow, got {widths!r}.")
    return widths


@dataclasses.dataclass(frozen=True)
class Sequential(AbstractDesignMethod):
    """The sequential trust-region method (`sequential_design`): at each iterate the problem
    linearised at the design (the requirement's slopes, the cost's curvature) is solved exactly
    inside a trust region, which grows on an accepted step and shrinks on a rejected one.

    - `widths` (m): smoothing widths, wide to narrow, each solved from the last one's design (a
      wide first width makes the method robust to its start: the contacts make the narrow
      objective rough far from the optimum).
    - `max_gradients`: the budget per width (gradient evaluations).
    - `trust`: the first trust region (relative step); `restart_trust` where a re-solve
      starts from a design (after a check shifted the requirement).
    """

    widths: tuple = (1e-6, 1e-7)
    max_gradients: int = 20
    trust: float = 0.5
    restart_trust: float = 0.1

    def __post_init__(self):
        object.__setattr__(self, "widths", _widths(self.widths))
        if int(self.max_gradients) < 0:
            raise ValueError(f"Sequential: max_gradients must be >= 0, got {self.max_gradients!r}.")

    def solve(self, problem, requirement, tol, *, x0=None, step=None, progress=False, callback=None):
        widths = self.widths if x0 is None else self.widths[-1:]
        trust = (self.trust if x0 is None else self.restart_trust) if step is None else float(step)
        return sequential_continuation(problem, requirement, widths, int(self.max_gradients), progress, callback, x0=x0,
                                       trust=trust, tol=tuple(np.atleast_1d(tol)))

    def most_gradients(self) -> int:
        return len(self.widths) * int(self.max_gradients)


@dataclasses.dataclass(frozen=True)
class AugmentedLagrangian(AbstractDesignMethod):
    """Adam on the augmented Lagrangian (`optimise_design`, on optax): `max_outer` outer
    iterations of `inner_steps` Adam steps at `learning_rate`, the multiplier and penalty
    updated between them; the smoothing widths one per outer iteration, the last repeated. One
    requirement on tangent slopes."""

    widths: tuple = (1e-6, 1e-7)
    max_outer: int = 6
    inner_steps: int = 10
    learning_rate: float = 0.1
    budget: ClassVar[str] = "max_outer"
    several: ClassVar[bool] = False
    fitted: ClassVar[bool] = False
    restarts: ClassVar[bool] = False

    def __post_init__(self):
        object.__setattr__(self, "widths", _widths(self.widths))

    def solve(self, problem, requirement, tol, *, x0=None, step=None, progress=False, callback=None):
        if np.size(requirement) != 1:
            raise ValueError("AugmentedLagrangian: one requirement only; several need Sequential().")
        requirement = np.asarray(requirement, dtype=float).reshape(())  # one requirement, as every solver is given it: (1,)
        if callback is not None:
            raise ValueError("AugmentedLagrangian: takes no callback (Sequential does).")
        widths = jnp.asarray(self.widths if x0 is None else self.widths[-1:])
        return optimise_design(
            problem.objective, problem.features, requirement=float(requirement), lower=problem.lower, upper=problem.upper,
            draws=problem.draws, x0=problem.x0 if x0 is None else x0, cost_model=problem.cost_model,
            optimiser=optax.adam(self.learning_rate), continuation=lambda i: widths[jnp.minimum(i, len(widths) - 1)],
            max_outer=int(self.max_outer), inner_steps=int(self.inner_steps), tol=1e-3, progress=progress)

    def most_gradients(self) -> int:
        return int(self.max_outer) * (int(self.inner_steps) + 1)  # and one value-and-gradient per outer iteration


@dataclasses.dataclass(frozen=True)
class SLSQP(AbstractDesignMethod):
    """SciPy's SLSQP (Kraft's sequential least squares programming, `scipy.optimize.minimize`)
    on the design problem as posed: $\\min C(b)$ s.t. $f_j(x) \\le R_j$ over the box, with the
    cost's and the constraints' exact gradients (the same programs `Sequential` differentiates),
    once per smoothing width, wide to narrow, each from the last one's design, and judged at the
    last. The variables in µm; SciPy's multipliers are the result's (cost per unit of each
    output). A reference, not a rival on rough outputs: it trusts every gradient it is given (no
    trust region), and it takes tangent slopes only (`fitted` is False: no secants or response
    surfaces).

    - `widths` (m): smoothing widths, wide to narrow.
    - `max_iterations`: SLSQP's `maxiter` per width; `ftol`: its `ftol` (on the cost)."""

    widths: tuple = (1e-6, 1e-7)
    max_iterations: int = 100
    ftol: float = 1e-9
    budget: ClassVar[str] = "max_iterations"
    fitted: ClassVar[bool] = False

    def __post_init__(self):
        object.__setattr__(self, "widths", _widths(self.widths))
        if int(self.max_iterations) < 1:
            raise ValueError(f"SLSQP: max_iterations must be >= 1, got {self.max_iterations!r}.")

    def solve(self, problem, requirement, tol, *, x0=None, step=None, progress=False, callback=None):
        del step, progress  # no trust region; SciPy reports no progress
        from .sequential import _row  # the sequential method's history rows: one History for every method

        widths = self.widths if x0 is None else self.widths[-1:]
        x = problem.x0 if x0 is None else x0
        cost_gradient = jax.jit(jax.grad(lambda b: problem.cost_model.total(b, problem.features.size_mm)))
        rows, evaluations = [], 0
        for width in widths:
            design = ConstrainedDesign(problem.objective, problem.features, requirement, tuple(np.atleast_1d(tol)),
                                       problem.lower, problem.upper, problem.cost_model, problem.draws, width)
            x, (f, g), lam, success, evaluations = _slsqp(design, x, cost_gradient, int(self.max_iterations), float(self.ftol),
                                                         callback, evaluations)
            rows.append(_row(design, float(problem.cost_model.total(jnp.asarray(x.band), problem.features.size_mm)), f, lam,
                             evaluations))
        n = len(problem.features.names)
        sensitivity = Design(g[:, :n] / 1e-6, g[:, n:] / 1e-6)  # arcsec per µm -> per m
        return make_result(design, x, f, sensitivity, lam, converged=success, iteration=len(rows) - 1, rows=rows)


def _um(x: Design) -> np.ndarray:
    return np.concatenate([np.asarray(x.nominal), np.asarray(x.band)]) / 1e-6


def _slsqp(design: ConstrainedDesign, x0: Design, cost_gradient, max_iterations: int, ftol: float, callback, evaluations: int):
    """SciPy's SLSQP on `design` from `x0`: `(x, (f, g) there, multipliers, success, evaluations
    so far)`, `f` the constraints' values (m,) and `g` their gradients per µm (m, 2n)."""
    # Here, not at the top: subproblem imports this module's neighbours (sequential, problem).
    from .subproblem import objective_value_and_gradient

    n, size = len(design.features.names), design.features.size_mm
    as_design = lambda z: Design(z[:n] * 1e-6, z[n:] * 1e-6)  # noqa: E731  (µm -> m)
    memo = {}  # SciPy asks for the constraints' values and their Jacobian at the same point: one solve

    def cost(z):
        return float(design.cost_model.total(jnp.asarray(z[n:] * 1e-6), size))

    def cost_jacobian(z):
        return np.concatenate([np.zeros(n), np.asarray(cost_gradient(jnp.asarray(z[n:] * 1e-6))) * 1e-6])

    def constraints(z):
        nonlocal evaluations
        key = z.tobytes()
        if key not in memo:
            memo.clear()
            f, g = objective_value_and_gradient(design.objective, as_design(z), design.draws, design.width)
            g = np.concatenate([np.atleast_2d(np.asarray(g.nominal)), np.atleast_2d(np.asarray(g.band))], axis=1) * 1e-6
            memo[key] = (np.atleast_1d(np.asarray(f, dtype=float)), g)
            evaluations += 1
            if callback is not None:
                f = memo[key][0]
                callback(evaluations, as_design(z), cost(z), f)
        return memo[key]

    R = np.asarray(design.requirements, dtype=float)
    margins = {"type": "ineq", "fun": lambda z: R - constraints(z)[0], "jac": lambda z: -constraints(z)[1]}
    lower, upper = _um(design.lower), _um(design.upper)
    found = scipy.optimize.minimize(cost, np.clip(_um(x0), lower, upper), jac=cost_jacobian, method="SLSQP",
                                    bounds=list(zip(lower, upper)), constraints=[margins],
                                    options={"ftol": ftol, "maxiter": max_iterations})
    z = np.clip(found.x, lower, upper)
    f, g = constraints(z)  # the memo's where SciPy ended on it (it usually does)
    lam = getattr(found, "multipliers", None)  # SciPy >= 1.16; else from the stationarity condition
    if lam is None:  # over the free variables and the constraints met with equality (the others' are 0)
        free = (z > lower + 1e-9 * (1 + np.abs(lower))) & (z < upper - 1e-9 * (1 + np.abs(upper)))
        active = f >= R * (1 - 1e-6)
        lam = np.zeros(design.m)
        if free.any() and active.any():
            lam[active] = scipy.optimize.nnls(g[active][:, free].T, -cost_jacobian(z)[free])[0]
    return as_design(z), (f, g), np.asarray(lam, dtype=float)[: design.m], bool(found.success), evaluations


def sequential_continuation(problem: DesignProblem, requirement, widths, max_iterations, progress, callback=None, x0=None, trust=0.5,
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
    return chain_results(results)
