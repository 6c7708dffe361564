"""The tolerance-design problem on a scene: its design variables (the lower limit and half-width
of each feature's tolerance zone), their bounds, the objective over manufactured units and the
cost model (`DesignProblem`, built by `design_problem`)."""

import dataclasses
from collections.abc import Mapping
import math
import warnings

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from .cost import AbstractCostModel, IsoGrade
from .features import design_names, design_of, feature_entries
from .objectives import AbstractObjective, unit_output, value_and_jacobian
from .spec import adjoint_named, check_adjoint
from .subproblem import objective_value
from .reliability import LinearisedYield, secant_draws, yield_draws
from .surface import fit_surface, secant_gradient_noise
from .types import Design, Features, realise, robust
from ..mechanism.joints import LumpedJoint
from ..uncertainty.sampling import Tolerances, unit_draws


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


def feature_pressure_angles(scene) -> np.ndarray:
    """Pressure angle (rad) of each design feature's mesh: the sun mesh's for a sun backlash, the
    ring mesh's for a ring backlash, the sun mesh's for a clearance (not read there)."""
    return np.asarray([float(stage.ring_pressure_angle if feature == "ring_backlash" else stage.sun_pressure_angle)
                       for _, feature, stage, _ in feature_entries(scene)])


class OnHalfWidth(AbstractCostModel):
    """A cost model of the full tolerance width $2b$ (as ISO 286 tabulates it) applied to the
    design's half-width `band` $b$ (nominal $\\pm b$)."""

    model: AbstractCostModel

    def __call__(self, band, size_mm):
        return self.model(2.0 * band, size_mm)

    @property
    def unit(self) -> str:
        return self.model.unit

    @property
    def grade_range(self):
        return self.model.grade_range


@eqx.filter_custom_vjp
def _unit_output_forward(values, pointing, output, width):
    """`unit_output`, whose reverse-mode derivative is computed in forward mode: the backward
    pass of a simulation needs the whole trajectory (checkpointed and recomputed), while a
    handful of tangents carried along the forward solve (`diffrax.ForwardMode`) cost less for
    the few clearances of a scene. The Jacobian over
    the unit's design vector is formed on the forward pass and kept for the backward one."""
    return unit_output(values, pointing, output, width)


@_unit_output_forward.def_fwd
def _unit_output_forward_fwd(perturbed, values, pointing, output, width):
    return value_and_jacobian(values, pointing, output, width)


@_unit_output_forward.def_bwd
def _unit_output_forward_bwd(jac, cotangent, perturbed, values, pointing, output, width):
    return jnp.tensordot(cotangent, jac, axes=jnp.ndim(cotangent))  # one output, or a tuple of them


