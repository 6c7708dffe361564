"""Tolerance design by sequential linearisation: a calibrated stack-up rebuilt at every iterate,
solved exactly, inside a trust region.

The problem is `optimise_design`'s, with the design variables read as `FromLowerLimit` does:
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
last two kept steps, SLSQP's test) with the *bands* at a KKT point (their residual, the lower
limits held, below `band_tol`). The last test exists because the lower limits carry no cost:
their optimality condition is $\\partial f/\\partial l = 0$, and on an objective rough at small
scales (impacts at a narrow smoothing width) that derivative is noise. Measured on the design
scan at 0.1 um: the output bearing's lower limit has a local derivative of +0.50 arcsec/um
where its secant over 5-90 um is -0.013 arcsec/um (1 arcsec over its whole range, 0.25 % of
the requirement); the iterates move it about and the full residual stays near 0.05 while the
cost has stopped changing. Where the constraints' gradients are estimates (slopes fitted over
a few units of a chaotic response: the jitter), the bands' test may also pass within two
standard errors of them (`gradient_noise`). Otherwise the run ends on its budget, reported not
converged, with the cheapest iterate on the requirement.

Why the subproblem is not solved on optax: it is separable with a few linear constraints,
so it has an exact solution (a one-dimensional dual by bisection for one; SLSQP on a problem
without simulations for several), and each iterate's simulation is the expensive part.
The optax path, Adam on an augmented Lagrangian (`optimise_design`), stays as a method and
loses the race on the design scan: 3.22 against 2.47
(benchmarks/results/design_comparison.md).
"""

from collections.abc import Callable

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import scipy.optimize
import tqdm

from ..cache import exported_jit
from .cost import AbstractCostModel
from .types import Design, Features, History, OptimisationResult, optimality_residual


def _bisect(fn, lower, upper):
    """The root of the increasing scalar function `fn` in `[lower, upper]`, or the bound nearer
    to it where `fn` does not change sign there. Bisection (`optimistix.Bisection`) on `fn`
    extended beyond the interval by lines steep enough to bracket a root always, then clipped."""
    f_low, f_high = fn(lower), fn(upper)
    span = upper - lower + 1e-300
    steep = (jnp.abs(f_low) + jnp.abs(f_high) + 1.0) / span

    def extended(y, _):
        return fn(jnp.clip(y, lower, upper)) + steep * (jnp.minimum(y - lower, 0.0) + jnp.maximum(y - upper, 0.0))

    solver = optx.Bisection(rtol=1e-12, atol=1e-300, flip=False)
    root = optx.root_find(extended, solver, 0.5 * (lower + upper), options=dict(lower=lower - span, upper=upper + span),
                          throw=False, max_steps=256).value
    return jnp.clip(root, lower, upper)


@exported_jit
def _value_and_grad(objective, x, draws, width):
    # One program per objective structure, shared by every call (starts, smoothing widths): the
    # width and the draws are arrays. Kept between processes with the compilation cache (its
    # tracing through the solve is most of a warm design's start: `tolerax.cache.exported_jit`).
    return jax.value_and_grad(lambda x_: objective(x_, draws, width))(x)


@eqx.filter_jit
def _value_and_jacobian(objective, x, draws, width):
    """Several constraints: their values and their Jacobian (one reverse pass each)."""
    f = lambda x_: objective(x_, draws, width)  # noqa: E731
    return f(x), jax.jacrev(f)(x)


