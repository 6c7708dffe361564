"""Identifying an as-built unit: the clearances and backlash (and, where asked, the joints' drag,
mesh stiffness and damping: `tolerax.identification.parameters`) that make the model reproduce a
test recording, how well the recording determines each, and the identified unit as a scene.

**Estimate.** With $\\theta$ the chosen parameters and the others at the scene's values,
the residual is the model's output angle at the recording's times minus the measured one,

$$r_i(\\theta) = \\frac{\\phi_i^{\\text{model}}(\\theta) - \\phi_i^{\\text{measured}}}{1\\,\\mu\\text{rad}},$$

over the saves in `[settle, duration]` and the recorded axes, minimised by Levenberg-Marquardt
(`optimistix`) with the exact Jacobian of the solve (forward mode through diffrax). The
parameters are optimised as $\\log(\\theta / 1\\,\\mu m)$ (a clearance or backlash) or
$\\log(\\theta / \\theta_{\\text{scene}})$ (a physical parameter), so they stay positive; the contacts' smoothing
width is continued from wide to narrow (`widths`), and several starts are run because
clearances and drag make the residual non-convex (the best of a Sobol screen over the prior box,
`starts`, `search`); the lowest residual wins.

**How well.** At the estimate, with $J = \\partial r/\\partial\\theta$ and $s^2 = \\lVert r \\rVert^2
/ (N - p)$ the residual variance, the Gauss-Newton covariance is $s^2 (J^TJ)^{+}$ and a 95 %
interval $\\hat\\theta \\pm 1.96\\,\\sigma_\\theta$ (the linearised one: it holds where the residual is
close to quadratic over the interval and the residuals are independent; `tests/test_identify.py`
measures its coverage on synthetic recordings instead of assuming it). Each interval is checked
against the residual itself along its profile path $\\hat\\theta \\pm k\\,\\Sigma e_j/\\sigma_j$ (the
other parameters at their linearised conditional best), where the linearised cost rises by
$k^2 s^2$: the measured rise over that at $k$ = 1.96, 10 and 100 (`Identification.profile`) is
1 where the residual is quadratic; an interval whose ratio at 1.96 or 10 is off by more than
`PROFILE_FACTOR` does not hold (`Identification.holds`, the status says so). The identifiability
table is the eigen-decomposition of the relative Fisher information $D J^TJ D / s^2$
($D$ = the estimates): a direction whose relative standard error is below `DETERMINED` is
determined; a parameter is determined itself, determined only in combination (it loads on a
determined direction but its own interval is wide: the recording sees a sum, as the lost motion
at a reversal sees the backlash and the pin play together), or not determined.

**Where it holds.** The residual matches trajectories, so it needs a Jacobian that reads how
the trajectory moves with the parameters. On the lumped joint the forward-mode derivative of the
solve does. On the full planetary stage it does not: through the rattle the trajectory's
tangents grow with the impacts' sensitivity to every perturbation (at the first start they
exceed the central secants by orders of magnitude), while the trajectory itself moves smoothly
with a clearance (the cost is close to quadratic in the ring backlash about the truth). So the
Jacobian is chosen (`identify(secant=None)`): forward mode where it agrees with the central
secants at `SECANT_STEP`, else the secants (`tolerax._linearise.secant_once`: 2p runs a
linearisation, in one batch), for Levenberg-Marquardt and the intervals alike. With the
forward-mode Jacobian on the full stage Levenberg-Marquardt stalls near the screen's best point
with an interval of nanometres, and the profile check finds the cost along it nowhere near its
linearised rise (its status "interval does not hold", not written into the identified scene). Of the physical
parameters, the drag is seen as the clearances are (it sets which flank the output rides); a
mesh stiffness or damping ratio only through the output's ringing after each reversal (the
reflector swinging on the mesh stiffness): that fit is non-convex beyond a few per cent (a unit well
below the scene's stiffness, fitted from the scene's value, ran to its bound), and the ringing's
sensitivity changes within a fraction of its standard error, so its interval is a rough guide; identify a stiffness from a close start, or leave it at its value.
"""

import dataclasses
import math
import sys
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._linearise import secant_once
from ..design.features import design_of, with_design
from ..design.objectives import PointingObjective, _widths
from ..eta import human_seconds, rough_wall
from .parameters import check_names, parameter_units, parameter_values, with_parameters
from .recording import ANGLE_UNITS, AXES, Recording, RecordingError
from .result import DETERMINED, PROFILE_STEPS, RESOLVED, Identification, show  # noqa: F401 (Identification, show: imported from here by callers)