class RobustPointing(eqx.Module):
    """`objective(x, draws, width)`: a robust statistic (`robust`, arcsec) of one output of a
    `PointingObjective` over the manufactured units `realise(x, draws)`, at smoothing width
    `width` (m). A failed solve makes the objective NaN (the optimiser then stops with an error
    naming the iteration) rather than a silently wrong number.

    `adjoint`: how `jax.grad` of the objective passes through each unit's simulation: `None`
    (default) or `diffrax.ForwardMode()`, one forward solve carrying one tangent per design
    feature, then the chain rule through `realise` (the objective then supports reverse-mode
    `jax.grad`/`vjp` but not `jax.jvp`); any other diffrax adjoint
    (`diffrax.RecursiveCheckpointAdjoint(...)`: checkpointed reverse mode) is handed to the
    pointing objective's solves. `benchmarks/gradient_methods.py` compares the two."""

    pointing: AbstractObjective
    output: str = eqx.field(static=True, default="pointing_rms")
    statistic: str = eqx.field(static=True, default="mean+kstd")
    k: float = eqx.field(static=True, default=1.0)
    adjoint: object = eqx.field(static=True, default=None)

    def __check_init__(self):
        check_adjoint(self.adjoint, "RobustPointing")

    def __call__(self, x: Design, draws, width) -> Array:
        if self.adjoint is None or isinstance(self.adjoint, diffrax.ForwardMode):
            unit, pointing = _unit_output_forward, self.pointing
        else:
            unit, pointing = unit_output, self.pointing.with_adjoint(self.adjoint)
        value = jax.vmap(lambda v: unit(v, pointing, self.output, width))(realise(x, draws))
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
class DesignProblem:
    """The tolerance-design problem `propose_design` solves, for other optimisers to solve too
    (benchmarks/design_comparison.py): minimise `cost_model.total(x.band, features.size_mm)`
    subject to `objective(x, draws, width) <= requirement` over `lower <= x <= upper`, with
    `x = Design(lower limit, band)` (m; `FromLowerLimit`), starting from `x0`; where
    `zone_upper` (n,) (m) is given, each zone's upper edge `l + 2 b` at most that too (the box
    a response surface was fitted over: `propose_design(surface_rounds=...)`)."""

    objective: FromLowerLimit
    features: Features
    draws: Array
    lower: Design
    upper: Design
    x0: Design
    cost_model: AbstractCostModel
    zone_upper: np.ndarray | None = None

    def value(self, x: Design | None = None, width: float = 1e-7) -> Array:
        """The objective at `x` (`Design(lower limit, band)`, m; default `x0`) and smoothing
        `width` (m; default `propose_design`'s last width): the value part of the program the
        optimiser differentiates, so that asking for a baseline before a design compiles nothing
        the design does not use. One value per requirement (an array of them for several)."""
        return objective_value(self.objective, self.x0 if x is None else x, self.draws, width)

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

    def refit_surface(self, lower, upper, width=None) -> "DesignProblem":
        """This problem on its outputs' response surface fitted again over the box `lower` <= v
        <= `upper` (m, one value per feature; `fit_surface` with the objective's secant units,
        at smoothing `width`, m): one batch of forward solves."""
        inner = self.objective.objective
        if not isinstance(inner, LinearisedYield) or inner.secant_units is None:
            raise ValueError("DesignProblem.refit_surface: the objective fits no secants (design_problem(secant_units=...)).")
        inner = eqx.tree_at(lambda o: o.surface, inner, fit_surface(inner, lower, upper, width), is_leaf=lambda v: v is None)
        return dataclasses.replace(self, objective=FromLowerLimit(inner))


