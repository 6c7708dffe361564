"""Differentiable objectives on a scene: pointing-error statistics as functions of its design
vector (`tolerax.design.features`). One `PointingObjective` serves the gradient checks, the tolerance optimiser
(`propose_design`) and the Monte Carlo engine (`monte_carlo`: a picklable model returning
scalar outputs and a `success` flag).
"""

import abc
import dataclasses
import warnings
from typing import ClassVar

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float
from .features import design_names, with_design
from .life import WEAR_FACTOR, MissionLife, window_wear_rates, worn_joints, worn_scene
from ..mechanism.outputs import check_jitter_sampling, pointing_metrics
from ..mechanism.scene import simulate
from ..solve import Integrator, refined

OBJECTIVE_INTEGRATOR = Integrator(max_steps=400_000)  # a design's units: `simulate`'s settings, a tenth of its step budget
_UNSET = object()  # a run setting not given to `PointingObjective`
EOL = "_eol"
"""The suffix of an output's end-of-life twin (`PointingObjective(life=...)`)."""
OUTPUTS = ("pointing_rms", "pointing_peak", "pointing_smooth_peak", "tracking_speed_rms", "pointing_jitter")
UNITS = {
    "pointing_rms": "arcsec", "pointing_peak": "arcsec", "pointing_smooth_peak": "arcsec", "tracking_speed_rms": "arcsec/s",
    "pointing_jitter": "arcsec",
}


class AbstractMetric(eqx.Module):
    """A scalar output of a run that a `PointingObjective` adds to its own by name, so that a
    `Requirement` can be put on it (a new kind of requirement is one such class).

    Write a final subclass with a class attribute `name` (the output's name, str) and optionally
    `unit` (default "arcsec"), and `__call__(result, times, window) -> scalar`: `result` the
    scene's result (e.g. `MechanismResult`: `pointing_error` in rad per save), `times` the save
    times (s, NumPy: decide masks in Python) and `window` (NumPy bool per save) the objective's
    window $t \\ge$ `settle`. Differentiable in the result for tangents; a yield linearised by
    secants (`Requirement(model=Secants())`) needs only its values.
    """

    name: ClassVar[str]
    unit: ClassVar[str] = "arcsec"

    @abc.abstractmethod
    def __call__(self, result, times: np.ndarray, window: np.ndarray) -> Array:
        raise NotImplementedError


class AbstractObjective(eqx.Module):
    """What the design and Monte Carlo layers ask of a model of one manufactured unit: its
    outputs as a function of the unit's design values, on the design features of `scene`.

    `PointingObjective` is the one that simulates. Another is a closed-form model of the same
    outputs: a calibrated stack-up, a response surface fitted to a test campaign, or a test's
    known function that exercises the design's orchestration (checks, re-solves, rounds) without
    a simulation. `propose_design`, `design_problem`, `LinearisedYield`, `yield_check` and
    `monte_carlo` take any of them.

    Write a final subclass with:

    - `scene`: the scene whose design features the values are (`design_names(scene)` order,
      m): it supplies the features' names, starting values, sizes for the cost model and the
      joints' fidelities. Building a scene runs nothing.
    - `outputs` (property): the names of the scalar outputs; `units` (property, optional):
      output -> unit (default arcsec).
    - `__call__(values, smoothing_width=None) -> dict`: each output (a scalar array) and
      `success` (bool array: a failed unit's numbers are never used), differentiable in
      `values` where the design uses tangents (`jax.jacfwd`).
    - Optionally `uncertain_inputs` and `uncertain_box()` (inputs a unit draws after its design
      values, e.g. a wear-rate factor; default none), `jitter_cutoff` (Hz, where
      `pointing_jitter` is an output) and `forward_mode()` (this objective set up for forward-mode
      derivatives; default itself).
    """

    scene: eqx.AbstractVar[eqx.Module]

    @property
    @abc.abstractmethod
    def outputs(self) -> tuple[str, ...]:
        """The scalar outputs this objective computes."""

    @property
    def units(self) -> dict[str, str]:
        """The unit of each output (default arcsec)."""
        return {name: UNITS.get(name, "arcsec") for name in self.outputs}

    @abc.abstractmethod
    def __call__(self, values: Float[Array, " n_features"], smoothing_width=None) -> dict[str, Array]:
        """The outputs and `success` of the unit with design `values` (m), at `smoothing_width`
        (m, the contacts' smoothing; `None`: the scene's own)."""

    @property
    def uncertain_inputs(self) -> tuple[str, ...]:
        """Names of the inputs a unit carries after its design values (default none)."""
        return ()

    def uncertain_box(self):
        """`(middle, half-width)` arrays of the bands `uncertain_inputs` spread over, or `None`."""
        return None

    def forward_mode(self) -> "AbstractObjective":
        """This objective with its derivatives in forward mode (`jax.jacfwd` through it); default
        itself (a closed form has no solve to set up)."""
        return self

    def with_adjoint(self, adjoint) -> "AbstractObjective":
        """This objective whose solves differentiate by `adjoint` (a diffrax adjoint); default
        itself (a closed form has no solve)."""
        return self