UNIT = 1e-6  # rad: the residual's unit (µrad); features in µm inside the solve
# Levenberg-Marquardt's relative and absolute tolerance on the step (log µm, log of the scene's
# value); it stops where an accepted step moves the parameters less than that and changes no
# residual by more than RESIDUAL_TOL (1 + |r|) µrad (`_termination_norm`). A finer residual
# tolerance is below the adaptive solve's own noise in the residual: at the cost floor every
# further step is rejected on that noise and the solve runs to its step limit for no gain
# (measured in benchmarks/identify_wall_time.py). The estimate is then checked to a tenth of a
# standard error and polished where it is not (`identify`).
LM_TOL = 1e-4
# Runs of the scene (at rough_wall's pace) a Levenberg-Marquardt step costs per parameter and
# one more, for the rough time said before the work: timed on the lumped azimuth scan with one
# parameter, compiled, 13-20 runs a step, i.e. 7-10 per (parameter + 1); the time said is the
# steps' budget, which a fit that converges early does not use (an order of magnitude).
LM_STEP_RUNS = 8
RESIDUAL_TOL = 0.2
# Each parameter is kept within this factor of the scene's value either side (`_bounded`): an
# undetermined one would otherwise walk off to where the model is not physical (a stiffness of 1e51 N/m).
BOUND = 100.0
# The Gauss-Newton polish after it (`_polish`): steps and tolerance.
POLISH_STEPS, POLISH_TOL = 3, 1e-7
# Of the screened starts (`_starts`), Levenberg-Marquardt runs from this many of the lowest cost.
STARTS_KEPT = 2
# The Jacobian where the forward-mode one is not the residual's (`identify(secant=...)`): central
# secants at a relative step of SECANT_STEP in each parameter (2 %: wide against the
# trajectory's sensitivity to a perturbation through the impacts, narrow against the residual's
# curvature in a clearance), chosen
# automatically where the forward-mode Jacobian at the first start differs from the secants by
# more than SECANT_SWITCH of their norm (on the full planetary stage by orders of magnitude: the
# rattle scrambles the tangents; on the lumped joint they agree to the step's truncation error).
SECANT_STEP, SECANT_SWITCH = 0.02, 0.5
# Runs of the scene a Levenberg-Marquardt step on secants costs per (parameter + 1), for the
# rough time: the 2p points (one batched run) and the trial point, rounded up.
SECANT_STEP_RUNS = 2
COMMAND_TOLERANCE = 20e-6  # rad: a recording's commanded angle may differ this much (or 1 % of its range) from the scene's


class _Fit(eqx.Module):
    """The residual of `identify`: the model's output angles at the recording's saves (`rows`)
    and axes (`columns`) with the parameters `names` at `scale * x` (SI units) over `measured`
    (rad), in µrad."""

    objective: PointingObjective
    names: tuple[str, ...] = eqx.field(static=True)
    scale: jax.Array
    rows: jax.Array
    columns: jax.Array
    measured: jax.Array
    # None: the Jacobian of forward mode through the solve; a step h: central secants at a
    # relative step h in each parameter (`SECANT_STEP`), static (a program per choice).
    secant: float | None = eqx.field(static=True, default=None)

    def run(self, x, width):
        scene = with_parameters(self.objective.scene, self.names, self.scale * x)
        return eqx.tree_at(lambda o: o.scene, self.objective, scene).run(design_of(scene), width)

    def outputs(self, x, width):
        """`(residual, (model angles, commanded angles))` at `x`: the residual (µrad) and, from
        the same solve, the model's output and commanded angles (rad) at the fitted saves."""
        res = self.run(x, width)
        ok = res.result == diffrax.RESULTS.successful
        angles = jnp.where(ok, res.joint_angle[self.rows][:, self.columns], jnp.nan)
        residual = jnp.where(ok, (angles - self.measured) / UNIT, 1e6).ravel()
        return residual, (angles, res.commanded_angle[self.rows][:, self.columns])

    def residual(self, x, width):
        return self.outputs(x, width)[0]


def _bounded_residual(w, fit: "_Fit", width, centre, reach):
    """The residual (µrad) at the optimiser's variable `w` (`_bounded`)."""
    return fit.residual(_bounded(w, centre, reach), width)


def _residual_in_w(fit: "_Fit"):
    """`_bounded_residual`, linearised by central secants in `w` (a step `fit.secant` in the
    logarithm of each parameter: relative) where the fit asks for them, else by forward mode."""
    return _bounded_residual if fit.secant is None else secant_once(_bounded_residual, fit.secant)


