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

import functools
from collections.abc import Callable
from typing import Any

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.special as jsp
import numpy as np
import optax
import scipy.optimize
import tqdm
from jaxtyping import Array, ArrayLike, Bool, Float, Int
from ..physics import smooth as _smooth
from .. import _validate as V
from ..uncertainty.sampling import manufactured
from .cost import AbstractCostModel, IsoGrade


class Design(eqx.Module):
    """A tolerance design: per feature a nominal value and a tolerance band half-width.

    **Arguments:**

    - `nominal`: nominal clearance or backlash of each feature (m), shape `(n_features,)`.
    - `band`: half-width of its tolerance band (m), same shape; a part is made anywhere in
      `nominal ± band`.

    A leading axis, `(m, n_features)`, holds one row per constraint (a derivative of several
    constraints, as `OptimisationResult.sensitivity` with two requirements).
    """

    nominal: Float[Array, " n"]
    band: Float[Array, " n"]

    def __init__(self, nominal, band):
        self.nominal = V.real("Design", "nominal", nominal, "m", shape=None)
        self.band = V.real("Design", "band", band, "m", shape=None)

    def __check_init__(self):
        if jnp.ndim(self.nominal) not in (1, 2) or jnp.shape(self.nominal) != jnp.shape(self.band):
            raise ValueError(
                f"Design.nominal and Design.band must both have shape (n_features,) (or (m, n_features), a row per constraint), got "
                f"{jnp.shape(self.nominal)} and {jnp.shape(self.band)}."
            )


