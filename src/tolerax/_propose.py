"""Tolerance proposals on a scene: the cheapest nominal clearances/backlash and tolerance bands
whose robust pointing error meets a requirement.

`propose_design` ties together the scene's design vector (`_design`), a `PointingObjective`,
fixed manufacturing draws (`_sampling.unit_draws`), the ISO 286-anchored cost model (`_cost`)
and the augmented-Lagrangian optimiser on optax (`_optimise`), and returns a `DesignReport`.
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optax
from jaxtyping import Array

from ._cost import AbstractCostModel, IsoGrade, grade_of
from ._design import design_names, design_of
from ._objectives import UNITS, PointingObjective
from ._optimise import Design, Features, OptimisationResult, optimise_design, realise, robust
from ._sampling import unit_draws


def feature_sizes(scene) -> np.ndarray:
    """Nominal size (mm) of each design feature for the cost model: the journal diameter of a
    bearing clearance, the pitch diameter of the gear whose mesh has the backlash (sun or ring)."""
    sizes = []
    for name in design_names(scene):
        joint, _, feature = name.rpartition(".")
        stage = getattr(scene, joint).stage if joint else scene.stage
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


class RobustPointing(eqx.Module):
    """`objective(x, draws, width)`: a robust statistic (`robust`, arcsec) of one output of a
    `PointingObjective` over the manufactured units `realise(x, draws)`, at smoothing width
    `width` (m). A failed solve makes the objective NaN (the optimiser then stops with an error
    naming the iteration) rather than a silently wrong number."""

    pointing: PointingObjective
    output: str = eqx.field(static=True, default="pointing_rms")
    statistic: str = eqx.field(static=True, default="mean+kstd")
    k: float = eqx.field(static=True, default=1.0)

    def __call__(self, x: Design, draws, width) -> Array:
        outputs = jax.vmap(lambda v: self.pointing(v, width))(realise(x, draws))
        value = jnp.where(outputs["success"], outputs[self.output], jnp.nan)
        return robust(value, kind=self.statistic, k=self.k)


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
    - `result`: the full `OptimisationResult` (history included).
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

    def table(self) -> str:
        """A Markdown table of the proposal, one row per feature."""
        rows = ["| feature | nominal (µm) | band ± (µm) | ISO grade | cost | d obj / d nominal (arcsec/µm) |", "|---|---|---|---|---|---|"]
        for k, name in enumerate(self.names):
            rows.append(
                f"| {name} | {self.nominal[k] * 1e6:.1f} | {self.band[k] * 1e6:.1f} | IT{self.grade[k]:.1f} | "
                f"{self.feature_cost[k]:.3g} | {float(self.sensitivity.nominal[k]) * 1e-6:.3g} |"
            )
        head = (
            f"Proposed design: cost {self.cost:.4g} (baseline {self.baseline[2]:.4g}); objective "
            f"{self.objective:.1f} arcsec against a requirement of {self.requirement:.1f} arcsec "
            f"(baseline {self.baseline[3]:.1f}); constraint {'active' if self.constraint_active else 'inactive'}."
        )
        return head + "\n\n" + "\n".join(rows)

    def plot(self):
        """History (cost, objective) and sensitivities; returns the matplotlib figure."""
        import matplotlib.pyplot as plt

        hist = self.result.history
        fig, axes = plt.subplots(1, 2, figsize=(10, 3.5))
        it = np.arange(1, len(np.asarray(hist.cost)) + 1)
        axes[0].plot(it, np.asarray(hist.cost), "o-", label="cost")
        ax2 = axes[0].twinx()
        ax2.plot(it, np.asarray(hist.objective), "s--", color="C1", label="objective (arcsec)")
        ax2.axhline(self.requirement, color="C1", lw=0.8, ls=":")
        axes[0].set_xlabel("outer iteration")
        axes[0].set_ylabel("cost (model units)")
        ax2.set_ylabel(f"robust pointing error ({UNITS['pointing_rms']})")
        y = np.arange(len(self.names))
        axes[1].barh(y, np.asarray(self.sensitivity.nominal) * 1e-6)
        axes[1].set_yticks(y, self.names, fontsize=7)
        axes[1].set_xlabel("d objective / d nominal (arcsec/µm)")
        fig.tight_layout()
        return fig


def propose_design(
    pointing: PointingObjective,
    requirement: float,
    *,
    band: float = 10e-6,
    lower: Design | None = None,
    upper: Design | None = None,
    n_draws: int = 4,
    key=None,
    statistic: str = "mean+kstd",
    k: float = 1.0,
    output: str = "pointing_rms",
    widths=(1e-6, 1e-7),
    cost_model: AbstractCostModel | None = None,
    max_outer: int = 6,
    inner_steps: int = 10,
    learning_rate: float = 0.1,
) -> DesignReport:
    """Propose nominal clearances/backlash and tolerance bands for `pointing.scene` that meet
    `requirement` (arcsec, on `statistic` of `output` over `n_draws` manufactured units) at the
    lowest cost.

    **Arguments:**

    - `pointing`: the `PointingObjective` (scene, horizon, window); its scene's current design
      is the starting nominal.
    - `requirement`: arcsec.
    - `band`: starting tolerance half-width (m) of every feature.
    - `lower`, `upper`: bounds (`Design`, m); default nominal in [1 µm, current], band in
      [1 µm, 50 µm].
    - `n_draws`, `key`: fixed standardised draws (`unit_draws`), the same at every iteration.
    - `statistic`, `k`: `robust` statistic (`"mean+kstd"` with `k`, or `"quantile"`).
    - `widths`: smoothing-width continuation (m), one value per outer iteration, the last
      repeated: wide first (a smoother, less chaotic objective), narrower later.
    - `cost_model`: a cost of the full tolerance width $2b$; default `IsoGrade()` (ISO 286
      grades, relative cost 1 per feature at IT7).
    - `max_outer`, `inner_steps`, `learning_rate`: optimiser budget (each inner step is one
      gradient of the objective over all draws: a simulation each, reverse mode).

    **Returns:** a `DesignReport`.
    """
    scene = pointing.scene
    names = design_names(scene)
    nominal0 = np.asarray(design_of(scene))
    n = len(names)
    key = jax.random.key(0) if key is None else key
    draws = unit_draws(key, n_draws, n)
    features = Features(names, feature_sizes(scene))
    if lower is None:
        lower = Design(np.full(n, 1e-6), np.full(n, 1e-6))
    if upper is None:
        upper = Design(np.maximum(nominal0, 1e-6), np.full(n, 50e-6))
    x0 = Design(np.clip(nominal0, lower.nominal, upper.nominal), np.clip(np.full(n, band), lower.band, upper.band))
    objective = RobustPointing(pointing, output, statistic, k)
    widths = tuple(float(w) for w in widths)
    schedule = lambda i: jnp.asarray(widths)[jnp.minimum(i, len(widths) - 1)]  # noqa: E731
    cost_model = OnHalfWidth(IsoGrade() if cost_model is None else cost_model)
    baseline_objective = float(eqx.filter_jit(objective)(x0, draws, widths[-1]))
    result = optimise_design(
        objective, features, requirement=requirement, lower=lower, upper=upper, draws=draws, x0=x0,
        cost_model=cost_model, optimiser=optax.adam(learning_rate), continuation=schedule,
        max_outer=max_outer, inner_steps=inner_steps, tol=1e-3,
    )
    band_opt = np.asarray(result.x.band)
    return DesignReport(
        names=names,
        nominal=np.asarray(result.x.nominal),
        band=band_opt,
        grade=np.asarray(grade_of(band_opt * 2, features.size_mm)),
        feature_cost=np.asarray(result.feature_cost),
        cost=float(result.cost),
        objective=float(result.objective),
        requirement=float(requirement),
        constraint_active=bool(result.constraint_active),
        multiplier=float(result.multiplier),
        sensitivity=result.sensitivity,
        baseline=(nominal0, np.asarray(x0.band), float(cost_model.total(x0.band, features.size_mm)), baseline_objective),
        result=result,
    )