@eqx.filter_jit
def _polish(fit: "_Fit", w0, width, centre, reach):
    """A few Gauss-Newton steps (optimistix) at a tolerance finer than `LM_TOL` from
    Levenberg-Marquardt's estimate `w0`: LM stops within its tolerance of the minimum, about
    half a standard error for a parameter the recording determines to 1e-4. (solution, cost)."""
    residual = _residual_in_w(fit)
    fn = lambda w, width: residual(w, fit, width, centre, reach)  # noqa: E731
    sol = optx.least_squares(fn, optx.GaussNewton(rtol=POLISH_TOL, atol=POLISH_TOL), w0, args=width, max_steps=POLISH_STEPS,
                             throw=False)
    return sol.value, jnp.sum(fn(sol.value, width) ** 2)


def _profile(fit: "_Fit", x, x0, cov_x, s2, width, batch: int | None, cost: float) -> np.ndarray:
    """The linearised intervals checked against the residual itself: for each parameter $j$ the
    cost at $x \\pm k\\,\\Sigma e_j / \\sigma_j$ (the linearised profile path: the other parameters
    at their conditional best, where the linearised cost rises by exactly $k^2 s^2$) for $k$ in
    `PROFILE_STEPS`, as its rise over $k^2 s^2$: 1 where the cost is quadratic out to there.
    `(parameters, 2 sides, steps)`, NaN where a point would leave the bounds or the standard error
    is not finite. Costed in batches of `batch` (the screen's: its compiled program), or where
    no screen ran (`batch` None) one point at a time through `_fit_and_jacobian` (compiled for the
    assessment already: no program compiled for the check), against `cost`, the assessment's own
    at `x` from that program (µrad²)."""
    se = np.sqrt(np.maximum(np.diag(cov_x), 0.0))
    ratio = np.full((x.size, 2, len(PROFILE_STEPS)), np.nan)
    if not (math.isfinite(s2) and s2 > 0):  # a residual of exactly zero: no scale to check against
        return ratio
    points, where = [x], []
    for j in range(x.size):
        if not (np.isfinite(se[j]) and se[j] > 0):
            continue
        for side, sign in enumerate((-1.0, 1.0)):
            for m, k in enumerate(PROFILE_STEPS):
                point = x + sign * k * cov_x[:, j] / se[j]
                if np.all(point > x0 / BOUND) and np.all(point < x0 * BOUND):
                    points.append(point)
                    where.append((j, side, m, k))
    if batch is None:
        costs = [cost] + [float(jnp.sum(((_fit_and_jacobian(fit, jnp.asarray(p), width)[1] - fit.measured) / UNIT) ** 2))
                          for p in points[1:]]
    else:
        points = np.vstack(points + [x] * (-len(points) % batch))
        costs = np.concatenate([np.asarray(_costs(fit, jnp.asarray(points[i:i + batch]), width))
                                for i in range(0, len(points), batch)])
    for (j, side, m, k), c in zip(where, costs[1:]):
        ratio[j, side, m] = (c - costs[0]) / (k * k * s2)
    return ratio


def _unbounded(x, centre, reach):
    """The optimiser's variable at `x` (`_bounded`'s inverse; `x` inside the bounds)."""
    return reach * np.arctanh(np.clip((np.log(x) - centre) / reach, -1 + 1e-12, 1 - 1e-12))


@eqx.filter_jit
def _costs(fit: "_Fit", points, width):
    """$\\lVert r\\rVert^2$ (µrad²) at each row of `points` (x), in one batched run."""
    return eqx.filter_vmap(lambda v: jnp.sum(fit.residual(v, width) ** 2))(points)


def _starts(fit, x0, width, starts, search: float):
    """The Levenberg-Marquardt starts (x): `starts` multiples of `x0` as given, or (an int) the
    `STARTS_KEPT` lowest-cost of `starts` points of a scrambled Sobol sequence over the box
    $[x_0/s, s\\,x_0]$ (log-uniform, $s$ = `search`) and `x0` itself, costed against the recording
    in one batched run at the scene's width. Returns `(starts, screened)`, `screened` the number
    of points costed (0 where the starts were given)."""
    if isinstance(starts, int):
        from scipy.stats import qmc

        if starts < 1 or not 1 < search < BOUND:
            raise ValueError(f"identify: starts={starts!r} must be >= 1 and search={search!r} in (1, {BOUND:g}).")
        unit = qmc.Sobol(len(x0), scramble=True, seed=0).random(starts)
        points = np.vstack([x0, x0 * search ** (2 * unit - 1)])
        cost = np.asarray(_costs(fit, jnp.asarray(points), width))
        cost = np.where(np.isfinite(cost), cost, np.inf)
        return points[np.argsort(cost)[:STARTS_KEPT]], len(points)
    out = []
    for factor in starts:
        if not 1 / BOUND < float(factor) < BOUND:
            raise ValueError(f"identify: a start {factor!r} times the scene's values is outside the bounds (a factor {BOUND:g} "
                             "either side): start nearer.")
        out.append(x0 * float(factor))
    return out, 0


