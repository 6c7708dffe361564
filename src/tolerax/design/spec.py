"""The tolerance-design problem as a value: what must be met, over which units, within which
zones, at what cost, and how each requirement is linearised.

`ToleranceProblem(objective, requirements, statistic, zones, cost)` is what `propose_design`
solves; how it is solved is the solver's (`tolerax.design.solvers`), how the answer is checked
the check's (`tolerax.design.check.Check`). Every part is a small frozen value with its own
defaults, so that the plain call reaches the configurations that were verified:

- the statistic: `Yield(0.99)` (the requirement met by that fraction of all units made within
  the zones) or `MeanPlusKStd(k)` over a few drawn units;
- the zones: `Zones(start, min_clearance, band_range, fixed)`: where the design starts, the
  functional minimum of each clearance, the half-widths allowed, the features whose zones are
  given;
- each requirement's **constraint model** (`Requirement(..., model=...)`): how its yield is
  linearised: `Tangents()` (forward-mode slopes at the zone middles), `Secants()` (a
  least-squares line through units of the zone, with its residual scatter: an output whose
  unit-to-unit scatter the features do not carry), `Surface()` (a response surface over a box,
  refitted where the design leaves it, as a trust region moves), or `Auto()` (the default:
  tangents, moved to secants where the tangent slopes stall or the Monte Carlo check finds
  their model off, and for an output measured at the start to scatter from unit to unit, the
  jitter of a rattling stage, the response-surface recipe that verified on the full stage).

The models of a problem's requirements are combined into one linearisation (`combine`): the
units one requirement is fitted over give every output, so where any requirement is fitted over
units, all are.
"""

import dataclasses
from typing import ClassVar
import warnings

from .requirements import SCATTERING_OUTPUTS, Requirement


@dataclasses.dataclass(frozen=True)
class Yield:
    """The requirement met by at least `level` of all units made within the zones:
    $P(\\text{output} \\le R) \\ge Y$, each requirement on its own (marginal yields). The
    quantile is read from `draws` fixed quasi-random units through the linearised model
    (`LinearisedYield`); a design's `Check` simulates fresh units against it."""

    level: float = 0.99
    draws: int = 16384

    def __post_init__(self):
        if not 0.0 < float(self.level) < 1.0:
            raise ValueError(f"Yield: level must be a fraction in (0, 1), e.g. 0.99, got {self.level!r}.")
        if int(self.draws) < 100:
            raise ValueError(f"Yield: draws must be >= 100 quasi-random units (the quantile's sample), got {self.draws!r}.")


@dataclasses.dataclass(frozen=True)
class MeanPlusKStd:
    """The requirement met by the mean + `k` standard deviations of the output over `units`
    units drawn uniformly within the zones (fixed draws from `key`, the same at every
    iteration; `robust`). `adjoint`: how the objective's gradient passes through each unit's
    simulation, a diffrax adjoint: `None` (default) or `diffrax.ForwardMode()`, one forward
    solve carrying one tangent per design feature (the cheaper for a scene's few clearances);
    `diffrax.RecursiveCheckpointAdjoint(...)`, checkpointed reverse mode (`RobustPointing`).
    No Monte Carlo check: it is not a yield. (`gradient="forward"` / `"reverse"`: deprecated,
    the same two as adjoints.)"""

    k: float = 1.0
    units: int = 4
    key: object = None
    adjoint: object = None
    gradient: str | None = None

    def __post_init__(self):
        if int(self.units) < 2:
            raise ValueError(f"MeanPlusKStd: units must be >= 2 (a standard deviation), got {self.units!r}.")
        # The former string (as `gradient=`, or in the fourth place where `adjoint` now is).
        name = self.gradient if self.gradient is not None else self.adjoint if isinstance(self.adjoint, str) else None
        if name is not None:
            adjoint = adjoint_named(name, "MeanPlusKStd")
            warnings.warn("MeanPlusKStd(gradient=...) is deprecated and goes in the next release: give adjoint=None or "
                          "diffrax.ForwardMode() (forward mode, the default) or diffrax.RecursiveCheckpointAdjoint() (reverse "
                          "mode).", DeprecationWarning, stacklevel=3)
            object.__setattr__(self, "adjoint", adjoint)
            object.__setattr__(self, "gradient", None)
        check_adjoint(self.adjoint, "MeanPlusKStd")


