"""Drawable tolerances: the continuous optimum put on grades a drawing can call out.

The optimiser's bands are continuous (IT6.2, IT7.8, ...); a drawing calls out a whole ISO 286
grade. `round_to_grades` puts every designed feature's zone on a whole grade, keeping its lower
limit (the functional minimum the design found) and choosing for each feature the grade just
tighter or just looser than its continuous one: the cheapest combination whose linearised
outputs still meet every requirement (all $2^n$ combinations for up to 16 features; beyond, a
greedy search that loosens first the feature whose looser grade saves the most cost per arcsec
it costs). The linear model is the design's own (its sensitivities at the continuous optimum,
`DesignReport.outcomes`); `propose_design` then checks the drawable design on simulated units
where the requirement is a yield (`DrawableDesign.checks`).

Grades: ISO 286-1 IT5-IT11 from the standard tolerance factor $i(D)$
(`tolerax.design.cost.it_tolerance`); outside that range the R5 progression ($10^{1/5}$ per
grade, of which ISO 286's IT12-IT18 multipliers 160i ... 2500i are the rounded values; IT1-IT4
follow other formulae) as `grade_of` extrapolates, said as such.

A journal bearing's radial clearance is not made to a grade of its own but by a bore and a
journal, each toleranced: for every clearance feature the drawable design also names the
loosest ISO 286 hole-basis fit (H6-H11 with a-k shafts of the grades ISO 286-2 prints, 5-11) whose whole clearance
zone lies inside the drawable zone (`tolerax.design.fits.nearest_fit`), or says why none does.
A backlash is called out as the gears' tooth-thickness allowances whose normal backlash lies
inside the zone (`tolerax.design.backlash`: the sun, planet and ring of a stage allotted
together), with its whole IT grade.
"""

import dataclasses
import math

import numpy as np

from .cost import GRADE_MULTIPLIERS, GRADE_RATIO, SIZE_STEPS, it_tolerance
from .backlash import callout_text, stage_allowances
from .fits import SMALLEST_SIZE, nearest_fit, why_no_fit

EXHAUSTIVE = 16  # features up to which every combination of the two grades is tried


def width_of_grade(grade: int, size_mm) -> np.ndarray:
    """The full tolerance width (m) of whole grade IT`grade` at nominal size `size_mm` (mm):
    ISO 286-1's standard tolerance for IT5-IT11, the R5 progression from the nearest of them
    beyond (within 1 % of ISO's rounded IT12-IT18 multipliers; an extrapolation for IT1-IT4)."""
    lo, hi = min(GRADE_MULTIPLIERS), max(GRADE_MULTIPLIERS)
    g = int(grade)
    anchor = min(max(g, lo), hi)
    return np.asarray(it_tolerance(anchor, size_mm), dtype=float) * GRADE_RATIO ** (g - anchor)


