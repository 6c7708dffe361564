"""What a tolerance design proposes and why: `DesignReport` (the proposal, how it stands against
each requirement (`RequirementOutcome`), its checks, a table and a plot). `JitterRequirement`
is the older view of a jitter requirement's outcome (deprecated)."""

import dataclasses
import math
import textwrap
import warnings

import numpy as np

from .drawable import DrawableDesign
from .outcome import DesignStatus
from .check import YieldCheck
from .requirements import Requirement
from .types import Design, OptimisationResult
from ..uncertainty.sampling import Tolerances


@dataclasses.dataclass(frozen=True)
class RequirementOutcome:
    """How a design stands against one requirement (`DesignReport.outcomes`).

    - `requirement`: the `Requirement` (output, limit, tolerance).
    - `objective`: its statistic at the design (the linearised yield quantile, or mean + k std
      over the units; the output's unit); `baseline`: the same at the starting design.
    - `target`: the (shifted) limit the returned design was solved for (the limit, or the
      limit less a Monte Carlo check's shift: the SORA correction); `tol`: the relative
      tolerance the optimiser held it to.
    - `constraint_active`; `multiplier` (cost per unit of the output: what one more unit of
      limit saves); `sensitivity` (output unit per m): d statistic / d (nominal, band).
    - `checks`: the Monte Carlo checks of this output (`YieldCheck`, on the same units for every
      requirement), the last the returned design's.
    """

    requirement: Requirement
    objective: float
    baseline: float
    target: float
    tol: float
    constraint_active: bool
    multiplier: float
    sensitivity: Design
    checks: tuple[YieldCheck, ...] = ()

    @property
    def met(self) -> bool:
        """The statistic meets the limit it was solved for, to its tolerance."""
        return self.objective <= self.target * (1 + self.tol)

    def text(self, what: str) -> str:
        """One sentence: `what` (the statistic's name) against the limit, met or not, and its check."""
        r, unit = self.requirement, self.requirement.unit
        return (f"{r.name[:1].upper() + r.name[1:]}: {what} {self.objective:.4g} {unit} against {r.limit:.4g} {unit} "
                + (f"(shifted to {self.target:.4g} by the check before) " if self.target != r.limit else "")
                + f"(baseline {self.baseline:.4g}): " + ("met" if self.met else "**not met**")
                + f", constraint {'active' if self.constraint_active else 'inactive'} to {self.tol:.0%}."
                + (f" Check of the {r.name}: " + self.checks[-1].text() + "." if self.checks else ""))


@dataclasses.dataclass(frozen=True)
class JitterRequirement:
    """The pointing-stability part of a proposal with two requirements (deprecated: `DesignReport.outcomes` holds it).

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

    @classmethod
    def of(cls, outcome: RequirementOutcome, cutoff: float) -> "JitterRequirement":
        """The older view of a jitter requirement's `RequirementOutcome` (`cutoff`, Hz)."""
        return cls(requirement=outcome.requirement.limit, cutoff=float(cutoff), objective=outcome.objective,
                   constraint_active=outcome.constraint_active, multiplier=outcome.multiplier, sensitivity=outcome.sensitivity,
                   baseline=outcome.baseline, tol=outcome.tol, target=outcome.target, checks=outcome.checks)


def _deprecated(name: str, instead: str) -> None:
    warnings.warn(f"DesignReport.{name} is deprecated and goes in the next release: read report.{instead} (one "
                  "RequirementOutcome per requirement, in the order given).", DeprecationWarning, stacklevel=3)


def _first_requirements(name: str, instead: str, read):
    """A read-only attribute of the first requirement's outcome, deprecated (`report.{instead}`)."""

    def get(self):
        _deprecated(name, instead)
        return read(self.outcomes[0])

    get.__doc__ = f"Deprecated: the first requirement's; read `report.{instead}`."
    return property(get)


