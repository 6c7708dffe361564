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
optimiser rebuilds $s$ at every iterate. Where the response bends, `yield_check`
(`tolerax.design.check`) simulates fresh
units at the design and compares them with the linear model on the *same* units; the difference
of their $Y$-quantiles is the shift by which `propose_design` tightens the requirement and solves
again (the SORA idea: a deterministic problem with a shifted limit, Du and Chen, J. Mech. Des.
126, 2004).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import jax.scipy.special
import scipy.stats
from jaxtyping import Array

from .objectives import AbstractObjective, unit_output, value_and_jacobian
from .types import Design, realise, robust


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
    zone are still noise); opt-in (`Secants(log=True)`).

    `secant_reach` (m, with `secant_units`): the secant units span the middle +- at least this
    much, wider than a narrower zone: the line is the response's trend over that neighbourhood.
    Where a chaotic output's trend per micrometre is small against its scatter over units (the
    jitter of a rattling stage), a fit over a tight zone's units is noise: a slope's standard
    error falls as $\\sigma / (\\text{reach} \\sqrt{K})$ for $K$ units spread over the reach, so a
    wider reach resolves the trend. The quantile is still over the zone's own units (its band),
    the residual scatter that of the wider fit (which includes the trend's curvature over it:
    conservative). It does not by itself make the full stage's stability design converge
    (benchmarks/README.md, design).

    `surface` (optional, a `Surface` from `fit_surface`): one line per output fitted once over a
    fixed box of feature values (the design bounds' range) instead of over each zone: the value
    at a zone's middle $m$ is $f_0 + s\\cdot(m - c)$, its slopes and scatter the surface's, with no
    simulation per evaluation. Where an output's trend is resolved only across the whole bounds
    (the jitter of a rattling stage), a local fit follows noise and the global one does not; what
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
