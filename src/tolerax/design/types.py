"""The tolerance design's shared types: a design (`Design`), the features it is over
(`Features`), an optimiser's history and result (`History`, `OptimisationResult`), the
first-order optimality residual, manufactured units of a design (`realise`) and robust statistics
over them (`robust`). Every optimiser in `tolerax.design` reads and returns these."""

import jax
import jax.numpy as jnp
import jax.scipy.special as jsp
import equinox as eqx
import numpy as np
import scipy.optimize
from jaxtyping import Array, Bool, Float, Int

from .. import _validate as V
from ..physics import smooth as _smooth
from ..uncertainty.sampling import Tolerances, manufactured


class Design(eqx.Module):
    """The design optimisers' variables: two arrays over the features, a position and a
    half-width (m). Not a zone a user holds (that is `tolerax.Tolerances`, which reports, scene
    files and Monte Carlo share, with names and a distribution): the arrays the objectives,
    their gradients and the optimisers pass about under `jit`.

    What `nominal` positions is the parameterisation's, named where it is read: the zone's
    middle for the objectives over units (`RobustPointing`, `LinearisedYield`, `realise`,
    `yield_check`: a part is made anywhere in `nominal ± band`), the zone's *lower limit* for
    the optimisers (`FromLowerLimit`, whose problems the solvers see: `OptimisationResult.x`,
    `ConstrainedDesign.lower`/`upper`). `tolerances` turns either into a `Tolerances`.

    **Arguments:**

    - `nominal`: the position of each feature's zone (m), shape `(n_features,)`.
    - `band`: the half-width of its zone (m), same shape.

    A leading axis, `(m, n_features)`, holds one row per constraint (a derivative of several
    constraints, as `OptimisationResult.sensitivity` with two requirements).
    """

    nominal: Float[Array, " n"]
    band: Float[Array, " n"]

    def __init__(self, nominal, band):
        self.nominal = V.real("Design", "nominal", nominal, "m", shape=None)
        self.band = V.real("Design", "band", band, "m", shape=None)

    def tolerances(self, names, *, from_lower_limit: bool) -> Tolerances:
        """These variables as zones (`Tolerances`, uniform) over the features `names`:
        `from_lower_limit` says whether `nominal` holds the zones' lower limits (an optimiser's
        `x`) or their middles."""
        band = np.asarray(self.band, dtype=float)
        middle = np.asarray(self.nominal, dtype=float) + (band if from_lower_limit else 0.0)
        return Tolerances(names, middle, band, "uniform")

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
    - `pressure_angle`: optional, the pressure angle (rad) of each backlash feature's mesh (any
      value for the others), for the drawing's tooth-thickness allowances
      (`tolerax.design.backlash`); None: backlash is called out by its grade alone.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    size_mm: Float[Array, " n"]
    pressure_angle: Float[Array, " n"] | None = None

    def __init__(self, names, size_mm, pressure_angle=None):
        self.names = tuple(str(name) for name in names)
        self.size_mm = V.real("Features", "size_mm", size_mm, "mm", shape=(len(self.names),))
        self.pressure_angle = None if pressure_angle is None else V.real(
            "Features", "pressure_angle", pressure_angle, "rad", shape=(len(self.names),))

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
    - `multiplier`: $\\lambda$ (cost per arcsec). These three: a column per requirement.
    - `penalty`: $\\rho$ (dimensionless).
    - `continuation`: the value passed to the objective. `steps`: optimiser steps so far.
    """

    cost: Float[Array, " iterations"]
    objective: Float[Array, "iterations m"]
    constraint: Float[Array, "iterations m"]
    multiplier: Float[Array, "iterations m"]
    penalty: Float[Array, " iterations"]
    continuation: Float[Array, " iterations"]
    steps: Float[Array, " iterations"]


class OptimisationResult(eqx.Module):
    """What `optimise_design` found.

    - `x`: the design (`Design`, m). `features`: the `Features` it was asked for.
    - `cost`: total cost; `feature_cost`: per feature (cost unit of the model).
    - `objective`: $f(x)$ (arcsec) at the last continuation value; `constraint`: $f(x) - R$.
      These, `multiplier` and `constraint_active` hold one entry per requirement (m,), and
      `sensitivity` one row each (m, n): one requirement or several, the same shapes.
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
    - `stalled` (optional): the run ended because its steps stopped being accepted at the
      smallest trust region (the sequential method), not on its budget.
    - `sensitivity_se` (optional): standard errors of `sensitivity` where it is an estimate
      (slopes fitted over a few simulated units: `sequential_design(gradient_noise=...)`).
    """

    x: Design
    features: Features
    cost: Float[Array, ""]
    feature_cost: Float[Array, " n"]
    objective: Float[Array, " m"]
    constraint: Float[Array, " m"]
    multiplier: Float[Array, " m"]
    constraint_active: Bool[Array, " m"]
    at_lower: Design
    at_upper: Design
    sensitivity: Design
    cost_gradient: Design
    converged: Bool[Array, ""]
    iteration: Int[Array, ""]
    history: History
    sensitivity_se: Design | None = None
    stalled: Bool[Array, ""] | None = None

    @property
    def optimality(self) -> float:
        """First-order optimality residual at `x` (`optimality_residual`): 0 at a KKT point."""
        flat = lambda d: np.concatenate([np.asarray(d.nominal), np.asarray(d.band)], axis=-1)  # noqa: E731
        sensitivity = flat(self.sensitivity)[counted_rows(self.constraint_active)]
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
        rows = counted_rows(self.constraint_active)
        sensitivity, se = np.asarray(self.sensitivity.band)[rows], None if se is None else se[rows]
        return optimality_residual(np.asarray(self.cost_gradient.band), sensitivity, np.asarray(self.at_lower.band),
                                   np.asarray(self.at_upper.band), se)


def counted_rows(active) -> np.ndarray:
    """Which constraints' gradients the optimality residual counts, given which are active
    (m,): the active ones, an inactive constraint's multiplier being 0 — but a lone constraint
    always (its multiplier is then the residual's own minimiser, 0 where that fits best: a
    design clear of its one requirement with bands left to widen reads far from optimal either
    way)."""
    active = np.atleast_1d(np.asarray(active, dtype=bool))
    return np.ones_like(active) if active.size == 1 else active


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


def chain_results(results):
    """The last of successive `OptimisationResult`s (each started from the one before) with one
    history over all of them: its gradient counts run on, its `iteration` indexes the whole."""
    offset = sum(len(np.asarray(r.history.cost)) for r in results[:-1])
    steps = np.cumsum([int(np.asarray(r.history.steps)[-1]) for r in results])
    history = jax.tree.map(lambda *h: jnp.concatenate(h), *[r.history for r in results])
    counts = np.concatenate([np.asarray(r.history.steps) + (steps[i - 1] if i else 0) for i, r in enumerate(results)])
    history = eqx.tree_at(lambda h: h.steps, history, jnp.asarray(counts, dtype=float))
    last = results[-1]
    return eqx.tree_at(lambda r: (r.history, r.iteration), last, (history, last.iteration + offset))
