"""Tolerance proposals on a scene: the cheapest nominal clearances/backlash and tolerance bands
whose robust pointing error meets a requirement.

`propose_design` ties together the scene's design vector (`tolerax.design.features`), a `PointingObjective`,
fixed manufacturing draws (`unit_draws`), the ISO 286-anchored cost model (`tolerax.design.cost`)
and the augmented-Lagrangian optimiser on optax (`tolerax.design.optimise`), and returns a `DesignReport`.
"""

import dataclasses
from collections.abc import Mapping
import math
import warnings

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array
from ..cache import exported_jit
from .cost import AbstractCostModel, IsoGrade, grade_of
from .features import design_names, design_of, feature_entries, lost_motion_weights
from .objectives import UNITS, PointingObjective, unit_output, value_and_jacobian
from .optimise import Design, Features, OptimisationResult, optimise_design, realise, robust
from .reliability import LinearisedYield, YieldCheck, secant_gradient_noise, secant_standard_error, yield_check, yield_draws
from .sequential import sequential_design
from ..mechanism.joints import LumpedJoint
from ..uncertainty.sampling import unit_draws


def feature_sizes(scene) -> np.ndarray:
    """Nominal size (mm) of each design feature for the cost model: the journal diameter of a
    bearing clearance, the pitch diameter of the gear whose mesh has the backlash (sun or ring)."""
    sizes = []
    for _, feature, stage, _ in feature_entries(scene):
        if feature.endswith("_clearance"):
            support = getattr(stage, feature.replace("_clearance", "_support"))
            radius = float(np.max(np.asarray(support.bearing.journal_radius)))
        else:
            base = stage.sun_base_radius if feature == "sun_backlash" else stage.ring_base_radius
            radius = float(base) / math.cos(float(stage.sun_pressure_angle))
        sizes.append(2e3 * radius)
    return np.asarray(sizes)


class OnHalfWidth(AbstractCostModel):
    """A cost model of the full tolerance width $2b$ (as ISO 286 tabulates it) applied to the
    design's half-width `band` $b$ (nominal $\\pm b$)."""

    model: AbstractCostModel

    def __call__(self, band, size_mm):
        return self.model(2.0 * band, size_mm)


@eqx.filter_custom_vjp
def _unit_output_forward(values, pointing, output, width):
    """`unit_output`, whose reverse-mode derivative is computed in forward mode: the backward
    pass of a simulation needs the whole trajectory (checkpointed and recomputed), while a
    handful of tangents carried along the forward solve (`diffrax.ForwardMode`) cost less for
    the few clearances of a scene (benchmarks/results/gradient_methods.md). The Jacobian over
    the unit's design vector is formed on the forward pass and kept for the backward one."""
    return unit_output(values, pointing, output, width)


@_unit_output_forward.def_fwd
def _unit_output_forward_fwd(perturbed, values, pointing, output, width):
    return value_and_jacobian(values, pointing, output, width)


@_unit_output_forward.def_bwd
def _unit_output_forward_bwd(jac, cotangent, perturbed, values, pointing, output, width):
    return cotangent * jac


class RobustPointing(eqx.Module):
    """`objective(x, draws, width)`: a robust statistic (`robust`, arcsec) of one output of a
    `PointingObjective` over the manufactured units `realise(x, draws)`, at smoothing width
    `width` (m). A failed solve makes the objective NaN (the optimiser then stops with an error
    naming the iteration) rather than a silently wrong number.

    `gradient`: how `jax.grad` of the objective is computed through each unit's simulation:
    `"forward"` (default; one forward solve carrying one tangent per design feature, then the
    chain rule through `realise`; the objective then supports reverse-mode `jax.grad`/`vjp` but
    not `jax.jvp`) or `"reverse"` (the pointing objective's own adjoint, checkpointed reverse
    mode). benchmarks/results/gradient_methods.md measures both."""

    pointing: PointingObjective
    output: str = eqx.field(static=True, default="pointing_rms")
    statistic: str = eqx.field(static=True, default="mean+kstd")
    k: float = eqx.field(static=True, default=1.0)
    gradient: str = eqx.field(static=True, default="forward")

    def __check_init__(self):
        if self.gradient not in ("forward", "reverse"):
            raise ValueError(f"RobustPointing: gradient must be 'forward' or 'reverse', got {self.gradient!r}.")

    def __call__(self, x: Design, draws, width) -> Array:
        unit = _unit_output_forward if self.gradient == "forward" else unit_output
        value = jax.vmap(lambda v: unit(v, self.pointing, self.output, width))(realise(x, draws))
        return robust(value, kind=self.statistic, k=self.k)


class FromLowerLimit(eqx.Module):
    """An objective of a `Design` whose `nominal` field holds the *lower limit* $l$ of each
    tolerance zone (the minimum clearance or backlash, m) instead of its middle: it calls
    `objective(Design(l + b, b), ...)`. With $l$ bounded below by a functional minimum (thermal
    growth, lubricant film, no jamming), the box of the optimiser is the set of buildable fits,
    which a box on (nominal, band) cannot express ($\\text{nominal} - \\text{band} \\ge l_{min}$)."""

    objective: eqx.Module

    def __call__(self, x: Design, draws, width) -> Array:
        return self.objective(Design(x.nominal + x.band, x.band), draws, width)