def _bounded(w, centre, reach):
    """x from the optimiser's unbounded variable `w`: $\\log x = c + R\\tanh(w/R)$, inside a factor
    $e^R$ either side of the scene's value $e^c$ (`BOUND`); $w = \\log x - c$ near the centre."""
    return jnp.exp(centre + reach * jnp.tanh(w / reach))


def _termination_norm(tree):
    """The norm of Levenberg-Marquardt's Cauchy termination (optimistix's `norm`: it measures the
    step in the parameters and the change in the residual, each divided by `LM_TOL` (1 + |.|)):
    the max norm, the residual's (the `{"residual": r}` of `_solve`) read at `RESIDUAL_TOL`."""
    return optx.max_norm(tree) * (LM_TOL / RESIDUAL_TOL if isinstance(tree, dict) else 1.0)


@eqx.filter_jit
def _solve(fit: _Fit, w0, width, max_steps: int, centre, reach):
    """Levenberg-Marquardt on `w` (`_bounded`) from `w0`: (solution, cost, steps, converged)."""
    residual = _residual_in_w(fit)
    fn = lambda w, width: {"residual": residual(w, fit, width, centre, reach)}  # noqa: E731
    solver = optx.LevenbergMarquardt(rtol=LM_TOL, atol=LM_TOL, norm=_termination_norm)
    sol = optx.least_squares(fn, solver, w0, args=width, max_steps=max_steps, throw=False)
    return sol.value, jnp.sum(fn(sol.value, width)["residual"] ** 2), sol.stats["num_steps"], sol.result == optx.RESULTS.successful


@eqx.filter_jit
def _fit_and_jacobian(fit: _Fit, x, width):
    """The residual's Jacobian (µrad per unit of x), the fitted angles and the scene's commanded
    angles (rad) at `x`: from one forward-mode solve (the angles are its primal), or where the
    fit takes secants (`_Fit.secant`) from one batched run of `x` and the central secants at
    $x\\,e^{\\pm h}$ in each parameter."""
    if fit.secant is None:
        jac, (angles, commanded) = jax.jacfwd(lambda v: fit.outputs(v, width), has_aux=True)(x)
        return jac, angles, commanded
    points, span = _secant_points(x, fit.secant)
    residuals, (angles, commanded) = jax.vmap(lambda v: fit.outputs(v, width))(jnp.concatenate([x[None], points]))
    return _central(residuals[1:], span), angles[0], commanded[0]


def _secant_points(x, h: float):
    """The $2n$ points $x\\,e^{\\pm h}$ along each parameter of `x` (shape `(n,)`; first the $n$
    raised, then the $n$ lowered: relative steps, the parameters' scales differ by orders of
    magnitude) and each pair's span $x_j(e^h - e^{-h})$."""
    n = x.shape[0]
    return x[None] * jnp.exp(h * jnp.concatenate([jnp.eye(n), -jnp.eye(n)])), x * (math.exp(h) - math.exp(-h))


def _central(values, span):
    """The central secants (one column per parameter) from `values` at `_secant_points`' $2n$
    points (leading axis) and their spans."""
    n = span.shape[0]
    return (values[:n] - values[n:]).reshape(n, -1).T / span[None, :]


def _model_times(recording: Recording, duration: float, n_save: int | None) -> tuple[int, np.ndarray]:
    if n_save is None:
        step = float(np.median(np.diff(recording.time)))
        n_save = int(min(max(round(duration / step) + 1, 3), 2001))
    return n_save, np.linspace(0.0, duration, n_save)