class PointingObjective(AbstractObjective):
    """Pointing statistics of `scene` over the window `[settle, duration]` (s), as a function of
    its design vector (clearances and backlash, m, in `design_names(scene)` order).

    Outputs (arcsec): `pointing_rms` $\\sqrt{\\overline{e^2}}$; `pointing_peak` $\\max e$;
    `pointing_smooth_peak` $(\\overline{e^p})^{1/p}$ with $p$ = `peak_order` (a smooth surrogate
    of the peak, $\\le$ the peak, $\\ge$ the RMS); `tracking_speed_rms` (arcsec/s, RMS norm of the
    reflector's angular-velocity error); with `jitter_cutoff` set, `pointing_jitter` (arcsec,
    the pointing stability: the RMS of the error with everything below `jitter_cutoff` Hz
    removed, `tolerax.mechanism.outputs.pointing_jitter`); and `success` (the solver reached
    `duration`; a failed sample's numbers are meaningless, and the Monte Carlo engine never
    averages them). `metrics` (optional): `AbstractMetric`s, each adding one output by its name
    (a requirement on any scalar of a run: `Requirement(metric.name, limit)`).

    `jitter_cutoff` (Hz, default `None`: no jitter output; 20 is the usual start of a pointing
    budget's stability band): the jitter's band starts there and ends at the Nyquist frequency
    of the saves, `(n_save - 1) / (2 duration)`. Calling the objective raises `ValueError`
    where the saves are too sparse for it (fewer than 4 per cutoff period, or a window
    `duration - settle` shorter than one period: raise `n_save`). Off by default so that the
    objectives without it (short smoke horizons, sparse saves) are unaffected. The jitter's
    window is the others', decided in Python from the save times (`jnp.linspace(0, duration,
    n_save)` computed by NumPy: a save within rounding of `settle` may fall on the other side).

    `smoothing_width` (m, optional): overrides every stage's smoothing width — the continuation
    parameter of the optimiser (wide early, exact late). `integrator`: the run settings as one
    value (`tolerax.Integrator`: the solver by name, the controller's tolerances and
    coefficients, the steps' limits; or a preset's name, `"fast-stage"`, `"accurate"`, on the
    objective's step budget; default (`"auto"`): the one `simulate` chooses for the scene,
    `scene.automatic_integrator()`, with a step budget of 400 000; `integrated_with` says which
    and why); its settings are read back as attributes (`objective.rtol`). Given one by one
    (`rtol=...`, `solver="Bosh3"`) they still refine the integrator (a preset's or, where none is
    named, `OBJECTIVE_INTEGRATOR`, Tsit5 at rtol 1e-6) for one release, with a
    `DeprecationWarning` naming the `Integrator` to pass instead (a scene file's `[run]` keys
    are made one by `SceneFile.objective`).
    Run settings are static: changing them recompiles; changing the design or the scene's
    values does not.

    `life` (optional, a `MissionLife`): the clearances worn over the mission's life
    (`tolerax.design.life`); every output then has an end-of-life twin named `<output>_eol`
    (e.g. `pointing_rms_eol`), from the scene re-simulated at `life.points` life points as its
    journal clearances grow by Archard wear (`points + 1` solves per call); the outputs without
    the suffix stay the beginning of life's and `success` covers every solve.

    `adjoint` (optional): how derivatives pass through the solve, a diffrax adjoint handed to
    `simulate` (default `None`: `diffrax.RecursiveCheckpointAdjoint()`, reverse mode;
    `diffrax.ForwardMode()` for `jax.jvp`/`jax.jacfwd`). Forward mode's cost grows with the
    tangents it carries, reverse mode's with the checkpointed trajectory, so for a few design
    features forward mode is the cheaper (`benchmarks/gradient_methods.py` compares them).
    """

    scene: eqx.Module
    duration: float = eqx.field(static=True)
    settle: float = eqx.field(static=True)
    n_save: int = eqx.field(static=True, default=201)
    peak_order: int = eqx.field(static=True, default=8)
    start: str = eqx.field(static=True, default="rest")
    # Not a static field although it is a run setting: `diffrax.BacksolveAdjoint` holds a dict
    # and cannot be hashed. It holds no arrays, so `eqx.filter_jit` still treats it as static.
    adjoint: diffrax.AbstractAdjoint | None = None
    jitter_cutoff: float | None = eqx.field(static=True, default=None)
    metrics: tuple[AbstractMetric, ...] = ()
    life: MissionLife | None = None
    integrator: Integrator = OBJECTIVE_INTEGRATOR  # the run settings, one value (static fields)
    integrated_with: str = eqx.field(static=True, default="")  # which integrator and why, in words

    def __init__(self, scene, duration, settle, n_save=201, rtol=_UNSET, atol=_UNSET, max_steps=_UNSET, peak_order=8, start="rest",
                 adjoint=None, pcoeff=_UNSET, icoeff=_UNSET, jitter_cutoff=None, metrics=(), life=None, solver=_UNSET, dt0=_UNSET,
                 dtmax=_UNSET, dtmin=_UNSET, fixed_step=_UNSET, integrator=None, integrated_with=None):
        self.scene, self.duration, self.settle, self.n_save = scene, duration, settle, n_save
        self.peak_order, self.start, self.adjoint, self.jitter_cutoff = peak_order, start, adjoint, jitter_cutoff
        self.metrics, self.life = metrics, life
        # The run settings given one by one (deprecated: the older spelling; None: not given)
        # refine the integrator (a preset by name or "auto": on the objective's step budget);
        # with none given and "auto", the scene's automatic one (`simulate`'s default) with the
        # objective's step budget.
        given = {k: v for k, v in dict(solver=solver, rtol=rtol, atol=atol, pcoeff=pcoeff, icoeff=icoeff, dt0=dt0, dtmax=dtmax,
                                        dtmin=dtmin, max_steps=max_steps, fixed_step=fixed_step).items()
                 if v is not _UNSET and v is not None}
        chosen, written = refined("auto" if integrator is None else integrator, given, where="PointingObjective",
                                  budget=OBJECTIVE_INTEGRATOR.max_steps)
        if given:
            settings = ", ".join(f"{k}={v!r}" for k, v in given.items())
            warnings.warn(f"PointingObjective({settings}) is deprecated: pass integrator={written} (one tolerax.Integrator "
                          "holds every run setting); the settings one by one go in the next release.", DeprecationWarning,
                          stacklevel=2)
        if chosen is None:
            chosen, reason = scene.automatic_integrator()
            self.integrator = chosen.replace(max_steps=OBJECTIVE_INTEGRATOR.max_steps)
            why = self.integrator.said(reason)
        else:
            self.integrator, why = chosen, chosen.said()
        # A copy (`dataclasses.replace`) hands its `integrated_with` back: kept where it still
        # describes this integrator, else said again.
        kept = integrated_with is not None and integrated_with.startswith(f"{self.integrator.describe()}:")
        self.integrated_with = integrated_with if kept else why

    # The run settings, read through the integrator that holds them.
    solver = property(lambda self: self.integrator.solver)
    rtol = property(lambda self: self.integrator.rtol)
    atol = property(lambda self: self.integrator.atol)
    pcoeff = property(lambda self: self.integrator.pcoeff)
    icoeff = property(lambda self: self.integrator.icoeff)
    dt0 = property(lambda self: self.integrator.dt0)
    dtmax = property(lambda self: self.integrator.dtmax)
    dtmin = property(lambda self: self.integrator.dtmin)
    max_steps = property(lambda self: self.integrator.max_steps)
    fixed_step = property(lambda self: self.integrator.fixed_step)

    def __check_init__(self):
        if not (0.0 <= self.settle < self.duration):
            raise ValueError(f"PointingObjective needs 0 <= settle < duration (s), got settle={self.settle!r}, duration={self.duration!r}.")
        names = [getattr(m, "name", None) for m in self.metrics]
        if not all(isinstance(m, AbstractMetric) for m in self.metrics) or len(set(names)) != len(names) or set(names) & set(OUTPUTS):
            raise ValueError(f"PointingObjective: metrics must be AbstractMetric instances with distinct names other than {OUTPUTS}, "
                             f"got {names}.")

    @property
    def outputs(self) -> tuple[str, ...]:
        """The scalar outputs this objective computes (`pointing_jitter` only with `jitter_cutoff`)."""
        own = tuple(o for o in OUTPUTS if o != "pointing_jitter" or self.jitter_cutoff is not None)
        names = own + tuple(m.name for m in self.metrics)
        return names if self.life is None else names + tuple(f"{o}{EOL}" for o in names)

    @property
    def units(self) -> dict[str, str]:
        """The unit of each output."""
        units = UNITS | {m.name: m.unit for m in self.metrics}
        return units | {f"{o}{EOL}": u for o, u in units.items()}

    def with_width(self, values, smoothing_width=None):
        """The scene with design `values` and, if given, every stage's smoothing width (m)."""
        scene = with_design(self.scene, values)
        if smoothing_width is None:
            return scene
        width = jnp.asarray(smoothing_width, dtype=float)
        return eqx.tree_at(_widths, scene, replace_fn=lambda _: width)

    def run(self, values, smoothing_width=None):
        """The scene's result for design `values` (`throw=False`: read `success`)."""
        return self.simulate_scene(self.with_width(values, smoothing_width))

    def simulate_scene(self, scene):
        """`scene`'s result with this objective's run settings (`throw=False`)."""
        return simulate(scene, self.duration, start=self.start, n_save=self.n_save, throw=False, adjoint=self.adjoint,
                        integrator=self.integrator)

    def forward_mode(self) -> "PointingObjective":
        """This objective whose solves carry forward-mode tangents (`diffrax.ForwardMode`)."""
        return self.with_adjoint(diffrax.ForwardMode())

    def with_adjoint(self, adjoint) -> "PointingObjective":
        """This objective whose solves differentiate by `adjoint` (a diffrax adjoint)."""
        return dataclasses.replace(self, adjoint=adjoint)

    def jitter_window(self) -> np.ndarray:
        """The saves in `[settle, duration]` (bool per save, NumPy: the jitter's FFT length must be
        known in Python), checked against `jitter_cutoff` (`ValueError` if too sparse)."""
        window = np.linspace(0.0, self.duration, int(self.n_save)) >= self.settle
        check_jitter_sampling(self.duration / (int(self.n_save) - 1), int(np.sum(window)), self.jitter_cutoff)
        return window

    @property
    def uncertain_inputs(self) -> tuple[str, ...]:
        """Inputs a unit may carry after its design values (Monte Carlo draws them): the wear-rate
        factor of a life with a `spread` (`tolerax.design.life.WEAR_FACTOR`), else none."""
        return (WEAR_FACTOR,) if self.life is not None and self.life.spread is not None else ()

    def uncertain_box(self):
        """`(middle, half-width)` of the band each of `uncertain_inputs` spreads over (arrays, one
        value per input; the wear-rate factor's logarithm: `MissionLife.spread_tolerances`), or
        `None` without them. A design's secant units draw them uniformly over it
        (`tolerax.design.reliability`)."""
        if not self.uncertain_inputs:
            return None
        box = self.life.spread_tolerances()
        return jnp.asarray(box.nominal, dtype=float), jnp.asarray(box.band, dtype=float)

    def __call__(self, values: Float[Array, " n_features"], smoothing_width=None) -> dict[str, Array]:
        window = None if self.jitter_cutoff is None else self.jitter_window()  # check before the solve
        values, scale = self._split(values)
        if self.life is not None:
            outputs, _ = self.over_life(values, smoothing_width, wear_scale=scale)
            begin = {name: v[0] for name, v in outputs.items()}
            return begin | {f"{name}{EOL}": v[-1] for name, v in outputs.items() if name != "success"} | dict(
                success=jnp.all(outputs["success"]))
        return self._outputs(self.run(values, smoothing_width), window)

    def _split(self, values):
        """`(design values, wear-rate factor)` of a unit's inputs: the design's, then where the
        life has a `spread` optionally the factor's logarithm (`uncertain_inputs`); factor 1
        without it."""
        n = len(design_names(self.scene))
        values = jnp.asarray(values)
        if self.uncertain_inputs and values.shape[-1] == n + 1:
            return values[:n], jnp.exp(values[n])
        if values.shape[-1] != n:
            extra = f" or {n + 1} (with {WEAR_FACTOR})" if self.uncertain_inputs else ""
            raise ValueError(f"PointingObjective: a unit has {values.shape[-1]} values; the scene has {n} design features "
                             f"({', '.join(design_names(self.scene))}){extra}.")
        return values, 1.0

    def over_life(self, values, smoothing_width=None, wear_scale=1.0):
        """`(outputs, depths)` at each of the life's points (`life.points + 1`, from the as-built
        design `values` to the end of life; `tolerax.design.life`): `outputs` the objective's
        outputs (without the `_eol` twins), each of shape (points + 1,); `depths` `{joint:
        (points + 1, n)}` the growth (m) at each point of each clearance and, where the flanks
        wear, each mesh's backlash, in `tolerax.physics.wear.wear_names` order. One solve per
        point, in one `lax.scan` (compiled once). `wear_scale`: a factor on every wear rate (a
        unit's draw from `MissionLife.spread`; default 1)."""
        life = self.life
        if life is None:
            raise ValueError("PointingObjective.over_life needs a life (PointingObjective(..., life=MissionLife(...))).")
        scene = self.with_width(values, smoothing_width)
        joints = worn_joints(scene, life)
        if not joints:
            raise ValueError("PointingObjective: the life wears nothing: no planetary joint of the scene has clearance contacts and "
                             "a wear model (life=MissionLife(..., wear=...); ideal and lumped joints do not wear).")
        window = None if self.jitter_cutoff is None else self.jitter_window()
        saves = np.linspace(0.0, self.duration, int(self.n_save)) >= self.settle
        step = life.operating_time / life.points

        def point(depth, _):
            worn = worn_scene(scene, depth)
            res = self.simulate_scene(worn)
            rates = window_wear_rates(worn, res, saves, life)
            return {j: depth[j] + step * wear_scale * rates[j] for j in depth}, (self._outputs(res, window), depth)

        start = {joint: jnp.zeros(len(names)) for joint, names in joints}
        _, (outputs, depths) = jax.lax.scan(point, start, None, length=life.points + 1)
        return outputs, depths

    def _outputs(self, res, window) -> dict[str, Array]:
        """The outputs of one run `res` (`window`: the jitter's saves, or `None`)."""
        metrics = pointing_metrics(res, res.ts >= self.settle, self.peak_order)
        out = dict(
            pointing_rms=metrics["pointing_rms"],
            pointing_peak=metrics["pointing_peak"],
            pointing_smooth_peak=metrics["pointing_smooth_peak"],
            tracking_speed_rms=metrics["tracking_speed_rms"],
            success=res.result == diffrax.RESULTS.successful,
        )
        if window is not None:
            out["pointing_jitter"] = pointing_metrics(res, window, jitter_cutoff=self.jitter_cutoff)["pointing_jitter"]
        if self.metrics:
            times = np.linspace(0.0, self.duration, int(self.n_save))
            for metric in self.metrics:
                out[metric.name] = metric(res, times, times >= self.settle)
        return out


def unit_output(values, pointing: AbstractObjective, output: str | tuple[str, ...], width):
    """One manufactured unit's `output` at design `values` (m), NaN if its solve failed; a tuple
    of outputs: a vector of them, from the one solve."""
    out = pointing(values, width)
    if isinstance(output, tuple):
        return jnp.where(out["success"], jnp.stack([out[name] for name in output]), jnp.nan)
    return jnp.where(out["success"], out[output], jnp.nan)


def value_and_jacobian(values, pointing: AbstractObjective, output: str, width):
    """`(unit_output, its Jacobian over values)` from one solve carrying one forward-mode
    tangent per feature (`diffrax.ForwardMode`)."""
    forward = pointing.forward_mode()
    jac, value = jax.jacfwd(lambda v: (lambda y: (y, y))(unit_output(v, forward, output, width)), has_aux=True)(values)
    return value, jac


def _widths(scene):
    """Every stage's smoothing width in a scene (a bench's stage, or each joint's)."""
    return [stage_of(scene).smoothing_width for _, stage_of, _ in scene.named_stages()]
