"""The Monte Carlo check of a yield design: fresh units simulated at the design against its
linearised model on the same units (`yield_check`, `YieldCheck`); the difference of their
quantiles is the shift by which `propose_design` tightens the requirement and solves again
(the SORA idea, `tolerax.design.reliability`).
"""

import dataclasses
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import scipy.stats

from .reliability import LinearisedYield, _uncertain_columns, _uncertain_count, _unfitted, _with_uncertain
from .surface import _simulate_units
from .types import Design, realise
from ..uncertainty.results import wilson_interval
from ..uncertainty.sampling import unit_draws


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