def identify(scene, recording: Recording, parameters=None, *, settle: float = 0.0, duration: float | None = None,
             n_save: int | None = None, start: str = "steady", widths=(1e-6, None), starts=32, search: float = 2.0,
             lm_steps: int = 20, rtol: float = 1e-6, atol: float = 1e-9, secant: float | bool | None = None, progress=False,
             **run) -> Identification:
    """The parameters `parameters` of `scene` that reproduce `recording` (module docstring).

    **Arguments:**

    - `scene`: the model (a `Mechanism` or `TestBench`) whose drive is the one the recording
      was made with; its other parameters stay at its values.
    - `recording`: a `Recording` (`read_recording`); its axes must be joints of the scene.
    - `parameters`: names from `parameter_names(scene)`: its design features (clearances and
      backlash, m) and its joints' physical parameters (`azimuth.drag_torque`, N m;
      `azimuth.sun_mesh_stiffness`, N/m; damping ratios: `tolerax.identification.parameters`);
      default all the design features. The scene's values are the first start.
    - `settle` (s): residuals from this time on; `duration` (s): the model's run, default the
      recording's length; `n_save`: the model's saves over it (default: the recording's rate,
      at most 2001). `start`: the model's initial state (`simulate`).
    - `widths`: the smoothing widths (m) continued through, `None` the scene's own; the
      estimate, its covariance and the fit are the last width's.
    - `starts`: an int (default 32): that many points of a Sobol sequence over the box within a
      factor `search` (2) of the scene's values either side, and the scene's values, costed
      against the recording in one batched run; Levenberg-Marquardt runs from the `STARTS_KEPT`
      (2) best. The fit of a clearance or a drag is not convex: from a start 40 % off it can
      stop in another basin with a residual many times the noise. Or a tuple: the starts, as
      multiples of the scene's values. Every parameter is kept within a factor `BOUND` (100)
      of the scene's value either side: an estimate at that bound is one the recording does not
      determine (the table says so).
    - `lm_steps`: Levenberg-Marquardt's steps per width, at most (its tolerance: `LM_TOL`; then
      where the best is not within a tenth of a standard error, `POLISH_STEPS` Gauss-Newton steps
      at `POLISH_TOL`, kept if they lower the cost);
      `rtol`, `atol` and `**run`: the model's run settings (`simulate`'s: solver, controller,
      `max_steps`, ...), as a scene file's `[run]` holds them.
    - `secant`: the residual's Jacobian, for Levenberg-Marquardt and the intervals. `None`
      (default): chosen at the first start, the forward-mode Jacobian through the solve where it
      agrees with the central secants at `SECANT_STEP` to `SECANT_SWITCH` of their norm, else
      the secants (the full planetary stage: its rattle scrambles the trajectory's tangents
      while the trajectory moves smoothly with a clearance); `False`: forward mode; a number
      $h > 0$: central secants at a relative step $h$ in each parameter. The result's
      `jacobian` says which, and why.
    - `progress`: True prints to stderr a rough time before any work, then a line per phase as
      it ends (the screen, each start at each width with its steps and cost, the assessment),
      with its wall time; or a callable taking those lines (an identification can take minutes
      where it compiles, or on the full stage).

    **Returns:** an `Identification`. Raises `RecordingError` where the recording does not fit
    the scene (its length; its commanded angle, where it has one, not the scene's drive to
    `COMMAND_TOLERANCE` or 1 % of its range) and `ValueError` for unknown parameters, a scene
    value that is not > 0, or starts outside the bounds.
    """
    parameters = check_names(scene, parameters)
    duration = recording.duration if duration is None else float(duration)
    if duration > recording.duration + 1e-12:
        raise RecordingError(f"{recording.source}: the recording lasts {recording.duration:g} s, shorter than the model's "
                             f"{duration:g} s run: record longer or give a shorter duration.")
    n_save, times = _model_times(recording, duration, n_save)
    window = times >= settle
    measured = recording.at(times[window])
    columns = [AXES.index(a) for a in recording.axes]
    objective = PointingObjective(scene, duration=duration, settle=settle, n_save=n_save, start=start, rtol=rtol, atol=atol,
                                  **run).forward_mode()
    units, scale = _scales(scene, parameters)
    x0 = np.asarray(parameter_values(scene, parameters)) / scale
    # The problem's data as arrays (traced): one compiled program per scene structure, parameter
    # names and shape, whichever recording, start or width (`_solve`, `_fit_and_jacobian` are module-level).
    fit = _Fit(objective, parameters, jnp.asarray(scale), jnp.asarray(np.flatnonzero(window)), jnp.asarray(columns),
               jnp.asarray(measured))
    widths = [own_width(scene) if w is None else jnp.asarray(w, dtype=float) for w in widths]
    clock = time.perf_counter()
    wall = {}
    say = (lambda line: print(line, file=sys.stderr, flush=True)) if progress is True else (progress or None)
    if say is not None:
        # The screen's batched costs, then from each kept start per width up to lm_steps
        # Levenberg-Marquardt steps, each LM_STEP_RUNS runs per parameter and one more (a
        # forward-mode Jacobian through the adaptive solve, which optimistix's linearisation runs
        # again for each product), then the intervals' check (each parameter's profile path at
        # PROFILE_STEPS both sides), at rough_wall's pace: an order of magnitude, not a bound.
        # A step on central secants instead: SECANT_STEP_RUNS runs per (parameter + 1). Where the
        # Jacobian is chosen (secant=None) both are said: the choice is made at the first start.
        one = rough_wall(scene, duration, objective.integrator)
        screen = starts + 1 if isinstance(starts, int) else 0  # given starts are fitted as they are
        kept = min(STARTS_KEPT, screen) if screen else len(starts)
        p = len(parameters)

        def rough(step_runs):
            runs = screen + kept * len(widths) * int(lm_steps) * (p + 1) * step_runs + 2 * p * len(PROFILE_STEPS) + p + 1
            return human_seconds(max(runs * one, 1.0))

        guess = ("" if one is None else f": roughly {rough(LM_STEP_RUNS)} on one core" if secant is False else
                 f": roughly {rough(SECANT_STEP_RUNS)} on one core" if secant is not None else
                 f": roughly {rough(SECANT_STEP_RUNS)} on one core on central secants, {rough(LM_STEP_RUNS)} with forward mode's "
                 "Jacobian (chosen at the first start)")
        say("identify: " + (f"{screen} starting points screened, then Levenberg-Marquardt from the best {kept}" if screen else
                            f"Levenberg-Marquardt from {kept} given start(s)")
            + f" at {len(widths)} smoothing width(s), at most {int(lm_steps)} steps each, then the intervals checked"
            + guess + " plus compilation")

    def lap(phase, line=None):
        nonlocal clock
        now = time.perf_counter()
        wall[phase] = wall.get(phase, 0.0) + now - clock
        if say and line:
            say(f"identify: {line} ({now - clock:.1f} s)")
        clock = now

    if recording.commanded is not None:  # the test must be the scene's: else a different command is fitted as clearance
        commanded = np.asarray(_fit_and_jacobian(fit, jnp.asarray(x0), widths[-1])[2])
        recorded = recording.at(times[window], "commanded")
        off = np.abs(recorded - commanded)
        if np.max(off) > max(COMMAND_TOLERANCE, 0.01 * float(np.max(np.abs(commanded)))):
            i, j = np.unravel_index(int(np.argmax(off)), off.shape)
            raise RecordingError(
                f"{recording.source}: the recording's commanded {recording.axes[j]} angle is not the scene's drive: "
                f"{recorded[i, j]:.6g} rad against the scene's {commanded[i, j]:.6g} rad at {times[window][i]:g} s. The "
                "model must run the test's profile (the scene's scan or profile_times/profile_angles), or the difference "
                "is fitted as clearance." + _unit_slip(recorded[:, j], commanded[:, j]))
    lap("check", "the recording's command checked against the scene's" if recording.commanded is not None else None)
    centre, reach = np.log(x0), np.full(len(parameters), math.log(BOUND))
    x_starts, screened = _starts(fit, x0, widths[-1], starts, search)
    lap("screen", f"{screened} starting points costed, Levenberg-Marquardt from the best {len(x_starts)}" if screened else None)
    fit, jacobian = _choose_jacobian(fit, x_starts[0], widths[-1], secant)
    lap("jacobian", f"the residual's Jacobian: {jacobian}")
    # A physical parameter is held at its start while the contacts are smoothed wider than the
    # scene's (its reach ~0 about it): the wide smoothing adds a compliance of its own, which a
    # stiffness would absorb and run to its bound. It is released at the scene's width.
    physical = np.array([u != "m" for u in units])
    tried = []
    for xs in x_starts:
        free = _unbounded(xs, centre, reach)
        held_centre, held_reach = np.where(physical, np.log(xs), centre), np.where(physical, 1e-9, reach)
        z = free if len(widths) == 1 else np.where(physical, 0.0, free)  # held: 0 about the start
        for k, width in enumerate(widths):
            last = k == len(widths) - 1
            if last and k > 0:
                z = np.where(physical, free, np.asarray(z))
            z, cost, steps, _ = _solve(fit, jnp.asarray(z), width, int(lm_steps), *(jnp.asarray(v) for v in (
                (centre, reach) if last else (held_centre, held_reach))))
            lap("fit", f"start {len(tried) + 1} of {len(x_starts)}, width {1e6 * float(width):.3g} µm: {int(steps)} steps, "
                       f"residual {math.sqrt(float(cost) / measured.size):.3g} µrad rms")
        tried.append((float(cost), z, int(steps)))
    cost, z, steps = min(tried, key=lambda t: t[0])
    centre, reach = jnp.asarray(centre), jnp.asarray(reach)

    def assess(z):
        """The fit at `z` (the last width's: every parameter free) and the Gauss-Newton step left
        from it along each direction the recording determines, in that direction's standard errors."""
        x = np.asarray(_bounded(z, centre, reach))
        jac, fitted, _ = (np.asarray(a) for a in _fit_and_jacobian(fit, jnp.asarray(x), widths[-1]))
        r = ((fitted - measured) / UNIT).ravel()
        s2 = max(float(np.sum(r**2)) / max(r.size - len(parameters), 1), (RESOLVED / UNIT) ** 2)  # floored: result.RESOLVED
        scaled, (values, vectors), cov_x = _information(jac, x, s2)
        remaining = (np.linalg.pinv(scaled) @ r) @ vectors  # relative step, in the eigenvectors
        seen = 1.0 / np.sqrt(values) < DETERMINED
        return x, fitted, r, s2, values, vectors, cov_x, np.abs(remaining[seen]) * np.sqrt(values[seen])

    # Converged: the Gauss-Newton step left is below a tenth of each determined direction's
    # standard error (Levenberg-Marquardt's own criterion can fail on the adaptive solve's noise
    # in the cost). Where it is not, a Gauss-Newton polish; where that cannot lower the cost, the
    # estimate is at the cost's numerical floor, and within one standard error counts: the step
    # left is then the solve's noise in the Jacobian, not a distance to the minimum.
    estimate_x, fitted, r, s2, values, vectors, cov_x, left = assess(z)
    converged = bool(np.all(left <= 0.1))
    if not converged:
        polished, polished_cost = _polish(fit, jnp.asarray(z), widths[-1], centre, reach)
        if float(polished_cost) < cost:  # kept only where it lowers the cost
            estimate_x, fitted, r, s2, values, vectors, cov_x, left = assess(polished)
            converged = bool(np.all(left <= 0.1))
        else:
            converged = bool(np.all(left <= 1.0))
    converged = converged and math.isfinite(s2)
    profile = _profile(fit, estimate_x, x0, cov_x, s2, widths[-1], screened or None, float(np.sum(r**2)))
    lap("assess", "the Jacobian, covariance and intervals at the estimate, the intervals checked along their profiles")
    n = r.size
    directions = tuple(sorted(((1.0 / math.sqrt(v), vectors[:, k]) for k, v in enumerate(values)), key=lambda d: d[0]))
    estimate = scale * estimate_x
    return Identification(
        names=parameters, units=units, estimate=estimate, covariance=cov_x * np.outer(scale, scale), sigma=math.sqrt(s2) * UNIT, n=n,
        cost=float(np.sum(r**2)), times=times[window], measured=measured, fitted=fitted, directions=directions,
        steps=steps, converged=converged, starts=tuple(t[0] for t in tried), screened=screened, noise=recording.noise,
        scene=with_parameters(scene, parameters, jnp.asarray(estimate)), wall=wall, profile=profile, jacobian=jacobian,
    )