def adjoint_named(gradient: str, who: str):
    """The diffrax adjoint the former `gradient` string names: `"forward"` -> `None` (forward
    mode, the default), `"reverse"` -> `diffrax.RecursiveCheckpointAdjoint()`; `ValueError`
    (from `who`) for anything else. `MeanPlusKStd`, `design_problem` and the former
    `propose_design` keywords all translate through it."""
    if gradient not in ("forward", "reverse"):
        raise ValueError(f"{who}: gradient must be 'forward' or 'reverse', got {gradient!r}; better, give "
                         "adjoint=diffrax.ForwardMode() or diffrax.RecursiveCheckpointAdjoint().")
    import diffrax  # here, not at the top: the command line reads this module before JAX is wanted

    return None if gradient == "forward" else diffrax.RecursiveCheckpointAdjoint()


def check_adjoint(adjoint, who: str) -> None:
    """`TypeError` (from `who`) unless `adjoint` is `None` or a diffrax adjoint."""
    if adjoint is None:
        return
    import diffrax

    if not isinstance(adjoint, diffrax.AbstractAdjoint):
        raise TypeError(f"{who}: adjoint must be a diffrax adjoint (diffrax.ForwardMode(), "
                        f"diffrax.RecursiveCheckpointAdjoint(...)) or None, got {adjoint!r}.")


@dataclasses.dataclass(frozen=True)
class Zones:
    """The tolerance zones a design may use (lengths in m).

    - `band`: the starting half-width of every zone, about the scene's current design (unused
      where `start` is given); `start` (optional): the starting zones, a `Tolerances` with one
      for every design feature (e.g. `SceneFile.tolerances()`, a former proposal's).
    - `min_clearance`: the functional minimum of each zone's lower limit (thermal growth over
      the orbit's temperature swing, the lubricant film, no jamming), a scalar or one value per
      feature (`design_names(scene)` order); the largest lower limit is the starting one.
    - `band_range`: (smallest, largest) half-width.
    - `fixed`: features whose zone is given, not designed (a bought-in bearing, a part already
      made): names (held at their starting zone), a mapping name -> half-width, or a
      `Tolerances`.
    """

    band: float = 10e-6
    start: object = None
    min_clearance: object = 5e-6
    band_range: tuple = (1e-6, 50e-6)
    fixed: object = ()

    def options(self) -> dict:
        """`design_problem`'s keywords for these zones."""
        return dict(band=self.band, start=self.start, min_clearance=self.min_clearance, band_range=tuple(self.band_range),
                    fixed=self.fixed)


class AbstractConstraintModel:
    """How a yield requirement is linearised for the optimiser. A model is a frozen dataclass
    with `options(requirement, n_features) -> dict`: the linearisation it asks of the problem
    (`design_problem`'s secant and surface keywords; `{}`: forward-mode tangents at the zone
    middles), and `rounds` (how many response surfaces at most: 1 where it fits none or one),
    `twin` (solve again with another set of units, the noise band) and `rescue` (where tangent
    slopes stall, finish on secants); `fitted` (its outputs fitted over units: `options` then
    gives `secant_units`, `scatter`, `secant_seed`, `secant_reach` and `log_outputs`) and
    `surface` (it fits a response surface over a box: `options` gives `surface_width` too, and
    `box_for(min_clearance)` the first box). `combine` merges a problem's models by these
    attributes alone, so a model of one's own needs no edit here."""

    rounds: ClassVar[int] = 1
    twin: ClassVar[bool] = False
    rescue: ClassVar[bool] = False
    fitted: ClassVar[bool] = False
    surface: ClassVar[bool] = False

    def options(self, requirement: Requirement, n_features: int) -> dict:
        raise NotImplementedError

    def resolve(self, requirement: Requirement) -> "AbstractConstraintModel":
        """The model itself (`Auto` resolves to a concrete one per requirement)."""
        return self


