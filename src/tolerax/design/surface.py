"""Secant and response-surface fits of a `LinearisedYield`'s outputs over simulated units.

The lines a yield design reads where tangents mislead (the jitter's chaotic rattle): `fit_surface`
fits one per output over a fixed box of feature values (`Surface`), `secant_standard_error` says
how far the fitted value moves from one set of units to the next (the noise an optimiser must not
chase), and `secant_gradient_noise` how far the linearised quantile's gradient does. Each simulates
`LinearisedYield.secant_units` units (`tolerax.design.reliability`) by forward solves, shared with
worker processes on idle cores as a Monte Carlo run's chunks are (`evaluate_rows`).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.special
import numpy as np

from ..uncertainty.backends import evaluate_rows
from ..uncertainty.montecarlo import default_chunk
from .objectives import unit_output
from .reliability import LinearisedYield, Surface, _design_rows, _fitted, _uncertain_count, _with_uncertain
from .types import Design, realise, robust


class _UnitOutputs(eqx.Module):
    """One unit's outputs at its feature values (m), as a Monte Carlo model: `{"value": ...}`
    (`unit_output`: NaN where its solve failed). A module, so worker processes unpickle it."""

    pointing: object
    output: str | tuple[str, ...] = eqx.field(static=True)
    width: object

    def __call__(self, values):
        return {"value": unit_output(values, self.pointing, self.output, self.width)}


def _simulate_units(pointing, output, values, width) -> np.ndarray:
    """`unit_output` at each row of `values` (units, features; m): one forward solve each, in
    chunks of about the scene's `unit_chunk()` shared with worker processes on idle cores
    (`tolerax.uncertainty.backends.evaluate_rows`: rows that make one chunk, one batch here)."""
    return evaluate_rows(_UnitOutputs(pointing, output, width), np.asarray(values), default_chunk(pointing))["value"]


def _secant_noise(objective: LinearisedYield, x: Design, width):
    """`(value, slopes, value_se, slope_se, sigma, t)` of the least-squares line `objective`'s secant fit
    draws at the design `x` (`Design(middle, half-width)`, m), from one batch of its
    `secant_units` forward solves: each of shape (k,) or (k, n) for the k outputs; the standard
    errors are the residual standard deviation times $\\sqrt{\\mathrm{diag}(X^T X)^{-1}}$ ($X$ the
    fit's design matrix), slopes' in output units per m; `sigma` the residual standard deviation.
    All on the fitted scale: the logarithm for `objective.log_outputs`. With a `surface`, its
    own fit, no simulation (the value's standard error is the surface's at its centre)."""
    if objective.surface is not None:
        sf = objective.surface
        slopes = np.asarray(sf.slopes)
        return (np.asarray(sf.value) + slopes @ (np.asarray(x.nominal) - np.asarray(sf.center)), slopes, np.asarray(sf.value_se),
                np.asarray(sf.slope_se), np.asarray(sf.sigma), np.asarray(sf.uncertain_slopes))
    if objective.secant_units is None:
        raise ValueError("secant_standard_error: the objective fits no secant (give LinearisedYield(secant_units=...)).")
    return _fit_units(objective, jnp.asarray(x.nominal), objective.fit_band(jnp.asarray(x.band)), width)


def line_fit(rows, values) -> tuple[np.ndarray, np.ndarray, int]:
    """The least-squares line of `values` (units, k) on the design matrix `rows` (units, columns):
    `(coefficients (columns, k), residual variance on its degrees of freedom (k,), degrees of
    freedom)`, the degrees of freedom the units less the matrix's rank (a feature held fixed, a
    zero column, takes none); the variance is NaN where there are none. What a secant fit, a
    response surface and `Auto()`'s probe (`tolerax.design.probe`) each fit."""
    rows, values = np.asarray(rows, dtype=float), np.asarray(values, dtype=float)
    dof = int(rows.shape[0] - np.linalg.matrix_rank(rows))
    coef = np.linalg.lstsq(rows, values, rcond=None)[0]
    residual = np.sum((values - rows @ coef) ** 2, axis=0) / dof if dof > 0 else np.full(values.shape[1:], np.nan)
    return coef, residual, dof