class Features(eqx.Module):
    """What the design variables are: feature names and their nominal sizes.

    **Arguments:**

    - `names`: one name per feature, e.g. `("azimuth sun-bearing clearance", ...)`.
    - `size_mm`: nominal size of each feature (mm) for the cost model: the journal diameter of a
      bearing fit, the pitch diameter of a gear mesh.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    size_mm: Float[Array, " n"]

    def __init__(self, names, size_mm):
        self.names = tuple(str(name) for name in names)
        self.size_mm = V.real("Features", "size_mm", size_mm, "mm", shape=(len(self.names),))

    def __check_init__(self):
        if len(set(self.names)) != len(self.names):
            raise ValueError(f"Features.names must be distinct, got {self.names}.")
        V.check(self, size_mm=V.POSITIVE("mm"))


def realise(x: Design, draws: Float[Array, "n_draws n"]) -> Float[Array, "n_draws n"]:
    """Manufactured values $\\max(0, \\text{nominal} + \\text{band}\\cdot u)$ (m) of standardised
    draws $u \\in [-1, 1]$, one row per manufactured unit (a clearance cannot be negative)."""
    return manufactured(x.nominal, x.band, draws, 0.0)


def _harrell_davis_weights(n: int, q: float) -> Float[Array, " n"]:
    a, b = q * (n + 1), (1.0 - q) * (n + 1)
    edges = jsp.betainc(a, b, jnp.linspace(0.0, 1.0, n + 1))
    return jnp.diff(edges)


def robust(
    values: Float[Array, "n_draws *rest"], kind: str = "mean+kstd", k: float = 3.0, q: float = 0.99
) -> Float[Array, "*rest"]:
    """A robust statistic of an objective over manufacturing draws (axis 0).

    - `kind="mean+kstd"`: $\\bar v + k\\,s$, $s$ the sample standard deviation ($n - 1$); its
      gradient is finite (zero spread gives the gradient of the mean).
    - `kind="quantile"`: the Harrell–Davis estimate of the `q` quantile (Harrell and Davis,
      Biometrika 69, 1982): $\\sum_i w_i v_{(i)}$ with $w_i = I_{i/n}(a, b) - I_{(i-1)/n}(a, b)$,
      $a = q(n + 1)$, $b = (1 - q)(n + 1)$. Unlike the empirical quantile, which follows one order
      statistic and jumps between them, every sample contributes with a weight that varies
      smoothly with its rank, so it is a continuous function of the values with a gradient that
      changes by $O(1/n)$ where two samples swap rank.

    **Arguments:**

    - `values`: the objective for each draw, draws along axis 0 (at least 2 draws).
    - `kind`: `"mean+kstd"` or `"quantile"`.
    - `k`: multiplier of the standard deviation (`"mean+kstd"`).
    - `q`: quantile in (0, 1) (`"quantile"`).

    **Returns:**

    The statistic, in the units of `values`, the shape of `values` without axis 0.
    """
    values = jnp.asarray(values)
    n = values.shape[0]
    if n < 2:
        raise ValueError(f"robust: values must hold at least 2 draws along axis 0, got shape {values.shape}.")
    if kind == "mean+kstd":
        return jnp.mean(values, axis=0) + k * _smooth.sqrt(jnp.var(values, axis=0, ddof=1))
    if kind == "quantile":
        if not 0.0 < q < 1.0:
            raise ValueError(f"robust: q must be in (0, 1), got {q!r}.")
        weights = _harrell_davis_weights(n, q)
        return jnp.tensordot(weights, jnp.sort(values, axis=0), axes=1)
    raise ValueError(f"robust: kind must be 'mean+kstd' or 'quantile', got {kind!r}.")


class History(eqx.Module):
    """One entry per outer iteration, at the end of its inner minimisation.

    - `cost`: total cost. `objective`: $f$ (arcsec). `constraint`: $f - R$ (arcsec).
    - `multiplier`: $\\lambda$ (cost per arcsec). `penalty`: $\\rho$ (dimensionless).
    - `continuation`: the value passed to the objective. `steps`: optimiser steps so far.
    """

    cost: Float[Array, " iterations"]
    objective: Float[Array, " iterations"]
    constraint: Float[Array, " iterations"]
    multiplier: Float[Array, " iterations"]
    penalty: Float[Array, " iterations"]
    continuation: Float[Array, " iterations"]
    steps: Float[Array, " iterations"]


class OptimisationResult(eqx.Module):
    """What `optimise_design` found.

    - `x`: the design (`Design`, m). `features`: the `Features` it was asked for.
    - `cost`: total cost; `feature_cost`: per feature (cost unit of the model).
    - `objective`: $f(x)$ (arcsec) at the last continuation value; `constraint`: $f(x) - R$.
    - `multiplier`: $\\lambda \\ge 0$ (cost per arcsec): the shadow price of the requirement,
      $\\partial C^*/\\partial R = -\\lambda$ at a regular optimum.
    - `constraint_active`: whether the requirement binds ($f \\ge R(1 - $`active_tol`$)$).
    - `at_lower`, `at_upper`: per variable, whether it sits on its bound (`Design` of booleans).
    - `sensitivity`: $\\partial f/\\partial x$ (arcsec/m) at the optimum; `cost_gradient`:
      $\\partial C/\\partial x$ (cost/m).
    - `converged`: the violation, the change of $x$ and the continuation all settled.
    - `iteration`: the outer iteration (index into `history`) whose design this is: the cheapest
      one that met the requirement (to `tol`) at the final continuation value, else the last one.
    - `history`: a `History`.
    - `optimality` (property): the first-order optimality residual at `x` (`optimality_residual`);
      `band_optimality`: the same over the bands alone, the lower limits held (they carry no
      cost, and their derivative is noise on an objective rough at small scales);
      `band_optimality_within_noise`: the bands' residual within the sensitivities' noise.
    - `sensitivity_se` (optional): standard errors of `sensitivity` where it is an estimate
      (slopes fitted over a few simulated units: `sequential_design(gradient_noise=...)`).
    """

    x: Design
    features: Features
    cost: Float[Array, ""]
    feature_cost: Float[Array, " n"]
    objective: Float[Array, ""]
    constraint: Float[Array, ""]
    multiplier: Float[Array, ""]
    constraint_active: Bool[Array, ""]
    at_lower: Design
    at_upper: Design
    sensitivity: Design
    cost_gradient: Design
    converged: Bool[Array, ""]
    iteration: Int[Array, ""]
    history: History
    sensitivity_se: Design | None = None

    @property
    def optimality(self) -> float:
        """First-order optimality residual at `x` (`optimality_residual`): 0 at a KKT point."""
        flat = lambda d: np.concatenate([np.asarray(d.nominal), np.asarray(d.band)], axis=-1)  # noqa: E731
        sensitivity = flat(self.sensitivity)
        if sensitivity.ndim == 2:  # several constraints: the active ones
            sensitivity = sensitivity[np.asarray(self.constraint_active, dtype=bool)]
        return optimality_residual(flat(self.cost_gradient), sensitivity, flat(self.at_lower), flat(self.at_upper))

    @property
    def band_optimality(self) -> float:
        """First-order optimality residual over the bands, the lower limits held where they are."""
        return self._band_residual(None)

    @property
    def band_optimality_within_noise(self) -> float:
        """`band_optimality` within 2 standard errors of the sensitivities (`sensitivity_se`,
        where they are estimates: `optimality_residual(gradient_se=...)`); NaN without them."""
        return float("nan") if self.sensitivity_se is None else self._band_residual(np.asarray(self.sensitivity_se.band))

    def _band_residual(self, se) -> float:
        """`optimality_residual` over the bands (the active constraints' rows where there are
        several), with the sensitivities' standard errors `se` where given."""
        sensitivity = np.asarray(self.sensitivity.band)
        if sensitivity.ndim == 2:
            active = np.asarray(self.constraint_active, dtype=bool)
            sensitivity, se = sensitivity[active], None if se is None else se[active]
        return optimality_residual(np.asarray(self.cost_gradient.band), sensitivity, np.asarray(self.at_lower.band),
                                   np.asarray(self.at_upper.band), se)


