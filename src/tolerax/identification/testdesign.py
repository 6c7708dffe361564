"""What test to run: the scan that makes the chosen parameters best determined by a recording.

A recording determines a parameter as far as the output angle's sensitivity to it stands out of
the encoder's noise, and that depends on the test: a slow scan loads the flanks with the drag
alone (the lost motion and the drag show, the mesh stiffness does not), a fast one with the
reflector's inertia too (its deflection shows the stiffness), more reversals in the same time
cross the lost motion more often. `design_test` evaluates, at the scene's values (the best
guess before the test), the Gauss-Newton information of each candidate scan over the same
duration, encoder and saves — the relative Fisher information $D J^TJ D / \\sigma^2$ of
`identify`, $J$ the output angles' Jacobian as `identify` chooses it (forward mode through the
solve, or central secants where the rattle scrambles the tangents: decided on the plain scan and
kept for every candidate) — and proposes
the candidate whose weakest parameter is best determined (the smallest largest relative standard
error: `criterion="weakest"`, E-optimality on the parameters themselves) or the largest
determinant (`criterion="D"`, D-optimality: the volume of the joint confidence region).

That information is local: a test can be sharp at the truth and rugged around it. A fast scan
makes the drag decide when the output leaves its flank at each reversal, and the fit's cost over
the drag then has dips away from the truth, where Levenberg-Marquardt stops with a residual
many times the noise (`tests/test_identify.py`). So each candidate's noise-free cost profile of
each parameter over the prior range (`SPREAD`, 0.5-2x the guess) is checked too, and a candidate
with a dip away from the truth is not proposed: the proposal is the sharpest test whose fit has
one basin over the range. The check is one parameter at a time about the guess: a unit far from
the guess, in one parameter or several, can still meet a dip it does not see: `identify`'s
screened starts are what finds the basin then.

The candidates are sine scans (`ScanServo`: amplitude $A$, period $T$, applied to every
scanning joint alike) on a grid inside the mechanism's limits: amplitude at most `max_amplitude`
and peak rate $2\\pi A/T$ at most `max_rate` (default the scene's own scan's: a test never
drives the unit harder than the scan it was built for unless told), and at least one reversal in
the recorded window (from a steady start, at $T/4 + kT/2$). Asked for (`dwells`), slews with
dwells too (`slew_profile`: a `ProfileServo` slewing between $\\pm A$ with dwells of $d$ at
each end, passing 0 at $t = 0$, each slew as fast as the rate limit lets its shape-preserving
cubic go: $3A/$`max_rate` for the $2A$, whose peak rate is 1.5 times its mean), where the
output stops at each end and each reversal starts from rest; then every candidate runs through
one compiled program (the scanning joints' drive selects the sine or the profile by a value).
Slews are not a default candidate: their stops make the fit's cost rugged about a unit away
from the guess, which the check above (at the guess) does not see, so a proposed slew test can
identify worse than the plain scan it was predicted to beat
(`benchmarks/identify_test_design.py --dwells`). The prediction is linearised at the guess:
how much sharper the proposed test really is, at a unit's own values, comes from identifying
recordings of both (`benchmarks/identify_test_design.py`). A parameter no candidate determines
is named: no test of these families separates it (the two backlashes of a lumped joint: the
output sees their sum).
"""

import dataclasses
import math
from typing import NamedTuple

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Bool

from ..design.objectives import PointingObjective
from ..design.phases import Phases
from ..eta import human_seconds, rough_wall, time_left
from ..mechanism.drives import AbstractServo, ProfileServo, ScanServo
from .fit import UNIT, _choose_jacobian, _costs, _Fit, _fit_and_jacobian, _information
from .identify import _scales, own_width
from .parameters import check_names, parameter_values
from .recording import AXES
from .result import DETERMINED

CRITERIA = ("weakest", "D")
# The prior range a unit's values may lie in, as factors of the guess, and the points of each
# parameter's cost profile over it (`_rugged`).
SPREAD = (0.5, 2.0)
PROFILE_POINTS = 33  # steps of 4.4 %: fine enough for the fast scans' dips in the drag, which 9 points missed
FACTORS = (1 / 8, 1 / 4, 1 / 2, 1.0)  # the default grid: these multiples of the limits' amplitude and period
SLEW_FACTORS = (1 / 4, 1.0)  # the slews' grid (with `dwells`): these multiples of the limits' amplitude