@exported_jit
def _subproblem(cost_of, size_mm, f_k, a, d, l_k, b_k, l_box, b_box, requirement):
    """Exact minimiser of the linearised problem over the boxes `l_box`, `b_box` (pairs of
    arrays): `(l, b, multiplier, predicted f)`; the multiplier is `inf` when even the tightest
    design in the boxes does not meet the linearised requirement (the tightest design is
    returned)."""
    l = jnp.where(a > 0, l_box[0], jnp.where(a < 0, l_box[1], l_k))
    n = a.shape[0]

    def slope(i, b):
        """$c_i'(b)$: the cost is separable, so feature `i`'s cost at band `b` is its entry of
        the cost of every band set to `b` (per-feature cost parameters stay with their feature)."""
        return jax.grad(lambda x: cost_of(jnp.full(n, x), size_mm)[i])(b)

    def bands(lam):
        def one(i, b_lo, b_hi, d_i):
            return jnp.where(d_i > 0, _bisect(lambda b: slope(i, b) + lam * d_i, b_lo, b_hi), b_hi)

        return jax.vmap(one)(jnp.arange(n), b_box[0], b_box[1], d)

    def linear(b):
        return f_k + jnp.dot(a, l - l_k) + jnp.dot(d, b - b_k)

    def predicted(lam):
        return linear(bands(lam))

    h0 = predicted(0.0) - requirement
    # The multiplier at which every band with d > 0 is at its tightest: the slope there balances.
    tightest = jax.vmap(slope)(jnp.arange(n), b_box[0])
    lam_max = jnp.max(jnp.where(d > 0, -tightest / jnp.where(d > 0, d, 1.0), 0.0)) * 1.01 + 1e-300
    h_max = predicted(lam_max) - requirement
    lam = jnp.where(h0 <= 0, 0.0, jnp.where(h_max >= 0, jnp.inf, _bisect(lambda x: requirement - predicted(x), 0.0, lam_max)))
    b = bands(jnp.where(jnp.isinf(lam), lam_max, lam))
    return l, b, lam, linear(b)


def _subproblem_many(cost_model, size_mm, f_k, a, d, l_k, b_k, l_box, b_box, requirement):
    """`_subproblem` with m linearised constraints (`f_k`, `requirement`: shape (m,); `a`,
    `d`: (m, n); boxes as pairs of NumPy arrays): `(l, b, multipliers (m,), predicted f (m,))`.
    The subproblem is small (the simulations are outside it), convex (a separable convex cost,
    linear constraints, a box) and solved by SciPy's SLSQP on the cost's exact gradient (a
    nested bisection over two multipliers was tried: exact but minutes per call on a CPU).
    The multipliers are the non-negative least-squares fit of the bands' stationarity,
    $c'(b) + \\lambda^T D = 0$ over the bands inside their boxes (`scipy.optimize.nnls`)."""
    n = a.shape[1]
    scale = np.where(b_box[1] > b_box[0], b_box[1] - b_box[0], 1.0)
    l_span = np.where(l_box[1] > l_box[0], l_box[1] - l_box[0], 1.0)
    c0 = max(abs(float(_cost_and_gradient(cost_model, size_mm, jnp.asarray(b_k))[0])), 1e-300)

    def unpack(y):  # unit-box coordinates -> (l, b)
        return l_box[0] + y[:n] * l_span, b_box[0] + y[n:] * scale

    def cost(y):
        return float(_cost_and_gradient(cost_model, size_mm, jnp.asarray(unpack(y)[1]))[0]) / c0

    def cost_grad(y):
        return np.concatenate([np.zeros(n), _cost_gradient(cost_model, size_mm, unpack(y)[1]) * scale]) / c0

    def linear(y):
        l, b = unpack(y)
        return f_k + a @ (l - l_k) + d @ (b - b_k)

    jac = -np.concatenate([a * l_span, d * scale], axis=1) / requirement[:, None]
    y0 = np.clip(np.concatenate([(l_k - l_box[0]) / l_span, (b_k - b_box[0]) / scale]), 0.0, 1.0)
    result = scipy.optimize.minimize(
        cost, y0, jac=cost_grad, method="SLSQP", bounds=[(0.0, 1.0)] * (2 * n),
        constraints=[{"type": "ineq", "fun": lambda y: (requirement - linear(y)) / requirement, "jac": lambda y: jac}],
        options=dict(ftol=1e-12, maxiter=500),
    )
    # SLSQP leaves a variable on its bound only to its own tolerance: snap it there, so that the
    # design and its optimality residual see which bounds hold.
    y = np.clip(result.x, 0.0, 1.0)
    y = np.where(y < 1e-7, 0.0, np.where(y > 1.0 - 1e-7, 1.0, y))
    l, b = unpack(y)
    free = (b > b_box[0] + 1e-9 * scale) & (b < b_box[1] - 1e-9 * scale)
    multipliers = np.zeros(a.shape[0])
    if np.any(free):
        multipliers = scipy.optimize.nnls(d[:, free].T, -_cost_gradient(cost_model, size_mm, b)[free])[0]
    predicted = linear(y)
    # A constraint that even this design does not meet: infeasible within the region (as `_subproblem`'s inf).
    multipliers = np.where(predicted > requirement * (1 + 1e-6), np.inf, multipliers)
    return l, b, multipliers, predicted