@dataclasses.dataclass(frozen=True)
class Tangents(AbstractConstraintModel):
    """Forward-mode slopes at the zone middles (one solve carrying one tangent per feature),
    at the smoothing width `slope_width` (m; default the design's own). Where the slopes stall
    (the trust region collapses on a rough response), or the Monte Carlo check finds their
    linear model off by more than half the requirement (a kink or a rattle they cannot see), and
    `rescue`, the design is finished on `Secants` from there (`propose_design`'s report says
    so)."""

    slope_width: float | None = None
    rescue: bool = True

    def options(self, requirement, n_features):
        return {} if self.slope_width is None else {"slope_width": float(self.slope_width)}


@dataclasses.dataclass(frozen=True)
class Secants(AbstractConstraintModel):
    """A least-squares line through `units` units of the zone (Latin hypercube, `seed`), with
    the fit's residual scatter in the quantile (`scatter`): an output whose scatter from unit
    to unit the features do not carry (chaotic rattle). `units` default: max(16, 2 x features
    + 2). `log`: the line fitted to the output's logarithm (a scatter relative to its level);
    `reach` (m): the units span the zone's middle +- at least this much; `twin`: fit again on
    another set of units (a response surface over its last box) and solve the design again on
    that fit from where it is, against the requirements it was solved for, and report both
    costs (the noise band, `finish.twin_problem`: where they differ by more than the
    requirements' tolerances resolve, the status is noise-limited)."""

    units: int | None = None
    scatter: bool = True
    log: bool = False
    reach: float | None = None
    seed: int = 1
    twin: bool = True
    fitted: ClassVar[bool] = True

    def default_units(self, n_features: int) -> int:
        return max(16, 2 * n_features + 2)

    def options(self, requirement, n_features):
        units = self.default_units(n_features) if self.units is None else int(self.units)
        if units <= n_features:
            raise ValueError(f"{type(self).__name__}: units must exceed the {n_features} design features (a line through the "
                             f"units), got {units}.")
        return dict(secant_units=units, scatter=bool(self.scatter), secant_reach=self.reach, secant_seed=int(self.seed),
                    log_outputs=(requirement.output,) if self.log else ())


@dataclasses.dataclass(frozen=True)
class Surface(Secants):
    """A response surface: the outputs fitted once over `units` units spread over `box`
    (`(lower, upper)`, m, scalars or one per feature; default from the smallest lower limit the
    zones allow to 100 um) at smoothing `width` (m; default the design's), the design made on
    it, then up to `rounds` - 1 more surfaces, each over a box about the zones the last design
    gave, the design held inside it, until the boxes settle (a trust region that moves itself).
    Defaults: the recipe that verified the full stage's jitter design on fresh units: 64 units,
    the line on the logarithm, six rounds."""

    units: int | None = 64
    log: bool = True
    box: tuple | None = None
    width: float | None = None
    rounds: int = 6
    surface: ClassVar[bool] = True

    def __post_init__(self):
        if int(self.rounds) < 1:
            raise ValueError(f"Surface: rounds must be >= 1 (1: one response surface over box), got {self.rounds!r}.")

    def options(self, requirement, n_features):
        return super().options(requirement, n_features) | dict(surface_width=self.width)

    def box_for(self, min_clearance) -> tuple:
        """The first surface's box (m): `box`, else [the smallest lower limit allowed, 100 um]."""
        if self.box is not None:
            return tuple(self.box)
        low = min(float(v) for v in (min_clearance if hasattr(min_clearance, "__len__") else [min_clearance]))
        return (max(low, 1e-6), 100e-6)