@dataclasses.dataclass(frozen=True)
class DrawableDesign:
    """A design on whole ISO grades (`round_to_grades`).

    - `grades` (one per feature: whole, except a feature in `kept`, which keeps its continuous
      zone and grade: a fixed one, or one with no whole grade inside the band range), `nominal`
      and `band` (m: the zone is nominal +- band, its lower limit the continuous design's),
      `cost` (the cost model's units) and `rounding_cost` (`cost` minus the continuous
      design's).
    - `objective`: each requirement's linearised output at the drawable design (the continuous
      design's linear model), `limit` what it must meet.
    - `checks`: Monte Carlo checks of the drawable design (`YieldCheck`, one per requirement)
      where `propose_design` made them, else `()`.
    - `extrapolated`: the features whose grade lies outside IT5-IT11 (R5 progression).
    - `fits`: per feature, the ISO 286 fit a drawing calls the zone out as (`journal_fits`):
      `"H8/e7 (20.0-45.5 µm)"` with its radial clearance zone, `"none inside the zone: <why>"`;
      for a backlash the gears' tooth-thickness allowances (`"jn 20.7–44.2 µm: sun -11/-24,
      planet -11/-23 µm tooth thickness (jt ...)"`) where the meshes' pressure angles were given,
      else `""`.
    - `tightened`: how far below the continuous design's grades the whole grades were chosen
      (0: rounded from them, the cheapest combination its linear model allows; `propose_design`
      rounds from every grade one lower where the check of the rounded design misses).
    """

    names: tuple[str, ...]
    grades: np.ndarray
    nominal: np.ndarray
    band: np.ndarray
    cost: float
    rounding_cost: float
    objective: np.ndarray
    limit: np.ndarray
    checks: tuple = ()
    extrapolated: tuple[str, ...] = ()
    kept: tuple[str, ...] = ()
    fits: tuple[str, ...] = ()
    tightened: int = 0

    @property
    def met(self) -> bool:
        """Whether the linear model says every requirement is met (and each check reached its
        yield where there are checks)."""
        ok = bool(np.all(self.objective <= self.limit * (1 + 1e-9)))
        return ok and not any(c.missed for c in self.checks)  # each check reached its yield within its noise

    def callout(self, k: int) -> str:
        """Feature `k`'s grade, with the ISO 286 fit inside its zone for a journal (`"IT8, H8/f7"`)
        or the tooth-thickness allowances for a backlash (`"IT9, jn 20.7–44.2 µm: sun -11/-24,
        planet -11/-23 µm tooth thickness"`)
        (`"IT5.2, kept"` for a feature that keeps its continuous grade)."""
        name, text = self.names[k], self.fits[k] if self.fits else ""
        grade = f"IT{self.grades[k]:.1f}, kept" if name in self.kept else f"IT{int(self.grades[k])}"
        fit = text.split(" (")[0] if text and not text.startswith("none") else ""
        return grade + (f", {fit}" if fit else "")

    def callouts(self) -> tuple[str, ...]:
        """Per feature, what a drawing calls out: its zone (µm) and `callout`:
        `"azimuth.planet_clearance 5.0–27.5 µm (IT8, H8/f7)"`."""
        return tuple(f"{name} {1e6 * (self.nominal[k] - self.band[k]):.1f}–{1e6 * (self.nominal[k] + self.band[k]):.1f} µm "
                     f"({self.callout(k)})" for k, name in enumerate(self.names))

    def table(self, unit: str = "cost units") -> str:
        """The drawable zones as a Markdown table with a sentence of what rounding cost."""
        rows = ["| feature | ISO grade | nominal (µm) | band ± (µm) | zone (µm) | drawn as: ISO 286 fit inside the zone (radial "
                "clearance, µm), or the gears' tooth-thickness allowances (backlash) |",
                "|---|---|---|---|---|---|"]
        fits = self.fits or ("",) * len(self.names)
        for k, name in enumerate(self.names):
            lo, hi = 1e6 * (self.nominal[k] - self.band[k]), 1e6 * (self.nominal[k] + self.band[k])
            grade = f"IT{self.grades[k]:.1f} (kept)" if name in self.kept else f"IT{int(self.grades[k])}"
            rows.append(f"| {name} | {grade} | {1e6 * self.nominal[k]:.1f} | {1e6 * self.band[k]:.1f} | "
                        f"{lo:.1f}–{hi:.1f} | {fits[k] or '- (a backlash: its IT grade)'} |")
        outputs = ", ".join(f"{float(o):.1f} against {float(r):.1f}" for o, r in zip(self.objective, self.limit))
        head = (f"On the drawing (whole ISO 286 grades, each zone on the continuous design's lower limit"
                + (f", each grade chosen from {self.tightened} below the continuous one after the check of the rounded grades "
                   "missed" if self.tightened else "") + f"): cost {self.cost:.4g} "
                f"({unit}), {self.rounding_cost:+.3g} for rounding the continuous optimum; linearised output(s) {outputs}"
                + ("" if self.met or self.checks else "; the linear model says it misses") + ".")
        if self.checks:
            head += " " + " ".join(c.text() + "." for c in self.checks)
        if self.extrapolated:
            head += f" Grades outside IT5-IT11 (R5 progression): {', '.join(self.extrapolated)}."
        return head + "\n\n" + "\n".join(rows)