def _fit_units(objective: LinearisedYield, middle, band, width):
    """`_secant_noise`'s fit over `objective.secant_units` units spread over middle +- band (m)."""
    n = middle.shape[0]
    positions = objective.unit_positions(n)
    units = realise(Design(middle, band), positions[:, :n])
    drawn = _with_uncertain(objective.pointing, units, positions)  # a life's wear rate, drawn per unit: carried by the line
    width = None if width is None else jnp.asarray(width, dtype=float)
    values = np.asarray(_fitted(_simulate_units(objective.pointing, objective.output, drawn, width).reshape(units.shape[0], -1),
                                objective.log))
    ok = np.all(np.isfinite(values), axis=1)
    scale = np.where(np.asarray(band) > 0, np.asarray(band), 1.0)
    rows = np.asarray(_design_rows(objective.pointing, units, drawn, middle, jnp.asarray(scale)))[ok]
    coef, residual, dof = line_fit(rows, values[ok])  # coef (1 + n + m, k)
    if dof < 1:
        raise ValueError(f"secant_standard_error: {int(ok.sum())} successful units leave no residual to estimate the noise from "
                         f"({n} features): use more secant_units.")
    sigma = np.sqrt(residual)  # (k,)
    root = np.sqrt(np.diag(np.linalg.pinv(rows.T @ rows)))
    per_m = np.where(np.asarray(band) > 0, 1.0 / scale, 0.0)
    return (coef[0], coef[1 : 1 + n].T * per_m, sigma * root[0], sigma[:, None] * root[None, 1 : 1 + n] * per_m, sigma,
            coef[1 + n :].T)


def fit_surface(objective: LinearisedYield, lower, upper, width=None) -> Surface:
    """The `Surface` of `objective`'s outputs over the box `lower` <= v <= `upper` (m, scalars or
    one per feature): `objective.secant_units` units spread over it (`secant_draws`, seed
    `objective.secant_seed`), one batch of forward solves at smoothing `width` (m), their
    least-squares line per output (on the log scale for `log_outputs`). Give the result to
    `LinearisedYield(surface=...)` (`design_problem(surface_box=...)` does)."""
    if objective.secant_units is None:
        raise ValueError("fit_surface: give the objective secant_units (the units spread over the box).")
    from .features import design_names

    sized = [np.size(v) for v in (lower, upper) if np.ndim(v)]
    n = sized[0] if sized else len(design_names(objective.pointing.scene))
    lower, upper = (np.broadcast_to(np.asarray(v, dtype=float), (n,)) for v in (lower, upper))
    if not (np.all(np.isfinite(lower)) and np.all(upper > lower) and np.all(lower >= 0)):
        raise ValueError(f"fit_surface: the box must have 0 <= lower < upper (m), finite; got {lower} and {upper}.")
    value, slopes, value_se, slope_se, sigma, t = _fit_units(objective, jnp.asarray(0.5 * (lower + upper)),
                                                             jnp.asarray(0.5 * (upper - lower)), width)
    return Surface(jnp.asarray(0.5 * (lower + upper)), jnp.asarray(0.5 * (upper - lower)), jnp.asarray(value), jnp.asarray(slopes), jnp.asarray(value_se),
                   jnp.asarray(slope_se), jnp.asarray(sigma), jnp.asarray(t))