class _TestServo(AbstractServo):
    """A scanning joint's drive while tests are compared: the sine scan (`scan`) or the
    tabulated profile (`profile`) as `slewing` says (a value: one program for both), the
    scan's gains."""

    scan: ScanServo
    profile: ProfileServo
    slewing: Bool[Array, ""]

    @property
    def proportional(self):
        return self.scan.proportional

    @property
    def integral(self):
        return self.scan.integral

    def angle(self, t):
        return jnp.where(self.slewing, self.profile.angle(t), self.scan.angle(t))

    def rate(self, t):
        return jnp.where(self.slewing, self.profile.rate(t), self.scan.rate(t))


def slew_profile(amplitude: float, slew: float, dwell: float, until: float, knots: int | None = None) -> tuple:
    """The knots `(times (s), angles (rad))` of slews between $\\pm$`amplitude` taking `slew` s
    each with `dwell` s at each end, past `until` s; `knots`: this many (the pattern continued).
    The first slew, from the dwell at $-A$ before $t = 0$, passes 0 at its peak rate at $t = 0$
    (a cubic between flat knots is symmetric): a steady start, as a sine scan's, its flanks
    loaded by the motion (a unit at rest sits anywhere in its lost motion)."""
    if not (slew > 0 and dwell > 0):
        raise ValueError(f"slew_profile: slew and dwell must be > 0 (s), got {slew!r} and {dwell!r}.")
    times, angles, t, side = [-slew / 2 - dwell, -slew / 2], [-amplitude, -amplitude], -slew / 2, 1.0
    while t <= until or (knots is not None and len(times) < knots):
        t += slew
        times += [t, t + dwell]
        angles += [side * amplitude] * 2
        t, side = t + dwell, -side
    if knots is not None and len(times) > knots + 1:  # the loop adds knots in pairs
        raise ValueError(f"slew_profile: {knots} knots do not reach past {until} s (it takes {len(times)}).")
    return np.array(times[:knots]), np.array(angles[:knots])


def _slew_reverses(slew: float, dwell: float, settle: float, duration: float) -> bool:
    """Does a slew from the dwell at an end (at $s/2 + d + k(s + d)$) start in `[settle, duration]`?"""
    first = slew / 2 + dwell
    k = max(math.ceil((settle - first) / (slew + dwell)), 0)
    return first + k * (slew + dwell) <= duration


def _scanning(scene) -> tuple[str, ...]:
    return tuple(j for j in AXES if isinstance(getattr(getattr(scene, j, None), "drive", None), ScanServo))


def _reverses(period: float, settle: float, duration: float) -> bool:
    """Does a scan from a steady start ($\\sin$ from 0: reversals at $T/4 + kT/2$) reverse inside
    the recorded window `[settle, duration]`?"""
    k = max(math.ceil((settle - period / 4) / (period / 2)), 0)
    return period / 4 + k * period / 2 <= duration


class _Candidate(NamedTuple):
    """One test as `_with_test` runs it: a sine's amplitude (rad) and period (s), or a slew
    test's knots (s, rad) with `slewing` True (its amplitude and cycle beside them)."""

    amplitude: float
    period: float
    times: np.ndarray
    angles: np.ndarray
    slewing: bool


def _with_test(scene, candidate):
    """`scene` (its scanning joints on `ScanServo`s) with each scanning joint's drive a
    `_TestServo` running `candidate`, a `_Candidate` (the same structure for every candidate)."""
    for joint in _scanning(scene):
        d = getattr(scene, joint).drive
        test = _TestServo(ScanServo(candidate.amplitude, candidate.period, d.proportional, d.integral),
                          ProfileServo(candidate.times, candidate.angles, d.proportional, d.integral), jnp.asarray(candidate.slewing))
        scene = eqx.tree_at(lambda s, j=joint: getattr(s, j).drive, scene, test)
    return scene


def with_profile(scene, times, angles):
    """`scene` with every scanning joint tracking the profile (`times` s, `angles` rad): a
    `ProfileServo` with the scan's gains."""
    for joint in _scanning(scene):
        drive = getattr(scene, joint).drive
        scene = eqx.tree_at(lambda s, j=joint: getattr(s, j).drive, scene, ProfileServo(times, angles, drive.proportional, drive.integral))
    return scene