def _choose_jacobian(fit: _Fit, x, width, secant) -> tuple[_Fit, str]:
    """The fit with the residual's Jacobian `identify(secant=...)` asks for, and that choice in
    words: where it is automatic (`None`), the forward-mode Jacobian and the central secants at
    `x` (the first start) compared, secants taken where they differ by more than `SECANT_SWITCH`
    (or cannot be compared: a run that failed)."""
    if secant is False:
        return fit, "forward mode through the solve (as asked)"
    if secant is not None:
        if not (isinstance(secant, (int, float)) and not isinstance(secant, bool) and 0 < secant < 1):
            raise ValueError(f"identify: secant={secant!r} must be None (chosen), False (forward mode) or a relative step in "
                             "(0, 1), e.g. 0.02.")
        return dataclasses.replace(fit, secant=float(secant)), f"central secants at ±{100 * secant:g} % of each parameter (as asked)"
    secants = dataclasses.replace(fit, secant=SECANT_STEP)
    # Both from the forward-mode program (compiled for the assessment in any case): its
    # Jacobian at x and its primal, the model's angles, at x e^(+-h) along each parameter.
    x = np.asarray(x, dtype=float)
    forward = np.asarray(_fit_and_jacobian(fit, jnp.asarray(x), width)[0])
    points, span = _secant_points(jnp.asarray(x), SECANT_STEP)
    angles = np.stack([np.asarray(_fit_and_jacobian(fit, point, width)[1]) for point in points])
    central = np.asarray(_central(angles / UNIT, span))
    scale = float(np.linalg.norm(central))
    differs = float(np.linalg.norm(forward - central)) / scale if scale > 0 else math.inf
    if np.isfinite(differs) and differs <= SECANT_SWITCH:
        return fit, f"forward mode through the solve (within {differs:.2g} of the central secants at the first start)"
    return secants, (f"central secants at ±{100 * SECANT_STEP:g} % of each parameter: the forward-mode Jacobian at the first "
                     f"start differs from them by {differs:.3g} of their norm (through a rattling stage the trajectory's "
                     "tangents grow with the impacts' sensitivity, while the trajectory moves smoothly with a clearance)")


