"""The result of an identification (`identify`): the estimates, their intervals and the check of
them, the identifiability table, and the identified unit as a scene file."""

import dataclasses
import math

import numpy as np

DETERMINED = 0.25  # a relative standard error below this (95 % interval within +-50 %) is determined
LOADING = 0.3  # a parameter takes part in a direction whose eigenvector component exceeds this
# A residual this many times the recording's stated noise is a model misfit, said in the table.
MISFIT = 1.5
# The interval's check (`identify`'s `_profile`): the cost along each parameter's profile
# direction at these many standard errors either side of the estimate, against the linearised
# model's rise. The interval holds where the rise at the first two is at least 1 / PROFILE_FACTOR
# of the linearised one (a flatter cost: the profile interval's ends at most ~1.4x beyond the
# linearised ones) and at most STEEP_FACTOR times it (a steeper cost ends the profile interval
# sooner, at no less than half the linearised half-width: the linearised interval conservative;
# steeper still, the cost is not quadratic at all: a kink or a rugged residual); the third says
# whether the curvature is the basin's or only the estimate's surroundings'.
PROFILE_STEPS = (1.96, 10.0, 100.0)
PROFILE_FACTOR = 2.0
STEEP_FACTOR = 4.0
# A side of an interval that does not hold is open where the cost's rise at 1.96 and 10 standard
# errors out stays within this many s^2 (the 95 % point of a chi-square on one degree of freedom:
# the profile likelihood's 95 % interval reaches past 10 standard errors there): the recording
# does not bound the parameter on that side, as a backlash larger than the recording ever takes
# up (the flank not reached before it ends) leaves the residual flat above it. With the other
# side's rise at least 1 / PROFILE_FACTOR of the linearised one at both steps (a steeper rise
# ends the interval sooner: the linearised end is then conservative), the parameter is bounded
# on that side only (`Identification.status`).
OPEN_RISE = 3.841
# rad: the finest residual the intervals are stated at. Below it the residual is the simulation's
# own error, not the unit's (noise-free recordings of the model itself: 1e-4 µrad RMS at the same
# smoothing width, 0.003-0.016 µrad fitted at another, on the lumped scan), and an
# interval that narrow lies inside that error: its check along the profile fails on the solve's
# noise. No encoder records that finely (a 24-bit one's rounding alone: 0.11 µrad RMS).
RESOLVED = 0.1e-6
# The table says how much of the intervals is the model's own irreproducibility where that
# share of a variance exceeds this.
MODEL_NOTED = 0.1


def interval_holds(ratios) -> bool | None:
    """One parameter's profile check (`Identification.holds`): its ratios ((2 sides, steps), the
    cost's rise over the linearised one) at 1.96 and 10 standard errors all above
    1 / `PROFILE_FACTOR` and below `STEEP_FACTOR`; None where none was read (NaN: not checked)."""
    ratios = np.asarray(ratios)[:, :2]
    seen = ratios[np.isfinite(ratios)]
    return None if seen.size == 0 else bool(np.all((seen > 1 / PROFILE_FACTOR) & (seen < STEEP_FACTOR)))


def show(value: float, unit: str) -> str:
    """A parameter's value for a report: µm for a length, else 4 significant digits and the unit."""
    if unit == "m":
        return f"{1e6 * value:.2f} µm"
    return f"{value:.4g}" + ("" if unit == "1" else f" {unit}")