@dataclasses.dataclass(frozen=True)
class JitterRequirement:
    """The pointing-stability part of a proposal with two requirements (`DesignReport.jitter`).

    - `requirement` (arcsec): the jitter (RMS of the pointing error above `cutoff` Hz over the
      window) that a fraction `yield_` of units must meet; `objective` (arcsec): its linearised
      quantile at the proposal; `baseline` (arcsec): the same at the starting design.
    - `constraint_active`, `multiplier` (cost per arcsec), `tol` (relative: the tolerance the
      optimiser held it to, twice its secant fit's standard error).
    - `sensitivity` (arcsec/m): d quantile / d (nominal, band), fitted over units (secants).
    - `target` (arcsec): the (shifted) requirement the returned design was solved for;
      `checks`: the Monte Carlo checks of the jitter (`YieldCheck`, the same units as the
      lost-motion checks).
    """

    requirement: float
    cutoff: float
    objective: float
    constraint_active: bool
    multiplier: float
    sensitivity: Design
    baseline: float
    tol: float
    target: float
    checks: tuple[YieldCheck, ...] = ()


@dataclasses.dataclass(frozen=True)
class DesignReport:
    """What `propose_design` proposes, and why.

    - `names`: the features; `nominal`, `band` (m): the proposed design; `grade`: the ISO 286
      grade of each band on its feature's size (fractional); `feature_cost`, `cost` (model
      units): per feature and total.
    - `baseline`: `(nominal, band, cost, objective)` of the starting design.
    - `objective` (arcsec): the robust statistic at the proposal over the fixed draws;
      `requirement` (arcsec); `constraint_active`; `multiplier` (cost per arcsec: what one more
      arcsec of requirement saves).
    - `sensitivity` (arcsec/m): d objective / d (nominal, band) per feature at the proposal.
    - `result`: the full `OptimisationResult` (history included); its `x.nominal` holds the
      lower limits $l$ (`FromLowerLimit`), the proposal's `nominal` is $l + b$.
    - `yield_`: the yield $Y$ of a yield requirement (the objective is then the linearised
      $Y$-quantile, `LinearisedYield`), else `None`; `checks`: the Monte Carlo checks of the
      proposal (`YieldCheck`; the last is the returned design's: the cheapest checked design
      whose simulated quantile met the requirement to 1 %, else the last one checked).
    - `lost_motion` (arcsec/m): the geometric stack-up's weight of each feature
      (`lost_motion_weights`), shown in `table()` beside the simulated sensitivities.
    - `jitter`: the stability requirement's part (`JitterRequirement`) where one was given
      (`propose_design(jitter=...)`), else `None`; the fields above are then the lost-motion
      requirement's.
    - `solved_for` (arcsec): the requirement the optimiser solved the returned design for
      (`target`).
    """

    names: tuple[str, ...]
    nominal: np.ndarray
    band: np.ndarray
    grade: np.ndarray
    feature_cost: np.ndarray
    cost: float
    objective: float
    requirement: float
    constraint_active: bool
    multiplier: float
    sensitivity: Design
    baseline: tuple
    result: OptimisationResult
    yield_: float | None = None
    checks: tuple[YieldCheck, ...] = ()
    lost_motion: np.ndarray | None = None
    fixed: tuple[str, ...] = ()
    jitter: JitterRequirement | None = None
    solved_for: float | None = None

    @property
    def target(self) -> float:
        """The requirement (arcsec) the optimiser met with the returned design: `requirement`
        itself, or, where a Monte Carlo check found the linear model under- or over-reading
        the quantile and the design was solved again, the requirement shifted by that check
        (`requirement - shift`, the SORA correction)."""
        if self.solved_for is not None:
            return self.solved_for
        return self.requirement if len(self.checks) < 2 else self.requirement - self.checks[-2].shift

    def table(self) -> str:
        """A Markdown table of the proposal, one row per feature."""
        geometric, jitter = self.lost_motion is not None, self.jitter
        rows = [
            "| feature | nominal (µm) | band ± (µm) | zone (µm) | ISO grade | cost | d obj / d nominal (arcsec/µm) |"
            + (" d jitter / d nominal (arcsec/µm) |" if jitter else "") + (" lost motion by the drawings (arcsec/µm) |" if geometric else ""),
            "|---|---|---|---|---|---|---|" + ("---|" if jitter else "") + ("---|" if geometric else ""),
        ]
        for k, name in enumerate(self.names):
            low, high = (self.nominal[k] - self.band[k]) * 1e6, (self.nominal[k] + self.band[k]) * 1e6
            rows.append(
                f"| {name}{' (given)' if name in self.fixed else ''} | {self.nominal[k] * 1e6:.1f} | {self.band[k] * 1e6:.1f} | {low:.1f}–{high:.1f} | IT{self.grade[k]:.1f} | "
                f"{self.feature_cost[k]:.3g} | {float(self.sensitivity.nominal[k]) * 1e-6:.3g} |"
                + (f" {float(jitter.sensitivity.nominal[k]) * 1e-6:.3g} |" if jitter else "")
                + (f" {float(self.lost_motion[k]) * 1e-6:.3g} |" if geometric else "")
            )
        if geometric:
            rows += ["", self._weights_text(), "", self._split_text()] + (["", self._split_text(jitter=True)] if jitter else [])
        what = "objective" if self.yield_ is None else f"{self.yield_:.1%} quantile (linearised)"
        head = (
            f"Proposed design: cost {self.cost:.4g} (relative, 1 per feature at IT7; baseline {self.baseline[2]:.4g}); {what} "
            f"{self.objective:.1f} arcsec against a requirement of {self.requirement:.1f} arcsec "
            + (f"(shifted to {self.target:.1f} by the check before: the linear model's error there) " if self.target != self.requirement else "")
            + f"(baseline {self.baseline[3]:.1f}); constraint {'active' if self.constraint_active else 'inactive'}; "
            f"{self._iteration_text()}; {'converged' if bool(self.result.converged) else 'not converged'}; first-order "
            f"optimality residual {self.result.optimality:.2g} (bands alone {self.result.band_optimality:.2g})."
        )
        if self.checks:
            head += " " + self.checks[-1].text() + "."
        if jitter:
            head += (
                f"\n\nStability: jitter (RMS pointing error above {jitter.cutoff:g} Hz), {self.yield_:.1%} quantile (linearised, "
                f"secants) {jitter.objective:.4g} arcsec against {jitter.requirement:.4g} arcsec "
                + (f"(shifted to {jitter.target:.4g} by the check before) " if jitter.target != jitter.requirement else "")
                + f"(baseline {jitter.baseline:.4g}): "
                + ("met" if jitter.objective <= jitter.target * (1 + jitter.tol) else "**not met** (the tightest design the optimiser "
                   "reached does not meet it)")
                + f", constraint {'active' if jitter.constraint_active else 'inactive'} to {jitter.tol:.0%} (twice its fit's standard error)."
                + (" Jitter check: " + jitter.checks[-1].text() + "." if jitter.checks else "")
            )
        return head + "\n\n" + "\n".join(rows)

    def _weights_text(self) -> str:
        """The simulated sensitivities beside the drawings' weights, each relative to the first
        feature the drawings weigh (a backlash or a pin clearance): where they differ, a stack-up
        from the drawings misallocates the bands."""
        s, w = np.asarray(self.sensitivity.nominal, dtype=float), np.asarray(self.lost_motion, dtype=float)
        ref = int(np.flatnonzero(w > 0)[0]) if np.any(w > 0) else None
        if ref is None or s[ref] == 0:
            return "No feature moves the output by the drawings: no weights to compare."
        pairs = ", ".join(f"{name} {s[k] / s[ref]:.2f} / {w[k] / w[ref]:.2f}" for k, name in enumerate(self.names))
        return f"Weight per µm relative to {self.names[ref]}, simulated / drawings (`lost_motion_weights`): {pairs}."

    @property
    def split(self) -> tuple[float, float, float]:
        """`(lost motion share, dynamics share, scale)` of the objective's variation over the
        proposed zones. The simulated sensitivities $s$ (arcsec/m) are split into the drawings'
        lost-motion weights $w$ (`lost_motion_weights`) times a scale $c$ and a remainder
        $r = s - c w$, orthogonal in the metric of the zones ($\\sum_i b_i^2 w_i r_i = 0$, $b$
        the half-widths): for units uniform in the zones the variance of the linearised objective,
        $\\sum_i s_i^2 b_i^2/3$, is the lost-motion part $\\sum_i c^2 w_i^2 b_i^2/3$ plus the
        dynamics part $\\sum_i r_i^2 b_i^2/3$. The shares sum to 1; $c$ is the arcsec of the
        objective per arcsec of lost motion (e.g. 0.72 for the RMS on the design scan, issue 30).
        NaN where the drawings weigh nothing or the bands are all zero."""
        return self._split_of(self.sensitivity.nominal)

    @property
    def jitter_split(self) -> tuple[float, float, float]:
        """`split` of the jitter requirement's sensitivities (NaN without one)."""
        return (math.nan,) * 3 if self.jitter is None else self._split_of(self.jitter.sensitivity.nominal)

    def _split_of(self, sensitivity) -> tuple[float, float, float]:
        s, w, b2 = (np.asarray(sensitivity, dtype=float), np.asarray(self.lost_motion, dtype=float),
                    np.asarray(self.band, dtype=float) ** 2)
        total, ww = float(np.sum(s * s * b2)), float(np.sum(w * w * b2))
        if total == 0.0 or ww == 0.0:
            return math.nan, math.nan, math.nan
        c = float(np.sum(s * w * b2)) / ww
        lost = c * c * ww / total
        return lost, 1.0 - lost, c

    def _split_text(self, jitter: bool = False) -> str:
        lost, dynamics, c = self.jitter_split if jitter else self.split
        what = "jitter's" if jitter else "objective's"
        if not math.isfinite(lost):
            return f"Split of the {what} variation into lost motion and dynamics: not defined (no feature moves the output by the drawings, or no band)."
        return (f"Of the {what} variation over the zones, {lost:.0%} is lost motion (the drawings' weights, scaled by "
                f"{c:.3g} arcsec per arcsec of lost motion) and {dynamics:.0%} dynamics (what those weights do not explain: "
                f"`DesignReport.{'jitter_split' if jitter else 'split'}`).")

    def _iteration_text(self) -> str:
        chosen, n = int(self.result.iteration), len(np.asarray(self.result.history.cost))
        if chosen == n - 1:
            return f"the last of {n} iterations"
        return f"iteration {chosen + 1} of {n}, the cheapest that met the requirement"

    def plot(self):
        """History (cost, objective) and sensitivities; returns the matplotlib figure."""
        import matplotlib.pyplot as plt

        hist = self.result.history
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.5))
        it = np.arange(1, len(np.asarray(hist.cost)) + 1)
        axes[0].plot(it, np.asarray(hist.cost), "o-", label="cost")
        ax2 = axes[0].twinx()
        what = "objective" if self.yield_ is None else f"{self.yield_:.1%} quantile (linearised)"
        objective = np.asarray(hist.objective)
        if self.jitter is None:
            ax2.plot(it, objective, "s--", color="C1", label=f"{what}, arcsec")
            ax2.axhline(self.requirement, color="C1", lw=0.8, ls=":", label="requirement")
            ax2.set_ylabel(f"RMS pointing error ({UNITS['pointing_rms']})")
        else:  # two requirements of different sizes: each over its own
            ax2.plot(it, objective[:, 0] / self.requirement, "s--", color="C1", label=f"RMS {what} / requirement")
            ax2.plot(it, objective[:, 1] / self.jitter.requirement, "^--", color="C2", label=f"jitter {what} / requirement")
            ax2.axhline(1.0, color="0.3", lw=0.8, ls=":", label="requirement")
            ax2.set_ylabel("objective / requirement")
        axes[0].axvline(int(self.result.iteration) + 1, color="0.5", lw=0.8, ls="--", label="proposed iterate")
        axes[0].set_xlabel("iteration (one gradient each)")
        axes[0].set_ylabel("tolerance cost (1 per feature at IT7)")
        lines = axes[0].get_legend_handles_labels()
        more = ax2.get_legend_handles_labels()
        axes[0].legend(lines[0] + more[0], lines[1] + more[1], fontsize=7, loc="upper right")
        y = np.arange(len(self.names))
        axes[1].barh(y, np.asarray(self.sensitivity.nominal) * 1e-6)
        axes[1].set_yticks(y, self.names, fontsize=7)
        axes[1].set_xlabel("d objective / d nominal (arcsec/µm)")
        axes[1].set_title("simulated sensitivity at the proposal", fontsize=9)
        fig.tight_layout()
        return fig