@eqx.filter_jit
def _cost_and_gradient(cost_model, size_mm, band):
    """The total cost and $\\partial C/\\partial b$ (cost/m) at the bands `band`: one program per
    cost model, shared by the subproblem, the stopping test and the result."""
    return jax.value_and_grad(lambda b: cost_model.total(b, size_mm))(band)


def _cost_gradient(cost_model, size_mm, band) -> np.ndarray:
    """$\\partial C/\\partial b$ (cost/m) at the bands `band`."""
    return np.asarray(_cost_and_gradient(cost_model, size_mm, jnp.asarray(band))[1])


def _optimality(dc, z, grad, f, requirements, tol, lo, hi, n, bands_only=False, se=None) -> float:
    """`optimality_residual` at box point `z` (flat lower limits then bands) with the cost's
    gradient over the bands `dc` (n,) and the gradients `grad` (m, 2n) of the constraints values
    `f`: over the active ones (to `tol`) where there are several, an inactive constraint's
    multiplier being 0; `bands_only`: over the bands, the lower limits held where they are;
    `se` (m, 2n): the gradients' standard errors (the residual within their noise)."""
    dc = np.concatenate([np.zeros(n), dc])
    keep = slice(n, None) if bands_only else slice(None)
    rows = slice(None) if grad.shape[0] == 1 else f >= requirements * (1 - tol)
    return optimality_residual(dc[keep], grad[rows][:, keep], (z <= lo)[keep], (z >= hi)[keep],
                               None if se is None else se[rows][:, keep])