@dataclasses.dataclass(frozen=True)
class Identification:
    """The result of `identify`.

    - `names`: the identified parameters, `units` their SI units ("m" for the clearances and
      backlash); `estimate`, `covariance`, `standard_error` in those units. The covariance is
      the recording's noise's, $s^2 (J^TJ)^{-1}$, plus `model_covariance`: the estimate's spread
      over the model's own realisations at the estimate (a run that does not reproduce itself at
      rounding level, as a rattling stage's: `fit._model_noise`; ~0 where it does);
      `model_rms` (rad): how far those realisations' outputs lie apart, RMS.
    - `sigma` (rad): the residual's standard deviation at the estimate, $s$, floored at
      `RESOLVED` (what the intervals are stated at; `residual_sd` is the residual's own); `n`
      residuals, `cost` $\\lVert r\\rVert^2$ (µrad²).
    - `residual` (rad, (saves, axes)), `times` (s), `measured` and `fitted` (rad): the fit.
    - `directions`: [(relative standard error, eigenvector over `names`)], best determined first.
    - `steps`: Levenberg-Marquardt steps of the winning start at the last width; `converged`:
      the Gauss-Newton step left from the estimate is below a tenth of each standard error (or
      below one where a Gauss-Newton polish could not lower the cost: the solve's own noise);
      `starts`: each start's final cost (µrad²); `screened`: the points the starts were chosen
      from (0: the starts were given); `line_screened`: the points costed along each parameter's
      line through the best fit where it missed the recording (0: none), the last start from
      their lowest. `noise` (rad): the recording's stated noise, or None.
    - `wall` (s): where the call's wall time went, by phase: `"check"` (the recording's command
      against the scene's), `"screen"` (the starts' costs), `"fit"` (Levenberg-Marquardt from each
      start through each width), `"assess"` (the Jacobian at the estimate, the covariance, the
      polish where one ran, and the intervals' check), `"profile"` (the profile-likelihood bounds
      where they were read); tracing and compiling included where a program was new.
    - `scene`: the identified unit (the scene with the estimates).
    - `profile` ((parameters, 2, 3)): the intervals checked against the residual itself
      (`identify`'s `_profile`): the cost's rise at 1.96, 10 and 100 standard errors below and above the
      estimate along each parameter's profile path, over the rise the linearised model predicts
      there; 1 where the residual is quadratic out to there. `holds` reads it. `profile_line`
      ((parameters, 2, 2)): the same rise at 1.96 and 10 standard errors along the parameter's
      own line, the others held at the estimate (NaN where not costed), which `one_sided` reads.
    - `profile_bound` ((parameters, 2), the parameters' units): for a parameter the recording
      does not see at its estimate (its linearised interval reaching past the bounds), the 95 %
      profile-likelihood interval's lower and upper ends, the others re-fitted
      (`tolerax.identification.profile`), -inf / inf where the recording leaves that side open;
      NaN for the others. `profile_lowest` (µrad²): the lowest cost met along each such profile,
      below `cost` by more than the threshold where the estimate is not the minimum.
    - `limits` ((parameters, 2), their units): the bounds the fit kept each parameter within
      (`identify(bounds=...)`; by default a factor 100 of the scene's value either side);
      `at_bound`: per parameter `"lower"` / `"upper"` where the estimate stopped at that bound
      (`fit.at_bound`: the recording asks for a value beyond it), else None.
    - `jacobian`: which Jacobian of the residual the fit and the intervals rest on (forward
      mode through the solve, or central secants), and why, in words.
    - `torque_measured`, `torque_fitted` (N m, (saves, axes)) where the recording had a motor
      torque (its part of the residual, weighed by the noises, is in `n` and `cost`; `residual`
      is the angles').
    """

    names: tuple[str, ...]
    units: tuple[str, ...]
    estimate: np.ndarray
    covariance: np.ndarray
    sigma: float
    n: int
    cost: float
    times: np.ndarray
    measured: np.ndarray
    fitted: np.ndarray
    directions: tuple
    steps: int
    converged: bool
    starts: tuple
    screened: int
    noise: float | None = None
    scene: object = dataclasses.field(repr=False, default=None)
    wall: dict = dataclasses.field(default_factory=dict)
    profile: np.ndarray | None = dataclasses.field(repr=False, default=None)
    profile_line: np.ndarray | None = dataclasses.field(repr=False, default=None)
    jacobian: str = ""  # the residual's Jacobian, and why (`identify(secant=...)`)
    torque_measured: np.ndarray | None = dataclasses.field(repr=False, default=None)
    torque_fitted: np.ndarray | None = dataclasses.field(repr=False, default=None)
    model_covariance: np.ndarray | None = dataclasses.field(repr=False, default=None)
    model_rms: float = 0.0
    line_screened: int = 0
    profile_bound: np.ndarray | None = dataclasses.field(repr=False, default=None)
    profile_lowest: np.ndarray | None = dataclasses.field(repr=False, default=None)
    limits: np.ndarray | None = dataclasses.field(repr=False, default=None)  # (p, 2): the fit's bounds, the parameters' units
    at_bound: tuple = ()  # per parameter: "lower" / "upper" where the estimate stopped at that bound, else None

    @property
    def residual_sd(self) -> float:
        """The residual's own standard deviation (rad; `sigma` is it floored at `RESOLVED`)."""
        return math.sqrt(self.cost / max(self.n - len(self.names), 1)) * 1e-6

    @property
    def standard_error(self) -> np.ndarray:
        return np.sqrt(np.maximum(np.diag(self.covariance), 0.0))

    @property
    def residual(self) -> np.ndarray:
        return self.fitted - self.measured

    def model_share(self) -> np.ndarray:
        """Per parameter: the share of its variance that is the model's own (`model_covariance`)."""
        if self.model_covariance is None:
            return np.zeros(len(self.names))
        total = np.diag(self.covariance)
        return np.where(total > 0, np.diag(self.model_covariance) / np.where(total > 0, total, 1.0), 0.0)

    def interval(self, level: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
        """Each parameter's linearised interval (its unit) at `level` (normal quantile)."""
        from scipy.stats import norm

        z = float(norm.ppf(0.5 + level / 2))
        return self.estimate - z * self.standard_error, self.estimate + z * self.standard_error

    def walked(self) -> np.ndarray:
        """Per parameter: were its profile-likelihood bounds read (`profile_bound`)?"""
        return np.zeros(len(self.names), bool) if self.profile_bound is None else ~np.isnan(self.profile_bound).any(axis=1)

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Each parameter's 95 % interval as stated: the profile-likelihood one where it was read
        (`profile_bound`, -inf / inf on an open side), else the linearised one (`interval`)."""
        lo, hi = self.interval()
        walked = self.walked()
        return (np.where(walked, self.profile_bound[:, 0], lo), np.where(walked, self.profile_bound[:, 1], hi)) if walked.any() else (lo, hi)

    def holds(self) -> tuple[bool | None, ...]:
        """Per parameter: does its linearised interval hold (the cost's rise along its profile at
        1.96 and 10 standard errors above 1 / `PROFILE_FACTOR` and below `STEEP_FACTOR` times
        the linearised rise on both sides)? None where it was not checked (an interval reaching past the bounds)."""
        if self.profile is None:
            return (None,) * len(self.names)
        return tuple(interval_holds(ratios) for ratios in self.profile)

    def one_sided(self) -> tuple[str | None, ...]:
        """Per parameter whose interval does not hold (`holds`): `"below"` where the recording
        bounds it from below only (the cost's rise above the estimate stays within `OPEN_RISE`
        s^2 at 1.96 and 10 standard errors along its profile path or along its own line, the
        others held: either costs at least the profile's, so the profile stays within it too;
        while below it rises at least 1 / `PROFILE_FACTOR` of the linearised rise at both along
        the path), `"above"` the other way round, else None (also where it holds or was not
        checked). Where the profile-likelihood bounds were read instead (`profile_bound`):
        `"below"` where its lower end is finite and its upper open, `"above"` the other way round."""
        walked = self.walked()
        if self.profile is None:
            return tuple(self._walked_side(j) for j in range(len(self.names))) if walked.any() else (None,) * len(self.names)
        steps = np.asarray(PROFILE_STEPS[:2]) ** 2
        lines = np.full((len(self.names), 2, 2), np.nan) if self.profile_line is None else self.profile_line
        out = []
        for ratios, line, held in zip(self.profile[:, :, :2], lines, self.holds()):
            flat = [any(bool(np.all(np.isfinite(r)) and np.all(np.abs(r * steps) < OPEN_RISE)) for r in pair)
                    for pair in zip(ratios, line)]  # each side: the path's or the line's rise in s^2
            rising = [bool(np.all(np.isfinite(r)) and np.all(r >= 1 / PROFILE_FACTOR)) for r in ratios]
            side = "below" if rising[0] and flat[1] else "above" if rising[1] and flat[0] else None
            out.append(side if held is False else None)
        return tuple(self._walked_side(j) if walked[j] else side for j, side in enumerate(out))

    def _walked_side(self, j) -> str | None:
        if not self.walked()[j]:
            return None
        low, high = np.isfinite(self.profile_bound[j])
        return "below" if low and not high else "above" if high and not low else None

    def misfit(self) -> bool:
        """Does the model miss part of the unit? The residual's standard deviation above `MISFIT`
        times the recording's stated noise (and above what the simulation resolves, `RESOLVED`);
        False where no noise is stated (nothing to judge it against)."""
        return bool(self.noise and self.residual_sd > max(MISFIT * self.noise, RESOLVED))

    def stopped(self) -> tuple[str | None, ...]:
        """`at_bound` where no other side or profile statement is made (`status`'s order)."""
        given = self.at_bound or (None,) * len(self.names)
        return tuple(None if side is not None or walk else b for b, side, walk in zip(given, self.one_sided(), self.walked()))

    def status(self) -> tuple[str, ...]:
        """Per parameter: "determined", "in combination", "not determined" (module docstring),
        "bounded below only" / "bounded above only" where the recording bounds it on one side
        (`one_sided`: the linearised interval's end there, or the profile likelihood's, the other
        open), "bounded by its profile" where the profile-likelihood interval is read and closed
        on both sides (`profile_bound`: the recording does not see it at the estimate, yet bounds
        it; "not determined" where that interval is open on both), "at its lower bound" / "at its
        upper bound" where the estimate stopped at a bound of the fit (`at_bound`: the recording
        asks for a value beyond it), or "interval does not hold" where the residual is otherwise
        not quadratic over it (`holds`): the estimate is where the search stopped, not a minimum
        the recording determines.

        With a misfit (`misfit`: the residual well above the recording's noise) "determined" and
        "in combination" read "determined (model misfit)" and "in combination (model misfit)":
        the recording determines the parameter *of this model*, but the interval counts only the
        residual's spread, not the bias of what the model leaves out (a lower fidelity than the
        unit's, a parameter left at the scene's value), which can be many standard errors."""
        relative = self.standard_error / np.maximum(np.abs(self.estimate), 1e-12)
        good = [vector for se, vector in self.directions if se < DETERMINED]
        out = []
        walked, misfit, stopped = self.walked(), self.misfit(), self.stopped()
        for j, (holds, side) in enumerate(zip(self.holds(), self.one_sided())):
            if side is not None:
                out.append(f"bounded {side} only")
            elif walked[j]:
                out.append("bounded by its profile" if np.all(np.isfinite(self.profile_bound[j])) else "not determined")
            elif stopped[j] is not None:
                out.append(f"at its {stopped[j]} bound")
            elif holds is False:
                out.append("interval does not hold")
            elif relative[j] < DETERMINED:
                out.append("determined" + " (model misfit)" * misfit)
            elif any(abs(v[j]) > LOADING for v in good):
                out.append("in combination" + " (model misfit)" * misfit)
            else:
                out.append("not determined")
        return tuple(out)

    def scene_file(self, scene_file, source: str = "a recording"):
        """The identified unit as a scene file (`tolerax.io.scenefile.SceneFile`), so that
        `tolerax run`, `montecarlo` (with its `[life]`) and the design tools answer for *this*
        unit: `scene_file` (the one the identification ran) with

        - the identified clearances and backlash under `[design]`, their uncertainty as zones
          whose standard deviation is the standard error, in the file's own distribution (a
          scene file has one for all its zones, and the drawing's zones of the features not
          identified stay as drawn): normal, band = 3 standard errors; uniform, band = sqrt(3);
        - the identified drag as the scene's `drag_torque` where one modelled joint's drag was
          identified and no other joint's drag acts (the scene file's key holds one drag for
          both joints; else `unwritten`); a mesh family's stiffness or damping ratio in that
          joint's stage table (`[scene.azimuth_stage] sun_mesh_stiffness = ...`, its other keys
          kept);
        - every estimate, its 95 % interval and status in its title and description
          (`source`: what the recording was).

        A parameter whose interval does not hold (`holds`) is not written: its zone (or value)
        stays the drawing's; one the recording bounds on one side only (`one_sided`) keeps the
        part of the drawing's zone on the bound's side (the drawing's zone whole where it lies
        there, the description saying so where none of it does), and one whose profile-likelihood
        interval was read (`profile_bound`) the part of the drawing's zone inside it, and one
        stopped at a bound of the fit (`at_bound`) the part inside the fit's bounds. Every zone
        written lies within the fit's bounds (`limits`: the user's, where given). With a
        misfit (`misfit`) the estimates are written as identified, their status in the
        description saying "(model misfit)": their zones do not count the misfit's bias.
        """
        from ..io import scenefile as F
        from ..uncertainty.sampling import Tolerances
        from .parameters import MESH_KEYS

        walked, stopped = self.walked(), self.stopped()
        features = [j for j, (u, kept) in enumerate(zip(self.units, self._kept())) if u == "m" and kept and not walked[j]]
        out, (lo, hi) = scene_file, self.bounds()
        limits = np.tile([-math.inf, math.inf], (len(self.names), 1)) if self.limits is None else self.limits
        drawn = scene_file.tolerances()
        if features:
            per_sigma = 3.0 if drawn.distribution == "normal" else math.sqrt(3.0)  # band / standard deviation
            low = np.maximum(self.estimate[features] - per_sigma * self.standard_error[features], limits[features, 0])
            high = np.minimum(self.estimate[features] + per_sigma * self.standard_error[features], limits[features, 1])
            out = scene_file.with_tolerances(Tolerances(tuple(self.names[j] for j in features), 0.5 * (low + high),
                                                        0.5 * (high - low), drawn.distribution))
        beyond = []  # bounded parameters whose whole drawn zone lies outside the recording's bounds
        cut = {}
        for j, side in enumerate(self.one_sided()):
            if (side is None and not walked[j] and stopped[j] is None) or self.units[j] != "m" or self.names[j] not in drawn.names:
                continue
            k = drawn.names.index(self.names[j])
            low, high = float(drawn.nominal[k] - drawn.band[k]), float(drawn.nominal[k] + drawn.band[k])
            least = max(float(lo[j]) if walked[j] or side == "below" else -math.inf, limits[j, 0])  # the recording's bounds, open: inf
            most = min(float(hi[j]) if walked[j] or side == "above" else math.inf, limits[j, 1])
            if least >= high or most <= low:
                beyond.append(j)
            elif least > low or most < high:  # else the whole drawn zone is inside the bounds: kept as drawn
                low, high = max(low, least), min(high, most)
                cut[self.names[j]] = (0.5 * (low + high), 0.5 * (high - low))
        if cut:
            out = out.with_tolerances(Tolerances(tuple(cut), np.array([c[0] for c in cut.values()]),
                                                 np.array([c[1] for c in cut.values()]), drawn.distribution))
        scene, writable = dict(out.data["scene"]), self._drag_writable()
        for name, value, held in zip(self.names, self.estimate, self._kept()):
            if name in writable:
                scene["drag_torque"] = float(value)
            joint, _, key = name.partition(".")
            if key in MESH_KEYS and held:
                scene[f"{joint}_stage"] = dict(scene.get(f"{joint}_stage", {})) | {key: float(value)}
        statuses = self.status()

        def said(j):
            n, u, st = self.names[j], self.units[j], statuses[j]
            if stopped[j] is not None:
                text = f"{n} {show(limits[j, int(stopped[j] == 'upper')], u)} ({st} of the fit: the recording asks for " + \
                    ("less" if stopped[j] == "lower" else "more")
            elif st == "bounded below only":
                text = f"{n} >= {show(lo[j], u)} (95 %, {st}"
            elif st == "bounded above only":
                text = f"{n} <= {show(hi[j], u)} (95 %, {st}"
            elif walked[j]:
                text = (f"{n} {show(lo[j], u)} to {show(hi[j], u)} (95 % profile likelihood, {st}" if st == "bounded by its profile"
                        else f"{n} not bounded by the recording ({st}")
            else:
                return f"{n} {show(self.estimate[j], u)} ({show(lo[j], u)} to {show(hi[j], u)}, 95 %, {st})"
            return text + (": its drawn zone lies wholly beyond the bound and is kept as drawn)" if j in beyond else ")")

        data = out.data | {"scene": scene, "title": f"Identified unit: {scene_file.title}",
                           "description": f"Written by tolerax identify from {source}: "
                           + "; ".join(said(j) for j in range(len(self.names))).replace("µm", "um")}
        return F.SceneFile.from_data(data, "identified", "<identified>")

    def _kept(self) -> list[bool]:
        """Per parameter: can its estimate be written (its interval not failed, not at a bound)?"""
        return [held is not False and stop is None for held, stop in zip(self.holds(), self.stopped())]

    def unwritten(self) -> tuple[str, ...]:
        """The identified parameters `scene_file` cannot write (no scene-file key holds them; those
        whose interval does not hold, or stopped at a bound, are not written either, and not listed here)."""
        from .parameters import MESH_KEYS

        return tuple(n for n, u, held in zip(self.names, self.units, self._kept())
                     if u != "m" and held and n not in self._drag_writable() and n.partition(".")[2] not in MESH_KEYS)

    def _drag_writable(self) -> tuple[str, ...]:
        """`("joint.drag_torque",)` where that joint's drag was identified and no other joint's
        drag acts (every other joint ideal and servo-driven, no coordinate to drag)."""
        from ..mechanism.drives import TorqueDrive
        from ..mechanism.joints import IdealJoint

        drags = [n for n, held in zip(self.names, self._kept()) if n.endswith(".drag_torque") and held]
        if len(drags) != 1 or self.scene is None or not hasattr(self.scene, "named_joints"):
            return ()
        joint = drags[0].split(".")[0]
        others = [j for name, j in self.scene.named_joints() if name != joint]
        return tuple(drags) if all(isinstance(j, IdealJoint) and not isinstance(j.drive, TorqueDrive) for j in others) else ()

    def table(self) -> str:
        """The estimates, intervals and identifiability as Markdown."""
        (lo, hi), walked = self.bounds(), self.walked()
        rows = ["| parameter | estimate | 95 % interval | relative standard error | determined? |", "|---|---|---|---|---|"]
        sides, stopped = self.one_sided(), self.stopped()
        for j, (name, status) in enumerate(zip(self.names, self.status())):
            rel = self.standard_error[j] / max(abs(self.estimate[j]), 1e-300)
            interval = f"{show(lo[j], self.units[j])} – {show(hi[j], self.units[j])}" if rel < 1 else "not bounded by the recording"
            interval += " (does not hold)" if status == "interval does not hold" else ""
            if status == "bounded by its profile":
                interval = f"{show(lo[j], self.units[j])} – {show(hi[j], self.units[j])} (profile likelihood)"
            if sides[j] is not None:
                interval = (f"≥ {show(lo[j], self.units[j])}, not bounded above" if sides[j] == "below"
                            else f"≤ {show(hi[j], self.units[j])}, not bounded below")
            if stopped[j] is not None:
                interval = f"{'below' if stopped[j] == 'lower' else 'above'} the bound, by the recording"
            rows.append(f"| {name} | {show(self.estimate[j], self.units[j])} | {interval} | {rel:.3g} | {status} |")
        below = self.residual_sd < RESOLVED * (1 - 1e-9)
        lines = [(f"Residual standard deviation {1e6 * self.residual_sd:.3g} µrad over {self.n} samples, below what the "
                  f"simulation resolves ({1e6 * RESOLVED:.3g} µrad: its own integration error, as from a noise-free recording "
                  f"of the model itself), so the intervals are stated at {1e6 * RESOLVED:.3g} µrad; "
                  if below else f"Residual standard deviation {1e6 * self.sigma:.3g} µrad over {self.n} samples; ")
                 + f"Levenberg-Marquardt {'converged' if self.converged else 'NOT converged (the step left exceeds a tenth of a standard error, or one at the cost floor' + ('; an estimate is held at a bound of the fit, below' if any(stopped) else '') + ')'} "
                 f"after {self.steps} steps "
                 f"(best of {len(self.starts)} starts" + (f", chosen from {self.screened} screened" + (f", the last from {self.line_screened} along each parameter's "
                                                                   "line through the best fit" if self.line_screened else "")
                    + ")." if self.screened else ").")
                 + (f" The residual's Jacobian: {self.jacobian}." if self.jacobian else ""), "", *rows, "", "Directions (relative standard error: combination):", ""]
        notes = []
        misfit = self.misfit()
        if misfit:
            notes += ["", f"**The residual ({1e6 * self.residual_sd:.3g} µrad) is {self.residual_sd / self.noise:.2g}x the recording's stated "
                      f"noise ({1e6 * self.noise:.3g} µrad): the model misses part of the unit** (a lower fidelity than the "
                      "unit's, or a parameter left at the scene's value). The intervals scale with the residual but do not "
                      "count that bias: the estimates can be off by more than they say (the status reads \"(model misfit)\"). "
                      "To bound the bias: identify with the model at the unit's fidelity, or free the parameter left at "
                      "the scene's value."]
        model = self.model_share()
        if np.any(model > MODEL_NOTED):
            notes += ["", f"The model does not reproduce its own run: at points 1e-9 from the estimate its output moves by "
                      f"{1e6 * self.model_rms:.2g} µrad RMS (through a rattling stage a rounding-level change changes the "
                      "impacts), and the estimate with it. The intervals include that spread: "
                      + ", ".join(f"{n} {100 * m:.0f} %" for n, m in zip(self.names, model))
                      + " of each variance is the model's, the rest the recording's noise."]
        for j in (j for j, side in enumerate(sides) if side is not None and not walked[j]):
            open_ = "above" if sides[j] == "below" else "below"
            o = 1 if open_ == "above" else 0
            rises = [r * np.asarray(PROFILE_STEPS[:2]) ** 2 for r in (self.profile[j, o, :2], *(
                () if self.profile_line is None else (self.profile_line[j, o],)))]
            rise = min((r for r in rises if np.all(np.isfinite(r))), key=lambda r: float(np.max(np.abs(r))))
            end = show((lo if sides[j] == "below" else hi)[j], self.units[j])
            notes += ["", f"**{self.names[j]} is bounded {sides[j]} only** ({'≥' if sides[j] == 'below' else '≤'} {end}): "
                      f"at {PROFILE_STEPS[0]:g} and {PROFILE_STEPS[1]:g} standard errors {open_} the estimate the residual's "
                      f"cost has risen only {_span(rise)} s² ({OPEN_RISE:g} s², the 95 % threshold), so the recording does not "
                      f"say how far {open_} it lies: values there reproduce it as well (as a backlash larger than the recording "
                      "ever takes up does, its far flank not reached before the recording ends). The estimate is not written "
                      "into the identified scene (a clearance or backlash keeps the part of its drawn zone the bound leaves). "
                      "To bound it: a recording that reaches that flank (longer after a reversal, "
                      "or a larger amplitude)."]
        for j in np.flatnonzero(walked):
            notes += ["", self._walked_note(j, lo[j], hi[j])]
        for j in (j for j, side in enumerate(stopped) if side is not None):
            less = "less" if stopped[j] == "lower" else "more"
            notes += ["", f"**{self.names[j]} stopped at the fit's {stopped[j]} bound** "
                      f"({show(self.limits[j, int(stopped[j] == 'upper')], self.units[j])}): the Gauss-Newton step from it points "
                      f"past the bound, so the residual's minimum lies beyond it: the recording asks for {less}. The estimate is the "
                      "bound, not a value the recording determines, and is not written into the identified scene (a clearance "
                      "or backlash keeps the part of its drawn zone inside the bounds). Widen the bound where such a value is "
                      "physical; where it is not, the model misses the unit (a parameter left at the scene's value, a lower "
                      "fidelity than the unit's) or the recording is not of this unit."]
        rugged = [j for j, (held, side, stop) in enumerate(zip(self.holds(), sides, stopped)) if held is False and side is None and stop is None]
        if rugged:
            near, far = self.profile[rugged][:, :, :2], self.profile[rugged][:, :, 2]
            many = len(rugged) > 1
            notes += ["", f"**The interval{'s' * many} of {', '.join(self.names[j] for j in rugged)} {'do' if many else 'does'} "
                      f"not hold**: along {'them' if many else 'it'} the residual's cost rose {_span(near)} "
                      f"times what the linearised model predicts at 1.96 and 10 standard errors (1 where "
                      f"it holds) and {_span(far)} times at 100: the residual is not "
                      "quadratic over the interval, so the estimate is where the search stopped, not a minimum the recording "
                      "determines to that precision, and it is not written into the identified scene. "
                      + ("With the misfit above, free the parameter the model leaves at the scene's value (or model the unit "
                         "at its own fidelity). " if misfit else "")
                      + "Where the Jacobian is not the residual's (forward mode through a rattling stage: its tangents "
                      "are the rattle's), identify with the central secants (secant=None chooses them where they "
                      "disagree, or give the step); where the residual itself is rugged at the interval's scale, identify "
                      "with a joint whose response the parameter moves smoothly (the lumped joint, with its bias against the "
                      "full stage in mind), or from a recording without rattle."]
        lines[1:1] = notes
        for se, vector in self.directions:
            terms = " ".join(f"{v:+.2f}·{n}" for v, n in zip(vector, self.names) if abs(v) > 0.05)
            lines.append(f"- {se:.3g}: {terms}")
        return "\n".join(lines)

    def _walked_note(self, j, low, high) -> str:
        """The table's note on a parameter whose profile-likelihood bounds were read."""
        n, u, s2 = self.names[j], self.units[j], (self.sigma / 1e-6) ** 2
        sides = [f"{'below' if k == 0 else 'above'} it the profile (the other parameters re-fitted) rises past the "
                 f"threshold at {show(b, u)}" if np.isfinite(b) else
                 f"{'below' if k == 0 else 'above'} it the cost along its own line (the others held, which costs at least "
                 "the profile's) stays within the threshold out to the bound of the fit ("
                 + ("a factor 100 of the scene's value" if self.limits is None else show(self.limits[j, k], u)) + ")"
                 for k, b in enumerate((low, high))]
        text = (f"**{n}: the recording does not see it at the estimate** ({show(self.estimate[j], u)}, its linearised interval "
                f"reaching past the bounds), so its 95 % interval is the profile likelihood's (the values whose cost rises "
                f"at most {OPEN_RISE:g} s² above the estimate's): {sides[0]}; {sides[1]}. ")
        if self.profile_lowest is not None and self.profile_lowest[j] < self.cost - OPEN_RISE * s2:
            text += (f"Along it the cost falls to {self.profile_lowest[j]:.1f} µrad² against the estimate's {self.cost:.1f}: the "
                     "estimate is not the minimum (identify again with starts nearer the bound). ")
        if np.isfinite(low) != np.isfinite(high):
            text += ("Values on the open side reproduce the recording as well (a backlash larger than the recording ever takes "
                     "up: its far flank not reached before it ends); the estimate is one point of that plateau, not written "
                     "into the identified scene (a clearance or backlash keeps the part of its drawn zone the bound leaves). "
                     "To bound it: a recording that reaches that flank (longer after a reversal, or a larger amplitude).")
        return text


def _span(ratios) -> str:
    """"a to b" of the finite ratios (one value where they agree to two digits, "not measured"
    where none is finite: a side not checked is NaN)."""
    lo, hi = (f"{f(ratios):.2g}" if np.isfinite(ratios).any() else None for f in (np.nanmin, np.nanmax))
    return "not measured" if lo is None else lo if lo == hi else f"{lo} to {hi}"
