"""The Monte Carlo check of a yield design: fresh units simulated at the design against its
linearised model on the same units (`yield_check`, `YieldCheck`); the difference of their
quantiles is the shift by which the requirement is tightened and the design solved again (the
SORA idea, `tolerax.design.reliability`): `Check`, a value `propose_design` takes, runs that
loop through whichever solver the design has. The units are a `tolerax.monte_carlo` run, so its
backends (one process, a process pool, a Dask cluster), chunks, checkpoints, devices and
progress bar serve the design's checks as they serve any Monte Carlo.
"""

import dataclasses
import hashlib
import json
import math
import os
import pathlib
import time

import equinox as eqx
import jax.numpy as jnp
import numpy as np
import scipy.stats

from .reliability import LinearisedYield, _uncertain_columns, _uncertain_count, _unfitted
from .outcome import MODEL_OFF
from .phases import Phases
from .types import Design, chain_results
from ..uncertainty.montecarlo import BACKENDS, _fingerprint, default_chunk, key_settings, monte_carlo
from ..uncertainty.results import wilson_interval
from ..uncertainty.sampling import Tolerances


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
    - `missed` (property): the units miss the yield beyond their own noise (the Wilson
      interval's upper end below `q`).
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

    @property
    def missed(self) -> bool:
        """The units miss the yield `q` beyond their sampling noise: the Wilson interval's upper
        end is below it."""
        return self.interval[1] < self.q

    def met(self, unit: str = "arcsec") -> str:
        """`"98.5% met 700 arcsec"`, and where that is short of the yield asked but the check's
        95 % Wilson interval holds it, that it is within the units' sampling noise."""
        said = f"{self.yield_simulated:.1%} met {self.requirement:g} {unit}"
        if self.yield_simulated < self.q and not self.missed:
            said += (f" (below {self.q:.1%}, but within what {self.n - self.n_failed} units resolve: their 95 % interval "
                     f"{self.interval[0]:.1%}-{self.interval[1]:.1%} holds it)")
        return said

    def text(self) -> str:
        return (
            f"Monte Carlo check on {self.n - self.n_failed} fresh units: yield {self.yield_simulated:.3f} "
            f"[{self.interval[0]:.3f}, {self.interval[1]:.3f}] (95 % Wilson) against the linear model's "
            f"{self.yield_linear:.3f} on the same units; {self.q:.1%} quantile simulated {self.quantile_simulated:.1f} arcsec, "
            f"linear {self.quantile_linear:.1f} (shift {self.shift:+.1f} ± {self.shift_se:.1f} arcsec)"
        )


@dataclasses.dataclass(frozen=True)
class Check:
    """The Monte Carlo check of a yield design, and its re-solves (SORA).

    - `units`: fresh units simulated per check (`yield_check`), drawn from `key` (default
      `jax.random.key(1)`; the drawn design's check uses the key folded with 1).
    - `rounds`: at most this many checks. Where a check finds the linear model under- or
      over-reading the yield's quantile by more than 1 % of the requirement and twice the
      check's standard error (and by less than `MODEL_OFF` of it: beyond that the model does not
      hold and no shift would help), or its units miss the yield beyond their noise (`shifted`),
      the requirement the solver sees is shifted by the difference and the design solved again
      from where it was, then checked again.

    The proposal is the cheapest checked design whose simulated quantile met the requirement
    (to the solver's tolerance) and whose units did not miss the yield beyond their noise, else
    the last one.

    How the units run (each check is one `tolerax.monte_carlo` run; its arguments of the same
    names): `chunk_size` units per compiled batch (default: the scene's `unit_chunk()` on a CPU,
    10 for a full planetary stage and 50 otherwise; 64 elsewhere); `backend` `"auto"` (the
    default: this process and worker processes on idle cores, `tolerax.monte_carlo`'s), `"vmap"`
    (this process alone), `"processes"` (with `workers`) or `"dask"` (with `client`); `out`, a
    folder where each check keeps its chunks (in a subfolder named by the design, the units, the
    key and the model, so a design run again with the same arguments reads its finished checks back
    instead of simulating them again; default none).
    """

    units: int = 200
    rounds: int = 3
    key: object = None
    chunk_size: int | None = None
    backend: str = "auto"
    workers: int | None = None
    client: object = None
    out: str | os.PathLike | None = None

    def __post_init__(self):
        if int(self.units) < 2:
            raise ValueError(f"Check: units must be >= 2 simulated units, got {self.units!r} (no check: check=None).")
        if int(self.rounds) < 1:
            raise ValueError(f"Check: rounds must be >= 1 (checks at most), got {self.rounds!r}.")
        if self.chunk_size is not None and int(self.chunk_size) < 1:
            raise ValueError(f"Check: chunk_size must be >= 1 unit per batch, got {self.chunk_size!r}.")
        if self.backend not in BACKENDS:
            raise ValueError(f"Check: backend must be one of {BACKENDS}, got {self.backend!r}.")

    def key_for(self, drawn: bool = False):
        """The units' key: `key` (default `jax.random.key(1)`); for the drawn design's check the
        key folded with 1 (default `jax.random.key(2)`)."""
        import jax

        if self.key is None:
            return jax.random.key(2 if drawn else 1)
        return jax.random.fold_in(self.key, 1) if drawn else self.key

    def simulate(self, objective: LinearisedYield, x: Design, requirements, width=None, *, drawn: bool = False,
                 progress: bool = False):
        """`yield_check` of design `x` (`Design(middle, half-width)`, m) against `requirements`
        (one per output of `objective`) on this check's units (`key_for(drawn)`), run as it says
        (chunks, backend, checkpoints), simulated at the scene's own smoothing widths against
        the linear model at `width` (m, the one the design was solved at): a tuple of
        `YieldCheck`s, one per requirement, however many."""
        chunk = None if self.chunk_size is None else int(self.chunk_size)
        got = yield_check(objective, x, as_requirement(requirements), int(self.units), self.key_for(drawn), width, chunk,
                          backend=self.backend, workers=self.workers, client=self.client, out=self.out, progress=progress)
        return got if isinstance(got, tuple) else (got,)

    def run(self, solver, problem, trusted, result, requirements, tol, progress=False, callback=None, say=None):
        """Check `result` (an `OptimisationResult` of `problem`, a `DesignProblem` whose
        objective is a `LinearisedYield`) against `requirements` (m,) and re-solve through
        `solver` on `trusted` (the problem held where its model was fitted) while the check
        moves them. Returns `(result, checked)`, `checked` one `(result, checks (one per
        requirement), requirements solved for)` per check, the last the returned design's. A
        design that misses what it was solved for is not checked."""
        target, checked = requirements.copy(), []
        for _ in range(int(self.rounds)):
            if np.any(np.asarray(result.objective, dtype=float) > target * (1 + tol)):
                break  # the design misses what it was solved for (infeasible, or not converged): nothing to check
            middle = Design(result.x.nominal + result.x.band, result.x.band)
            paced = isinstance(say, Phases)  # a Phases keeps each check's wall time, to say the next's
            if say is not None:
                say(f"Monte Carlo check {len(checked) + 1} (of at most {int(self.rounds)}): {int(self.units)} fresh units"
                    + (say.at_pace("check") if paced else "") + " ...")
            begun = time.perf_counter()
            got = self.simulate(problem.objective.objective, middle, requirements, solver.width, progress=progress)
            if paced:
                say.took("check", time.perf_counter() - begun)
            checked.append((result, got, target.copy()))
            if model_off(got, requirements):
                break  # the linear model does not hold here: no shift of it would (`diagnose` says so)
            corrected, moved = shifted(got, requirements, target, tol)
            if not np.all(np.isfinite(corrected)) or not np.any(moved) or len(checked) == int(self.rounds):
                break
            target = np.where(moved, corrected, target)
            if say is not None:
                say("the linear model was off by more than its noise: solving again against the shifted requirement ...")
            again = solver.solve(trusted, as_requirement(target), tol, x0=result.x, progress=progress, callback=callback)
            result = chain_results([result, again])  # its history (gradients) continues the one before
        k = cheapest_accepted([float(r.cost) for r, _, _ in checked],
                              [[c.quantile_simulated for c in got] for _, got, _ in checked], requirements, tol,
                              missed=[any(c.missed for c in got) for _, got, _ in checked])
        if k is not None:
            checked = checked[: k + 1]
            result = checked[-1][0]
        return result, checked


def shifted(checks, requirements, target, tol):
    """`(corrected, moved)`: the requirements (m,) less each check's shift (`YieldCheck.shift`,
    the units' quantile over the linear model's), and which of them the next solve takes instead
    of `target` (the ones the design was solved for). A shift within the check's own noise (twice
    its standard error) or the method's relative tolerance `tol` is not one, unless the check
    missed its yield beyond its noise (its Wilson interval below the yield asked) with the model
    under-reading: a fitted output's tolerance is twice its fit's standard error (up to 50 %,
    `propose._tolerances`), wide enough to hide a shift that leaves a fifth of the units out."""
    shift = np.array([c.shift for c in checks])
    corrected = np.asarray(requirements, dtype=float) - shift
    noise = np.maximum(tol * requirements, 2.0 * np.array([c.shift_se for c in checks]))
    missed = np.array([c.missed for c in checks]) & (shift > 0)
    return corrected, (np.abs(corrected - target) > noise) | (missed & (corrected < target))


def model_off(checks, requirements) -> bool:
    """Whether a check (`checks`, one `YieldCheck` per requirement) found the linear model's
    quantile off from the units' by more than `MODEL_OFF` of its requirement (`requirements`,
    (m,)) for any requirement: the model does not hold there, and no shift of it would."""
    return any(abs(c.shift) > MODEL_OFF * r for c, r in zip(checks, np.atleast_1d(requirements)))


def as_requirement(requirements):
    """The requirements (m,) as the solvers and `yield_check` take them: a tuple of m floats,
    one or several."""
    requirements = np.atleast_1d(requirements)
    return tuple(float(v) for v in requirements)


def cheapest_accepted(costs, quantiles, requirement, tol=0.01, missed=None):
    """Index of the cheapest design whose simulated quantile met `requirement` to `tol` (each
    of them, with several requirements: `quantiles` one array per design) and whose check did not
    miss its yield beyond its noise (`missed`, one bool per design; default none did), or `None`
    where none did: a re-solve that did not land is not kept over a cheaper design the simulation
    already accepted, nor one the units rejected kept for a quantile inside a wide tolerance."""
    missed = [False] * len(costs) if missed is None else missed
    ok = [k for k, q in enumerate(quantiles)
          if not missed[k] and np.all(np.asarray(q) <= np.asarray(requirement) * (1 + np.asarray(tol)))]
    return min(ok, key=lambda k: costs[k]) if ok else None


@eqx.filter_jit
def _model(objective, x, width):
    """`objective.model(x, width)`, one program per objective structure for every check."""
    return objective.model(x, width)


def own_width(pointing):
    """The smoothing width (m) of `pointing`'s scene as an array where every stage shares one (so
    that `AtWidth` at it has the structure of `AtWidth` at any other width, and one compiled
    program serves both), else `None` (each stage keeps its own)."""
    from .objectives import _widths

    widths = {float(w) for w in _widths(pointing.scene)}
    return jnp.asarray(widths.pop(), dtype=float) if len(widths) == 1 else None


class AtWidth(eqx.Module):
    """An objective (`AbstractObjective`) as a Monte Carlo model at one smoothing width:
    `AtWidth(objective, width)(values)` is `objective(values, width)` (`width` in m; `None`: the
    scene's own), what `monte_carlo` evaluates on each unit."""

    objective: object
    width: object = None

    def __call__(self, values):
        return self.objective(values, self.width)


def unit_tolerances(pointing, x: Design) -> Tolerances:
    """The zones a check draws its units from: the design `x` (`Design(middle, half-width)`,
    m) over `pointing`'s design features, uniform and floored at zero (a clearance cannot be
    negative: `realise`), then `pointing`'s uncertain inputs (a life's wear-rate factor) over
    their band (`uncertain_box`), not floored. Sample $i$ of `monte_carlo` on these is the unit
    `realise(x, unit_draws(key, n, ...)[i])` with its uncertain inputs appended."""
    from .features import design_names

    zones = Tolerances(design_names(pointing.scene), np.asarray(x.nominal, dtype=float), np.asarray(x.band, dtype=float), "uniform")
    if not _uncertain_count(pointing):
        return zones
    return zones.joined(Tolerances(pointing.uncertain_inputs, *pointing.uncertain_box(), "uniform", lower=None))


def yield_check(objective: LinearisedYield, x: Design, requirement, n: int, key, width=None, chunk: int | None = None, *,
                backend: str = "auto", workers=None, client=None, out=None, progress: bool = False):
    """Simulate `n` fresh units of design `x` (`Design(middle, half-width)`, m) with
    `objective`'s pointing model and compare them with its linearised model on the same units
    (see `YieldCheck`); each unit draws the objective's uncertain inputs too (a life's wear
    rate: `LinearisedYield`). The linear model is the one the design was solved on, at
    smoothing `width` (m; `None`: the scene's own); the units are simulated at the scene's own
    smoothing widths (`own_width`), what a built unit is, so the check's shift carries the
    smoothing's bias (a wider width rounds the contacts off, which moves the vibration
    outputs) as well as the line's. The units are one `tolerax.monte_carlo` run
    (`unit_tolerances`, `key`) in chunks of `chunk` units (default `default_chunk` of the pointing
    model: its scene's `unit_chunk()` on a CPU) on `backend` (`workers`,
    `client`, a progress bar with `progress`, as `monte_carlo`'s), its chunks kept under `out`
    where given (a subfolder per design, units, key and model). A tuple `output` (two
    requirements, e.g. RMS and jitter): `requirement` one per output, and one `YieldCheck` per
    output from the same units."""
    if int(n) < 2:
        raise ValueError(f"yield_check: n must be >= 2 units, got {n!r}.")
    outputs = objective.output if isinstance(objective.output, tuple) else (objective.output,)
    requirements = np.broadcast_to(np.asarray(requirement, dtype=float), (len(outputs),))
    x = Design(jnp.asarray(x.nominal), jnp.asarray(x.band))
    width = None if width is None else jnp.asarray(width, dtype=float)
    tolerances = unit_tolerances(objective.pointing, x)
    model = AtWidth(objective.pointing, own_width(objective.pointing))
    folder = None
    if out is not None:  # one subfolder per design, units, key and model: another never meets these chunks
        said = json.dumps([tolerances.to_json(), key_settings(key), int(n), _fingerprint(model)], sort_keys=True)
        folder = pathlib.Path(out) / f"units-{hashlib.sha256(said.encode()).hexdigest()[:16]}"
    chunk = default_chunk(objective.pointing) if chunk is None else chunk
    run = monte_carlo(model, tolerances, int(n), key, backend=backend, chunk_size=min(int(chunk), int(n)), out=folder,
                      progress=progress, workers=workers, client=client)
    ds = run.dataset
    drawn = jnp.asarray(np.stack([ds[name].values for name in tolerances.names], axis=1))
    values = drawn[:, : x.nominal.shape[0]]
    success = np.asarray(ds["success"].values, dtype=bool)
    simulated = np.stack([np.where(success, ds[name].values, np.nan) for name in outputs], axis=1)
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
