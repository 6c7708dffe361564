"""The linearised subproblem of the sequential method, solved exactly: the cheapest bands and
lower limits in a box for a linear model of the constraints (`_subproblem` for one constraint:
its one-dimensional dual by bisection; `_subproblem_many` for several: SciPy's SLSQP on a
problem without simulations), and the objective's value and gradient programs."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx
import scipy.optimize

from ..cache import exported_jit


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


def objective_value_and_gradient(objective, x, draws, width):
    """`(value, gradient)` of the design objective at `x`: the program the optimiser
    differentiates (`_value_and_grad`, or `_value_and_jacobian` for several requirements: then a
    value and a gradient row per requirement)."""
    output = getattr(getattr(objective, "objective", objective), "output", None)
    width = None if width is None else jnp.asarray(width, dtype=jnp.float64)  # not weakly typed: the optimiser's program
    several = isinstance(output, tuple) and len(output) > 1
    return (_value_and_jacobian if several else _value_and_grad)(objective, x, draws, width)


def objective_value(objective, x, draws, width):
    """The design objective at `x`: the value part of the program the optimiser differentiates
    (`objective_value_and_gradient`), so that a design compiles one program through its
    simulations, not two (each is a solve carrying the slopes' tangents: the value alone would
    be a second program of about the same size)."""
    return objective_value_and_gradient(objective, x, draws, width)[0]


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


def _subproblem_many(cost_model, size_mm, f_k, a, d, l_k, b_k, l_box, b_box, requirement, zone_upper=None):
    """`_subproblem` with m linearised constraints (`f_k`, `requirement`: shape (m,); `a`,
    `d`: (m, n); boxes as pairs of NumPy arrays): `(l, b, multipliers (m,), predicted f (m,))`.
    The subproblem is small (the simulations are outside it), convex (a separable convex cost,
    linear constraints, a box) and solved by SciPy's SLSQP on the cost's exact gradient (a
    nested bisection over two multipliers was tried: exact but minutes per call on a CPU).
    The multipliers are the non-negative least-squares fit of the bands' stationarity,
    $c'(b) + \\lambda^T D = 0$ over the bands inside their boxes (`scipy.optimize.nnls`), over
    the constraints the design reaches (the others' are 0).
    `zone_upper` (n,) (optional, m): each zone's upper edge $l + 2b$ at most this (linear
    constraints beside the box; the bands held by one count as bound in the multipliers' fit)."""
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
    constraints = [{"type": "ineq", "fun": lambda y: (requirement - linear(y)) / requirement, "jac": lambda y: jac}]
    if zone_upper is not None:
        top = np.asarray(zone_upper, dtype=float)
        edge = np.maximum(top, 1e-12)  # each row relative to its edge
        zone_jac = -np.concatenate([np.diag(l_span), 2.0 * np.diag(scale)], axis=1) / edge[:, None]
        def zone_room(y):
            l, b = unpack(y)
            return (top - l - 2.0 * b) / edge

        constraints.append({"type": "ineq", "fun": zone_room, "jac": lambda y: zone_jac})
    result = scipy.optimize.minimize(cost, y0, jac=cost_grad, method="SLSQP", bounds=[(0.0, 1.0)] * (2 * n),
                                     constraints=constraints, options=dict(ftol=1e-12, maxiter=500))
    # SLSQP leaves a variable on its bound only to its own tolerance: snap it there, so that the
    # design and its optimality residual see which bounds hold.
    y = np.clip(result.x, 0.0, 1.0)
    y = np.where(y < 1e-7, 0.0, np.where(y > 1.0 - 1e-7, 1.0, y))
    l, b = unpack(y)
    free = (b > b_box[0] + 1e-9 * scale) & (b < b_box[1] - 1e-9 * scale)
    if zone_upper is not None:
        free &= l + 2.0 * b < np.asarray(zone_upper, dtype=float) - 1e-7 * scale
    predicted = linear(y)
    # Complementary slackness: a constraint the subproblem's design does not reach carries no
    # multiplier; the fit is over the others alone (with two nearly parallel constraints, a fit
    # over both could price the slack one instead).
    active = predicted >= requirement * (1 - 1e-6)
    multipliers = np.zeros(a.shape[0])
    if np.any(free) and np.any(active):
        multipliers[active] = scipy.optimize.nnls(d[active][:, free].T, -_cost_gradient(cost_model, size_mm, b)[free])[0]
    # A constraint that even this design does not meet: infeasible within the region (as `_subproblem`'s inf).
    multipliers = np.where(predicted > requirement * (1 + 1e-6), np.inf, multipliers)
    return l, b, multipliers, predicted


def linearised_minimiser(cost_model, size_mm, f_k, a, d, l_k, b_k, l_box, b_box, requirement, zone_upper=None):
    """The minimiser of the linearised problem (m constraints: `f_k`, `requirement` (m,); `a`,
    `d` (m, n); boxes as pairs of NumPy arrays): `(l, b, multipliers (m,), predicted f (m,))`.
    One constraint and no zone edge: the exact solution (`_subproblem`, one bisection over its
    multiplier); else SciPy's SLSQP (`_subproblem_many`)."""
    if np.shape(f_k)[0] > 1 or zone_upper is not None:
        l, b, lam, f_pred = _subproblem_many(cost_model, size_mm, f_k, a, d, l_k, b_k, l_box, b_box, requirement, zone_upper)
    else:
        boxes = [(jnp.asarray(lo), jnp.asarray(hi)) for lo, hi in (l_box, b_box)]
        l, b, lam, f_pred = _subproblem(cost_model, size_mm, jnp.asarray(f_k[0]), jnp.asarray(a[0]), jnp.asarray(d[0]),
                                        jnp.asarray(l_k), jnp.asarray(b_k), *boxes,
                                        jnp.asarray(requirement[0]))  # arrays: no retrace when values change
    return l, b, np.atleast_1d(np.asarray(lam, dtype=float)), np.atleast_1d(np.asarray(f_pred, dtype=float))


@eqx.filter_jit
def _cost_and_gradient(cost_model, size_mm, band):
    """The total cost and $\\partial C/\\partial b$ (cost/m) at the bands `band`: one program per
    cost model, shared by the subproblem, the stopping test and the result."""
    return jax.value_and_grad(lambda b: cost_model.total(b, size_mm))(band)


def _cost_gradient(cost_model, size_mm, band) -> np.ndarray:
    """$\\partial C/\\partial b$ (cost/m) at the bands `band`."""
    return np.asarray(_cost_and_gradient(cost_model, size_mm, jnp.asarray(band))[1])