def journal_fits(names, size_mm, lower_limit, upper_limit, pressure_angle=None) -> tuple[str, ...]:
    """Per feature, how a drawing calls out its zone [`lower_limit`, `upper_limit`] (m):

    - a journal's clearance: the loosest ISO 286 fit (`tolerax.design.fits.nearest_fit`) whose
      radial clearance zone lies inside it at the journal diameter `size_mm` (mm), as
      `"H8/e7 (20.0-45.5 µm)"`; `"none inside the zone: <why>"` where no H6-H11 fit with a
      shaft a-k (`tolerax.design.fits.DEFAULT_SHAFTS`) does (`why_no_fit`: too narrow, too loose,
      or between positions);
    - a backlash, where `pressure_angle` (rad, one per feature) is given: the gears'
      tooth-thickness allowances (`tolerax.design.backlash.stage_allowances`, the sun and ring
      backlash of one stage (and planet) split together, the planet sharing both), as
      `"jn 20.5-44.9 µm: sun -11/-23, planet -11/-23 µm tooth thickness (jt ...)"`; else `""`.
    """
    n = len(names)
    angle = None if pressure_angle is None else np.broadcast_to(np.asarray(pressure_angle, dtype=float), (n,))
    out = []
    for name, size, lo, hi in zip(names, np.broadcast_to(np.asarray(size_mm, dtype=float), (n,)), lower_limit, upper_limit):
        if not name.endswith("_clearance") or not SMALLEST_SIZE <= size <= SIZE_STEPS[-1]:
            out.append("" if not name.endswith("_clearance") else
                       f"none: Ø{size:g} mm is outside ISO 286's {SMALLEST_SIZE:g}-{SIZE_STEPS[-1]:g} mm")
            continue
        fit = nearest_fit(float(lo), float(hi), float(size))
        if fit is None:
            out.append(f"none inside the zone: {why_no_fit(float(lo), float(hi), float(size))}")
            continue
        c_lo, c_hi = fit.radial_clearance(float(size))
        out.append(f"{fit} ({1e6 * c_lo:.1f}–{1e6 * c_hi:.1f})")
    if angle is not None:
        for k, text in _backlash_callouts(names, lower_limit, upper_limit, angle).items():
            out[k] = text
    return tuple(out)


def _backlash_callouts(names, lower_limit, upper_limit, angle) -> dict[int, str]:
    """{feature index: callout} for the backlash features, the sun and ring backlash of one
    stage (and planet) allotted together (`stage_allowances`)."""
    groups: dict[str, dict[str, int]] = {}  # "joint.*[i]" -> {"sun": k, "ring": k}
    for k, name in enumerate(names):
        for mesh in ("sun", "ring"):
            if f"{mesh}_backlash" in name.rsplit(".", 1)[-1]:
                groups.setdefault(name.replace(f"{mesh}_backlash", "*"), {})[mesh] = k
    out = {}
    for members in groups.values():
        zone = {mesh: (float(lower_limit[k]), float(upper_limit[k])) for mesh, k in members.items()}
        angles = {mesh: float(angle[k]) for mesh, k in members.items()}
        try:
            allowances = stage_allowances(zone.get("sun"), zone.get("ring"), angles.get("sun", 0.35), angles.get("ring", 0.35))
        except ValueError as error:
            out.update({k: f"none: {error}".replace("stage_allowances: ", "") for k in members.values()})
            continue
        out.update({k: callout_text(mesh, allowances, angles[mesh]) for mesh, k in members.items()})
    return out


