"""Identifying an as-built unit: the clearances and backlash (and, where asked, the joints' drag,
mesh stiffness and damping: `tolerax.identification.parameters`) that make the model reproduce a
test recording, how well the recording determines each, and the identified unit as a scene.

**Estimate.** With $\\theta$ the chosen parameters and the others at the scene's values,
the residual is the model's output angle at the recording's times minus the measured one,

$$r_i(\\theta) = \\frac{\\phi_i^{\\text{model}}(\\theta) - \\phi_i^{\\text{measured}}}{1\\,\\mu\\text{rad}},$$

over the saves in `[settle, duration]` and the recorded axes (and, where the recording has the
motor torque, each torque's misfit times $\\sigma_\\phi / \\sigma_T$, the encoder's noise over the
torque's: weighted least squares of the two channels), minimised by Levenberg-Marquardt
(`optimistix`) with the exact Jacobian of the solve (forward mode through diffrax). The
parameters are optimised as $\\log(\\theta / 1\\,\\mu m)$ (a clearance or backlash) or
$\\log(\\theta / \\theta_{\\text{scene}})$ (a physical parameter), so they stay positive; the contacts' smoothing
width is continued from wide to narrow (`widths`; on central secants the scene's own alone), and several starts are run because
clearances and drag make the residual non-convex (the best of a Sobol screen over the prior box,
`starts`, `search`; where the best of them misses the recording with several parameters, each
again along its own line through it); the lowest residual wins.

**How well.** At the estimate, with $J = \\partial r/\\partial\\theta$ and $s^2 = \\lVert r \\rVert^2
/ (N - p)$ the residual variance, the Gauss-Newton covariance is $s^2 (J^TJ)^{+}$ and a 95 %
interval $\\hat\\theta \\pm 1.96\\,\\sigma_\\theta$ (the linearised one: it holds where the residual is
close to quadratic over the interval and the residuals are independent; `tests/test_identify.py`
measures its coverage on synthetic recordings instead of assuming it). Where the model does not
reproduce its own run (through a rattling stage a rounding-level perturbation changes its
impacts), the estimate moves with the run's realisation: the covariance adds the estimate's
spread over the model's realisations at points $10^{-9}$ from it, twice (the recording is one
realisation and the fit another: `fit._model_noise`; zero to rounding on the lumped joint).
Each interval is checked
against the residual itself along its profile path $\\hat\\theta \\pm k\\,\\Sigma e_j/\\sigma_j$ (the
other parameters at their linearised conditional best), where the linearised cost rises by
$k^2 s^2$: the measured rise over that at $k$ = 1.96, 10 and 100 (`Identification.profile`) is
1 where the residual is quadratic (read where that rise exceeds the cost's own spread over the
model's realisations, `COST_NOISE` times); an interval whose ratio at 1.96 or 10 is below
1 / `PROFILE_FACTOR` or above `STEEP_FACTOR` does not hold (`Identification.holds`, the status says so); where it rises on one
side and stays within the 95 % threshold out to 10 standard errors on the other, the parameter is
bounded on one side only (`Identification.one_sided`: a backlash larger than the recording takes
up). Where the recording does not see a parameter at its estimate at all (its linearised interval
past the bounds: the plateau itself), its profile-likelihood bounds are read instead, the others
re-fitted (`tolerax.identification.profile`). The identifiability
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

import jax
import jax.numpy as jnp
import numpy as np

from ..design.features import with_design
from ..design.objectives import PointingObjective, _widths
from ..eta import human_seconds, rough_wall
from .fit import (REALISATIONS_ALONE, at_bound, centre_reach, inside, limits_of, SECANT_STEP, STARTS_KEPT, UNIT, _bounded, _choose_jacobian, _Fit, _fit_and_jacobian, _information,
                  _in_batches, _model_noise, _polish, _profile, _solve, _starts, _unbounded)
from .profile import profile_bounds
from .parameters import check_names, parameter_units, parameter_values, with_parameters
from .recording import AXES, Recording, RecordingError, _check_measured, _unit_slip
from .result import DETERMINED, LOADING, OPEN_RISE, PROFILE_STEPS, RESOLVED, Identification, show  # noqa: F401 (Identification, show: imported from here by callers)

# Runs of the scene (at rough_wall's pace) a Levenberg-Marquardt step costs per parameter and
# one more, for the rough time said before the work: timed on the lumped azimuth scan with one
# parameter, compiled, 13-20 runs a step, i.e. 7-10 per (parameter + 1); the time said is the
# steps' budget, which a fit that converges early does not use (an order of magnitude).
LM_STEP_RUNS = 8
# Runs of the scene a Levenberg-Marquardt step on secants costs per (parameter + 1), for the
# rough time: the 2p points (one batched run) and the trial point, rounded up.
SECANT_STEP_RUNS = 2
# The default screen (`identify(starts=None)`): SCREEN Sobol points for one parameter, doubled
# for each further one (a power of 2 keeps the sequence balanced), at most SCREEN_MAX.
SCREEN, SCREEN_MAX = 32, 256
# Where the best fit from the screen's starts misses the recording by more than this many standard
# deviations of its residual variance (a chi-square's, sqrt(2 / dof) relative), each parameter is
# screened again along its line through it (`identify(starts=...)`): a residual at the noise is
# below it with a probability of 0.999, while a wrong basin's sits above the noise by more than
# the model's own misfit.
LINE_CHI = 3.0
# The wide smoothing width (m) of the default continuation (`_continuation`).
WIDE = 1e-6
COMMAND_TOLERANCE = 20e-6  # rad: a recording's commanded angle may differ this much (or 1 % of its range) from the scene's


def _model_times(recording: Recording, duration: float, n_save: int | None) -> tuple[int, np.ndarray]:
    if n_save is None:
        step = float(np.median(np.diff(recording.time)))
        n_save = int(min(max(round(duration / step) + 1, 3), 2001))
    return n_save, np.linspace(0.0, duration, n_save)


def identify(scene, recording: Recording, parameters=None, *, settle: float = 0.0, duration: float | None = None,
             n_save: int | None = None, start: str = "steady", widths=None, starts=None, search: float = 2.0,
             lm_steps: int = 20, integrator="auto", secant: float | bool | None = None, progress=False, bounds=None,
             **run) -> Identification:
    """The parameters `parameters` of `scene` that reproduce `recording` (module docstring).

    **Arguments:**

    - `scene`: the model (a `Mechanism` or `TestBench`) whose drive is the one the recording
      was made with; its other parameters stay at its values.
    - `recording`: a `Recording` (`read_recording`); its axes must be joints of the scene. Where
      it has a motor torque, the residual holds the torque's misfit too (`AbstractJoint.motor_torque`,
      weighed by `noise / torque_noise`, both of which it must then state; a `Mechanism` scene,
      its recorded joints lumped or planetary); to fit the angles alone, give it without
      (`dataclasses.replace(recording, torque=None)`).
    - `parameters`: names from `parameter_names(scene)`: its design features (clearances and
      backlash, m) and its joints' physical parameters (`azimuth.drag_torque`, N m;
      `azimuth.sun_mesh_stiffness`, N/m; damping ratios: `tolerax.identification.parameters`);
      default all the design features. The scene's values are the first start.
    - `settle` (s): residuals from this time on; `duration` (s): the model's run, default the
      recording's length; `n_save`: the model's saves over it (default: the recording's rate,
      at most 2001). `start`: the model's initial state (`simulate`).
    - `widths`: the smoothing widths (m) continued through, `None` in it the scene's own; the
      estimate, its covariance and the fit are the last width's. Default (`None`): `WIDE` then
      the scene's own where the Jacobian is forward mode's, the scene's own alone on central
      secants (`_continuation`).
    - `starts`: an int: that many points of a Sobol sequence over the box within a factor
      `search` (2) of the scene's values either side, and the scene's values, costed against the
      recording in one batched run; Levenberg-Marquardt runs from the `STARTS_KEPT` (2) best.
      Default (`None`): `SCREEN` (32) points for one parameter, doubled for each further one,
      at most `SCREEN_MAX`: the box's volume grows with the parameters while a basin's width in
      each does not. The fit of a clearance or a drag is not convex: from a start 40 % off it
      can stop in another basin with a residual many times the noise (the full stage's pitch
      backlash: a plateau at larger backlash, its residual above the noise, beside the truth's
      narrow basin). Where the best fit from them misses the recording (its residual variance
      over the stated noise's by more than `LINE_CHI` of its standard deviations) and several
      parameters are identified, each is screened
      again along its own line through that fit (`_lines`: as many points, the others held) and
      Levenberg-Marquardt runs from the lowest point where it is below the fit: a screen in p
      dimensions lies ~its p-th root of points apart in each, too coarse for a basin a few per
      cent wide. Or a tuple: the starts, as
      multiples of the scene's values. Every parameter is kept within its bounds: `bounds`.
    - `bounds`: `{name: (low, high)}` (the parameter's SI unit: m for a clearance or backlash;
      0 < low < high, the scene's value between them): what the unit can physically have (a
      drawing's limits, a stiffness's plausible range). Default, for each parameter not named: a
      factor `fit.BOUND` (100) of the scene's value either side. The screen's points are moved
      inside them; an estimate at a bound is one the recording does not determine (the table
      says so), and a profile-likelihood bound open on one side reaches to them.
    - `lm_steps`: Levenberg-Marquardt's steps per width, at most (its first damping Marquardt's,
      `DAMPING` of the largest diagonal of $J^TJ$ at the start; its tolerance: `LM_TOL`; then
      where the best is not within a tenth of a standard error, `POLISH_STEPS` Gauss-Newton steps
      at `POLISH_TOL`, kept if they lower the cost);
      `integrator`: the model's run settings (a `tolerax.Integrator`, a preset's name, or
      `"auto"`: the scene's automatic choice, on a design unit's step budget:
      `PointingObjective`'s); `**run`: its other `PointingObjective` fields.
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
    `COMMAND_TOLERANCE` or 1 % of its range; without one, its measured angle's span more than
    `recording.SPAN_FACTOR` times the model's at the scene's values, or less than its inverse; a
    unit slip named) and `ValueError` for unknown parameters, a scene
    value that is not > 0, starts outside the bounds, or bounds that are not (`bounds`).
    """
    parameters = check_names(scene, parameters)
    if starts is None:
        starts = min(SCREEN * 2 ** (len(parameters) - 1), SCREEN_MAX)
    fit, x0, scale, units, times, window, measured, duration = _problem(scene, recording, parameters, settle, duration, n_save,
                                                                        start, integrator, run)
    given = None if widths is None else [own_width(scene) if w is None else jnp.asarray(w, dtype=float) for w in widths]
    final = own_width(scene) if given is None else given[-1]  # the estimate's width: the check, screen and choice run at it
    limits = limits_of(parameters, x0, scale, bounds)  # (2, p), x's units: refused before any run
    clock = time.perf_counter()
    wall = {}
    say = (lambda line: print(line, file=sys.stderr, flush=True)) if progress is True else (progress or None)
    if say is not None:
        # The screen's batched costs, then from each kept start per width up to lm_steps
        # Levenberg-Marquardt steps, each LM_STEP_RUNS runs per parameter and one more (a
        # forward-mode Jacobian through the adaptive solve, which optimistix's linearisation runs
        # again for each product), then the intervals' check (each parameter's profile path at
        # PROFILE_STEPS both sides, and the model's realisations where no screen's batch holds
        # them), at rough_wall's pace: an order of magnitude, not a bound.
        # A step on central secants instead: SECANT_STEP_RUNS runs per (parameter + 1). Where the
        # Jacobian is chosen (secant=None) both are said: the choice is made at the first start.
        one = rough_wall(scene, duration, fit.objective.integrator)
        screen = starts + 1 if isinstance(starts, int) else 0  # given starts are fitted as they are
        kept = min(STARTS_KEPT, screen) if screen else len(starts)
        p = len(parameters)

        def rough(step_runs, n_widths):
            realisations = 0 if screen else REALISATIONS_ALONE  # else in the check's batch (`_profile`)
            runs = screen + kept * n_widths * int(lm_steps) * (p + 1) * step_runs + 2 * p * len(PROFILE_STEPS) + p + 1 + realisations
            return human_seconds(max(runs * one, 1.0))

        # The widths each Jacobian would run through (`_continuation`: the choice comes later).
        n_forward, n_secant = (len(_continuation(given, f, final)) for f in (fit, dataclasses.replace(fit, secant=SECANT_STEP)))

        guess = ("" if one is None else f": roughly {rough(LM_STEP_RUNS, n_forward)} on one core" if secant is False else
                 f": roughly {rough(SECANT_STEP_RUNS, n_secant)} on one core" if secant is not None else
                 f": roughly {rough(SECANT_STEP_RUNS, n_secant)} on one core on central secants, "
                 f"{rough(LM_STEP_RUNS, n_forward)} with forward mode's Jacobian (chosen at the first start)")
        n_widths = (f"{n_forward}" if secant is False else f"{n_secant}" if secant is not None or n_forward == n_secant else
                    f"{n_forward} ({n_secant} on central secants)")
        say("identify: " + (f"{screen} starting points screened, then Levenberg-Marquardt from the best {kept}" if screen else
                            f"Levenberg-Marquardt from {kept} given start(s)")
            + f" at {n_widths} smoothing width(s), at most {int(lm_steps)} steps each, then the intervals checked"
            + guess + " plus compilation")

    def lap(phase, line=None):
        nonlocal clock
        now = time.perf_counter()
        wall[phase] = wall.get(phase, 0.0) + now - clock
        if say and line:
            say(f"identify: {line} ({now - clock:.1f} s)")
        clock = now

    # The test must be the scene's: else a different command (or a unit slip) is fitted as clearance.
    _, angles, commanded = (np.asarray(a) for a in _fit_and_jacobian(fit, jnp.asarray(x0), final)[:3])
    if recording.commanded is None:  # the measured angle's span against the model's at the scene's values
        _check_measured(recording, measured, angles)
    else:
        recorded = recording.at(times[window], "commanded")
        off = np.abs(recorded - commanded)
        if np.max(off) > max(COMMAND_TOLERANCE, 0.01 * float(np.max(np.abs(commanded)))):
            i, j = np.unravel_index(int(np.argmax(off)), off.shape)
            raise RecordingError(
                f"{recording.source}: the recording's commanded {recording.axes[j]} angle is not the scene's drive: "
                f"{recorded[i, j]:.6g} rad against the scene's {commanded[i, j]:.6g} rad at {times[window][i]:g} s. The "
                "model must run the test's profile (the scene's scan or profile_times/profile_angles), or the difference "
                "is fitted as clearance." + _unit_slip(recorded[:, j], commanded[:, j]))
    lap("check", "the recording checked against the scene's drive")
    centre, reach = centre_reach(limits, x0)
    x_starts, screened = _starts(fit, x0, final, starts, search, limits)
    lap("screen", f"{screened} starting points costed, Levenberg-Marquardt from the best {len(x_starts)}" if screened else None)
    fit, jacobian = _choose_jacobian(fit, x_starts[0], final, secant)
    lap("jacobian", f"the residual's Jacobian: {jacobian}")
    widths = _continuation(given, fit, final)
    # A physical parameter is held at its start while the contacts are smoothed wider than the
    # scene's (its reach ~0 about it): the wide smoothing adds a compliance of its own, which a
    # stiffness would absorb and run to its bound. It is released at the scene's width.
    physical = np.array([u != "m" for u in units])
    n_residuals = measured.size + (0 if fit.torque_measured is None else int(np.size(fit.torque_measured)))
    tried = []

    def fit_from(xs, label):
        """Levenberg-Marquardt from `xs` through the widths: `(cost, z, steps)`."""
        free = _unbounded(xs, centre, reach)
        held_centre, held_reach = np.where(physical, np.log(xs), centre), np.where(physical, 1e-9, reach)
        z = free if len(widths) == 1 else np.where(physical, 0.0, free)  # held: 0 about the start
        for k, width in enumerate(widths):
            last = k == len(widths) - 1
            if last and k > 0:
                z = np.where(physical, free, np.asarray(z))
            z, cost, steps, _ = _solve(fit, jnp.asarray(z), width, int(lm_steps), *(jnp.asarray(v) for v in (
                (centre, reach) if last else (held_centre, held_reach))))
            lap("fit", f"{label}, width {1e6 * float(width):.3g} µm: {int(steps)} steps, "
                       f"residual {math.sqrt(float(cost) / measured.size):.3g} µrad rms")
        return float(cost), z, int(steps)

    for xs in x_starts:
        tried.append(fit_from(xs, f"start {len(tried) + 1} of {len(x_starts)}"))
    # A misfit after the screen's starts (the residual's variance over the stated noise's by more
    # than LINE_CHI of its own standard deviations, sqrt(2 / dof) of it: the wrong basin, where
    # the truth's leaves the noise alone), with several parameters: the screen's points lie too far
    # apart in each parameter to find a basin a few per cent wide (the full-stage dual's pitch
    # backlash: a narrow dip below a plateau at larger backlash, whose points the screen finds
    # instead), so each parameter is screened again along its own line through the best fit,
    # the others held, at the screen's number of points (its compiled batch), and
    # Levenberg-Marquardt runs from the lowest of them where it is below the fit.
    line_screened = 0
    best = min(tried, key=lambda t: t[0])
    dof = max(n_residuals - len(parameters), 1)
    misfit = recording.noise is not None and best[0] / dof > (recording.noise / UNIT) ** 2 * (1 + LINE_CHI * math.sqrt(2 / dof))
    if screened and len(parameters) > 1 and misfit:
        x_best = np.asarray(_bounded(jnp.asarray(best[1]), jnp.asarray(centre), jnp.asarray(reach)))
        points = inside(_lines(x_best, x0, search, screened), limits)
        costs = np.sum(_in_batches(fit, points, final, screened) ** 2, axis=1)
        costs = np.where(np.isfinite(costs), costs, np.inf)
        line_screened = len(points)
        lap("screen", f"the fit's residual is {math.sqrt(best[0] / n_residuals) / (recording.noise / UNIT):.2g}x the noise: "
                      f"{line_screened} points costed along each parameter through it, the lowest "
                      f"{'below' if costs.min() < best[0] else 'not below'} the fit")
        if costs.min() < best[0]:
            tried.append(fit_from(points[int(np.argmin(costs))], "from the lines' lowest point"))
    cost, z, steps = min(tried, key=lambda t: t[0])
    centre, reach = jnp.asarray(centre), jnp.asarray(reach)

    def assess(z):
        """The fit at `z` (the last width's: every parameter free) and the Gauss-Newton step left
        from it along each direction the recording determines, in that direction's standard errors."""
        x = np.asarray(_bounded(z, centre, reach))
        jac, fitted, _, r = (np.asarray(a) for a in _fit_and_jacobian(fit, jnp.asarray(x), widths[-1]))
        r = r if np.all(np.isfinite(fitted)) else np.full_like(r, np.nan)  # a failed run: no residual (not the fit's 1e6)
        s2 = max(float(np.sum(r**2)) / max(r.size - len(parameters), 1), (RESOLVED / UNIT) ** 2)  # floored: result.RESOLVED
        scaled, (values, vectors), cov_x = _information(jac, x, s2)
        remaining = (np.linalg.pinv(scaled) @ r) @ vectors  # relative step, in the eigenvectors
        seen = 1.0 / np.sqrt(values) < DETERMINED
        return x, fitted, r, s2, values, vectors, cov_x, np.abs(remaining[seen]) * np.sqrt(values[seen]), jac

    # Converged: the Gauss-Newton step left is below a tenth of each determined direction's
    # standard error (Levenberg-Marquardt's own criterion can fail on the adaptive solve's noise
    # in the cost). Where it is not, a Gauss-Newton polish; where that cannot lower the cost, the
    # estimate is at the cost's numerical floor, and within one standard error counts: the step
    # left is then the solve's noise in the Jacobian, not a distance to the minimum.
    estimate_x, fitted, r, s2, values, vectors, cov_x, left, jac = assess(z)
    converged = bool(np.all(left <= 0.1))
    if not converged:
        polished, polished_cost = _polish(fit, jnp.asarray(z), widths[-1], centre, reach)
        if float(polished_cost) < cost:  # kept only where it lowers the cost
            estimate_x, fitted, r, s2, values, vectors, cov_x, left, jac = assess(polished)
            converged = bool(np.all(left <= 0.1))
        else:
            converged = bool(np.all(left <= 1.0))
    converged = converged and math.isfinite(s2)
    profile, line, realised_x, realised = _profile(fit, estimate_x, limits, cov_x, s2, widths[-1], screened or None, r)
    model_cov, model_rms = _model_noise(jac, estimate_x, r, realised_x, realised, cov_x, s2)
    lap("assess", "the Jacobian, covariance and intervals at the estimate, the intervals checked along their profiles, "
                  f"the model's own realisations ({len(realised)}: {model_rms:.2g} µrad rms apart)")
    # A parameter the recording does not see at its estimate (its linearised interval reaching past
    # the bounds, on no determined direction: not "in combination"): its profile-likelihood bounds
    # instead (a backlash on the plateau above its flank).
    se_x, seen = np.sqrt(np.maximum(np.diag(cov_x), 0.0)), np.abs(vectors[:, 1.0 / np.sqrt(values) < DETERMINED]) > LOADING
    walk = [j for j in range(len(parameters)) if not se_x[j] < DETERMINED * estimate_x[j] and not seen[j].any()
            and not (limits[0, j] < estimate_x[j] - 1.96 * se_x[j] and estimate_x[j] + 1.96 * se_x[j] < limits[1, j])]
    # An estimate stopped at a bound: the Gauss-Newton step from it points past the bound.
    finite = bool(np.all(np.isfinite(jac)) and np.all(np.isfinite(r)))
    stopped = at_bound(estimate_x, -np.linalg.lstsq(jac, r, rcond=None)[0] if finite else np.full(len(parameters), np.nan), se_x, limits)
    walked, lowest, solves = profile_bounds(fit, estimate_x, float(np.sum(r**2)), s2, widths[-1], limits, walk, screened or None,
                                            lm_steps, centre, reach)
    lap("profile", walk and f"the profile-likelihood bounds of {', '.join(parameters[j] for j in walk)} (the recording does "
                            f"not see {'them' if len(walk) > 1 else 'it'} at the estimate): {solves} re-fits")
    converged = converged and not np.any(lowest < float(np.sum(r**2)) - OPEN_RISE * s2)  # a lower cost along a profile: not the minimum
    n = r.size
    directions = tuple(sorted(((1.0 / math.sqrt(v), vectors[:, k]) for k, v in enumerate(values)), key=lambda d: d[0]))
    estimate = scale * estimate_x
    torque = {} if not fit.torque_axes else {  # the torque part of the residual, back in N m
        "torque_measured": np.asarray(fit.torque_measured),
        "torque_fitted": np.asarray(fit.torque_measured) + r[measured.size:].reshape(-1, len(fit.torque_axes)) / float(fit.torque_weight)}
    return Identification(
        names=parameters, units=units, estimate=estimate, covariance=(cov_x + model_cov) * np.outer(scale, scale),
        model_covariance=model_cov * np.outer(scale, scale), model_rms=model_rms * UNIT, sigma=math.sqrt(s2) * UNIT, n=n,
        cost=float(np.sum(r**2)), times=times[window], measured=measured, fitted=fitted, directions=directions,
        steps=steps, converged=converged, starts=tuple(t[0] for t in tried), screened=screened, line_screened=line_screened,
        noise=recording.noise,
        scene=with_parameters(scene, parameters, jnp.asarray(estimate)), wall=wall, profile=profile, profile_line=line,
        jacobian=jacobian, profile_bound=walked * scale[:, None], profile_lowest=lowest, limits=limits.T * scale[:, None], at_bound=stopped, **torque,
    )


def _problem(scene, recording: Recording, parameters, settle, duration, n_save, start, integrator, run):
    """The least-squares problem `identify` solves, before any solving: `(fit, x0, scale, units,
    times, window, measured, duration)`: the residual (`_Fit`: `fit.residual(x, width)`, µrad,
    at parameters x = values / scale), the scene's values as x, the scales and units, the
    model's save times and the window of them the residual reads, the recording there, the run's
    length (s). Also what a benchmark races another search on (the same batched cost)."""
    duration = recording.duration if duration is None else float(duration)
    if duration > recording.duration + 1e-12:
        raise RecordingError(f"{recording.source}: the recording lasts {recording.duration:g} s, shorter than the model's "
                             f"{duration:g} s run: record longer or give a shorter duration.")
    n_save, times = _model_times(recording, duration, n_save)
    window = times >= settle
    measured = recording.at(times[window])
    columns = [AXES.index(a) for a in recording.axes]
    objective = PointingObjective(scene, duration=duration, settle=settle, n_save=n_save, start=start,
                                  integrator=integrator, **run).forward_mode()
    units, scale = _scales(scene, parameters)
    x0 = np.asarray(parameter_values(scene, parameters)) / scale
    # The problem's data as arrays (traced): one compiled program per scene structure, parameter
    # names and shape, whichever recording, start or width (`_solve`, `_fit_and_jacobian` are module-level).
    fit = _Fit(objective, parameters, jnp.asarray(scale), jnp.asarray(np.flatnonzero(window)), jnp.asarray(columns),
               jnp.asarray(measured), **_torque_channel(scene, recording, times[window]))
    return fit, x0, scale, units, times, window, measured, duration


def _torque_channel(scene, recording: Recording, times) -> dict:
    """`_Fit`'s torque fields for a recording with a motor torque (none without): its torque at
    `times` and its weight, the encoder's noise over the torque's (µrad per N m). Refused where
    the recording does not state both noises (the two channels cannot be weighed against each
    other otherwise) or the scene has no motor to read a torque from."""
    if recording.torque is None:
        return {}
    if recording.noise is None or recording.torque_noise is None:
        raise RecordingError(f"{recording.source}: the recording has a motor torque but does not state "
                             + ("its noise" if recording.torque_noise is None else "the encoder's noise")
                             + " (Recording.noise, rad; Recording.torque_noise, N m; the command line's --noise, --encoder-bits "
                             "and --torque-noise): the fit weighs the angles and the torque by their noises. State them, or "
                             "identify from the angles alone (dataclasses.replace(recording, torque=None)).")
    from ..mechanism.mechanism import Mechanism

    if not isinstance(scene, Mechanism):
        raise RecordingError(f"{recording.source}: a motor torque is fitted on a Mechanism scene only; this one is a "
                             f"{type(scene).__name__}: identify from the angles alone (dataclasses.replace(recording, torque=None)).")
    for axis, (joint, _, _, _) in zip(scene.JOINTS, scene.joints()):
        if axis in recording.axes and joint.motor_torque(jnp.zeros(joint.layout.size), jnp.zeros(joint.layout.size), 0.0) is None:
            raise RecordingError(f"{recording.source}: the {axis} joint is ideal under a servo (its motion is prescribed): it "
                                 "has no motor torque to fit; model it lumped or planetary, or drop the torque.")
    return {"torque_axes": tuple(recording.axes), "torque_measured": jnp.asarray(recording.at(times, "torque")),
            "torque_weight": jnp.asarray(recording.noise / recording.torque_noise / UNIT)}


def _continuation(given, fit: _Fit, final) -> list:
    """The smoothing widths (m) Levenberg-Marquardt runs through: `given` where given, else
    `WIDE` then `final` (the scene's) where the Jacobian is forward mode's (the continuation
    the lumped joint's identifications are measured with), `final` alone on central secants.
    Through a rattling stage (where secants are chosen) the residual at a wide width is rugged
    at the secants' scale, its cost jumping between neighbouring points, and its minimum is not
    the scene's: Levenberg-Marquardt spends its steps there rejecting its own (its damping grows
    by a constant factor per rejection, slowly against the residual's scale), while at the
    scene's own width the cost is close to quadratic about the estimate and the fit converges
    from the screened start in a few steps."""
    if given is not None:
        return given
    return [jnp.asarray(WIDE, dtype=float), final] if fit.secant is None else [final]


def _lines(x, x0, search: float, k: int) -> np.ndarray:
    """`k` points along each parameter's line through `x` (the others held), log-spaced over the
    screen's box $[x_0/s, s\\,x_0]$: `(p k, p)`."""
    grid = x0[None, :] * search ** np.linspace(-1.0, 1.0, k)[:, None]
    return np.vstack([np.where(np.arange(x.size)[None, :] == j, grid, x[None, :]) for j in range(x.size)])


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


def synthetic_recording(scene, values=None, *, duration: float, n_save: int, start: str = "steady", noise: float = 0.0,
                        quantum: float = 0.0, key=None, axes=("azimuth",), torque_noise: float | None = None,
                        **run) -> Recording:
    """A recording the model makes of itself: `scene` at `values` (its design vector, m, or a
    `{parameter: value}` dict of any of `parameter_names(scene)`, SI; default its own) run for `duration` (s) with `n_save` saves, its output angles plus encoder noise (standard
    deviation `noise`, rad, drawn with `key`) and quantisation to steps of `quantum` (rad; 0:
    none; a 20-bit encoder: $2\\pi / 2^{20}$ = 6.0 µrad). `torque_noise` (N m, > 0): with it, each
    axis's motor torque too (`AbstractJoint.motor_torque`, a `Mechanism` scene), plus noise of
    that standard deviation (drawn with a key split from `key`)."""
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
    torque = None
    if torque_noise is not None:
        from .fit import _motor_torques

        q, u = res.states[:2]
        torque = np.asarray(jax.vmap(lambda qi, ui, ti: _motor_torques(unit, qi, ui, ti, tuple(axes)))(q, u, res.ts))
        key = jax.random.key(0) if key is None else key
        torque = torque + torque_noise * np.asarray(jax.random.normal(jax.random.fold_in(key, 1), torque.shape))
    return Recording(np.asarray(res.ts), angles, tuple(axes), np.asarray(res.commanded_angle)[:, columns],
                     noise=math.hypot(noise, quantum / math.sqrt(12)) or None, source="synthetic", torque=torque,
                     torque_noise=torque_noise)