# Auto(): above this share of an output's variance over the starting zones off a line in the features, a response
# surface (how it was set, on which scenes: benchmarks/auto_model.py).
SCATTER_SHARE = 0.45


@dataclasses.dataclass(frozen=True)
class Auto(AbstractConstraintModel):
    """The default: cheap first, moved on where a measurement says so. Before the design,
    `propose_design` measures, over units drawn within the starting zones (`probe.PROBE_UNITS`,
    one Monte Carlo run giving every output), the share of each output's variance that a line
    in the features does not carry (`tolerax.design.probe.scatter_share`: one minus the fit's
    adjusted $R^2$) and keeps it here (`share`). Where it exceeds `SCATTER_SHARE` the output
    scatters from unit to unit for reasons the features do not carry (the chaotic rattle's
    jitter), so a tangent at the zone's middle and a line through the zone's own units read
    noise: the `Surface` recipe. Else `Tangents`, finished on `Secants` where their slopes stall
    or the check finds their model off. A design fitted over units that is noise-limited (two
    sets of units disagree on it by more than the requirements' tolerances resolve) is made
    again on twice the units, up to 128 (`propose.AUTO_MAX_UNITS`).

    `units` (optional): fit over K units, whichever fit the measurement picks: a scattering
    output's response surface on K units (default: `Surface`'s), any other output's line through
    K units of the zone (`Secants(units=K, scatter=False, twin=False)`: its scatter is small by
    the measurement), where without `units` it takes tangents. `Auto(units=128)` is the same
    recipe on more units, what a noise-limited answer asks for (`propose_design` moves only the
    requirements already fitted over units); `tolerax design --secant-units K` with no `--model`
    gives every requirement `Auto(units=K)`. Where a surface is fitted, its units' solves give
    every output, so the problem's other outputs are fitted on the surface too (`combine`).
    `share` (a fraction; default `None`, measured by `propose_design`):
    given, it is not measured again; where nothing is measured, because nothing could follow
    from it (a `MeanPlusKStd` problem fits nothing over units, a solver on tangents alone takes
    no surface, a life's drawn wear rate fits every output over units anyway), the outputs in
    `SCATTERING_OUTPUTS`, the jitter, count as scattering."""

    units: int | None = None
    share: float | None = None

    def __post_init__(self):
        if self.units is not None and int(self.units) < 2:
            raise ValueError(f"Auto: units must be >= 2 (the response surface's units), got {self.units!r}.")
        if self.share is not None and not 0.0 <= float(self.share) <= 1.0:
            raise ValueError(f"Auto: share is a fraction of the output's variance, in [0, 1], got {self.share!r}.")

    @property
    def scattering_measured(self) -> bool | None:
        """Whether the measured share says the output scatters (`None`: not measured)."""
        return None if self.share is None else float(self.share) > SCATTER_SHARE

    def resolve(self, requirement):
        scattering = self.scattering_measured
        if not (requirement.output in SCATTERING_OUTPUTS if scattering is None else scattering):
            return Tangents() if self.units is None else Secants(units=int(self.units), scatter=False, twin=False)
        return Surface() if self.units is None else Surface(units=int(self.units))

    def options(self, requirement, n_features):
        return self.resolve(requirement).options(requirement, n_features)


@dataclasses.dataclass(frozen=True)
class Combined:
    """A problem's requirements' models merged (`combine`): `options` for `design_problem`,
    `surface` (the `Surface` whose box, width and rounds apply, or `None`), `twin`, `rescue`,
    `secants` (whether the outputs are fitted over units)."""

    options: dict
    surface: Surface | None
    twin: bool
    rescue: bool
    secants: bool