@dataclasses.dataclass(frozen=True)
class DesignProblem:
    """The tolerance-design problem `propose_design` solves, for other optimisers to solve too
    (benchmarks/design_comparison.py): minimise `cost_model.total(x.band, features.size_mm)`
    subject to `objective(x, draws, width) <= requirement` over `lower <= x <= upper`, with
    `x = Design(lower limit, band)` (m; `FromLowerLimit`), starting from `x0`."""

    objective: FromLowerLimit
    features: Features
    draws: Array
    lower: Design
    upper: Design
    x0: Design
    cost_model: AbstractCostModel

    @property
    def gradient_noise(self):
        """For `sequential_design(gradient_noise=...)`: `noise(x, width)`, the standard errors
        (arcsec/m) of the objective's gradient at `x` (`Design(lower limit, band)`) where it is
        fitted by secants over a few units (`secant_gradient_noise`); `None` where the gradient
        is exact (tangents), or where the fit leaves no residual to estimate its noise from
        (`secant_units` at most one more than the features)."""
        inner = self.objective.objective
        if not isinstance(inner, LinearisedYield) or inner.secant_units is None or inner.secant_units < len(self.features.names) + 2:
            return None
        return lambda x, width: secant_gradient_noise(inner, Design(x.nominal + x.band, x.band), self.draws, width)