def sequential_design(
    objective: Callable,
    features: Features,
    *,
    requirement: float | tuple[float, float],
    lower: Design,
    upper: Design,
    draws,
    x0: Design,
    cost_model: AbstractCostModel,
    width=None,
    max_iterations: int = 20,
    trust_region: float = 0.5,
    tol: float | tuple[float, float] = 0.01,
    step_tol: float = 1e-3,
    optimality_tol: float = 1e-3,
    cost_tol: float = 1e-3,
    band_tol: float = 1e-2,
    progress: bool = False,
    callback: Callable[[int, Design, float, float], None] | None = None,
    gradient_noise: Callable | None = None,
) -> OptimisationResult:
    """Cheapest bands meeting `requirement` by sequential linearisation (see the module
    docstring). The design's `nominal` field holds the zone's *lower limit* (`FromLowerLimit`'s
    convention), its `band` the half-width; the cost is `cost_model(band, features.size_mm)`.

    **Arguments:**

    - `objective`: `objective(x: Design, draws, width) -> scalar` (arcsec), differentiable; or,
      with m requirements, a vector of m (e.g. a lost-motion metric and a stability metric:
      `_subproblem_many` solves the linearised problem with all; each constraint is tested as the
      one-constraint method tests it and a step must pass for both).
    - `features`, `requirement` (arcsec, or one per constraint), `lower`, `upper` (`Design` boxes, m), `draws`, `x0`
      (the start), `cost_model`: as `optimise_design`; `width` the continuation value passed
      to the objective (e.g. a smoothing width, m), fixed here.
    - `max_iterations`: gradient evaluations at most (one per iteration).
    - `trust_region`: the starting trust-region half-width, as a fraction of each variable's range.
    - `tol`: relative tolerance on the constraint ($|f - R| \\le$ `tol`$\\cdot R$ for an active one);
      with several requirements one each, e.g. a noisy constraint's at its estimate's own noise (a
      stability metric fitted over a few chaotic units: `secant_standard_error`), which a model
      error below does not shrink the trust region for.
    - `step_tol`: the design has stopped moving when no variable moves by more than this fraction
      of its range.
    - `optimality_tol`: or has stopped improving: the first-order optimality residual (see
      `_optimality`) is below this.
    - `cost_tol`, `band_tol`: or the cost changed by less than `cost_tol` (relative) over the
      last two kept steps with the bands' own residual (lower limits held) below `band_tol`.
    - `progress`: a tqdm bar over iterations.
    - `callback`: called after every gradient evaluation as `callback(evaluations, x, cost,
      objective)` with the design just evaluated (the trial point, kept or not), its cost and
      objective (arcsec; an array with several requirements): a live plot, a log, or a race against another method's wall time.
    - `gradient_noise` (optional): `gradient_noise(x, width) -> (m, 2n)` standard errors of
      the constraints' gradients at `x` (arcsec/m; lower limits then bands), where the
      gradients are estimates: slopes fitted over a few units of a chaotic response
      (`DesignProblem.gradient_noise`). The cost-stationary test then also accepts bands
      at a KKT point *within that noise* (`optimality_residual(gradient_se=...)`, 2 standard
      errors) below `band_tol`: on noisy slopes a plain KKT test never passes (measured: the
      two-requirement design with a jitter fitted over 16 planetary units sat at cost 1.722,
      stationary, bands' residual 0.66). Called (one batch of simulations) only when the cost
      has become stationary and the plain tests failed, and once at the returned design.

    **Returns:** an `OptimisationResult` whose design is the cheapest iterate on the requirement
    (objective $\\le R(1 + $`tol`$/10)$), else the last one (its `history.penalty` is NaN and
    `history.steps` counts gradient evaluations; `multiplier` is the subproblem's $\\lambda$ there).
    With several requirements the objective, constraint, multiplier, activity and the history's
    columns hold one value per constraint and `sensitivity` one row each.
    """
    lo = np.concatenate([np.asarray(lower.nominal), np.asarray(lower.band)])
    hi = np.concatenate([np.asarray(upper.nominal), np.asarray(upper.band)])
    span = np.where(hi > lo, hi - lo, 1.0)
    n = len(features.names)
    width = None if width is None else jnp.asarray(width, dtype=float)
    size_mm = features.size_mm

    requirements = np.atleast_1d(np.asarray(requirement, dtype=float))
    m = requirements.shape[0]
    if requirements.ndim != 1 or not np.all(requirements > 0):
        raise ValueError(f"sequential_design: one or more requirements > 0 (arcsec), got {requirement!r}.")
    tols = np.asarray(tol, dtype=float)
    if tols.ndim > 1 or tols.size not in (1, m) or not np.all((tols > 0) & (tols < 1)):
        raise ValueError(f"sequential_design: tol must be in (0, 1), one value or one per requirement ({m}), got {tol!r}.")
    tol = np.broadcast_to(tols, (m,))

    def evaluate(z):
        """`(f, grad)`: the constraints' values (m,) and gradients (m, 2n)."""
        x = Design(z[:n], z[n:])
        if m == 1:
            f, g = _value_and_grad(objective, x, draws, width)
            return np.atleast_1d(float(f)), np.concatenate([np.asarray(g.nominal), np.asarray(g.band)])[None]
        f, g = _value_and_jacobian(objective, x, draws, width)
        return np.asarray(f, dtype=float).reshape(m), np.concatenate([np.asarray(g.nominal), np.asarray(g.band)], axis=1)

    def reported(v):
        return float(v[0]) if m == 1 else np.asarray(v)

    def cost(z):
        return float(_cost_and_gradient(cost_model, size_mm, jnp.asarray(z[n:]))[0])

    noise_cache = {}

    def noise_at(z):
        """The constraints' gradient standard errors (m, 2n) at `z`, one batch of simulations per point."""
        key = z.tobytes()
        if key not in noise_cache:
            noise_cache[key] = np.asarray(gradient_noise(Design(z[:n], z[n:]), width), dtype=float).reshape(m, 2 * n)
        return noise_cache[key]

    z = np.clip(np.concatenate([np.asarray(x0.nominal), np.asarray(x0.band)]), lo, hi)
    f, grad = evaluate(z)
    if callback is not None:
        callback(1, Design(z[:n], z[n:]), cost(z), reported(f))
    radius = float(trust_region)
    rows, lam, converged, previous = [], np.zeros(m), False, None
    kept = [cost(z)]  # the cost at the start and after every kept step
    best = None  # (cost, row index, z, f, grad, multiplier) of the cheapest iterate on the requirement (to tol / 10)
    bar = tqdm.tqdm(total=max_iterations, desc="sequential_design", disable=not progress)
    evaluations = 1
    for _ in range(max_iterations):
        box_lo, box_hi = np.maximum(lo, z - radius * span), np.minimum(hi, z + radius * span)
        boxes = (jnp.asarray(box_lo[:n]), jnp.asarray(box_hi[:n])), (jnp.asarray(box_lo[n:]), jnp.asarray(box_hi[n:]))
        if m == 1:
            l, b, lam_k, f_pred = _subproblem(
                cost_model, size_mm, jnp.asarray(f[0]), jnp.asarray(grad[0, :n]), jnp.asarray(grad[0, n:]), jnp.asarray(z[:n]),
                jnp.asarray(z[n:]), *boxes,
                jnp.asarray(requirements[0]),  # arrays, not Python floats: no retrace when values change
            )
        else:
            l, b, lam_k, f_pred = _subproblem_many(
                cost_model, size_mm, f, grad[:, :n], grad[:, n:], z[:n], z[n:], (box_lo[:n], box_hi[:n]), (box_lo[n:], box_hi[n:]),
                requirements,
            )
        trial = np.clip(np.concatenate([np.asarray(l), np.asarray(b)]), lo, hi)
        f_trial, grad_trial = evaluate(trial)
        evaluations += 1
        if callback is not None:
            callback(evaluations, Design(trial[:n], trial[n:]), cost(trial), reported(f_trial))
        f_pred, lam_k = np.atleast_1d(np.asarray(f_pred, dtype=float)), np.atleast_1d(np.asarray(lam_k, dtype=float))
        # Per constraint, each as the one-constraint method reads it; a step must satisfy all.
        model_error = np.abs(f_trial - f_pred)
        change = np.maximum(np.abs(f_pred - f), tol * requirements)
        violation, violation_trial = np.maximum(f - requirements, 0.0), np.maximum(f_trial - requirements, 0.0)
        # A constraint whose model predicted and whose simulation found it clear of its
        # requirement (by more than its tolerance) cannot be violated by the step, whatever its
        # model's error: it neither rejects the step nor shrinks the region. (With a far-from-
        # binding jitter requirement the region otherwise shrank on the jitter's noisy fit at
        # every step and the design crawled: cost 2.19 after 10 gradients where the lost-motion
        # requirement alone reached 1.05 in 5.)
        clear = np.maximum(f_trial, f_pred) < requirements * (1 - tol)
        model_error = np.where(clear, 0.0, model_error)
        accept = bool(np.all(violation_trial <= np.maximum(violation, tol * requirements)) or np.all(model_error <= 0.5 * change))
        step = (trial - z) / span
        moved = float(np.max(np.abs(step)))
        # A step stopped by the trust region, not by the box or the model's own optimum: a small
        # one says the region collapsed, not that the design converged.
        inner = (box_lo > lo) | (box_hi < hi)
        limited = bool(np.any(inner & ((trial <= box_lo + 1e-12 * span) | (trial >= box_hi - 1e-12 * span)) & (np.abs(step) > 0)))
        if accept:
            z, f, grad, lam = trial, f_trial, grad_trial, lam_k
        radius = min(2.0 * radius, 1.0) if np.all(model_error <= 0.25 * change) else max(0.25 * radius, 1e-4)
        if accept and previous is not None and np.dot(step, previous) < 0:
            # A step that turns back: the constraint's curvature, which the linear model lacks,
            # makes the iterates zig-zag along it; halving the region damps that.
            radius = min(radius, max(0.5 * moved, 1e-6))
        if accept:
            previous = step
            kept.append(cost(z))
        met = bool(np.all(f <= requirements * (1 + tol)))
        active = bool(np.any(f >= requirements * (1 - tol)))
        widest = bool(np.all(z[n:] >= hi[n:] - step_tol * span[n:]))
        rows.append((cost(z), reported(f), reported(f - requirements), reported(lam), np.nan, np.nan if width is None else float(width), evaluations))
        if np.all(f <= requirements * (1 + 0.1 * tol)) and (best is None or rows[-1][0] <= best[0]):
            best = (rows[-1][0], len(rows) - 1, z, f, grad, lam)
        bar.update(1)
        bar.set_postfix(cost=f"{rows[-1][0]:.4g}", objective=np.array2string(f, precision=1), requirement=np.array2string(requirements))
        stationary = len(kept) >= 3 and max(kept[-3:]) - min(kept[-3:]) <= cost_tol * kept[-1]
        if accept and met and (active or widest):
            dc = _cost_gradient(cost_model, size_mm, z[n:])
            if (
                (moved <= step_tol and not limited)
                or _optimality(dc, z, grad, f, requirements, tol, lo, hi, n) <= optimality_tol
                or (stationary and _optimality(dc, z, grad, f, requirements, tol, lo, hi, n, bands_only=True) <= band_tol)
                or (stationary and gradient_noise is not None
                    and _optimality(dc, z, grad, f, requirements, tol, lo, hi, n, bands_only=True, se=noise_at(z)) <= band_tol)
            ):
                converged = True
                break
    bar.close()
    chosen = len(rows) - 1
    if best is not None and (not converged or best[0] < rows[-1][0]):
        # The cheapest iterate on the requirement (to a tenth of `tol`), unless the converged one
        # is cheaper (met to `tol`): on a rough objective a run that ends on its budget can wander
        # past cheaper designs it had already found.
        _, chosen, z, f, grad, lam = best
    x = Design(z[:n], z[n:])
    x_lo, x_hi = Design(lo[:n], lo[n:]), Design(hi[:n], hi[n:])
    feature_cost = cost_model(jnp.asarray(z[n:]), size_mm)
    history = History(*(jnp.asarray(np.asarray(col, dtype=float)) for col in zip(*rows)))
    return OptimisationResult(
        x=x,
        features=features,
        cost=jnp.sum(feature_cost),
        feature_cost=feature_cost,
        objective=jnp.asarray(reported(f)),
        constraint=jnp.asarray(reported(f - requirements)),
        multiplier=jnp.asarray(reported(lam)),
        constraint_active=jnp.asarray(reported(f >= requirements * (1 - tol))),
        at_lower=jax.tree.map(lambda v, bound: v <= bound, x, x_lo),
        at_upper=jax.tree.map(lambda v, bound: v >= bound, x, x_hi),
        sensitivity=Design(grad[0, :n], grad[0, n:]) if m == 1 else Design(grad[:, :n], grad[:, n:]),
        sensitivity_se=None if gradient_noise is None else (
            Design(noise_at(z)[0, :n], noise_at(z)[0, n:]) if m == 1 else Design(noise_at(z)[:, :n], noise_at(z)[:, n:])),
        cost_gradient=Design(np.zeros(n), _cost_gradient(cost_model, size_mm, z[n:])),
        converged=jnp.asarray(converged),
        iteration=jnp.asarray(chosen),
        history=history,
    )