def secant_standard_error(objective: LinearisedYield, x: Design, width=None):
    """The standard error (output units) of the value $f$ that `objective`'s secant fit finds
    at the design `x` (`Design(middle, half-width)`, m): the residual standard deviation of the
    least-squares line through its `secant_units` units, times
    $\\sqrt{[(X^T X)^{-1}]_{00}}$ ($X$ the fit's design matrix). Where the response scatters about
    its trend from unit to unit (chaotic rattle: the jitter), the linearised quantile moves by
    about this much from one design to the next for no other reason; a tolerance on that
    constraint below it makes an optimiser chase noise (`sequential_design(tol=...)`). One batch
    of `secant_units` forward solves; a scalar, or one value per output of a tuple `output`. For
    an output in `objective.log_outputs` the standard error of its logarithm: a relative error."""
    se = _secant_noise(objective, x, width)[2]
    return se if isinstance(objective.output, tuple) else float(se[0])


def secant_gradient_noise(objective: LinearisedYield, x: Design, draws, width=None, lower_limit: bool = True) -> np.ndarray:
    """Standard errors of the gradient of `objective` (its linearised quantile) with respect to
    the design variables, from the scatter of its secant fit: shape (2n,) (lower limits or
    middles, then bands), or (k, 2n) for k outputs; arcsec/m.

    The quantile's gradient is linear in the fitted slopes $s$: with the lower limit $l$ and the
    half-width $b$ as variables (`FromLowerLimit`, `lower_limit=True`; the zone middle is
    $l + b$), $\\partial Q/\\partial l_i = s_i$ and $\\partial Q/\\partial b_i = s_i(1 + \\bar u_i)$,
    $\\bar u_i$ the Harrell–Davis-weighted mean of the standardised deviation $u_i$ of the units
    at the quantile (in $[-1, 1]$; `lower_limit=False`: $s_i \\bar u_i$ for the middle held).
    Their standard errors are those of $s$ (`_secant_noise`) times 1 and $|1 + \\bar u_i|$; the
    dependence of $\\bar u$ on $s$ (which units sit at the quantile) is left out. Evaluated at
    the zone `x` = `Design(middle, half-width)` (m), with the quantile draws `draws`
    (`yield_draws`). For `sequential_design(gradient_noise=...)` and `optimality_residual`'s
    `gradient_se`. One batch of `secant_units` forward solves. For an output in
    `objective.log_outputs` ($Q = \\exp Q_{\\log}$) the log scale's standard errors times $Q$."""
    value, slopes, _, slope_se, residual, t = _secant_noise(objective, x, width)
    middle, band = jnp.asarray(x.nominal), jnp.asarray(x.band)  # the zone's units, whatever the fit spanned
    n = middle.shape[0]
    deltas = realise(Design(middle, band), draws[:, :n]) - middle
    u = deltas / jnp.where(band > 0, band, 1.0)
    sigma = residual if objective.scatter else np.zeros_like(residual)
    z = (jax.scipy.special.ndtri(jnp.clip(0.5 * (draws[:, n] + 1.0), 1e-12, 1.0 - 1e-12)) if objective.scatter
         else jnp.zeros(draws.shape[0]))

    more = objective.uncertain_term(jnp.atleast_2d(jnp.asarray(t)) if _uncertain_count(objective.pointing) else None, draws)
    more = jnp.zeros((draws.shape[0], np.shape(value)[0])) if more is None else more  # the drawn inputs' part (a wear rate)

    def weights(f, s, sd, c):  # Q and d Q / d t at t = s * b: the HD-weighted mean of u at the quantile
        return jax.value_and_grad(lambda t_: robust(f + u @ t_ + sd * z + c, kind="quantile", q=objective.q))(jnp.asarray(s) * band)

    quantile, u_bar = (np.asarray(a) for a in jax.vmap(weights, in_axes=(0, 0, 0, 1))(jnp.asarray(value), jnp.asarray(slopes),
                                                                                     jnp.asarray(sigma), more))
    band_factor = np.abs(1.0 + u_bar) if lower_limit else np.abs(u_bar)
    noise = np.concatenate([slope_se, slope_se * band_factor], axis=1)
    noise = noise * np.where(objective.log, np.exp(np.where(objective.log, quantile, 0.0)), 1.0)[:, None]  # d exp(Q) = exp(Q) dQ
    return noise if isinstance(objective.output, tuple) else noise[0]