def with_scan(scene, amplitude, period):
    """`scene` with every scanning joint's scan set to `amplitude` (rad) and `period` (s)
    (traceable: no new compilation)."""
    for joint in _scanning(scene):
        scene = eqx.tree_at(lambda s, j=joint: (getattr(s, j).drive.amplitude, getattr(s, j).drive.period), scene,
                            (jnp.asarray(amplitude, dtype=float), jnp.asarray(period, dtype=float)))
    return scene


def _profiles(fit: _Fit, x, width, factors) -> np.ndarray:
    """The noise-free cost $\\lVert r\\rVert^2$ (µrad²) with each parameter in turn at `factors`
    times `x`, the others at `x`: ((parameters, factors)), in one batched run."""
    p, k = x.shape[0], factors.shape[0]
    points = np.where(np.eye(p, dtype=bool)[:, None, :], x[None, None, :] * factors[None, :, None], x[None, None, :])
    return np.asarray(_costs(fit, jnp.asarray(points.reshape(p * k, p)), width)).reshape(p, k)


def _rugged(profiles, middle: int) -> np.ndarray:
    """Per parameter: does its cost profile have a dip other than at the guess (`middle`)? A fit
    started from anywhere in the range could then stop there (a local minimum)."""
    left, right = profiles[:, : middle + 1], profiles[:, middle:]
    slack = 1e-9 * np.max(profiles, axis=1, keepdims=True)  # the adaptive solve's rounding in a flat profile
    return ~(np.all(np.diff(left, axis=1) <= slack, axis=1) & np.all(np.diff(right, axis=1) >= -slack, axis=1))


