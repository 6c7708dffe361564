"""A least-squares function linearised once per step (`jacobian_once`, `secant_once`).

optimistix's Gauss-Newton solvers (Levenberg-Marquardt, Gauss-Newton) linearise their function
once per step (`jax.linearize`) and then multiply by the linearisation and by its transpose. Given
a plain function of a simulation, the transpose is the reverse-mode program of the whole
computation, compiled beside the forward one, and where the computation is an adaptive solve
(a while loop that keeps no primal for the tangents) every product runs the solve again. With
`jacobian_once(fn)` the linearisation is the matrix of one forward-mode pass (`jax.jacfwd`, a
tangent per unknown), whose transpose is its transpose; with `secant_once(fn, step)` it is the
matrix of central secants, from one batched evaluation.
"""

import equinox as eqx
import jax
import jax.numpy as jnp


def _linearised_by(fn, jacobian):
    """`fn(x, *rest)` with a custom JVP: in `x`, `jacobian(x, rest) -> (J, fn(x, *rest))` times
    the tangent; in `rest`, their own forward-mode tangent (`jacobian_once`, `secant_once`)."""

    @eqx.filter_custom_jvp
    def once(x, *rest):
        return fn(x, *rest)

    @once.def_jvp
    def _jvp(primals, tangents):
        (x, *rest), (dx, *drest) = primals, tangents
        if dx is None:
            y = fn(x, *rest)
            dy = jnp.zeros_like(y)
        else:
            jac, y = jacobian(x, rest)
            dy = jac @ dx
        if jax.tree.leaves(drest):
            dy = dy + eqx.filter_jvp(lambda r: fn(x, *r), (tuple(rest),), (tuple(drest),))[1]
        return y, dy

    return once


def jacobian_once(fn):
    """`fn(x, *rest) -> array` (x a 1-D array) with the same values and a custom JVP: in `x`,
    its Jacobian from one forward-mode pass times the tangent; in `rest` (any pytrees: a scene,
    states, widths), their own forward-mode tangent, so a derivative through the solver
    (optimistix's implicit function theorem) stays exact."""
    return _linearised_by(fn, lambda x, rest: jax.jacfwd(lambda v: (lambda out: (out, out))(fn(v, *rest)), has_aux=True)(x))


def secant_once(fn, step: float):
    """`fn(x, *rest) -> array` (x a 1-D array) with the same values and a custom JVP whose
    Jacobian in `x` is the central secants at `step` (in x's units) along each unknown,

    $$J_{:j} = \\frac{f(x + h e_j) - f(x - h e_j)}{2h},$$

    from one batched evaluation of the $2n$ points; in `rest`, their own forward-mode tangent (as
    `jacobian_once`). For a response whose forward-mode tangent is dominated by a part that does
    not move it at the scale of the step: through a rattling gear stage the tangents of a
    trajectory grow with the impacts' sensitivity to every perturbation, while the trajectory
    itself moves smoothly with a clearance (`tolerax.identification.identify`)."""

    def secants(x, rest):
        n = x.shape[0]
        shift = step * jnp.eye(n, dtype=x.dtype)
        values = jax.vmap(lambda v: fn(v, *rest))(jnp.concatenate([x + shift, x - shift]))
        return ((values[:n] - values[n:]) / (2.0 * step)).T, fn(x, *rest)

    return _linearised_by(fn, secants)