def design_problem(
    pointing: PointingObjective,
    *,
    band: float = 10e-6,
    min_clearance=5e-6,
    band_range: tuple[float, float] = (1e-6, 50e-6),
    n_draws: int = 4,
    key=None,
    statistic: str = "mean+kstd",
    k: float = 1.0,
    output: str = "pointing_rms",
    cost_model: AbstractCostModel | None = None,
    gradient: str = "forward",
    yield_: float | None = None,
    n_yield_draws: int = 16384,
    slope_width: float | None = None,
    secant_units: int | None = None,
    scatter: bool = False,
    fixed=(),
) -> DesignProblem:
    """The `DesignProblem` that `propose_design` solves.

    **Arguments:**

    - `pointing`: the `PointingObjective` (scene, horizon, window); its scene's current design
      is the starting nominal.
    - `band`: starting tolerance half-width (m) of every feature; the starting lower limit is
      the current nominal minus `band` (at least `min_clearance`).
    - `min_clearance`: smallest allowed lower limit (m), a scalar or one value per feature
      (`design_names(scene)` order). The largest allowed is the starting one.
    - `band_range`: (smallest, largest) half-width (m).
    - `n_draws`, `key`: fixed standardised draws (`unit_draws`), the same at every iteration.
    - `statistic`, `k`: `robust` statistic (`"mean+kstd"` with `k`, or `"quantile"`) of
      `output` over the draws.
    - `cost_model`: a cost of the full tolerance width $2b$; default `IsoGrade()` (ISO 286
      grades, relative cost 1 per feature at IT7).
    - `gradient`: `"forward"` (default) or `"reverse"` mode through each simulation
      (`RobustPointing`).
    - `yield_`: a yield $Y$ in (0, 1) makes the objective the $Y$-quantile of `output` over all
      units made within the bands, linearised at the zone middles (`LinearisedYield`: one
      simulation with one forward-mode tangent per feature; `n_draws`, `key`, `statistic`, `k`
      and `gradient` unused), so that objective $\\le R$ reads $P(\\text{output} \\le R) \\ge Y$;
      `n_yield_draws` fixed quasi-random draws (`yield_draws`) carry the quantile;
      `slope_width` (m, optional): take the slopes at this smoothing width (`LinearisedYield`:
      at a narrow width forward-mode tangents through the contacts can be spiky); default at
      the objective's own width. On the dual scan slopes at 1 um did not make the design
      converge (it stalled at cost 8.47 where a run without them reached 2.69): the value is
      rough there too. `secant_units` (optional, more than the features): fit the value and
      slopes by least squares over this many units of the zone instead (`LinearisedYield`:
      forward solves only; where tangents are noise, a line through the units is not);
      `scatter` (with `secant_units`): the quantile includes the fit's residual scatter
      (`LinearisedYield(scatter=True)`: a chaotic metric such as the jitter).
    - `fixed`: features whose tolerance zone is given, not designed (a bought-in bearing, a
      part already made): names, held at their nominal +- `band`, or a mapping name -> its
      half-width (m), held at nominal +- that. Their lower limit and band are bounded to those
      values (their cost is counted, constant).
    """
    scene = pointing.scene
    names = design_names(scene)
    nominal0 = np.asarray(design_of(scene))
    lumped = [joint for joint, stage_of, _ in scene.named_stages()
              if stage_of(scene).distinct_planets and isinstance(getattr(scene, joint, None), LumpedJoint)]
    if lumped:
        warnings.warn(
            f"design_problem: the lumped joint(s) {', '.join(lumped)} have per-planet features (distinct_planets), but a lumped "
            "joint keeps only the tightest planet's lost motion: a design there tightens one planet and leaves the others wide, "
            "which the planetary stage does not bear out (benchmarks/results/design_antenna_planets.md: 0.055 verified yield "
            "against 0.99). Design per-planet features at planetary fidelity.", stacklevel=2)
    n = len(names)
    min_clearance = np.broadcast_to(np.asarray(min_clearance, dtype=float), (n,))
    if not (np.all(np.isfinite(min_clearance)) and np.all(min_clearance >= 0)):
        raise ValueError(f"propose_design: min_clearance must be finite and >= 0 (m), got {min_clearance}.")
    band_lo, band_hi = (float(v) for v in band_range)
    if not (0 < band_lo <= band <= band_hi and np.isfinite(band_hi)):
        raise ValueError(
            f"propose_design: need 0 < band_range[0] <= band <= band_range[1] (m), got band={band!r}, band_range={band_range!r}."
        )
    key = jax.random.key(0) if key is None else key
    limit0 = np.maximum(nominal0 - band, min_clearance)
    lower_limit, lower_band, upper_band, band0 = min_clearance.copy(), np.full(n, band_lo), np.full(n, band_hi), np.full(n, float(band))
    given = dict(fixed) if isinstance(fixed, Mapping) else {name: float(band) for name in fixed}
    for name, half in given.items():
        if name not in names:
            raise ValueError(f"propose_design: fixed feature {name!r} is not a design feature of this scene; its features: {', '.join(names)}.")
        if not (np.isfinite(half) and half > 0):  # a zero band would cost infinitely much (ISO 286)
            raise ValueError(f"propose_design: the fixed feature {name!r} needs a finite half-width > 0 (m), got {half!r}.")
        j = names.index(name)  # not `k`: that is the robust statistic's
        limit0[j] = lower_limit[j] = max(float(nominal0[j]) - half, 0.0)
        lower_band[j] = upper_band[j] = band0[j] = half
    if yield_ is None:
        objective, draws = RobustPointing(pointing, output, statistic, k, gradient), unit_draws(key, n_draws, n)
    else:
        objective = LinearisedYield(pointing, output, float(yield_), None if slope_width is None else float(slope_width),
                                    None if secant_units is None else int(secant_units), bool(scatter))
        draws = yield_draws(n + 1 if scatter else n, n_yield_draws)  # the last column carries the scatter's draws
    return DesignProblem(
        objective=FromLowerLimit(objective),
        features=Features(names, feature_sizes(scene)),
        draws=draws,
        lower=Design(lower_limit, lower_band),
        upper=Design(limit0, upper_band),
        x0=Design(limit0, band0),
        cost_model=OnHalfWidth(IsoGrade() if cost_model is None else cost_model),
    )