def own_width(scene) -> jax.Array:
    """The scene's smoothing width (m) as an array: one compiled program for every width."""
    return jnp.asarray(float(np.ravel(_widths(scene)[0])[0]))


def _scales(scene, parameters):
    """`(units, scale)`: each parameter is estimated as x = value / scale, in µm for a clearance
    or backlash and as a multiple of the scene's value for a physical parameter; the scene's
    values must be > 0 (x is estimated on a log scale)."""
    values = np.asarray(parameter_values(scene, parameters))
    if np.any(~(values > 0)):
        raise ValueError(f"identify: the scene's values of {[p for p, v in zip(parameters, values) if not v > 0]} are not > 0: "
                         "give the scene a positive starting value (they are estimated on a log scale).")
    units = parameter_units(scene, parameters)
    return units, np.array([UNIT if u == "m" else v for u, v in zip(units, values)])


def _information(jac, x, s2):
    """The relative Fisher information $D J^TJ D / s^2$ ($D$ = `x`, the values the Jacobian
    `jac` is taken at, in its units) in its eigenvectors, and the covariance of `x`:
    `(scaled Jacobian, (eigenvalues, eigenvectors), covariance)`. A direction the recording does
    not see has an eigenvalue at rounding level: floored there, its variance is huge, not
    dropped (a pseudo-inverse would drop it and report the parameters that load on it as sharply
    determined)."""
    scaled = jac * x[None, :]
    values, vectors = np.linalg.eigh(scaled.T @ scaled / s2)
    if not float(values.max()) > 1e-200:  # the recording sees none of them (no reversal, a joint that does not move)
        return scaled, (np.full_like(values, 1e-200), vectors), np.full((x.size, x.size), np.inf)
    values = np.maximum(values, float(values.max()) * 1e-15)
    return scaled, (values, vectors), x[:, None] * ((vectors / values) @ vectors.T) * x[None, :]