def design_problem(
    pointing: AbstractObjective,
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
    adjoint=None,
    yield_: float | None = None,
    n_yield_draws: int = 16384,
    slope_width: float | None = None,
    secant_units: int | None = None,
    scatter: bool = False,
    fixed=(),
    secant_seed: int = 1,
    start: Tolerances | None = None,
    log_outputs: tuple[str, ...] = (),
    secant_reach: float | None = None,
    surface_box: tuple | None = None,
    surface_width: float | None = None,
    gradient: str | None = None,
) -> DesignProblem:
    """The `DesignProblem` that `propose_design` solves.

    **Arguments:**

    - `pointing`: the `PointingObjective` (scene, horizon, window), or any `AbstractObjective`;
      its scene's current design is the starting nominal.
    - `band`: starting tolerance half-width (m) of every feature; the starting lower limit is
      the current nominal minus `band` (at least `min_clearance`).
    - `start` (optional): the starting zones instead, a `Tolerances` with a zone for every
      design feature (`design_names(scene)`; e.g. `SceneFile.tolerances()`, a former
      proposal's `DesignReport.tolerances`): each feature starts at its nominal and band
      (`band` unused).
    - `min_clearance`: smallest allowed lower limit (m), a scalar or one value per feature
      (`design_names(scene)` order). The largest allowed is the starting one.
    - `band_range`: (smallest, largest) half-width (m).
    - `n_draws`, `key`: fixed standardised draws (`unit_draws`), the same at every iteration.
    - `statistic`, `k`: `robust` statistic (`"mean+kstd"` with `k`, or `"quantile"`) of
      `output` over the draws.
    - `cost_model`: a cost of the full tolerance width $2b$; default `IsoGrade()` (ISO 286
      grades, relative cost 1 per feature at IT7).
    - `adjoint`: how the gradient passes through each simulation, a diffrax adjoint: `None`
      (default, forward mode) or `diffrax.RecursiveCheckpointAdjoint()` (reverse mode;
      `RobustPointing`); `gradient="forward"|"reverse"`: the same, deprecated.
    - `yield_`: a yield $Y$ in (0, 1) makes the objective the $Y$-quantile of `output` over all
      units made within the bands, linearised at the zone middles (`LinearisedYield`: one
      simulation with one forward-mode tangent per feature; `n_draws`, `key`, `statistic`, `k`
      and `adjoint` unused), so that objective $\\le R$ reads $P(\\text{output} \\le R) \\ge Y$;
      `n_yield_draws` fixed quasi-random draws (`yield_draws`) carry the quantile;
      `slope_width` (m, optional): take the slopes at this smoothing width (`LinearisedYield`:
      at a narrow width forward-mode tangents through the contacts can be spiky); default at
      the objective's own width (where the value is rough too, wider slopes may not make the
      design converge: secants, below, fit a line through that roughness). `secant_units` (optional, more than the features): fit the value and
      slopes by least squares over this many units of the zone instead (`LinearisedYield`:
      forward solves only; where tangents are noise, a line through the units is not);
      `scatter` (with `secant_units`): the quantile includes the fit's residual scatter
      (`LinearisedYield(scatter=True)`: a chaotic metric such as the jitter); `secant_seed`:
      which set of secant units (`LinearisedYield.secant_seed`; handed to it as positions,
      `secant_positions`, so that two seeds run one compiled program); `log_outputs` (with
      `secant_units`): outputs whose line is fitted to their logarithm, a scatter relative to
      their level (`LinearisedYield.log_outputs`: the jitter); `secant_reach` (m, with
      `secant_units`): the secant units span the middle +- at least this much
      (`LinearisedYield.secant_reach`: a trend resolved over a wider neighbourhood than a tight zone);
      `surface_box` (`(lower, upper)`, m, scalars or one per feature; with `secant_units`): fit
      the outputs once over units spread over that box (`fit_surface`, at smoothing
      `surface_width`, m) and design on that response surface (`LinearisedYield.surface`).
    - A pointing objective whose units draw uncertain inputs (`PointingObjective.uncertain_inputs`:
      a life with a wear-rate `spread`) needs `yield_`, `secant_units` and `scatter`: the
      secant units draw them, the line carries them and the quantile draws them
      (`LinearisedYield`; `draws` get one more column each).
    - `fixed`: features whose tolerance zone is given, not designed (a bought-in bearing, a
      part already made): names, held at their starting zone (nominal +- `band`, or `start`'s),
      a mapping name -> its half-width (m), held at the starting nominal +- that, or a
      `Tolerances` (held at its zones). Their lower limit and band are bounded to those values
      (their cost is counted, constant).
    """
    if gradient is not None:  # the former string, for one release
        adjoint = adjoint_named(gradient, "design_problem")
        warnings.warn("design_problem(gradient=...) is deprecated and goes in the next release: give adjoint=None (forward "
                      "mode) or diffrax.RecursiveCheckpointAdjoint() (reverse mode).", DeprecationWarning, stacklevel=2)
    scene = pointing.scene
    uncertain = getattr(pointing, "uncertain_inputs", ())
    if uncertain and not (yield_ is not None and secant_units is not None and scatter):
        raise ValueError(
            f"propose_design: each unit of this pointing objective draws {', '.join(uncertain)} (a life's spread: the wear rate "
            "varies from unit to unit); a design over it needs a yield requirement (yield_=...) linearised by secants over units "
            "that draw it, with their residual scatter (secant_units=..., scatter=True): a tangent at the zone's middle cannot "
            "carry it. propose_design sets them for every requirement; design_problem needs them given.")
    if uncertain and secant_units <= len(design_names(scene)) + len(uncertain):
        raise ValueError(f"propose_design: secant_units must exceed the {len(design_names(scene))} design features plus the "
                         f"{len(uncertain)} input(s) each unit draws ({', '.join(uncertain)}): a line through the units needs "
                         f"at least {len(design_names(scene)) + len(uncertain) + 1}; got {secant_units}.")
    names = design_names(scene)
    nominal0 = np.asarray(design_of(scene))
    lumped = [joint for joint, stage_of, _ in scene.named_stages()
              if stage_of(scene).distinct_planets and isinstance(getattr(scene, joint, None), LumpedJoint)]
    if lumped:
        warnings.warn(
            f"design_problem: the lumped joint(s) {', '.join(lumped)} have per-planet features (distinct_planets), but a lumped "
            "joint keeps only the tightest planet's lost motion: a design there tightens one planet and leaves the others wide, "
            "which the planetary stage does not bear out (its verified yield falls far below the one designed for). "
            "Design per-planet features at planetary fidelity.", stacklevel=2)
    n = len(names)
    min_clearance = np.broadcast_to(np.asarray(min_clearance, dtype=float), (n,))
    if not (np.all(np.isfinite(min_clearance)) and np.all(min_clearance >= 0)):
        raise ValueError(f"propose_design: min_clearance must be finite and >= 0 (m), got {min_clearance}.")
    band_lo, band_hi = (float(v) for v in band_range)
    if start is None:
        band0 = np.full(n, float(band))
    else:
        zones = start.of(names)
        nominal0, band0 = np.array(zones.nominal, dtype=float), np.array(zones.band, dtype=float)  # copies: written below
    if isinstance(fixed, Tolerances):
        given = {name: (float(m), float(b)) for name, m, b in zip(fixed.names, fixed.nominal, fixed.band)}
    elif isinstance(fixed, Mapping):
        given = {name: (None, half) for name, half in fixed.items()}
    else:
        given = {name: (None, None) for name in fixed}
    designed = [j for j, name in enumerate(names) if name not in given]
    bad = {names[j]: float(band0[j]) for j in designed if not (0 < band_lo <= band0[j] <= band_hi)}
    if (bad or not np.isfinite(band_hi)) and start is None:
        raise ValueError(
            f"propose_design: need 0 < band_range[0] <= band <= band_range[1] (m), got band={band!r}, band_range={band_range!r}."
        )
    if bad or not np.isfinite(band_hi):
        raise ValueError(f"propose_design: the starting half-widths {bad} (m) are outside band_range={band_range!r}: start inside "
                         "it, widen it, or give those features as fixed.")
    key = jax.random.key(0) if key is None else key
    limit0 = np.maximum(nominal0 - band0, min_clearance)
    lower_limit, lower_band, upper_band = min_clearance.copy(), np.full(n, band_lo), np.full(n, band_hi)
    for name, (middle, half) in given.items():
        if name not in names:
            raise ValueError(f"propose_design: fixed feature {name!r} is not a design feature of this scene; its features: {', '.join(names)}.")
        j = names.index(name)  # not `k`: that is the robust statistic's
        half = float(band0[j]) if half is None else float(half)
        middle = float(nominal0[j]) if middle is None else middle
        if not (np.isfinite(half) and half > 0):  # a zero band would cost infinitely much (ISO 286)
            raise ValueError(f"propose_design: the fixed feature {name!r} needs a finite half-width > 0 (m), got {half!r}.")
        limit0[j] = lower_limit[j] = max(middle - half, 0.0)
        lower_band[j] = upper_band[j] = band0[j] = half
    if yield_ is None:
        objective, draws = RobustPointing(pointing, output, statistic, k, adjoint), unit_draws(key, n_draws, n)
    else:
        # The secant units' positions as values (from `secant_seed`), not as a static seed: the
        # noise band's twin design (`secant_seed` + 1) runs the same compiled programs.
        positions = None if secant_units is None else secant_draws(n + len(uncertain), int(secant_units), int(secant_seed))
        objective = LinearisedYield(pointing, output, float(yield_), None if slope_width is None else float(slope_width),
                                    None if secant_units is None else int(secant_units), bool(scatter), None,
                                    tuple(log_outputs), None if secant_reach is None else float(secant_reach),
                                    secant_positions=positions)
        if surface_box is not None:
            objective = eqx.tree_at(lambda o: o.surface, objective, fit_surface(objective, *surface_box, surface_width),
                                    is_leaf=lambda v: v is None)
        # The features' columns, then the scatter's, then each drawn input's (a wear rate: LinearisedYield).
        draws = yield_draws(n + (1 if scatter else 0) + len(uncertain), n_yield_draws)
    return DesignProblem(
        objective=FromLowerLimit(objective),
        features=Features(names, feature_sizes(scene), feature_pressure_angles(scene)),
        draws=draws,
        lower=Design(lower_limit, lower_band),
        upper=Design(limit0, upper_band),
        x0=Design(limit0, band0),
        cost_model=OnHalfWidth(IsoGrade() if cost_model is None else cost_model),
    )
