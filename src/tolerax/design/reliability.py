"""Yield as the requirement: $P(\\text{metric} \\le R) \\ge Y$, from one simulated unit and its
sensitivities, corrected by a Monte Carlo check of fresh units.

A unit made to the design $x = (m, b)$ (zone middle $m$, half-width $b$, m) has features
$v = \\max(0, m + b \\circ u)$ with $u$ uniform on $[-1, 1]^n$ (`tolerax.design.types.realise`).
Where the pointing metric is close to linear in the features (the lost-motion regime), it is

$$\\text{metric}(v) \\approx f(m) + s \\cdot (v - m),\\qquad s = \\partial\\,\\text{metric}/\\partial v\\,|_m,$$

one simulation at the zone's middle carrying one forward-mode tangent per feature. Its
$Y$-quantile is $f(m) + Q_Y(s \\cdot (v - m))$: a statistical stack-up whose weights are simulated,
not drawn from geometry. $Q_Y$ (the quantile of a sum of independent uniforms) is the
Harrell–Davis estimate (`robust(kind="quantile")`) over fixed scrambled-Sobol draws
(`yield_draws`), a smooth function of $s \\circ b$; `tests/test_reliability.py` checks it against
OpenTURNS' exact distribution of the same sum (`openturns.LinearCombinationDistribution`). The requirement
$Q_Y \\le R$ is the yield requirement $P \\ge Y$ of the linearised response.

The gradient of $Q_Y$ with respect to the design holds $s$ fixed (its own derivative would need
second derivatives through the solve): exact where the response is linear, and the sequential
optimiser rebuilds $s$ at every iterate. Where the response bends, `yield_check` simulates fresh
units at the design and compares them with the linear model on the *same* units; the difference
of their $Y$-quantiles is the shift by which `propose_design` tightens the requirement and solves
again (the SORA idea: a deterministic problem with a shifted limit, Du and Chen, J. Mech. Des.
126, 2004).
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.special
import numpy as np
import scipy.stats
from jaxtyping import Array

from .objectives import AbstractObjective, unit_output, value_and_jacobian
from .types import Design, realise, robust
from ..uncertainty.results import wilson_interval
from ..uncertainty.sampling import unit_draws


def yield_draws(n_features: int, n: int = 16384, seed: int = 0) -> Array:
    """`n` standardised manufacturing draws $u \\in [-1, 1]^{n_{features}}$, uniform: a scrambled
    Sobol sequence (`scipy.stats.qmc.Sobol`), so that the quantile of the linearised response is
    estimated with less noise than by as many pseudo-random draws. `n` a power of 2. At the
    default 16384 the 99 % quantile of a sum of four uniforms is within 0.3 % of its reach of
    the exact one, 99.9 % within 0.5 % (`tests/test_reliability.py`)."""
    if n < 2 or n & (n - 1):
        raise ValueError(f"yield_draws: n must be a power of 2 >= 2, got {n!r}.")
    points = scipy.stats.qmc.Sobol(d=int(n_features), scramble=True, seed=seed).random(int(n))
    return jnp.asarray(2.0 * points - 1.0)


def linear_quantile(value, slopes, x: Design, draws, q: float, scatter=None, shift=None) -> Array:
    """The `q`-quantile (Harrell–Davis) of the linearised metric $f + s \\cdot (v - m)$ over the
    units $v$ = `realise(x, draws)`: `value` $f$ at the zone middles `x.nominal` $m$ (metric
    units), `slopes` $s$ (metric units per m). Several metrics: `value` of shape (k,), `slopes`
    (k, n), and the quantile of each (their marginal quantiles, not a joint one).

    `scatter` $\\sigma$ (metric units, one per metric; optional): add an independent normal term
    $\\sigma z$ per unit, the unit-to-unit scatter the features do not explain (a secant fit's
    residual: chaotic rattle). `draws` then has one more column than the features, whose
    uniform draws give $z = \\Phi^{-1}((u + 1)/2)$.

    `shift` (optional, shape (draws,), or (draws, k) for k metrics): a further term per draw,
    the part of the line in inputs that are drawn, not designed (`LinearisedYield.uncertain_term`:
    a life's wear rate)."""
    n = x.nominal.shape[0]
    deltas = realise(x, draws[:, :n]) - x.nominal
    noise = 0.0 if scatter is None else jax.scipy.special.ndtri(jnp.clip(0.5 * (draws[:, n] + 1.0), 1e-12, 1.0 - 1e-12))
    if jnp.ndim(value) == 1:
        sigma = jnp.zeros_like(value) if scatter is None else scatter
        more = jnp.zeros((draws.shape[0], value.shape[0])) if shift is None else shift
        return jax.vmap(lambda f, s, sd, c: robust(f + deltas @ s + sd * noise + c, kind="quantile", q=q),
                        in_axes=(0, 0, 0, 1))(value, slopes, sigma, more)
    return robust(value + deltas @ slopes + (0.0 if scatter is None else scatter * noise) + (0.0 if shift is None else shift),
                  kind="quantile", q=q)


@eqx.filter_custom_vjp
def value_and_slopes(values, pointing, output, width):
    """`(f, s)`: one unit's `output` at feature `values` (m) and its gradient $s$ over them,
    from one solve carrying one forward-mode tangent per feature (`diffrax.ForwardMode`). The
    derivative passed back is that of $f$ alone ($s$ is treated as a constant: see the module
    docstring). NaN where the solve failed."""
    return value_and_jacobian(values, pointing, output, width)


@value_and_slopes.def_fwd
def _value_and_slopes_fwd(perturbed, values, pointing, output, width):
    value, jac = value_and_jacobian(values, pointing, output, width)
    return (value, jac), jac


@value_and_slopes.def_bwd
def _value_and_slopes_bwd(jac, cotangent, perturbed, values, pointing, output, width):
    return jnp.tensordot(cotangent[0], jac, axes=jnp.ndim(cotangent[0]))


def secant_draws(n_features: int, n_units: int, seed: int = 1) -> Array:
    """Standardised positions $u \\in [-1, 1]^{n_{features}}$ of the units a secant fit
    simulates (`value_and_secants`): the zone's middle first, then `n_units - 1` points of a
    Latin hypercube (`scipy.stats.qmc.LatinHypercube`, seed `seed`: every feature's range cut
    into that many slices, one unit in each)."""
    if n_units < n_features + 1:
        raise ValueError(f"secant_draws: a secant fit over {n_features} features needs at least {n_features + 1} units, got {n_units!r}.")
    points = scipy.stats.qmc.LatinHypercube(d=int(n_features), seed=seed).random(int(n_units) - 1)
    return jnp.concatenate([jnp.zeros((1, int(n_features))), jnp.asarray(2.0 * points - 1.0)])


def _uncertain_count(pointing) -> int:
    """How many inputs a unit of `pointing` carries after its design values
    (`PointingObjective.uncertain_inputs`: a life's wear-rate factor)."""
    return len(getattr(pointing, "uncertain_inputs", ()))


def _with_uncertain(pointing, units, positions):
    """`units` (design values, m; one row per unit) with `pointing`'s uncertain inputs appended
    (`PointingObjective.uncertain_inputs`: a life's wear-rate factor), each spread over its band
    (`PointingObjective.uncertain_box`) by the columns of the standardised `positions` ([-1, 1])
    after the design's; `units` itself where there are none. The line through such units carries
    each input as a regressor (`_uncertain_columns`), and the quantile draws it
    (`LinearisedYield`)."""
    box = None if not _uncertain_count(pointing) else pointing.uncertain_box()
    if box is None:
        return units
    middle, half = box
    if positions.shape[1] != units.shape[1] + middle.shape[0]:
        raise ValueError(f"the units of this pointing objective draw {', '.join(pointing.uncertain_inputs)} after their "
                         f"{units.shape[1]} design values: their positions need {units.shape[1] + middle.shape[0]} columns, got "
                         f"{positions.shape[1]}.")
    return jnp.concatenate([units, middle + half * positions[:, units.shape[1] :]], axis=1)


def _uncertain_columns(pointing, x):
    """The line's regressors of drawn uncertain inputs `x` (shape (units, m): each the logarithm
    of a factor, the wear rate's): each factor $e^x$, scaled to [-1, 1] over its band
    (`PointingObjective.uncertain_box`). In the factor, not its logarithm: the depth worn, and so
    each clearance's growth, is proportional to the rate."""
    middle, half = pointing.uncertain_box()
    low, high = jnp.exp(middle - half), jnp.exp(middle + half)
    spread = 0.5 * (high - low)
    return (jnp.exp(x) - 0.5 * (low + high)) / jnp.where(spread > 0, spread, 1.0)


def _design_rows(pointing, units, drawn, middle, scale):
    """A least-squares line's design matrix: 1, each feature's standardised deviation from the
    middle, and each uncertain input's regressor (`_uncertain_columns`) where `pointing` draws
    them (`drawn`: the units with those inputs appended)."""
    rows = [jnp.ones((units.shape[0], 1)), (units - middle) / scale]
    if _uncertain_count(pointing):
        rows.append(_uncertain_columns(pointing, drawn[:, units.shape[1] :]))
    return jnp.concatenate(rows, axis=1)


def _fitted(values, log):
    """`values` (units, outputs) on the scale their line is fitted on: the logarithm of the
    outputs where `log` (a tuple of bools, one per output) holds, non-positive values then NaN
    (left out of the fit like a failed solve)."""
    if not any(log):
        return values
    mask = jnp.asarray(log)
    return jnp.where(mask, jnp.log(jnp.where(mask & (values > 0), values, 1.0)), values) + jnp.where(mask & ~(values > 0), jnp.nan, 0.0)


def _unfitted(values, log):
    """The inverse of `_fitted` along the last axis (a scalar: the one output's value): `exp` of
    the log-fitted outputs."""
    if not any(log):
        return values
    mask = jnp.asarray(log) if jnp.ndim(values) else jnp.asarray(log[0])
    return jnp.where(mask, jnp.exp(jnp.where(mask, values, 0.0)), values)


@eqx.filter_custom_vjp
def value_and_secants(middle, band, positions, pointing, output, width, log=()):
    """`(f, s, sigma)`: the least-squares line $f + s \\cdot (v - m)$ through `output` at the units
    $v$ = `realise(Design(middle, band), positions)` (m; `positions` from `secant_draws`): the
    statistical linearisation of the response over the zone, from forward solves only (no
    tangents). Failed solves are left out of the fit. The derivative passed back is $s$ for the
    middle (as `value_and_slopes`; the band's effect on the fit, i.e. curvature, is not
    differentiated: pass the band through `jax.lax.stop_gradient`). A tuple of outputs: `f` of
    shape (k,) and `s` (k, n), all fitted from the same solves. `sigma`: the residual standard
    deviation about the line (output units; the unit-to-unit scatter the features do not
    explain), not differentiated. `log` (one bool per output; default none): fit those outputs'
    logarithm instead, and `f`, `s`, `sigma` are then on that scale (`LinearisedYield.log_outputs`).
    Where `pointing` has uncertain inputs (a life's wear-rate spread), `positions` carries one
    more column for each, each unit draws them (`_with_uncertain`) and the line carries them
    (`_uncertain_columns`): a fourth result `t`, the line's coefficient of each input's regressor
    (shape (k, m), or (m,) for one output; m = 0 without them), not differentiated."""
    units = realise(Design(middle, band), positions[:, : middle.shape[0]])
    drawn = _with_uncertain(pointing, units, positions)
    values = jax.vmap(lambda v: unit_output(v, pointing, output, width))(drawn)
    values = _fitted(values.reshape(units.shape[0], -1), log)  # (units, outputs)
    ok = jnp.all(jnp.isfinite(values), axis=1)
    scale = jnp.where(band > 0, band, 1.0)
    n = middle.shape[0]
    rows = _design_rows(pointing, units, drawn, middle, scale)
    rows, values = jnp.where(ok[:, None], rows, 0.0), jnp.where(ok[:, None], values, 0.0)
    coef = jnp.linalg.lstsq(rows, values)[0]
    value, slopes, t = coef[0], jnp.where(band > 0, coef[1 : 1 + n].T / scale, 0.0), coef[1 + n :].T
    dof = jnp.maximum(jnp.sum(ok) - rows.shape[1], 1)  # the design matrix has full column rank (Latin hypercube)
    sigma = jnp.sqrt(jnp.sum(jnp.where(ok[:, None], values - rows @ coef, 0.0) ** 2, axis=0) / dof)
    return (value, slopes, sigma, t) if isinstance(output, tuple) else (value[0], slopes[0], sigma[0], t[0])


@value_and_secants.def_fwd
def _value_and_secants_fwd(perturbed, middle, band, positions, pointing, output, width, log=()):
    value, slopes, sigma, t = value_and_secants(middle, band, positions, pointing, output, width, log)
    return (value, slopes, sigma, t), slopes


@value_and_secants.def_bwd
def _value_and_secants_bwd(slopes, cotangent, perturbed, middle, band, positions, pointing, output, width, log=()):
    return jnp.tensordot(cotangent[0], slopes, axes=jnp.ndim(cotangent[0]))


class Surface(eqx.Module):
    """A response surface fitted once over a fixed box of feature values (`fit_surface`): per
    output the least-squares line $f_0 + s\\cdot(v - c)$ through units spread over the box
    (centre $c$, half-widths `half`, m), with the standard errors of $f_0$ and $s$ and the
    residual scatter $\\sigma$ (on the log scale for a `log_outputs` output). Shapes: `center`,
    `half` (n,), `value`, `value_se`,
    `sigma` (k,), `slopes`, `slope_se` (k, n) (output units per m); `uncertain_slopes` (k, m):
    the line's coefficients of the uncertain inputs' regressors (`_uncertain_columns`; m = 0
    without them)."""

    center: Array
    half: Array
    value: Array
    slopes: Array
    value_se: Array
    slope_se: Array
    sigma: Array
    uncertain_slopes: Array


class LinearisedYield(eqx.Module):
    """`objective(x, draws, width)`: the `q`-quantile (arcsec) of `output` over units made to
    the design `x` (`Design(middle, half-width)`, m), linearised at the zone middles (see the
    module docstring): one simulation with one tangent per feature, whatever the yield. `draws`:
    `yield_draws` (fixed); `width`: the smoothing width (m) passed to `pointing`.
    $P(\\text{output} \\le R) \\ge q$ for the linearised response exactly when the objective is
    $\\le R$.

    `slope_width` (m, optional): take the slopes $s$ from a solve at this (wider) smoothing width
    and only the value $f$ at `width` (one more solve, without tangents). Where the contacts
    make the response rough, forward-mode tangents at a narrow width are not the slope of the
    response: at a narrow width they can jump by orders of magnitude for a tiny change of the
    design while the value barely moves. The slopes of the smoothed model are what a stack-up needs; the Monte Carlo check measures
    what they miss.

    `secant_units` (optional, at least one more than the features): instead of tangents at the
    middle, fit $f$ and $s$ by least squares over this many units spread over the zone
    (`value_and_secants` at `secant_draws`): forward solves only, one batch. A tangent is the
    response's slope at a point; the quantile needs its spread over the zone, and where the
    contacts make the response rough at small scales the two differ: a line through the values
    does not see that roughness. It costs `secant_units` forward
    solves where a tangent costs one solve carrying one tangent per feature.

    A tuple `output` (e.g. `("pointing_rms", "pointing_jitter")`, a lost-motion and a stability
    metric) gives one quantile per output from the same solves: a vector objective for two
    requirements (`sequential_design`), each met at yield `q` on its own (marginal yields).

    `scatter` (with `secant_units`): the quantile includes the fit's residual scatter $\\sigma$ as
    an independent normal term per unit (`linear_quantile(scatter=...)`; `draws` then carry one
    more column: `yield_draws(n_features + 1)`). Where the response scatters about its trend from
    unit to unit for reasons the features do not carry (the jitter of a rattling stage: a line
    in the features explains a small part of its variance), the line's quantile alone
    under-reads the units'. $\\sigma$ is held fixed in the derivative, like the slopes.

    `secant_seed`: the seed of the secant units' Latin hypercube (`secant_draws`; `None`: seed 1).
    Two seeds are two independent sets of units: where the response is chaotic the design found
    with each differs by the fits' noise (`propose_design`'s noise band). Or `secant_positions`
    (an array, `secant_draws`' shape: the standardised positions of the units, middle first)
    instead of a seed: the positions are then values, not structure, so designs with two sets of
    units run one compiled program (`design_problem` gives them so; `propose_design`'s noise band
    solves its twin design without compiling again).

    `log_outputs` (with `secant_units`): outputs whose line is fitted to their logarithm,
    $\\log y \\approx f + s\\cdot(v - m) + \\sigma z$, and whose quantile is then $\\exp$ of that
    one's (quantiles commute with a monotone map). For a positive output whose unit-to-unit
    scatter grows with its level: the jitter of a rattling stage, whose standard deviation over
    units of one zone is about proportional to its mean across the design space. Fitted on its
    own scale, such a scatter is the one measured at the current zone and held fixed, so the
    optimiser cannot see that a tighter zone scatters less, and a requirement below the scatter
    reads as unreachable; on the log scale the scatter is relative and moves with the level. It
    does not by itself make the full stage's stability design converge (its slopes within a
    zone are still noise); opt-in (`Requirement(log_fit=True)`).

    `secant_reach` (m, with `secant_units`): the secant units span the middle +- at least this
    much, wider than a narrower zone: the line is the response's trend over that neighbourhood.
    Where a chaotic output's trend is small against its scatter per micrometre (the jitter:
    about 1 % per um against a 29 % scatter, `jitter_reach.md`), a fit over a tight zone's
    units is noise; over +-25 um with 32 units a slope's standard error is about 0.4 % per um.
    The quantile is still over the zone's own units (its band), the residual scatter that of the
    wider fit (which includes the trend's curvature over it: conservative). Measured: with it the
    full stage's stability design still stalls far above the requirement
    (design_stability_planetary_log.md).

    `surface` (optional, a `Surface` from `fit_surface`): one line per output fitted once over a
    fixed box of feature values (the design bounds' range) instead of over each zone: the value
    at a zone's middle $m$ is $f_0 + s\\cdot(m - c)$, its slopes and scatter the surface's, with no
    simulation per evaluation. Where an output's trend is resolved only across the whole bounds
    (the jitter: `jitter_reach.md`), a local fit follows noise and the global one does not; what
    the line misses of the response's curvature over the box is in its scatter (conservative).
    Checked by the Monte Carlo verification like any linearisation.

    **Uncertain inputs** (`PointingObjective.uncertain_inputs`: a life's wear-rate spread, which
    varies from unit to unit but is not designed): every secant or surface unit, and every unit
    of `yield_check`, draws them over their band (`PointingObjective.uncertain_box`, one more
    Latin-hypercube column each), and the line carries each as one more regressor, the factor
    $e^x$ scaled over its band (`_uncertain_columns`: wear grows in proportion to the rate, not
    its logarithm), its coefficient `t` fitted with the slopes and held fixed like them. The
    quantile draws the inputs too (the last m columns of `draws`: `yield_draws(n_features + 1 +
    m)` with `scatter`), so the residual scatter is what neither the features nor the inputs
    explain. `design_problem` refuses such an objective without secants and scatter."""

    pointing: AbstractObjective
    output: str | tuple[str, ...] = eqx.field(static=True, default="pointing_rms")
    q: float = eqx.field(static=True, default=0.99)
    slope_width: float | None = eqx.field(static=True, default=None)
    secant_units: int | None = eqx.field(static=True, default=None)
    scatter: bool = eqx.field(static=True, default=False)
    secant_seed: int | None = eqx.field(static=True, default=None)
    log_outputs: tuple[str, ...] = eqx.field(static=True, default=())
    secant_reach: float | None = eqx.field(static=True, default=None)
    surface: Surface | None = None
    secant_positions: Array | None = None

    def __check_init__(self):
        if not 0.0 < self.q < 1.0:
            raise ValueError(f"LinearisedYield: the yield q must be in (0, 1), got {self.q!r}.")
        if self.slope_width is not None and not self.slope_width > 0:
            raise ValueError(f"LinearisedYield: slope_width must be > 0 (m), got {self.slope_width!r}.")
        if self.secant_units is not None and self.slope_width is not None:
            raise ValueError("LinearisedYield: give slope_width (tangents at a wider smoothing) or secant_units (a fit over units), not both.")
        if self.scatter and self.secant_units is None:
            raise ValueError("LinearisedYield: scatter (the secant fit's residual) needs secant_units.")
        unknown = [o for o in self.log_outputs if o not in self.outputs]
        if unknown:
            raise ValueError(f"LinearisedYield: log_outputs {unknown} are not among the outputs {self.outputs}.")
        if self.log_outputs and self.secant_units is None:
            raise ValueError("LinearisedYield: log_outputs (a line through the logarithm over units) needs secant_units.")
        if _uncertain_count(self.pointing) and self.secant_units is None:
            raise ValueError(f"LinearisedYield: each unit of this pointing objective draws {', '.join(self.pointing.uncertain_inputs)} "
                             "(a life's spread); a tangent at the zone's middle cannot carry it: give secant_units (and scatter).")
        if self.secant_positions is not None:
            if self.secant_units is None or self.secant_seed is not None:
                raise ValueError("LinearisedYield: secant_positions (the units' standardised positions) need secant_units and replace "
                                 "secant_seed: give one of the two.")
            if jnp.shape(self.secant_positions)[0] != self.secant_units:
                raise ValueError(f"LinearisedYield: secant_positions has {jnp.shape(self.secant_positions)[0]} rows; it needs one per "
                                 f"secant unit ({self.secant_units}).")
        if self.secant_reach is not None and (self.secant_units is None or not self.secant_reach > 0):
            raise ValueError(f"LinearisedYield: secant_reach must be > 0 (m) and needs secant_units, got {self.secant_reach!r}.")

    def unit_positions(self, n_features: int) -> Array:
        """The standardised positions ([-1, 1]) of the secant units over `n_features` design
        features and the uncertain inputs: `secant_positions`, or `secant_draws` at `secant_seed`."""
        if self.secant_positions is not None:
            return self.secant_positions
        seed = 1 if self.secant_seed is None else self.secant_seed
        return secant_draws(n_features + _uncertain_count(self.pointing), self.secant_units, seed)

    def fit_band(self, band):
        """The half-widths (m) the secant units span about the middle: the zone's, at least
        `secant_reach`."""
        return band if self.secant_reach is None else jnp.maximum(band, self.secant_reach)

    @property
    def outputs(self) -> tuple[str, ...]:
        return self.output if isinstance(self.output, tuple) else (self.output,)

    @property
    def log(self) -> tuple[bool, ...]:
        """Per output: is its line fitted to its logarithm (`log_outputs`)."""
        return tuple(o in self.log_outputs for o in self.outputs)

    def linear_model(self, x: Design, width):
        """`(f, s)` for the design `x` (`Design(middle, half-width)`, m): the value at the zone
        middles at `width` and the slopes (at `slope_width` where set; or both fitted over
        `secant_units` units of the zone); the derivative passed back through `f` is `s`."""
        return self.model(x, width)[:2]

    def model(self, x: Design, width):
        """`(f, s, sigma, t)`: `linear_model`, the residual scatter `sigma` about it (output
        units; `None` unless `scatter`) and the line's coefficients `t` of the uncertain inputs'
        regressors (`None` without uncertain inputs), from the same solves; on the log scale for
        the `log_outputs`."""
        middle = x.nominal
        uncertain = _uncertain_count(self.pointing) > 0
        if self.surface is not None:
            sf = self.surface
            slopes = jax.lax.stop_gradient(sf.slopes)
            value = sf.value + slopes @ (middle - sf.center)
            sigma, t = sf.sigma, jax.lax.stop_gradient(sf.uncertain_slopes)
            if not isinstance(self.output, tuple):
                value, slopes, sigma, t = value[0], slopes[0], sigma[0], t[0]
            return value, slopes, (sigma if self.scatter else None), (t if uncertain else None)
        if self.secant_units is not None:
            positions = self.unit_positions(middle.shape[0])
            f, s, sigma, t = value_and_secants(middle, jax.lax.stop_gradient(self.fit_band(x.band)), positions, self.pointing,
                                               self.output, width, self.log)
            return f, s, (jax.lax.stop_gradient(sigma) if self.scatter else None), (jax.lax.stop_gradient(t) if uncertain else None)
        if self.slope_width is None:
            return (*value_and_slopes(middle, self.pointing, self.output, width), None, None)
        smooth, slopes = value_and_slopes(middle, self.pointing, self.output, jnp.asarray(self.slope_width, dtype=float))
        value = jax.lax.stop_gradient(unit_output(middle, self.pointing, self.output, width))
        return value + (smooth - jax.lax.stop_gradient(smooth)), slopes, None, None

    def uncertain_term(self, t, draws):
        """Per draw, the uncertain inputs' part of the line: `_uncertain_columns` of the inputs
        the last m columns of `draws` draw (uniform on [-1, 1] over each input's band, the
        logarithm's: log-uniform factors) times their coefficients `t`; shape (draws,) for one
        output, (draws, k) for k; `None` where `t` is `None`."""
        if t is None:
            return None
        m = _uncertain_count(self.pointing)
        middle, half = self.pointing.uncertain_box()
        columns = _uncertain_columns(self.pointing, middle + half * draws[:, draws.shape[1] - m :])
        return columns @ (t.T if jnp.ndim(t) == 2 else t)

    def __call__(self, x: Design, draws, width) -> Array:
        value, slopes, sigma, t = self.model(x, width)
        m = _uncertain_count(self.pointing)
        if m and draws.shape[1] != x.nominal.shape[0] + (sigma is not None) + m:
            raise ValueError(f"LinearisedYield: the draws need {x.nominal.shape[0] + (sigma is not None) + m} columns (the "
                             f"features, {'the scatter, ' if sigma is not None else ''}then each of "
                             f"{', '.join(self.pointing.uncertain_inputs)}), got {draws.shape[1]}.")
        quantile = linear_quantile(value, jax.lax.stop_gradient(slopes), x, draws, self.q, sigma, self.uncertain_term(t, draws))
        return _unfitted(quantile, self.log) if any(self.log) else quantile


@dataclasses.dataclass(frozen=True)
class YieldCheck:
    """A Monte Carlo check of a design against its linearised yield model (`yield_check`).

    - `n`: fresh units simulated; `n_failed`: of them, solves that failed (not counted).
    - `simulated`, `linear` (arcsec): each unit's metric, simulated and predicted by the linear
      model (same units; with `scatter`, each prediction carries a draw of the fit's residual).
    - `yield_simulated`, `interval`: the fraction of units with metric $\\le R$ and its 95 %
      Wilson interval; `yield_linear`: the same fraction for the linear predictions.
    - `quantile_simulated`, `quantile_linear` (arcsec): Harrell–Davis `q`-quantiles of the two;
      `shift` = their difference: how much the linear model under-reads the tail; `shift_se`
      (arcsec): its standard error (bootstrap over the units, 400 resamples): a shift smaller
      than twice this is not distinguishable from the check's own sampling noise.
    """

    n: int
    n_failed: int
    q: float
    requirement: float
    simulated: np.ndarray
    linear: np.ndarray
    yield_simulated: float
    interval: tuple[float, float]
    yield_linear: float
    quantile_simulated: float
    quantile_linear: float
    shift: float
    shift_se: float

    def text(self) -> str:
        return (
            f"Monte Carlo check on {self.n - self.n_failed} fresh units: yield {self.yield_simulated:.3f} "
            f"[{self.interval[0]:.3f}, {self.interval[1]:.3f}] (95 % Wilson) against the linear model's "
            f"{self.yield_linear:.3f} on the same units; {self.q:.1%} quantile simulated {self.quantile_simulated:.1f} arcsec, "
            f"linear {self.quantile_linear:.1f} (shift {self.shift:+.1f} ± {self.shift_se:.1f} arcsec)"
        )


@eqx.filter_jit
def _model(objective, x, width):
    """`objective.model(x, width)`, one program per objective structure for every check."""
    return objective.model(x, width)


@eqx.filter_jit
def _simulate_units(pointing, output, values, width):
    return jax.vmap(lambda v: unit_output(v, pointing, output, width))(values)


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
    dof = rows.shape[0] - np.linalg.matrix_rank(rows)
    if dof < 1:
        raise ValueError(f"secant_standard_error: {int(ok.sum())} successful units leave no residual to estimate the noise from "
                         f"({n} features): use more secant_units.")
    coef = np.linalg.lstsq(rows, values[ok], rcond=None)[0]  # (1 + n + m, k)
    sigma = np.sqrt(np.sum((values[ok] - rows @ coef) ** 2, axis=0) / dof)  # (k,)
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


def yield_check(objective: LinearisedYield, x: Design, requirement, n: int, key, width=None, chunk: int = 50):
    """Simulate `n` fresh units of design `x` (`Design(middle, half-width)`, m; draws from
    `unit_draws(key, ...)`) with `objective`'s pointing model, and compare them with its
    linearised model on the same units (see `YieldCheck`); each unit draws the objective's
    uncertain inputs too (a life's wear rate: `LinearisedYield`). `width`: smoothing width (m);
    `chunk`: units per compiled batch. A tuple `output` (two requirements, e.g. RMS and
    jitter): `requirement` one per output, and one `YieldCheck` per output from the same units."""
    if int(n) < 2:
        raise ValueError(f"yield_check: n must be >= 2 units, got {n!r}.")
    outputs = objective.output if isinstance(objective.output, tuple) else (objective.output,)
    requirements = np.broadcast_to(np.asarray(requirement, dtype=float), (len(outputs),))
    x = Design(jnp.asarray(x.nominal), jnp.asarray(x.band))
    width = None if width is None else jnp.asarray(width, dtype=float)
    draws = unit_draws(key, int(n), x.nominal.shape[0] + _uncertain_count(objective.pointing))
    values = realise(x, draws[:, : x.nominal.shape[0]])
    drawn = _with_uncertain(objective.pointing, values, draws)  # each unit's wear rate drawn too (a life's spread)
    f, s, sigma, t = _model(objective, x, width)
    linear = jnp.atleast_1d(f) + (values - x.nominal) @ jnp.atleast_2d(s).T
    if t is not None:  # each unit's own drawn inputs (a wear rate) through the line
        linear = linear + _uncertain_columns(objective.pointing, drawn[:, x.nominal.shape[0] :]) @ jnp.atleast_2d(t).T
    linear = np.asarray(linear).reshape(int(n), len(outputs))
    if sigma is not None:
        # The model's scatter cannot predict a unit's own: each unit's prediction carries an
        # independent draw of it (seeded), so that the model's quantile over these units is the
        # one the optimiser met.
        linear = linear + np.atleast_1d(np.asarray(sigma)) * np.random.default_rng(0).standard_normal((int(n), len(outputs)))
    linear = np.asarray(_unfitted(jnp.asarray(linear), objective.log))  # from the log scale for `log_outputs`
    simulated = np.concatenate([
        np.asarray(_simulate_units(objective.pointing, objective.output, drawn[i : i + chunk], width)).reshape(-1, len(outputs))
        for i in range(0, int(n), chunk)
    ])
    ok = np.all(np.isfinite(simulated), axis=1)
    checks = tuple(_yield_check(simulated[:, k], linear[:, k], ok, objective.q, float(requirements[k])) for k in range(len(outputs)))
    return checks if isinstance(objective.output, tuple) else checks[0]


def _yield_check(simulated, linear, ok, q, requirement) -> YieldCheck:
    """One output's `YieldCheck` from its simulated and linearised units (`ok`: the units whose
    solves succeeded)."""
    sim, lin, used = simulated[ok], linear[ok], int(np.sum(ok))
    met = int(np.sum(sim <= requirement))
    low, high = wilson_interval(met, used)

    def hd(v):  # the Harrell-Davis q-quantile, as `robust(kind="quantile")` computes it
        return float(scipy.stats.mstats.hdquantiles(v, prob=[q])[0])

    q_sim, q_lin, se = math.nan, math.nan, math.nan
    if used >= 2:
        q_sim, q_lin = hd(sim), hd(lin)
        rows = np.random.default_rng(0).integers(0, used, size=(400, used))
        se = float(np.std([hd(sim[r]) - hd(lin[r]) for r in rows], ddof=1))
    return YieldCheck(
        n=len(simulated), n_failed=int(np.sum(~ok)), q=q, requirement=float(requirement), simulated=simulated, linear=linear,
        yield_simulated=met / max(used, 1), interval=(float(low), float(high)),
        yield_linear=float(np.mean(lin <= requirement)) if used else math.nan,
        quantile_simulated=q_sim, quantile_linear=q_lin, shift=q_sim - q_lin, shift_se=se,
    )