def _sequential_continuation(problem: DesignProblem, requirement, widths, max_iterations, progress, callback=None, x0=None, trust=0.5,
                             tol=0.01):
    """`sequential_design` once per smoothing width, wide to narrow, each started from the
    last design with a smaller trust region (a wide width smooths the contact onsets that make
    a narrow width's gradients unreliable far from the optimum); one result whose history runs
    over all of them. Where the slopes are fitted over units, the optimiser is told their
    noise (`DesignProblem.gradient_noise`)."""
    results, x = [], problem.x0 if x0 is None else x0
    for k, width in enumerate(widths):
        done = sum(int(np.asarray(r.history.steps)[-1]) for r in results)  # gradients before this width
        result = sequential_design(
            problem.objective, problem.features, requirement=requirement, lower=problem.lower, upper=problem.upper,
            draws=problem.draws, x0=x, cost_model=problem.cost_model, width=width, max_iterations=max_iterations,
            trust_region=trust if k == 0 else 0.1, progress=progress, tol=tol, gradient_noise=problem.gradient_noise,
            callback=None if callback is None else (lambda i, *rest, done=done: callback(done + i, *rest)),
        )
        results.append(result)
        x = result.x
    offset = sum(len(np.asarray(r.history.cost)) for r in results[:-1])
    steps = np.cumsum([int(np.asarray(r.history.steps)[-1]) for r in results])
    history = jax.tree.map(lambda *h: jnp.concatenate(h), *[r.history for r in results])
    counts = np.concatenate([np.asarray(r.history.steps) + (steps[i - 1] if i else 0) for i, r in enumerate(results)])
    history = eqx.tree_at(lambda h: h.steps, history, jnp.asarray(counts, dtype=float))
    last = results[-1]
    return eqx.tree_at(lambda r: (r.history, r.iteration), last, (history, last.iteration + offset))