def round_to_grades(names, size_mm, lower_limit, band, grade, objective, limit, slopes, cost, band_range=None,
                    fixed=(), pressure_angle=None) -> DrawableDesign:
    """The cheapest whole-grade design next to a continuous one (module docstring).

    **Arguments:**

    - `names`, `size_mm` (mm): the features; `lower_limit`, `band` (m): the continuous design's
      zones (lower limit, half-width); `grade`: its fractional grades (`grade_of(2 band)`).
    - `objective` (m,), `limit` (m,): the requirements' linearised outputs at the continuous
      design and what each must meet; `slopes` (m, n): d output / d half-width at fixed lower
      limit (output units per m).
    - `cost`: `cost(band) -> (n,)`, each feature's cost in the cost model's units (of the
      half-widths, m; the total is their sum).
    - `band_range`: (smallest, largest) half-width (m) a zone may have, scalars or one per
      feature; whole grades outside it
      are not offered, and a feature with none inside keeps its continuous band (`kept`).
    - `fixed`: names of features given, not designed: not moved (`kept`).
    - `pressure_angle`: the meshes' pressure angles (rad, one per feature), for the backlash
      features' tooth-thickness allowances (`journal_fits`); None: none.
    """
    names = tuple(names)
    n = len(names)
    lower_limit, band, grade = (np.asarray(v, dtype=float) for v in (lower_limit, band, grade))
    objective, limit = np.atleast_1d(np.asarray(objective, dtype=float)), np.atleast_1d(np.asarray(limit, dtype=float))
    slopes = np.atleast_2d(np.asarray(slopes, dtype=float))
    size = np.broadcast_to(np.asarray(size_mm, dtype=float), (n,))
    lo_band, hi_band = (np.zeros(n), np.full(n, np.inf)) if band_range is None else (
        np.broadcast_to(np.asarray(band_range[0], dtype=float), (n,)), np.broadcast_to(np.asarray(band_range[1], dtype=float), (n,)))
    options = []  # per feature: [(grade, half-width)], tighter first
    for k in range(n):
        if names[k] in fixed:
            options.append([(None, band[k])])
            continue
        g0 = grade[k]
        whole = sorted({math.floor(g0 + 1e-9), math.ceil(g0 - 1e-9)})
        cands = [(g, 0.5 * float(width_of_grade(g, size[k]))) for g in whole]
        cands = [(g, b) for g, b in cands if lo_band[k] * (1 - 1e-9) <= b <= hi_band[k] * (1 + 1e-9)]
        options.append(cands or [(None, band[k])])

    # Two candidates per feature (a single one repeated), their half-widths and costs once:
    # the search is then array arithmetic over combinations (the cost is a sum over features).
    b_opt = np.array([[o[min(j, len(o) - 1)][1] for o in options] for j in (0, 1)])  # (2, n)
    c_opt = np.stack([np.asarray(cost(b_opt[j]), dtype=float).reshape(n) for j in (0, 1)])

    def evaluate(choice):
        """Costs (N,), outputs (N, m) and half-widths (N, n) of the combinations `choice` (N, n) in {0, 1}."""
        b = np.where(choice == 1, b_opt[1], b_opt[0])
        return np.where(choice == 1, c_opt[1], c_opt[0]).sum(axis=1), objective + (b - band) @ slopes.T, b

    free = [k for k in range(n) if len(options[k]) > 1]
    ok = lambda f: np.all(f <= limit * (1 + 1e-9), axis=-1)  # noqa: E731
    if len(free) <= EXHAUSTIVE:
        bits = (np.arange(2 ** len(free))[:, None] >> np.arange(len(free))) & 1
        combos = np.zeros((bits.shape[0], n), dtype=int)
        combos[:, free] = bits
        c, f, b = evaluate(combos)
        good = np.flatnonzero(ok(f))
        choice = combos[good[np.argmin(c[good])]] if good.size else None
    else:  # greedy: all tight, then loosen where a looser grade saves the most per arcsec it costs
        choice = np.zeros(n, dtype=int)
        while True:
            c0, f0, _ = evaluate(choice[None])
            trials = np.repeat(choice[None], len(free), axis=0)
            trials[np.arange(len(free)), free] = 1
            c, f, _ = evaluate(trials)
            gain = (c0 - c) / np.maximum(np.max(f - f0, axis=1), 1e-12)
            gain[~ok(f) | (choice[free] == 1)] = -np.inf
            if not np.any(np.isfinite(gain)):
                break
            choice[free[int(np.argmax(gain))]] = 1
        choice = choice if ok(evaluate(choice[None])[1])[0] else None
    if choice is None:  # no whole-grade combination meets the linear model: the tightest one, said so
        choice = np.zeros(n, dtype=int)
    c, f, b = (v[0] for v in evaluate(np.asarray(choice)[None]))
    c = float(c)
    picked = [options[k][min(int(ch), len(options[k]) - 1)][0] for k, ch in enumerate(choice)]
    kept = tuple(names[k] for k in range(n) if picked[k] is None)
    grades = np.array([grade[k] if g is None else g for k, g in enumerate(picked)], dtype=float)
    lo, hi = min(GRADE_MULTIPLIERS), max(GRADE_MULTIPLIERS)
    extrapolated = tuple(f"{names[k]} (IT{grades[k]:g})" for k in range(n) if picked[k] is not None and not lo <= grades[k] <= hi)
    return DrawableDesign(names, grades, lower_limit + b, b, c, c - float(np.sum(cost(band))), f, limit, (), extrapolated, kept,
                          journal_fits(names, size, lower_limit, lower_limit + 2 * b, pressure_angle))