def optimality_residual(cost_gradient, gradient, at_lower, at_upper, gradient_se=None, k: float = 2.0) -> float:
    """The first-order (KKT) optimality residual of $\\min C$ s.t. $f \\le R$ in a box:
    $\\min_{\\lambda \\ge 0} \\|P(\\nabla C + \\lambda\\nabla f)\\| / \\|P(\\nabla C)\\|$, where $P$
    projects onto the directions the box lets the design move in (a variable on its lower bound
    keeps only a negative component, one on its upper bound only a positive one: the
    projected-gradient criticality measure). Zero at a KKT point of an active constraint; 1 where
    $\\nabla f$ offers no trade (e.g. an inactive constraint with bands that could still widen);
    0 where even $P(\\nabla C)$ vanishes (every band at its widest).

    The multiplier is the one that minimises the projected residual (a convex, piecewise-quadratic
    function of $\\lambda$, minimised exactly over its pieces), so variables held on a bound do
    not bias it: a least-squares multiplier fitted over every variable, the lower limits on
    their bounds included, under-reads $\\lambda$ and reports a KKT point as far from one.

    Arguments are flat arrays over all variables: $\\nabla C$, $\\nabla f$ and whether each
    variable sits on its lower or upper bound (on both: fixed, left out). Several (active) constraints: `gradient` of
    shape (m, n), one row each, and $\\lambda \\in \\mathbb{R}^m_{\\ge 0}$ found by bounded
    quasi-Newton (`scipy.optimize.minimize`, L-BFGS-B: the squared projected norm is convex and
    once differentiable); no rows: $\\lambda = 0$.

    `gradient_se` (optional, the shape of `gradient`): standard errors of the constraints'
    gradients where they are estimates (slopes fitted over a few simulated units of a chaotic
    response: `secant_gradient_noise`). The residual is then *within that noise*: each
    component of $P(\\nabla C + \\lambda^T\\nabla f)$ is shrunk towards 0 by `k` standard errors
    of $\\lambda^T\\nabla f$ there, $k\\,\\lambda^T \\sigma$ (soft thresholding), before the norm:
    0 where some gradients within `k` standard errors of the estimates make the design a KKT
    point, i.e. where no first-order improvement is distinguishable from the estimates' noise.
    The shrunk squared norm is still convex in $\\lambda$ and once differentiable (L-BFGS-B)."""
    dc, grad = np.asarray(cost_gradient, dtype=float), np.asarray(gradient, dtype=float)
    at_lower, at_upper = np.asarray(at_lower, dtype=bool), np.asarray(at_upper, dtype=bool)
    free = ~(at_lower & at_upper)  # a variable on both bounds (a fixed feature) cannot move at all
    dc, grad, at_lower, at_upper = dc[free], grad[..., free], at_lower[free], at_upper[free]

    def project(g):
        return np.where(at_lower, np.minimum(g, 0.0), np.where(at_upper, np.maximum(g, 0.0), g))

    scale = np.linalg.norm(project(dc))
    if scale == 0.0:
        return 0.0
    if gradient_se is not None:
        se = np.asarray(gradient_se, dtype=float)
        if se.shape != np.asarray(gradient).shape or not np.all(np.isfinite(se) & (se >= 0)):
            raise ValueError(f"optimality_residual: gradient_se must be finite, >= 0 and shaped like gradient {np.shape(gradient)}, "
                             f"got shape {se.shape}.")
        rows, se = np.atleast_2d(grad), float(k) * np.atleast_2d(se[..., free])
        if rows.shape[0] == 0:
            return 1.0

        def shrunk(lam):
            p = project(dc + lam @ rows)
            e = np.maximum(np.abs(p) - lam @ se, 0.0) * np.sign(p)
            # d|p|/dlam = sign(p) rows where p is counted (project keeps it), d(threshold) = se
            return e @ e, 2.0 * ((rows * np.sign(p)) - se) @ np.abs(e)

        best = min((scipy.optimize.minimize(shrunk, np.full(rows.shape[0], start), jac=True, method="L-BFGS-B",
                                            bounds=[(0.0, None)] * rows.shape[0], options=dict(ftol=1e-15, gtol=1e-14)).x
                    for start in (0.0, float(np.linalg.norm(dc) / max(np.linalg.norm(rows), 1e-300)))), key=lambda lam: shrunk(lam)[0])
        return float(np.sqrt(shrunk(best)[0]) / scale)
    if grad.ndim == 2 and grad.shape[0] == 1:
        grad = grad[0]
    if grad.ndim == 2:
        if grad.shape[0] == 0:
            return 1.0

        def squared(lam):
            r = project(dc + lam @ grad)
            return r @ r, 2.0 * grad @ r

        lam = scipy.optimize.minimize(squared, np.zeros(grad.shape[0]), jac=True, method="L-BFGS-B",
                                      bounds=[(0.0, None)] * grad.shape[0], options=dict(ftol=1e-15, gtol=1e-12)).x
        return float(np.sqrt(squared(lam)[0]) / scale)

    def projected(lam):
        return project(dc + lam * grad)
    # Pieces: between the multipliers where a bounded variable's component changes sign, the
    # set of counted components is fixed and the squared norm is a quadratic in lambda.
    bounded = (at_lower | at_upper) & (grad != 0)
    kinks = np.unique(np.concatenate([[0.0], -dc[bounded] / grad[bounded]]))
    kinks = kinks[np.isfinite(kinks) & (kinks >= 0)]
    edges = np.concatenate([kinks, [np.inf]])
    candidates = list(kinks)
    for a, b in zip(edges[:-1], edges[1:]):
        probe = a + 1.0 if np.isinf(b) else 0.5 * (a + b)
        counted = ~(at_lower | at_upper) | (projected(probe) != 0)
        gg = grad[counted] @ grad[counted]
        if gg > 0:
            candidates.append(float(np.clip(-(dc[counted] @ grad[counted]) / gg, a, b)))
    return float(min(np.linalg.norm(projected(lam)) for lam in candidates) / scale)


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
    schedule = continuation if callable(continuation) else (lambda _, c=continuation: c)
    optimiser = _with_extra_args(optimiser)

    span = jax.tree.map(lambda lo, hi: hi - lo, lower, upper)
    z = jax.tree.map(lambda x, lo, s: (x - lo) / jnp.where(s > 0, s, 1.0), x0, lower, span)
    cost_scale = cost_model.total(x0.band, features.size_mm)
    if not (np.isfinite(cost_scale) and cost_scale > 0):
        raise ValueError(f"optimise_design: cost_model gives a total cost {float(cost_scale)} at x0; need finite, > 0.")
    problem = _Problem(lower, span, features.size_mm, jnp.asarray(requirement, dtype=float), cost_scale)
    to_arcsec = cost_scale / problem.requirement  # dimensionless multiplier -> cost per arcsec

    multiplier, rho = jnp.asarray(0.0, dtype=float), jnp.asarray(float(penalty), dtype=float)
    previous_violation, rows, converged = np.inf, [], False
    # The objective is noisy at the scale of an optimiser step (rattle), so the augmented
    # Lagrangian iterates oscillate about the constraint instead of settling on it; the result is
    # the cheapest iterate that met the requirement at the final continuation value (if any
    # did), not merely the last one.
    final_value = float(schedule(max_outer - 1))
    best, meets = None, lambda f_: f_ <= float(requirement) * (1.0 + tol)  # within the violation tolerance
    bar = tqdm.tqdm(total=max_outer, desc="optimise_design (outer iterations)", unit="it", disable=not progress)
    for iteration in range(max_outer):
        value = jnp.asarray(schedule(iteration), dtype=float)
        z_new, multiplier_new, violation, f, feature_cost, sensitivity, cost_gradient = _outer_iteration(
            z, multiplier, rho, problem, draws, value, objective, cost_model, optimiser, inner_steps
        )
        if not (np.isfinite(f) and all(np.all(np.isfinite(leaf)) for leaf in jax.tree.leaves(z_new))):
            raise RuntimeError(
                f"optimise_design: the objective returned {float(f)} (or a non-finite gradient) at outer "
                f"iteration {iteration}, continuation {float(value)}."
            )
        change = max(float(jnp.max(jnp.abs(a - b))) for a, b in zip(jax.tree.leaves(z_new), jax.tree.leaves(z)))
        z, multiplier, violation = z_new, multiplier_new, float(violation)
        row = (jnp.sum(feature_cost), f, f - problem.requirement, multiplier * to_arcsec, rho, value)
        rows.append(tuple(float(v) for v in row) + ((iteration + 1) * inner_steps,))
        if meets(rows[-1][1]) and float(value) == final_value and (best is None or rows[-1][0] < best[0]):
            best = (rows[-1][0], iteration, z, f, feature_cost, sensitivity, cost_gradient, multiplier)
        bar.set_postfix(cost=f"{rows[-1][0]:.4g}", objective=f"{rows[-1][1]:.4g}", requirement=f"{float(requirement):.4g}")
        bar.update()
        settled = float(schedule(iteration + 1)) == float(value)
        if abs(violation) <= tol and change <= tol and settled:
            converged = True
            break
        if abs(violation) > 0.5 * abs(previous_violation):
            rho = jnp.minimum(rho * penalty_growth, max_penalty)
        previous_violation = violation
    bar.close()
    chosen = len(rows) - 1
    if best is not None and (not meets(rows[-1][1]) or best[0] < rows[-1][0]):
        _, chosen, z, f, feature_cost, sensitivity, cost_gradient, multiplier = best

    return OptimisationResult(
        x=problem.to_x(z),
        features=features,
        cost=jnp.sum(feature_cost),
        feature_cost=feature_cost,
        objective=f,
        constraint=f - problem.requirement,
        multiplier=multiplier * to_arcsec,
        constraint_active=f >= problem.requirement * (1.0 - active_tol),
        at_lower=jax.tree.map(lambda zz: zz <= 1e-9, z),
        at_upper=jax.tree.map(lambda zz, s: (zz >= 1.0 - 1e-9) | (s == 0), z, span),
        sensitivity=sensitivity,
        cost_gradient=cost_gradient,
        converged=jnp.asarray(converged),
        iteration=jnp.asarray(chosen),
        history=History(*(jnp.asarray(column, dtype=float) for column in zip(*rows))),
    )