def _unit_slip(recorded, commanded) -> str:
    """A sentence naming the unit slip where the recorded command is the scene's times the factor
    between two angle units (values in one written under the other's header) to 1 %, else ""."""
    big = np.abs(commanded) > 0.5 * np.max(np.abs(commanded))
    if not np.any(big):
        return ""
    ratio = float(np.median(recorded[big] / commanded[big]))
    units = {f: u for u, f in ANGLE_UNITS.items()}  # one name per factor (µrad for urad and µrad alike)
    for said, written in ((s, w) for s in units for w in units if s != w):
        if abs(ratio / (said / written) - 1) < 0.01:
            return (f" The two are {ratio:.4g}x apart: the header's unit is likely wrong (values in {units[written]} under a "
                    f"[{units[said]}] header?).")
    return ""


def synthetic_recording(scene, values=None, *, duration: float, n_save: int, start: str = "steady", noise: float = 0.0,
                        quantum: float = 0.0, key=None, axes=("azimuth",), **run) -> Recording:
    """A recording the model makes of itself: `scene` at `values` (its design vector, m, or a
    `{parameter: value}` dict of any of `parameter_names(scene)`, SI; default its own) run for `duration` (s) with `n_save` saves, its output angles plus encoder noise (standard
    deviation `noise`, rad, drawn with `key`) and quantisation to steps of `quantum` (rad; 0:
    none; a 20-bit encoder: $2\\pi / 2^{20}$ = 6.0 µrad)."""
    from ..mechanism.scene import simulate

    if isinstance(values, dict):
        names = check_names(scene, values, "synthetic_recording")
        unit = with_parameters(scene, names, jnp.asarray([values[n] for n in names], dtype=float))
    else:
        unit = scene if values is None else with_design(scene, jnp.asarray(values, dtype=float))
    res = simulate(unit, duration, start=start, n_save=n_save, **run)
    columns = [AXES.index(a) for a in axes]
    angles = np.asarray(res.joint_angle)[:, columns]
    if noise > 0:
        angles = angles + noise * np.asarray(jax.random.normal(jax.random.key(0) if key is None else key, angles.shape))
    if quantum > 0:
        angles = quantum * np.round(angles / quantum)
    return Recording(np.asarray(res.ts), angles, tuple(axes), np.asarray(res.commanded_angle)[:, columns],
                     noise=math.hypot(noise, quantum / math.sqrt(12)) or None, source="synthetic")