def _cheapest_accepted(costs, quantiles, requirement, tol=0.01):
    """Index of the cheapest design whose simulated quantile met `requirement` to `tol` (each
    of them, with several requirements: `quantiles` one array per design), or `None` where none
    did."""
    ok = [k for k, q in enumerate(quantiles) if np.all(np.asarray(q) <= np.asarray(requirement) * (1 + np.asarray(tol)))]
    return min(ok, key=lambda k: costs[k]) if ok else None


@exported_jit
def _objective_value(objective, x, draws, width):
    """The design objective at `x` (one program per objective structure, kept between processes
    with the compilation cache: `tolerax.cache.exported_jit`)."""
    return objective(x, draws, width)


def propose_design(
    pointing: PointingObjective,
    requirement: float,
    *,
    widths=(1e-6, 1e-7),
    max_outer: int | None = None,
    inner_steps: int = 10,
    learning_rate: float = 0.1,
    method: str = "sequential",
    progress: bool = False,
    callback=None,
    check_units: int | None = None,
    max_checks: int = 3,
    check_key=None,
    jitter: float | None = None,
    **problem,
) -> DesignReport:
    """Propose nominal clearances/backlash and tolerance bands for `pointing.scene` that meet
    `requirement` (arcsec, on `statistic` of `output` over `n_draws` manufactured units) at the
    lowest cost.

    The optimiser varies, per feature, the lower limit $l$ of the tolerance zone (the smallest
    clearance or backlash a part may have) and its half-width $b$; the zone is $[l, l + 2b]$, the
    nominal $l + b$ (`FromLowerLimit`). Only the bands cost; the lower limits may not go below
    `min_clearance`, the functional minimum (thermal growth over the orbit's temperature swing,
    the lubricant film, no jamming) — without it the optimum would be a zero-clearance nominal.

    **Arguments:**

    - `pointing`: the `PointingObjective` (scene, horizon, window); its scene's current design
      is the starting nominal.
    - `requirement`: arcsec.
    - `widths`: smoothing widths (m), wide to narrow; the proposal is judged at the last. The
      sequential method solves at each in turn from the last design; the augmented Lagrangian
      takes one value per outer iteration, the last repeated. On the design scan the wide first
      width makes the sequential method robust to its start (three starts within 0.3 %); at
      0.1 um alone it converged from a 10 um start (cost 2.463 in 6 gradients) but not from 5 or
      30 um (the contacts make the narrow objective rough far from the optimum).
    - `method`: `"sequential"` (default: `sequential_design`, the linearised problem solved
      exactly at each iterate in a trust region, once per width of `widths`, each from the last
      one's design; at most `max_outer` gradients per width, default 20; `inner_steps` and
      `learning_rate` unused) or `"augmented-lagrangian"` (`optimise_design`: Adam on the
      augmented Lagrangian, on optax, with the `widths` continuation; `max_outer` outer
      iterations, default 6, of `inner_steps` steps at `learning_rate`).
      benchmarks/results/design_comparison.md races the two, SciPy's SLSQP, a calibrated
      stack-up and derivative-free search.
    - `progress`: a progress bar over the optimiser's iterations.
    - `callback`: `method="sequential"` only: `callback(gradients, x, cost, objective)` after
      every gradient evaluation (`sequential_design`; `x.nominal` holds the lower limits).
    - `check_units`, `max_checks`, `check_key`: with a yield requirement (`yield_`), the
      proposal is checked on `check_units` fresh simulated units (default 200; 0: no check;
      `yield_check`, units from `check_key`, default `jax.random.key(1)`) and, where the linear
      model under- or over-reads their `yield_` quantile by more than 1 % of `requirement` and
      twice the check's standard error, the requirement the optimiser sees is shifted by the
      difference and the design solved again from where it was, at most `max_checks` checks
      (`method="sequential"` only).
    - `jitter` (arcsec, optional): a pointing-stability requirement beside the lost-motion one:
      the `yield_` quantile of `pointing_jitter` (the RMS of the pointing error above
      `pointing.jitter_cutoff` Hz over the window; set `PointingObjective(jitter_cutoff=...)`)
      at most `jitter`. Needs `yield_`. Both metrics are linearised by secants over
      `secant_units` units of the zone (default max(16, 2 x features + 2); jitter tangents are
      not its slopes: rattle is chaotic, benchmarks/results/stability_gradient.md), from the same
      solves (their quantiles include the fits' residual scatter, `scatter=True`, unless
      `scatter=False` is given), so at the pointing objective's fidelity: give a planetary one (lumped jitter does
      not predict the planetary stage's: issue 30 measured a correlation of -0.07 unit by
      unit). The jitter's tolerance is twice its fit's standard error at the start
      (`secant_standard_error`, at least 1 %, at most 50 %); the optimiser is told the slopes'
      noise (`DesignProblem.gradient_noise`); each check simulates both metrics on the same
      units and may shift either requirement. The report's `jitter` holds that part.
    - `**problem`: the problem's options, as `design_problem` takes them (starting band,
      functional minima, band range, manufactured units, robust statistic or `yield_`, cost
      model, gradient mode, `fixed` features).

    **Returns:** a `DesignReport`.
    """
    if method not in ("augmented-lagrangian", "sequential"):
        raise ValueError(f"propose_design: method must be 'augmented-lagrangian' or 'sequential', got {method!r}.")
    if callback is not None and method != "sequential":
        raise ValueError("propose_design: callback is supported by method='sequential' only.")
    yield_ = problem.get("yield_")
    fixed = tuple(problem.get("fixed", ()))
    check_units = (200 if yield_ is not None else 0) if check_units is None else int(check_units)
    if check_units and yield_ is None:
        raise ValueError("propose_design: check_units needs a yield requirement (yield_=...), the thing it checks.")
    if check_units and method != "sequential":
        raise ValueError("propose_design: a yield requirement's Monte Carlo check needs method='sequential' (or check_units=0).")
    if max_outer is None:
        max_outer = 20 if method == "sequential" else 6
    if jitter is not None:
        if yield_ is None or method != "sequential":
            raise ValueError("propose_design: a jitter requirement needs a yield requirement (yield_=...) and method='sequential': "
                             "the jitter is linearised by secants over units of the zone, not by tangents (rattle is chaotic).")
        if pointing.jitter_cutoff is None:
            raise ValueError("propose_design: a jitter requirement needs a pointing objective that measures it: "
                             "PointingObjective(..., jitter_cutoff=20.0) (Hz, the start of the stability band).")
        if not (math.isfinite(float(jitter)) and float(jitter) > 0):
            raise ValueError(f"propose_design: the jitter requirement must be > 0 (arcsec), got {jitter!r}.")
        problem["output"] = (problem.get("output", "pointing_rms"), "pointing_jitter")
        if problem.get("secant_units") is None:
            problem["secant_units"] = max(16, 2 * len(design_names(pointing.scene)) + 2)
        problem.setdefault("scatter", True)
    problem = design_problem(pointing, **problem)
    objective, features, draws, x0, cost_model = problem.objective, problem.features, problem.draws, problem.x0, problem.cost_model
    widths = tuple(float(w) for w in widths)
    schedule = lambda i: jnp.asarray(widths)[jnp.minimum(i, len(widths) - 1)]  # noqa: E731
    baseline_objective = np.asarray(_objective_value(objective, x0, draws, jnp.asarray(widths[-1])), dtype=float)
    checks, checked, stability, solved_for = [], [], None, None
    requirements = np.asarray([requirement] if jitter is None else [requirement, jitter], dtype=float)
    tol = np.full(requirements.shape, 0.01)
    if jitter is not None:
        # The jitter scatters about its trend from unit to unit (chaotic rattle), so its fitted
        # value moves by about its standard error from one design to the next for no other
        # reason: a tolerance below twice that makes the optimiser chase noise.
        se = secant_standard_error(objective.objective, Design(x0.nominal + x0.band, x0.band), widths[-1])
        tol[1] = min(max(0.01, 2.0 * float(se[1]) / float(jitter)), 0.5)
    as_requirement = (lambda r: float(r[0])) if jitter is None else (lambda r: tuple(float(v) for v in r))  # noqa: E731
    if method == "sequential":
        result = _sequential_continuation(problem, as_requirement(requirements), widths, max_outer, progress, callback, tol=tuple(tol))
        target = requirements.copy()
        key = jax.random.key(1) if check_key is None else check_key
        checked = []  # (result, its checks: one per requirement)
        for _ in range(max_checks if check_units else 0):
            middle = Design(result.x.nominal + result.x.band, result.x.band)
            got = yield_check(objective.objective, middle, as_requirement(requirements), check_units, key, widths[-1])
            got = got if jitter is not None else (got,)
            checked.append((result, got, target.copy()))
            corrected = requirements - np.array([c.shift for c in got])
            # a shift within the check's own noise (or the method's tolerance) is not one
            noise = np.maximum(tol * requirements, 2.0 * np.array([c.shift_se for c in got]))
            moved = np.abs(corrected - target) > noise
            if not np.all(np.isfinite(corrected)) or not np.any(moved) or len(checked) == max_checks:
                break
            target = np.where(moved, corrected, target)
            result = _sequential_continuation(problem, as_requirement(target), widths[-1:], max_outer, progress, callback, x0=result.x,
                                              trust=0.1, tol=tuple(tol))
        # The proposal: the cheapest checked design whose simulated quantile met the requirement
        # (to the method's tolerance), else the last one: a re-solve that did not land is not
        # kept over a cheaper design the simulation already accepted.
        k = _cheapest_accepted([float(r.cost) for r, _, _ in checked], [[c.quantile_simulated for c in got] for _, got, _ in checked],
                               requirements, tol)
        if k is not None:
            checked = checked[: k + 1]
            result = checked[-1][0]
        checks = [got[0] for _, got, _ in checked]
        solved_for = checked[-1][2] if checked else requirements  # the (shifted) requirements the returned design was solved for
    else:
        result = optimise_design(
            objective, features, requirement=requirement, lower=problem.lower, upper=problem.upper, draws=draws, x0=x0,
            cost_model=cost_model, optimiser=optax.adam(learning_rate), continuation=schedule,
            max_outer=max_outer, inner_steps=inner_steps, tol=1e-3, progress=progress,
        )
    band_opt = np.asarray(result.x.band)
    # The optimiser's sensitivities are to (l, b); at fixed band a nominal shift is a shift of l,
    # and at fixed nominal d/db = d/db|_l - d/dl.
    s_limit, s_band = np.asarray(result.sensitivity.nominal), np.asarray(result.sensitivity.band)
    first = (lambda v: float(np.asarray(v).reshape(-1)[0]))  # noqa: E731
    if jitter is not None:  # (method="sequential": refused otherwise)
        stability = JitterRequirement(
            requirement=float(jitter), cutoff=float(pointing.jitter_cutoff), objective=float(np.asarray(result.objective)[1]),
            constraint_active=bool(np.asarray(result.constraint_active)[1]), multiplier=float(np.asarray(result.multiplier)[1]),
            sensitivity=Design(s_limit[1], s_band[1] - s_limit[1]), baseline=float(baseline_objective[1]), tol=float(tol[1]),
            target=float(solved_for[1]), checks=tuple(got[1] for _, got, _ in checked),
        )
        s_limit, s_band = s_limit[0], s_band[0]
    return DesignReport(
        names=features.names,
        nominal=np.asarray(result.x.nominal) + band_opt,
        band=band_opt,
        grade=np.asarray(grade_of(band_opt * 2, features.size_mm)),
        feature_cost=np.asarray(result.feature_cost),
        cost=float(result.cost),
        objective=first(result.objective),
        requirement=float(requirement),
        constraint_active=bool(np.asarray(result.constraint_active).reshape(-1)[0]),
        multiplier=first(result.multiplier),
        sensitivity=Design(s_limit, s_band - s_limit),
        baseline=(np.asarray(x0.nominal + x0.band), np.asarray(x0.band), float(cost_model.total(x0.band, features.size_mm)),
                  first(baseline_objective)),
        result=result,
        yield_=yield_,
        checks=tuple(checks),
        lost_motion=np.asarray(lost_motion_weights(pointing.scene)),
        fixed=fixed,
        jitter=stability,
        solved_for=float(solved_for[0]) if method == "sequential" else None,
    )