@dataclasses.dataclass(frozen=True)
class TestDesign:
    """The result of `design_test`.

    - `names`, `units`: the parameters; `values`: the scene's (the guess the prediction is at).
    - `amplitude` (rad), `period` (s): per candidate (a slew test's period: its cycle, two slews
      and two dwells); `slew`, `dwell` (s): a slew test's slew and dwell times, NaN for a sine
      scan (`slew_profile` gives its knots); `relative_error` ((candidates, parameters)):
      each parameter's predicted relative standard error (floored at rounding level: a huge
      value is "not determined"); `score`: the criterion, smaller is better.
    - `rugged` ((candidates, parameters), bool): the parameter's noise-free cost profile over the
      prior range `SPREAD` has a dip away from the truth: a fit could stop there, and the
      candidate is not proposed (unless every candidate is).
    - `plain`: the index of the scene's own scan; `best`: of the proposed one.
    - `criterion`, `noise` (rad), `duration` (s), `settle` (s); `scene`: the scene with the
      proposed test (a `ScanServo`, or a `ProfileServo` for slews); `undetermined`: the
      parameters no candidate determines; `jacobian`: which Jacobian the information rests on,
      and why (`identify`'s `Identification.jacobian`).
    """

    __test__ = False  # not a pytest class, though its name starts with "Test"

    names: tuple[str, ...]
    units: tuple[str, ...]
    values: np.ndarray
    amplitude: np.ndarray
    period: np.ndarray
    relative_error: np.ndarray
    rugged: np.ndarray
    score: np.ndarray
    plain: int
    best: int
    criterion: str
    noise: float
    duration: float
    settle: float
    undetermined: tuple[str, ...]
    scene: object = dataclasses.field(repr=False, default=None)
    jacobian: str = ""
    slew: np.ndarray | None = None
    dwell: np.ndarray | None = None

    def slewing(self, k: int) -> bool:
        """Is candidate `k` a slew test?"""
        return self.dwell is not None and bool(np.isfinite(self.dwell[k]))

    def profile(self, k: int) -> tuple:
        """Candidate `k`'s profile knots `(times (s), angles (rad))` (a slew test's)."""
        return slew_profile(float(self.amplitude[k]), float(self.slew[k]), float(self.dwell[k]), self.duration)

    def test_of(self, k: int) -> str:
        """Candidate `k` in words, with its peak rate."""
        a = math.degrees(self.amplitude[k])
        if self.slewing(k):
            return (f"±{a:.3g}° slews of {self.slew[k]:.3g} s with {self.dwell[k]:.3g} s dwells "
                    f"(peak rate {3 * a / self.slew[k]:.3g} °/s)")
        return f"±{a:.3g}° × {self.period[k]:.3g} s scan (peak rate {2 * math.pi * a / self.period[k]:.3g} °/s)"

    def sharper(self) -> np.ndarray:
        """Per parameter: the plain scan's relative standard error over the proposed one's."""
        return self.relative_error[self.plain] / self.relative_error[self.best]

    def table(self) -> str:
        """The candidates and the proposal as Markdown."""
        def rel(v):
            return f"{v:.3g}" if v < 1 else "not determined"

        lines = [f"Proposed test: a {self.test_of(self.best)} for {self.duration:g} s, against the plain "
                 f"{self.test_of(self.plain)}; predicted at the scene's values with "
                 f"{1e6 * self.noise:.3g} µrad of encoder noise (criterion: {self.criterion})."
                 + (f" The output's Jacobian: {self.jacobian}." if self.jacobian else ""), "",
                 "| parameter | plain: relative standard error | proposed | sharper by |", "|---|---|---|---|"]
        worse = []
        for j, name in enumerate(self.names):
            a, b = self.relative_error[self.plain, j], self.relative_error[self.best, j]
            lines.append(f"| {name} | {rel(a)} | {rel(b)} | {f'{a / b:.3g}x' if min(a, b) < 1 else '—'} |")
            if a < 1 and b > a * 1.0001:
                worse.append(f"{name} ({a / b:.3g}x)")
        if worse and self.best != self.plain:
            lines += ["", f"The proposed test determines {', '.join(worse)} less well than the plain scan: it is chosen for "
                      f"the {'weakest parameter' if self.criterion == 'weakest' else 'criterion'}; record both where that one "
                      "matters."]
        if self.undetermined:
            lines += ["", f"Not determined by any candidate: {', '.join(self.undetermined)} (no test of these families "
                      "separates them; another measurement or a fixed value is needed)."]
        if self.rugged[self.best].any():
            lines += ["", "**Every candidate's fit is rugged** (a local minimum inside the range for "
                      f"{', '.join(n for n, r in zip(self.names, self.rugged[self.best]) if r)}): identify from several starts."]
        lines += ["", "Candidates, best score first." + ("" if self.rugged[self.best].any() else
                  f" One whose fit has another local minimum within {SPREAD[0]:g}-{SPREAD[1]:g}x of the scene's values (last "
                  "column) is not proposed, however well it scores: a fit of its recording can stop in that other basin."), "",
                  "| amplitude (°) | period (s) | slews: slew, dwell (s) | weakest relative standard error (of those some "
                  "candidate determines) | score | "
                  f"another local minimum within {SPREAD[0]:g}-{SPREAD[1]:g}x for |", "|---|---|---|---|---|---|"]
        for k in np.argsort(self.score):
            mark = " (proposed)" if k == self.best else " (plain)" if k == self.plain else ""
            dips = ", ".join(n for n, r in zip(self.names, self.rugged[k]) if r) or "none"
            seen = [j for j, n in enumerate(self.names) if n not in self.undetermined] or list(range(len(self.names)))
            slews = f"{self.slew[k]:.3g}, {self.dwell[k]:.3g}" if self.slewing(k) else "— (sine)"
            lines.append(f"| {math.degrees(self.amplitude[k]):.3g} | {self.period[k]:.3g}{mark} | {slews} | "
                         f"{rel(float(np.max(self.relative_error[k, seen])))} | {self.score[k]:.4g} | {dips} |")
        return "\n".join(lines)