def combine(requirements, n_features: int, min_clearance) -> Combined:
    """One linearisation for all `requirements` (each with its resolved `model`): fitted over
    units where any is (the same solves give every output: the most units any asks for, the
    log fit per output, a scatter where any keeps it), on a response surface where any asks for
    one; tangents (with their slope width) where none does."""
    models = [r.model.resolve(r) for r in requirements]
    fitted = [(r, m) for r, m in zip(requirements, models) if m.fitted]
    if not fitted:
        options = {}
        for r, m in zip(requirements, models):
            options |= m.options(r, n_features)
        return Combined(options, None, False, any(m.rescue for m in models), False)
    parts = [m.options(r, n_features) for r, m in fitted]
    surfaces = [m for _, m in fitted if m.surface]
    options = dict(secant_units=max(p["secant_units"] for p in parts), scatter=any(p["scatter"] for p in parts),
                   secant_seed=parts[0]["secant_seed"], log_outputs=tuple(o for p in parts for o in p["log_outputs"]))
    reaches = [p["secant_reach"] for p in parts if p["secant_reach"] is not None]
    options["secant_reach"] = max(reaches) if reaches else None
    surface = None
    if surfaces:
        surface = surfaces[0]
        options |= dict(surface_box=surface.box_for(min_clearance), surface_width=surface.width)
    return Combined(options, surface, any(m.twin for _, m in fitted), False, True)


def with_model(requirement: Requirement) -> Requirement:
    """`requirement` with its constraint model: its own, else the one its older flags name
    (`secants=True`, `log_fit`: `Secants`), else `Auto()`."""
    if requirement.model is not None:
        return requirement
    model = Secants(log=bool(requirement.log_fit)) if requirement.secants and requirement.output not in SCATTERING_OUTPUTS \
        else Auto()
    return dataclasses.replace(requirement, model=model)


@dataclasses.dataclass(frozen=True)
class ToleranceProblem:
    """What `propose_design` solves: the cheapest tolerance zones on `objective`'s design
    features whose outputs meet `requirements` at `statistic`, within `zones`, at `cost`.

    - `objective`: a `PointingObjective` (scene, horizon, window: `SceneFile.objective()`), or
      any `AbstractObjective` (a closed-form model of the outputs).
    - `requirements`: a number (the RMS pointing error's limit, arcsec), a `Requirement` or a
      sequence of them; each carries its constraint model (`Requirement(model=...)`, default
      `Auto()`).
    - `statistic`: `Yield(level)` (default `Yield(0.99)`) or `MeanPlusKStd(k)`.
    - `zones`: `Zones(...)`: start, functional minima, half-width range, fixed features.
    - `cost`: a cost model of the zone widths (`AbstractCostModel`; default `IsoGrade()`: ISO
      286 grades, relative cost 1 per feature at IT7).
    - `allow_proxy`: design an output on joints that do not read it as the full stage does (a
      jitter on a lumped joint: `tolerax.design.fidelity`) instead of refusing; the report
      says so.
    """

    objective: object
    requirements: object = 900.0
    statistic: Yield | MeanPlusKStd = Yield()
    zones: Zones = Zones()
    cost: object = None
    allow_proxy: bool = False

    def __post_init__(self):
        if not isinstance(self.statistic, (Yield, MeanPlusKStd)):
            raise TypeError(f"ToleranceProblem: statistic must be Yield(level) or MeanPlusKStd(k), got {self.statistic!r}.")
        if not isinstance(self.zones, Zones):
            raise TypeError(f"ToleranceProblem: zones must be a Zones(...), got {self.zones!r}.")

    @property
    def yield_(self) -> float | None:
        return float(self.statistic.level) if isinstance(self.statistic, Yield) else None

    def statistic_options(self) -> dict:
        """`design_problem`'s keywords for the statistic."""
        s = self.statistic
        if isinstance(s, Yield):
            return dict(yield_=float(s.level), n_yield_draws=int(s.draws))
        return dict(statistic="mean+kstd", k=float(s.k), n_draws=int(s.units), key=s.key, adjoint=s.adjoint)