@dataclasses.dataclass(frozen=True)
class DesignReport:
    """What `propose_design` proposes, and why.

    One proposal: the zones to draw are `tolerances` (the drawable design's, on whole ISO
    grades, where there is one), its cost `proposal_cost`, its check `drawable.checks`; the
    fields below describe the optimiser's continuous optimum they round from (`continuous`).

    - `names`: the features; `nominal`, `band` (m): the continuous optimum; `grade`: the ISO
      286 grade of each band on its feature's size (fractional); `feature_cost`, `cost` (model
      units): per feature and total, of the continuous optimum.
    - `baseline`: `(nominal, band, cost, first requirement's objective)` of the starting design.
    - `result`: the full `OptimisationResult` (history included); its `x.nominal` holds the
      lower limits $l$ (`FromLowerLimit`), the proposal's `nominal` is $l + b$.
    - `outcomes`: one `RequirementOutcome` per requirement, in the order given: its statistic at
      the proposal (the linearised yield quantile, or mean + k std), the limit it was solved for
      (`target`: the limit, or shifted by a Monte Carlo check), whether its constraint is active,
      its multiplier (cost per unit of the output: what one more unit of limit saves), its
      sensitivities (output unit per m) and its Monte Carlo checks (`YieldCheck`; the last is
      the returned design's). The first requirement's are the ones `plain`, `table` and `plot`
      lead with. (`objective`, `requirement`, `constraint_active`, `multiplier`,
      `sensitivity`, `checks`, `solved_for`, `target` and `jitter` once copied them flat: still
      read, deprecated.)
    - `yield_`: the yield $Y$ of a yield requirement (the objective is then the linearised
      $Y$-quantile, `LinearisedYield`), else `None`.
    - `lost_motion` (arcsec/m): the geometric stack-up's weight of each feature
      (`lost_motion_weights`), shown in `table()` beside the simulated sensitivities; `fixed`:
      the features whose zones were given.
    - `noise_band`: `(cost, cost with an independent set of secant units)` where the slopes are
      fitted over units (`Secants(twin=True)`), else `None`.
    - `status`, `diagnosis`: whether this is a proposal (`DesignStatus.CONVERGED`, equal to
      `"converged"`) or the best design reached (`INFEASIBLE`, `CHECK_MISSED`, `NOISE_LIMITED`,
      `NOT_CONVERGED`: `"infeasible"`, `"check missed"`, `"noise-limited"`, `"not converged"`), and
      why, with what would change it (`tolerax.design.outcome.diagnose`); `accepted`.
    - `notes`: what the method did beyond the problem as posed (e.g. finished on secant slopes
      where the tangents stalled), one sentence each.
    - `drawable`: the proposal as drawn, the continuous optimum on whole ISO grades
      (`DrawableDesign`: grades, zones, journal fits, cost and the rounding's cost, the linear
      model's outputs and, with a yield, its own Monte Carlo check), from `propose_design`'s
      sequential method; else `None`. `status` is `"converged"` only where it meets too.
    - `cost_unit`: what one unit of `cost` is (the cost model's `unit`); `grade_range`: the
      grades a shop's price table covers (`GradeTable`), outside which `table()` flags a
      feature's cost as extrapolated, else `None`.
    """

    names: tuple[str, ...]
    nominal: np.ndarray
    band: np.ndarray
    grade: np.ndarray
    feature_cost: np.ndarray
    cost: float
    baseline: tuple
    result: OptimisationResult
    outcomes: tuple[RequirementOutcome, ...]
    yield_: float | None = None
    lost_motion: np.ndarray | None = None
    fixed: tuple[str, ...] = ()
    status: DesignStatus = DesignStatus.CONVERGED
    diagnosis: str = ""
    notes: tuple[str, ...] = ()
    cost_unit: str = "relative, 1 per feature at IT7"
    grade_range: tuple[float, float] | None = None
    drawable: "DrawableDesign | None" = None
    noise_band: tuple[float, float] | None = None

    def __post_init__(self):
        object.__setattr__(self, "status", DesignStatus(self.status))  # a status given as its string: the enum
        object.__setattr__(self, "outcomes", tuple(self.outcomes))
        if not self.outcomes:
            raise ValueError("DesignReport: outcomes must hold one RequirementOutcome per requirement (at least one).")

    # The first requirement's outcome, once copied flat onto the report: served for one release.
    objective = _first_requirements("objective", "outcomes[0].objective", lambda o: o.objective)
    requirement = _first_requirements("requirement", "outcomes[0].requirement.limit", lambda o: o.requirement.limit)
    constraint_active = _first_requirements("constraint_active", "outcomes[0].constraint_active", lambda o: o.constraint_active)
    multiplier = _first_requirements("multiplier", "outcomes[0].multiplier", lambda o: o.multiplier)
    sensitivity = _first_requirements("sensitivity", "outcomes[0].sensitivity", lambda o: o.sensitivity)
    checks = _first_requirements("checks", "outcomes[0].checks", lambda o: o.checks)
    solved_for = _first_requirements("solved_for", "outcomes[0].target", lambda o: o.target)
    target = _first_requirements("target", "outcomes[0].target", lambda o: o.target)

    @property
    def jitter(self):
        """Deprecated: the jitter requirement's outcome is one of `outcomes` (`output ==
        "pointing_jitter"`). Its older view, `JitterRequirement`, with `cutoff` NaN (the cutoff is
        the objective's `jitter_cutoff`, not kept on the report); `None` without a jitter requirement."""
        _deprecated("jitter", 'the RequirementOutcome in outcomes whose requirement.output is "pointing_jitter"')
        o = self._jitter_outcome
        return None if o is None else JitterRequirement.of(o, math.nan)

    @property
    def _jitter_outcome(self) -> "RequirementOutcome | None":
        return next((o for o in self.outcomes if o.requirement.output == "pointing_jitter"), None)

    @property
    def accepted(self) -> bool:
        """Whether this is a proposal: the run converged and, with a yield requirement, its
        Monte Carlo check reached the yield (`status == "converged"`, `tolerax.design.outcome`).
        Otherwise the design is the best one reached, and `diagnosis` says why it is not a
        proposal and what would change that."""
        return self.status == "converged"

    @property
    def tolerances(self) -> Tolerances:
        """The proposal's zones as a `Tolerances` (nominal ± band per feature, m; drawn
        uniformly, as the design assumed): the drawable design's (`drawable`: whole ISO grades,
        what the report says to put on the drawing and what its own check simulated) where there
        is one, else the continuous optimum's (`continuous`). What `monte_carlo` draws units
        from and `SceneFile.with_proposal` writes."""
        if self.drawable is not None:
            return Tolerances(self.names, np.asarray(self.drawable.nominal), np.asarray(self.drawable.band), "uniform")
        return self.continuous

    @property
    def continuous(self) -> Tolerances:
        """The continuous optimum's zones (`nominal`, `band`): the bound the drawable design
        rounds from (the difference in cost is `drawable.rounding_cost`)."""
        return Tolerances(self.names, self.nominal, self.band, "uniform")

    @property
    def proposal_cost(self) -> float:
        """The cost of the proposal's zones (`tolerances`): the drawable design's where there is
        one, else the continuous optimum's `cost`."""
        return float(self.drawable.cost) if self.drawable is not None else float(self.cost)

    def plain(self) -> str:
        """The proposal in plain words, first in `table()`: what to put on the drawing (the
        drawable zones where there are some: whole grades, and each journal's ISO 286 fit),
        what it meets and how that was checked, what it costs against the baseline, and which
        feature the pointing is most sensitive to."""
        d = self.drawable
        if d is not None:
            zones = [c[:-1] + ", given)" if name in self.fixed else c for c, name in zip(d.callouts(), self.names)]
        else:
            zones = [f"{name} {1e6 * (m - b):.1f}–{1e6 * (m + b):.1f} µm (IT{float(g):.1f}{', given' if name in self.fixed else ''})"
                     for name, m, b, g in zip(self.names, self.nominal, self.band, self.grade)]
        requirements = [o.requirement.text() for o in self.outcomes]
        where = f" in {self.yield_:.0%} of units" if self.yield_ is not None else ""
        checks = d.checks if d is not None and d.checks else self.outcomes[0].checks[-1:]
        units = [o.requirement.unit for o in self.outcomes]
        checked = (" Checked on " + ", ".join(f"{c.n - c.n_failed} simulated units: {c.met(u)}"
                                              for c, u in zip(checks, units + units[-1:] * len(checks))) + ".") if checks else ""
        cost = d.cost if d is not None else self.cost
        baseline = float(self.baseline[2])
        change = f", {cost / baseline - 1:+.0%} against the baseline's {baseline:.3g}" if baseline > 0 else ""
        sensitivity = self.outcomes[0].sensitivity.nominal
        k = int(np.argmax(np.abs(np.asarray(sensitivity))))
        verb = "Put on the drawing" if self.accepted else "The best design reached (not a proposal) would put on the drawing"
        why = ""
        if self.lost_motion is not None:
            lost, dynamics, _ = self.split
            if math.isfinite(lost):
                why = (f"; {lost:.0%} of the output's spread over these zones is lost motion through the gear ratios (what "
                       f"a stack-up of the drawings sees) and {dynamics:.0%} dynamics the geometry does not see")
        model = "linear model" if self.yield_ is not None else "statistic over its simulated units"
        if d is not None and self.outcomes:  # the drawn zones' own linear model, not the continuous optimum's
            ok = list(np.asarray(d.objective) <= np.asarray(d.limit) * (1 + 1e-9))
            values = [float(v) for v in d.objective]
        else:
            ok, values = [o.met for o in self.outcomes], [o.objective for o in self.outcomes]
        met = [o for o, good in zip(self.outcomes, ok) if good]
        if len(met) == len(self.outcomes):
            verdict = f"It meets {' and '.join(requirements)}{where} by the design's {model}."
        else:  # say what it misses, never "meets" for all (an infeasible or unconverged design)
            missed = [f"{o.requirement.text()}{where} (by the design's {model}: {v:.4g} {o.requirement.unit})"
                      for o, v, good in zip(self.outcomes, values, ok) if not good]
            verdict = (f"It meets {' and '.join(o.requirement.text() for o in met)}{where} but misses " if met else "It misses ") + (
                " and ".join(missed) + ".")
        return (f"{verb}: {'; '.join(zones)}. {verdict}{checked} "
                f"Cost {cost:.3g} ({self.cost_unit}){change}. Why these zones: the pointing is most sensitive to "
                f"{self.names[k]} ({float(sensitivity[k]) * 1e-6:.3g} {self.outcomes[0].requirement.unit} per µm of its nominal){why}.")

    def table(self) -> str:
        """The proposal in Markdown: `plain` first (after what makes it not a proposal, where it
        is not), then the zones on the drawing (`drawable`'s table, with its check), then the
        continuous optimum they round from, a paragraph on each requirement and a row per
        feature."""
        geometric, more = self.lost_motion is not None, self.outcomes[1:]
        rows = [
            "| feature | nominal (µm) | band ± (µm) | zone (µm) | ISO grade | cost | d obj / d nominal (arcsec/µm) |"
            + "".join(f" d {o.requirement.name} / d nominal ({o.requirement.unit}/µm) |" for o in more)
            + (" lost motion by the drawings (arcsec/µm) |" if geometric else ""),
            "|---|---|---|---|---|---|---|" + "---|" * len(more) + ("---|" if geometric else ""),
        ]
        for k, name in enumerate(self.names):
            low, high = (self.nominal[k] - self.band[k]) * 1e6, (self.nominal[k] + self.band[k]) * 1e6
            rows.append(
                f"| {name}{' (given)' if name in self.fixed else ''} | {self.nominal[k] * 1e6:.1f} | {self.band[k] * 1e6:.1f} | {low:.1f}–{high:.1f} | IT{self.grade[k]:.1f} | "
                f"{self.feature_cost[k]:.3g} | {float(self.outcomes[0].sensitivity.nominal[k]) * 1e-6:.3g} |"
                + "".join(f" {float(o.sensitivity.nominal[k]) * 1e-6:.3g} |" for o in more)
                + (f" {float(self.lost_motion[k]) * 1e-6:.3g} |" if geometric else "")
            )
        if geometric:
            rows += ["", self._weights_text(), "", self._split_text()]
            rows += [x for o in more for x in ("", self._split_text(o))]
        what = "objective" if self.yield_ is None else f"{self.yield_:.1%} quantile (linearised)"
        first = self.outcomes[0]
        unit, limit = first.requirement.unit, first.requirement.limit
        banner = "" if self.accepted else f"**Not a proposal: {self.status}.** {self.diagnosis}\n\n"
        if self.drawable is not None:
            name = "Continuous optimum (the bound the drawn zones round from)"
        else:
            name = "Proposed design" if self.accepted else "Best design reached"
        head = (
            f"{name}: cost {self.cost:.4g} ({self.cost_unit}; baseline {self.baseline[2]:.4g}); {what} "
            f"{first.objective:.1f} {unit} against a requirement of {limit:.1f} {unit} "
            + (f"(shifted to {first.target:.1f} by the check before: the linear model's error there) " if first.target != limit else "")
            + f"(baseline {self.baseline[3]:.1f}); constraint {'active' if first.constraint_active else 'inactive'}; "
            f"{self._iteration_text()}; {'converged' if bool(self.result.converged) else 'not converged'}; first-order "
            f"optimality residual {self.result.optimality:.2g} (bands alone {self.result.band_optimality:.2g})."
        )
        if first.checks:
            head += " " + first.checks[-1].text() + "."
        for note in self.notes + self.extrapolated:
            head += " " + note
        if self.noise_band is not None:
            head += (f" Cost noise band: {self.noise_band[0]:.4g} with these secant units, {self.noise_band[1]:.4g} with an "
                     "independent set.")
        for o in more:
            head += "\n\n" + o.text(what + (", secants" if o.requirement.secants else ""))
        drawing = "" if self.drawable is None else self.drawable.table(self.cost_unit) + "\n\n"
        return banner + self.plain() + "\n\n" + drawing + head + "\n\n" + "\n".join(rows)

    @property
    def extrapolated(self) -> tuple[str, ...]:
        """A sentence naming the features whose grade lies outside the price table's
        (`grade_range`), priced by extrapolation; empty if none."""
        if self.grade_range is None:
            return ()
        lo, hi = self.grade_range
        out = [f"{name} (IT{g:.1f})" for name, g in zip(self.names, np.asarray(self.grade, dtype=float)) if not lo <= g <= hi]
        if not out:
            return ()
        return (f"Priced by extrapolation beyond the price table's IT{lo:g}-IT{hi:g}: {', '.join(out)}; ask the shop for "
                "those grades.",)

    def _weights_text(self) -> str:
        """The simulated sensitivities beside the drawings' weights, each relative to the first
        feature the drawings weigh (a backlash or a pin clearance): where they differ, a stack-up
        from the drawings misallocates the bands."""
        s, w = np.asarray(self.outcomes[0].sensitivity.nominal, dtype=float), np.asarray(self.lost_motion, dtype=float)
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
        objective per arcsec of lost motion.
        NaN where the drawings weigh nothing or the bands are all zero."""
        return self.split_of(self.outcomes[0])

    @property
    def jitter_split(self) -> tuple[float, float, float]:
        """Deprecated: `split_of(outcome)` of the jitter's outcome (NaN without one)."""
        _deprecated("jitter_split", 'split_of(outcome) of the outcome whose requirement.output is "pointing_jitter"')
        o = self._jitter_outcome
        return (math.nan,) * 3 if o is None else self.split_of(o)

    def split_of(self, outcome: RequirementOutcome) -> tuple[float, float, float]:
        """`split` of one requirement's sensitivities (`outcomes`)."""
        return self._split_of(outcome.sensitivity.nominal)

    def _split_of(self, sensitivity) -> tuple[float, float, float]:
        s, w, b2 = (np.asarray(sensitivity, dtype=float), np.asarray(self.lost_motion, dtype=float),
                    np.asarray(self.band, dtype=float) ** 2)
        total, ww = float(np.sum(s * s * b2)), float(np.sum(w * w * b2))
        if total == 0.0 or ww == 0.0:
            return math.nan, math.nan, math.nan
        c = float(np.sum(s * w * b2)) / ww
        lost = c * c * ww / total
        return lost, 1.0 - lost, c

    def _split_text(self, outcome: RequirementOutcome | None = None) -> str:
        lost, dynamics, c = self.split if outcome is None else self.split_of(outcome)
        what = "objective's" if outcome is None else f"{outcome.requirement.name}'s"
        if not math.isfinite(lost):
            return f"Split of the {what} variation into lost motion and dynamics: not defined (no feature moves the output by the drawings, or no band)."
        return (f"Of the {what} variation over the zones, {lost:.0%} is lost motion (the drawings' weights, scaled by "
                f"{c:.3g} arcsec per arcsec of lost motion) and {dynamics:.0%} dynamics (what those weights do not explain: "
                f"`DesignReport.{'split' if outcome is None else 'split_of'}`).")

    def _iteration_text(self) -> str:
        chosen, n = int(self.result.iteration), len(np.asarray(self.result.history.cost))
        gradients = int(np.asarray(self.result.history.steps)[-1])  # the count the progress and the diagnosis give
        return (f"the last of {n} steps" if chosen == n - 1 else f"step {chosen + 1} of {n}, the cheapest that met the requirement") \
            + f" ({gradients} gradient{'' if gradients == 1 else 's'} in all)"

    def plot_zones(self, ax, title: str | None = None):
        """The tolerance zones on `ax`: the baseline's, the proposal's and, where there is one,
        the drawable design's, each feature's whole grade or ISO 286 fit written beside it
        (what a drawing calls out)."""
        y = np.arange(len(self.names))
        base_nominal, base_band = np.asarray(self.baseline[0]), np.asarray(self.baseline[1])
        d = self.drawable
        rows = [(base_nominal, base_band, "0.7", f"baseline: cost {self.baseline[2]:.3g}")]
        answer = "proposal" if self.accepted else "best design reached"
        if d is None:
            rows.append((self.nominal, self.band, "C0", f"{answer}: cost {self.cost:.3g}"))
        else:  # the drawn zones are the answer; the continuous optimum the bound they round from
            rows.append((self.nominal, self.band, "C0", f"continuous optimum (bound): cost {self.cost:.3g}"))
            rows.append((d.nominal, d.band, "C2", f"{answer}, whole grades: cost {d.cost:.3g}"))
        height = 0.8 / len(rows)
        offsets = (np.arange(len(rows))[::-1] - (len(rows) - 1) / 2) * height
        for (nominal, band, color, label), off in zip(rows, offsets):
            ax.barh(y + off, 2e6 * np.asarray(band), left=1e6 * (np.asarray(nominal) - np.asarray(band)), height=height * 0.9,
                    color=color, label=label)
        right = 1e6 * max(float(np.max(np.asarray(r[0]) + np.asarray(r[1]))) for r in rows)
        nominal, band, _, _ = rows[-1]
        for k in range(len(self.names)):
            label = d.callout(k) if d is not None else f"IT{float(self.grade[k]):.1f}"
            ax.text(1e6 * float(nominal[k] + band[k]) + 0.01 * right, y[k] + offsets[-1], label, va="center", fontsize=7)
        ax.set_xlim(0, right * 1.22)
        ax.set_ylim(-0.6, len(self.names) + 0.2)  # room above the bars for the legend
        joints = {n.partition(".")[0] for n in self.names}
        ax.set_yticks(y, [n.partition(".")[2] if len(joints) == 1 else n for n in self.names], fontsize=8)
        ax.set_xlabel("tolerance zone (µm)")
        if title is None:
            met = " and ".join(o.requirement.text() for o in self.outcomes)
            where = f" in {self.yield_:.0%} of units" if self.yield_ is not None else ""
            checks = d.checks if d is not None and d.checks else self.outcomes[0].checks[-1:]
            checked = ("; checked: " + ", ".join(f"{c.yield_simulated:.1%} of {c.n - c.n_failed} units" for c in checks)) if checks else ""
            title = f"tolerance zones for {met}{where}{checked}"
            if not self.accepted:  # the status first: an infeasible or unconverged run proposes nothing
                title = f"NOT A PROPOSAL ({self.status}): best design reached for {met}{where}{checked}"
        ax.set_title(title, fontsize=9)
        ax.legend(fontsize=7, loc="upper center", ncol=len(rows))
        ax.grid(alpha=0.3, axis="x")

    def plot(self):
        """The figure an engineer reads: the zones (baseline, proposal, drawable with its
        grades and fits, the requirement and the checked yield in the title) above what drives
        them (the simulated sensitivities); returns the matplotlib figure. The optimiser's
        history is `plot_history`."""
        import matplotlib.pyplot as plt

        fig, (zones, sens) = plt.subplots(2, 1, figsize=(9, 6.5), height_ratios=[1.2, 1.0])
        self.plot_zones(zones)
        y = np.arange(len(self.names))
        sens.barh(y, np.asarray(self.outcomes[0].sensitivity.nominal) * 1e-6)
        sens.set_yticks(y, self.names, fontsize=7)
        first = self.outcomes[0].requirement
        sens.set_xlabel(f"d {first.name} / d nominal ({first.unit}/µm)", fontsize=8)
        sens.set_title("why: the simulated sensitivity at the proposal", fontsize=9)
        fig.tight_layout()
        return fig

    def plot_history(self):
        """The optimiser's history from the baseline (iteration 0: the starting zones' cost and
        objective) on: cost and each requirement's objective (what the design holds to its
        limit: the linearised quantile with a yield) per iteration, the proposed iterate marked;
        returns the matplotlib figure."""
        import matplotlib.pyplot as plt

        fig, hist_ax = plt.subplots(figsize=(6.5, 3.5))
        hist = self.result.history
        first = self.outcomes[0].requirement
        it = np.arange(0, len(np.asarray(hist.cost)) + 1)
        hist_ax.plot(it, np.r_[float(self.baseline[2]), np.asarray(hist.cost)], "o-", label="cost (0: the baseline)")
        ax2 = hist_ax.twinx()
        what = "objective" if self.yield_ is None else f"{self.yield_:.1%} quantile (linearised)"
        objective = np.asarray(hist.objective)
        start = np.array([o.baseline for o in self.outcomes])
        if len(self.outcomes) == 1:  # one requirement: in its own unit
            values = np.r_[start[:1], objective.reshape(-1)]
            ax2.plot(it[-len(values):], values, "s--", color="C1", label=f"{what}, {first.unit}")
            ax2.axhline(first.limit, color="C1", lw=0.8, ls=":", label="requirement")
            ax2.set_ylabel(f"{first.name}: {what} ({first.unit})", fontsize=8)
        else:  # requirements of different sizes: each over its own
            for k, (o, marker) in enumerate(zip(self.outcomes, "s^vD<>ph")):
                ax2.plot(it, np.r_[o.baseline, objective[:, k]] / o.requirement.limit, f"{marker}--", color=f"C{k + 1}",
                         label=f"{o.requirement.name} / limit")
            ax2.axhline(1.0, color="0.3", lw=0.8, ls=":", label="requirement")
            ax2.set_ylabel("objective / requirement", fontsize=8)
        hist_ax.axvline(int(self.result.iteration) + 1, color="0.5", lw=0.8, ls="--", label="proposed iterate")
        hist_ax.set_xlabel("iteration (one gradient each)")
        hist_ax.set_ylabel("tolerance cost\n(" + textwrap.shorten(self.cost_unit, 40, placeholder="...") + ")", fontsize=8)
        hist_ax.set_title("how the optimiser got there", fontsize=9)
        lines, more = hist_ax.get_legend_handles_labels(), ax2.get_legend_handles_labels()
        hist_ax.legend(lines[0] + more[0], lines[1] + more[1], fontsize=6, loc="best")
        fig.tight_layout()
        return fig