def design_test(scene, parameters, *, duration: float, n_save: int, noise: float, settle: float = 0.0,
                max_amplitude: float | None = None, max_rate: float | None = None, amplitudes=None, periods=None,
                dwells=(), criterion: str = "weakest", start: str = "steady", secant: float | bool | None = None, progress=False,
                integrator="auto", **run) -> TestDesign:
    """The test (a sine scan's amplitude and period, or slews with dwells) that makes
    `parameters` of `scene` best determined by a recording of `duration` s (module docstring).

    **Arguments:**

    - `scene`: the model with its scanning joints (`ScanServo`); the recorded axes are those.
    - `parameters`: names from `tolerax.identification.parameters.parameter_names(scene)`.
    - `duration` (s), `n_save` (samples over it), `settle` (s, the first samples not fitted),
      `noise` (rad): the encoder's standard deviation, quantisation included
      ($\\sqrt{\\sigma^2 + q^2/12}$); it scales every candidate alike.
    - `max_amplitude` (rad), `max_rate` (rad/s): the mechanism's limits; default the scene's
      own scan's amplitude and peak rate.
    - `amplitudes` (rad), `periods` (s): the grid; default `FACTORS` times the limits' amplitude
      and times the plain scan's period (candidates beyond the limits dropped). The scene's own
      scan is always a candidate.
    - `dwells` (s): slew tests with these dwells join the candidates, each with slews of
      `SLEW_FACTORS` times the limits' amplitude at the rate limit (module docstring); default
      none: sine scans only. A slew test with no reversal inside the window is dropped.
    - `criterion`: "weakest" (default) or "D"; `start`, `integrator`, `**run`: the model's run
      (`identify`'s).
    - `secant`: the Jacobian, as `identify`'s (`None`: chosen on the plain scan at the guess).
    - `progress`: True prints to stderr a rough time before the candidates are evaluated (the
      simulations they need at `tolerax.eta.rough_wall`'s pace, compilation not included) and a
      line as each is done, with the time left at the pace so far; a callable receives the
      lines instead.

    **Returns:** a `TestDesign`. Raises `ValueError` for a scene with no scanning joint, unknown
    parameters or criterion, or no candidate inside the limits.
    """
    parameters = check_names(scene, parameters, "design_test")
    if criterion not in CRITERIA:
        raise ValueError(f"design_test: criterion={criterion!r} is unknown; use one of {CRITERIA}.")
    axes = _scanning(scene)
    if not axes:
        raise ValueError("design_test varies a sine scan: the scene has no joint driven by one (a scene file with "
                         "[scene] kind = \"scan\" and its mode, amplitude and period; in Python tolerax.scan, a ScanServo).")
    if not noise > 0:
        raise ValueError(f"design_test: noise={noise!r} must be > 0 (rad): the encoder's standard deviation.")
    drive = getattr(scene, axes[0]).drive
    a0, t0 = float(drive.amplitude), float(drive.period)
    max_amplitude = abs(a0) if max_amplitude is None else float(max_amplitude)
    max_rate = 2 * math.pi * abs(a0) / t0 if max_rate is None else float(max_rate)
    amplitudes = [f * max_amplitude for f in FACTORS] if amplitudes is None else list(amplitudes)
    periods = [f * t0 for f in FACTORS] if periods is None else list(periods)
    window = duration - settle
    grid = [(a0, t0)] + [(a, t) for a in amplitudes for t in periods
                         if 0 < a <= max_amplitude * (1 + 1e-12) and 2 * math.pi * a / t <= max_rate * (1 + 1e-12)
                         and _reverses(t, settle, duration) and not (a == a0 and t == t0)]
    dwells = [float(d) for d in dwells]
    if not all(math.isfinite(d) and d > 0 for d in dwells):
        raise ValueError(f"design_test: dwells={dwells!r} must be > 0 (s), or () for sine scans only.")
    slews = [(a, 3 * a / max_rate, d) for a in (f * max_amplitude for f in SLEW_FACTORS) for d in dwells
             if _slew_reverses(3 * a / max_rate, d, settle, duration)]
    if len(grid) + len(slews) < 2:
        raise ValueError(f"design_test: no candidate scan inside the limits (amplitude <= {max_amplitude:g} rad, peak rate "
                         f"<= {max_rate:g} rad/s, a reversal inside {window:g} s): widen the limits or give amplitudes and periods.")
    # One structure for every candidate: the profiles padded to one number of knots (the pattern
    # continued past the window), the sine scans carrying a placeholder profile they do not follow.
    knots = max((len(slew_profile(a, s, d, duration)[0]) for a, s, d in slews), default=2)
    candidates = [_Candidate(a, t, np.arange(float(knots)), np.zeros(knots), False) for a, t in grid] + [
        _Candidate(a, 2 * (s + d), *slew_profile(a, s, d, duration, knots), True) for a, s, d in slews]
    units, scale = _scales(scene, parameters)
    x = np.asarray(parameter_values(scene, parameters)) / scale
    times = np.linspace(0.0, duration, int(n_save))
    rows = jnp.asarray(np.flatnonzero(times >= settle))
    columns = jnp.asarray([AXES.index(a) for a in axes])
    objective = PointingObjective(scene, duration=duration, settle=settle, n_save=int(n_save), start=start, integrator=integrator,
                                  **run).forward_mode()
    width = own_width(scene)
    measured = jnp.zeros((rows.size, columns.size))
    factors = np.geomspace(SPREAD[0], SPREAD[1], PROFILE_POINTS)
    middle = int(np.argmin(np.abs(np.log(factors))))
    factors[middle] = 1.0
    errors, logdets, rugged = [], [], []
    say = Phases(progress, "design_test")
    if say.on:
        # Per candidate: a forward-mode Jacobian (about a simulation per parameter and one more)
        # and each parameter's cost profile (PROFILE_POINTS simulations each, one batched run).
        one = rough_wall(scene, duration, objective.integrator)
        runs = len(parameters) + 1 + len(parameters) * PROFILE_POINTS
        say(f"{len(candidates)} candidate {'tests' if slews else 'scans'}, each a Jacobian and {len(parameters)} cost profiles of {PROFILE_POINTS} "
            "points" + ("" if one is None else f": roughly {human_seconds(max(len(grid) * runs * one, 1.0))} on one core") +
            " plus compilation")
    for k, c in enumerate(candidates):  # one compiled program for all: each test's values are arrays of the scene
        # (sine scans alone: the scene's own ScanServo, the program as without slews)
        test = _with_test(scene, c) if slews else with_scan(scene, c.amplitude, c.period)
        candidate = eqx.tree_at(lambda o: o.scene, objective, test)
        fit = _Fit(candidate, parameters, jnp.asarray(scale), rows, columns, measured)
        if k == 0:  # the plain scan: the Jacobian chosen once for every candidate (one compiled program)
            chosen, jacobian = _choose_jacobian(fit, x, width, secant)
        fit = dataclasses.replace(fit, secant=chosen.secant)
        jac, angles, _, _ = _fit_and_jacobian(fit, jnp.asarray(x), width)
        jac = np.asarray(jac)
        # The noise-free recording at the guess, and the fit's cost profile of each parameter over the range.
        truth = eqx.tree_at(lambda f: f.measured, fit, angles)
        rugged.append(_rugged(_profiles(truth, x, width, factors), middle))
        _, (eigenvalues, _), cov = _information(jac, x, (noise / UNIT) ** 2)
        errors.append(np.sqrt(np.maximum(np.diag(cov), 0.0)) / x)
        logdets.append(float(np.sum(np.log(eigenvalues))))
        what = f"slews to ±{math.degrees(c.amplitude):.3g}°, period {c.period:.3g} s" if c.slewing else \
            f"±{math.degrees(c.amplitude):.3g}° × {c.period:.3g} s"
        say(f"candidate {k + 1} of {len(candidates)} ({what}) done{time_left(say.elapsed(), k + 1, len(candidates))}")
    errors, rugged = np.array(errors), np.array(rugged)
    seen = np.any(errors < DETERMINED, axis=0)
    if criterion == "weakest":
        # The weakest of the parameters some candidate determines: one no scan determines would
        # make every candidate equally bad and hide the differences among the others.
        score = np.max(errors[:, seen], axis=1) if np.any(seen) else np.max(errors, axis=1)
    else:
        score = -np.array(logdets)  # -log det of the relative information
    smooth = ~np.any(rugged, axis=1)
    best = int(np.argmin(np.where(smooth, score, np.inf))) if smooth.any() else int(np.argmin(score))
    amplitude, period = np.array([c.amplitude for c in candidates]), np.array([c.period for c in candidates])
    slew, dwell = (np.array([np.nan] * len(grid) + [v[i] for v in slews]) for i in (1, 2))
    plan = TestDesign(names=parameters, units=units, values=x * scale, amplitude=amplitude, period=period,
                      relative_error=errors, rugged=rugged, score=score, plain=0, best=best, criterion=criterion, noise=float(noise),
                      duration=float(duration), settle=float(settle), undetermined=tuple(n for n, s in zip(parameters, seen) if not s),
                      jacobian=jacobian, slew=slew, dwell=dwell)
    return dataclasses.replace(plan, scene=with_profile(scene, *plan.profile(best)) if plan.slewing(best)
                               else with_scan(scene, amplitude[best], period[best]))
