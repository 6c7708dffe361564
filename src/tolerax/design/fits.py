"""ISO 286 fits for journal bearings: a designed radial-clearance zone as a hole/shaft fit (H7/g6).

A journal of nominal diameter $D$ in a bore has the radial clearance $c = (d_\\mathrm{hole} -
d_\\mathrm{shaft})/2$. A fit gives it the zone

$$c_\\min = (EI - es)/2, \\qquad c_\\max = (ES - ei)/2,$$

with ES, EI the hole's and es, ei the shaft's upper and lower limit deviations. `fits_covering`
lists the fits whose whole zone lies inside a designed one (every bore and journal made to the
fit meets the design), cheapest first (the two parts' grades); `nearest_fit` is the first of them, and
`why_no_fit` says why a zone holds none (too narrow for any grade pair, a smallest clearance
above the loosest position's, or between two positions). Hole basis (H with shafts a-k) by
default; shaft basis (holes A-H with an h shaft, `basis="shaft"`) where one journal carries
several bores, as a planet pin may: for A-H the hole's EI is the shaft letter's $-es$ (ISO
286-1's general rule), so C9/h9 has H9/c9's clearance.

**Values.** Tabulated, not computed: ISO 286-1 rounds its formulas by rules that do not reproduce
the published tables everywhere (the first size step, the tolerance grades' coarser rounding above
60 µm), and `tolerax.design.cost.it_tolerance` returns the unrounded formula (up to 13 % off the
table at and below 3 mm). Here:

- standard tolerances IT5-IT11: ISO 286-1:2010 Table 1;
- fundamental deviations: ISO 286-1:2010 Tables 2-3 (shafts), as printed in the ISO 286-2:2010
  Tables of limit deviations: es of d, e, f, g, h (their formulas, rounded: $-16 D^{0.44}$,
  $-11 D^{0.41}$, $-5.5 D^{0.41}$, $-2.5 D^{0.34}$, 0 µm, $D$ the geometric mean of the step);
  es of a, b, c on ISO 286's intermediate size steps (10-14 and 14-18 alike, 18-24 and 24-30
  alike, then 30-40, 40-50, 50-65, ... 450-500 mm: `ABC_STEPS`), the steps on which these
  letters differ; ei of k, $+0.6 D^{1/3}$ µm rounded for grades 4-7 (0 up to 3 mm), 0 for the
  other grades; the holes A-H: $EI = -es$ of the same letter;
- js: ±IT/2, with ISO 286-1's rule for js7 to js11 that an odd IT (whole µm) is first rounded
  down to the even value below, so the limits are whole µm (js7 at 18-30 mm: ±10 µm, not ±10.5;
  js5 and js6 keep their half micrometres: js6 at 18-30 mm is ±6.5 µm), as ISO 286-2 prints them.

Sizes: ISO 286's main size steps 1-3, 3-6, 6-10, 10-18, 18-30, 30-50, 50-80, 80-120, 120-180,
180-250, 250-315, 315-400 and 400-500 mm ("over ... up to and including"; the same steps as
`tolerax.design.cost.SIZE_STEPS`), and for a, b, c (A, B, C) the intermediate steps above.
Sizes below 1 mm are refused although ISO's first step reads "up to 3 mm": the diameter is the one
length this module takes in mm, and a value below 1 is far more likely a diameter in metres.
Tabulated: shafts a, b, c, d, e, f, g, h, js, k and holes A-H, grades 5-11 (ISO 286-2 prints
a from grade 9 and b, c from grade 8; the finer ones follow the same rule). Not tabulated: the
intermediate positions cd, ef, fg (sizes up to 50 mm only), and j, m-zc (interference).
"""

import dataclasses
import math
import re

import numpy as np

from .cost import GRADE_MULTIPLIERS, GRADE_RATIO, SIZE_STEPS

SMALLEST_SIZE = 1.0  # mm: the lower limit of ISO 286's first size step
GRADES = tuple(sorted(GRADE_MULTIPLIERS))  # 5 ... 11
HOLE_LETTERS = ("A", "B", "C", "D", "E", "F", "G", "H")  # EI = -es of the same shaft letter; H: 0
SHAFT_LETTERS = ("a", "b", "c", "d", "e", "f", "g", "h", "js", "k")

# ISO 286-1:2010 Table 1: standard tolerance IT (µm), one value per size step of SIZE_STEPS
# (up to 3, 3-6, 6-10, 10-18, 18-30, 30-50, 50-80, 80-120, 120-180, 180-250, 250-315, 315-400, 400-500 mm).
IT_TABLE_UM = {
    5: (4, 5, 6, 8, 9, 11, 13, 15, 18, 20, 23, 25, 27),
    6: (6, 8, 9, 11, 13, 16, 19, 22, 25, 29, 32, 36, 40),
    7: (10, 12, 15, 18, 21, 25, 30, 35, 40, 46, 52, 57, 63),
    8: (14, 18, 22, 27, 33, 39, 46, 54, 63, 72, 81, 89, 97),
    9: (25, 30, 36, 43, 52, 62, 74, 87, 100, 115, 130, 140, 155),
    10: (40, 48, 58, 70, 84, 100, 120, 140, 160, 185, 210, 230, 250),
    11: (60, 75, 90, 110, 130, 160, 190, 220, 250, 290, 320, 360, 400),
}
# ISO 286-1:2010 Table 2 (ISO 286-2:2010 Tables): upper deviation es (µm) of shafts d ... h, every grade.
SHAFT_ES_UM = {
    "d": (-20, -30, -40, -50, -65, -80, -100, -120, -145, -170, -190, -210, -230),
    "e": (-14, -20, -25, -32, -40, -50, -60, -72, -85, -100, -110, -125, -135),
    "f": (-6, -10, -13, -16, -20, -25, -30, -36, -43, -50, -56, -62, -68),
    "g": (-2, -4, -5, -6, -7, -9, -10, -12, -14, -15, -17, -18, -20),
    "h": (0,) * len(SIZE_STEPS),
}
# ISO 286's intermediate size steps (upper limits, mm) on which a, b and c differ: 10-14 and 14-18 share
# their values, as do 18-24 and 24-30, so those pairs are one step here.
ABC_STEPS = (3.0, 6.0, 10.0, 18.0, 30.0, 40.0, 50.0, 65.0, 80.0, 100.0, 120.0, 140.0, 160.0, 180.0, 200.0, 225.0,
             250.0, 280.0, 315.0, 355.0, 400.0, 450.0, 500.0)
# ISO 286-1:2010 Table 2 (ISO 286-2:2010 Tables): upper deviation es (µm) of shafts a, b, c on ABC_STEPS.
SHAFT_ES_ABC_UM = {
    "a": (-270, -270, -280, -290, -300, -310, -320, -340, -360, -380, -410, -460, -520, -580, -660, -740, -820, -920,
          -1050, -1200, -1350, -1500, -1650),
    "b": (-140, -140, -150, -150, -160, -170, -180, -190, -200, -220, -240, -260, -280, -310, -340, -380, -420, -480,
          -540, -600, -680, -760, -840),
    "c": (-60, -70, -80, -95, -110, -120, -130, -140, -150, -170, -180, -200, -210, -230, -240, -260, -280, -300, -330,
          -360, -400, -440, -480),
}
# Lower deviation ei (µm) of shaft k for grades 4-7 (the same tables); 0 for the other grades.
SHAFT_K_EI_UM = (0, 1, 1, 1, 2, 2, 2, 3, 3, 4, 4, 4, 5)
K_GRADES_WITH_EI = (4, 5, 6, 7)
JS_EVEN_GRADES = (7, 8, 9, 10, 11)  # js grades whose odd IT is rounded down to even (module docstring)

# The classes `fits_covering` combines by default, the grades ISO 286-2 prints for each position (a
# from IT9, b and c from IT8: the loose positions are not made to fine grades): hole basis, H6-H11
# with shafts a-k; shaft basis (basis="shaft"), holes A-H of the same grades with h5-h11.
FIRST_GRADE = {"a": 9, "b": 8, "c": 8}  # else GRADES[0]
DEFAULT_HOLES = tuple(f"H{grade}" for grade in range(6, 12))
DEFAULT_SHAFTS = tuple(f"{letter}{grade}" for letter in SHAFT_LETTERS for grade in GRADES
                       if grade >= FIRST_GRADE.get(letter, GRADES[0]))
SHAFT_BASIS_HOLES = tuple(f"{letter}{grade}" for letter in HOLE_LETTERS for grade in range(6, 12)
                          if grade >= FIRST_GRADE.get(letter.lower(), GRADES[0]))
SHAFT_BASIS_SHAFTS = tuple(f"h{grade}" for grade in GRADES)
# m: a fit's zone counts as inside limits it passes by less. A designed zone's limits come out of a
# continuous optimum in floating point (5.0-13.98 µm where the grade's width is meant); ISO 286
# tabulates whole micrometres, so a fit that passes a limit by under 1/20 µm is that zone's fit.
SLACK = 0.05e-6

_CLASS = re.compile(r"([A-Za-z]{1,2})(0|[1-9][0-9]?)")


def _real(value, message: str) -> float:
    """`value` as a float, or `ValueError(message)` where it is not one real number."""
    if isinstance(value, (bool, str, bytes)) or value is None or np.ndim(value) != 0:
        raise ValueError(message)
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(message) from None


def _step(diameter_mm) -> int:
    """Index into SIZE_STEPS of the step holding `diameter_mm`, after checking it."""
    d = _real(diameter_mm, f"diameter_mm must be a real number (the nominal diameter, mm), got {diameter_mm!r}.")
    if not (math.isfinite(d) and SMALLEST_SIZE <= d <= SIZE_STEPS[-1]):
        hint = " (a diameter below 1 is probably given in m: give it in mm)" if math.isfinite(d) and 0 < d < SMALLEST_SIZE else ""
        raise ValueError(
            f"diameter_mm must be a nominal size in [{SMALLEST_SIZE:g}, {SIZE_STEPS[-1]:g}] mm, the ISO 286 size steps "
            f"tabulated here (1-3, 3-6, ..., 400-500 mm), got {diameter_mm!r}{hint}."
        )
    return next(k for k, upper in enumerate(SIZE_STEPS) if d <= upper)


def size_step(diameter_mm) -> tuple[float, float]:
    """The ISO 286 size step (mm) that `diameter_mm` (mm) falls in: over the first, up to and
    including the second (the first step, 1-3 mm, includes 1 mm)."""
    k = _step(diameter_mm)
    return (SMALLEST_SIZE if k == 0 else SIZE_STEPS[k - 1]), SIZE_STEPS[k]


def _parse_class(text, kind: str) -> tuple[str, int]:
    """(letter, grade) of tolerance class `text` ("H7", "g6", "js5"), `kind` "hole" or "shaft"."""
    letters = HOLE_LETTERS if kind == "hole" else SHAFT_LETTERS
    example = "H7" if kind == "hole" else "g6"
    match = _CLASS.fullmatch(text) if isinstance(text, str) else None
    if match is None:
        raise ValueError(f"A {kind} tolerance class is a position letter and a grade such as {example!r}, got {text!r}.")
    letter, grade = match.group(1), int(match.group(2))
    if letter not in letters:
        other = SHAFT_LETTERS if kind == "hole" else HOLE_LETTERS
        swapped = " (upper case is a hole, lower case a shaft: are hole and shaft swapped?)" if letter in other else ""
        raise ValueError(f"{kind} position {letter!r} in {text!r} is not tabulated here{swapped}: use one of "
                         f"{', '.join(letters)} (ISO 286 hole-basis clearance and transition fits).")
    if grade not in GRADES:
        raise ValueError(f"grade {grade} in {kind} class {text!r} is not tabulated here: use IT{GRADES[0]} ... "
                         f"IT{GRADES[-1]} (ISO 286-1 Table 1 as tabulated here).")
    return letter, grade


def _kind_of(tolerance_class) -> str:
    if not (isinstance(tolerance_class, str) and tolerance_class[:1].isalpha()):
        raise ValueError(f"A tolerance class is a position letter and a grade such as 'H7' (hole) or 'g6' (shaft), "
                         f"got {tolerance_class!r}.")
    return "hole" if tolerance_class[0].isupper() else "shaft"


def _it_um(grade: int, step: int) -> int:
    return IT_TABLE_UM[grade][step]


def _es_um(letter: str, diameter: float) -> int:
    """Upper deviation es (µm) of shaft position `letter` (a ... h) at a checked diameter (mm)."""
    if letter in SHAFT_ES_ABC_UM:
        return SHAFT_ES_ABC_UM[letter][next(k for k, upper in enumerate(ABC_STEPS) if diameter <= upper)]
    return SHAFT_ES_UM[letter][_step(diameter)]


def _limits_um(tolerance_class: str, diameter: float) -> tuple[float, float]:
    """(lower, upper) limit deviations (µm) of a hole or shaft class at a diameter (mm) `_step` accepts."""
    kind = _kind_of(tolerance_class)
    letter, grade = _parse_class(tolerance_class, kind)
    step = _step(diameter)
    it = _it_um(grade, step)
    if kind == "hole":  # A-H: EI = -es of the shaft letter (ISO 286-1's general rule; H: 0)
        ei = -_es_um(letter.lower(), float(diameter))
        return float(ei), float(ei + it)
    if letter == "js":
        half = (it - it % 2 if grade in JS_EVEN_GRADES else it) / 2
        return -half, half
    if letter == "k":
        ei = SHAFT_K_EI_UM[step] if grade in K_GRADES_WITH_EI else 0
        return float(ei), float(ei + it)
    es = _es_um(letter, float(diameter))
    return float(es - it), float(es)


def standard_tolerance(grade: int, diameter_mm) -> float:
    """ISO 286-1 standard tolerance IT`grade` (m) at nominal diameter `diameter_mm` (mm), the
    tabulated (rounded) value of ISO 286-1:2010 Table 1, for grades 5-11; `it_tolerance` in
    `tolerax.design.cost` is the unrounded formula."""
    if isinstance(grade, bool) or grade not in GRADES:
        raise ValueError(f"standard_tolerance: grade must be one of {list(GRADES)}, got {grade!r}.")
    return _it_um(int(grade), _step(diameter_mm)) / 1e6


def limit_deviations(tolerance_class: str, diameter_mm) -> tuple[float, float]:
    """Lower and upper limit deviations (m) of a tolerance class at nominal diameter `diameter_mm`
    (mm): (EI, ES) of a hole class ("H7"), (ei, es) of a shaft class ("g6", "js6", "k6")."""
    lower, upper = _limits_um(tolerance_class, diameter_mm)
    return lower / 1e6, upper / 1e6


def fundamental_deviation(tolerance_class: str, diameter_mm) -> float:
    """ISO 286-1's fundamental deviation (m), the limit deviation nearest zero: EI of A ... H,
    es of a ... h, ei of k; of js (a zone symmetric about zero) its upper deviation +IT/2."""
    lower, upper = limit_deviations(tolerance_class, diameter_mm)
    kind = _kind_of(tolerance_class)
    return lower if kind == "hole" or _parse_class(tolerance_class, kind)[0] == "k" else upper


def _signed(value_um: float) -> str:
    """A deviation as ISO writes it: signed, a zero unsigned."""
    return "0" if value_um == 0 else f"{value_um:+g}"


@dataclasses.dataclass(frozen=True)
class Fit:
    """A hole-basis ISO 286 fit, hole class and shaft class: `Fit("H7", "g6")`, or
    `Fit.parse("H7/g6")`; `str(fit)` writes it back. Limits are in m, the diameter in mm."""

    hole: str
    shaft: str

    def __post_init__(self):
        _parse_class(self.hole, "hole")
        _parse_class(self.shaft, "shaft")

    @classmethod
    def parse(cls, text: str) -> "Fit":
        """The fit written as on a drawing, hole class '/' shaft class: "H7/g6" (spaces around
        the classes ignored)."""
        parts = text.split("/") if isinstance(text, str) else []
        if len(parts) != 2:
            raise ValueError(f"Fit.parse: a fit is written hole class '/' shaft class, such as 'H7/g6', got {text!r}.")
        return cls(parts[0].strip(), parts[1].strip())

    def __str__(self) -> str:
        return f"{self.hole}/{self.shaft}"

    def hole_limits(self, diameter_mm) -> tuple[float, float]:
        """The hole's (EI, ES) (m) at nominal diameter `diameter_mm` (mm)."""
        return limit_deviations(self.hole, diameter_mm)

    def shaft_limits(self, diameter_mm) -> tuple[float, float]:
        """The shaft's (ei, es) (m) at nominal diameter `diameter_mm` (mm)."""
        return limit_deviations(self.shaft, diameter_mm)

    def _clearance_um(self, diameter_mm) -> tuple[float, float]:
        (ei_hole, es_hole), (ei_shaft, es_shaft) = _limits_um(self.hole, diameter_mm), _limits_um(self.shaft, diameter_mm)
        return (ei_hole - es_shaft) / 2, (es_hole - ei_shaft) / 2

    def radial_clearance(self, diameter_mm) -> tuple[float, float]:
        """Smallest and largest radial clearance (m) of a journal in this fit at nominal diameter
        `diameter_mm` (mm): half the diametral ones, (EI - es)/2 and (ES - ei)/2. Negative is
        interference."""
        low, high = self._clearance_um(diameter_mm)
        return low / 1e6, high / 1e6

    def is_clearance_fit(self, diameter_mm) -> bool:
        """Whether every journal made to the fit has a clearance (ISO 286-1: EI >= es, zero
        allowed, as in H7/h6); False for a transition or interference fit."""
        return self._clearance_um(diameter_mm)[0] >= 0

    def kind(self, diameter_mm) -> str:
        """"clearance" (smallest clearance >= 0), "transition" (interference possible, clearance
        too) or "interference" (largest clearance < 0) at nominal diameter `diameter_mm` (mm)."""
        low, high = self._clearance_um(diameter_mm)
        return "clearance" if low >= 0 else ("transition" if high >= 0 else "interference")

    def text(self, diameter_mm) -> str:
        """One line for a report: the limits (µm) and the radial clearance of the fit."""
        (ei_h, es_h), (ei_s, es_s) = _limits_um(self.hole, diameter_mm), _limits_um(self.shaft, diameter_mm)
        low, high = self._clearance_um(diameter_mm)
        return (f"Ø{float(diameter_mm):g} {self}: hole {_signed(es_h)}/{_signed(ei_h)} µm, "
                f"shaft {_signed(es_s)}/{_signed(ei_s)} µm, "
                f"radial clearance {low:g} to {high:g} µm ({self.kind(diameter_mm)} fit)")


def _classes(values, kind: str, name: str) -> tuple[str, ...]:
    values = (values,) if isinstance(values, str) else tuple(values)
    if not values:
        raise ValueError(f"fits_covering: {name} is empty: give at least one {kind} class such as "
                         f"{'H7' if kind == 'hole' else 'g6'!r}.")
    for v in values:
        _parse_class(v, kind)
    return tuple(dict.fromkeys(values))


def _limit(value, name: str) -> float:
    v = _real(value, f"fits_covering: {name} must be a real number (radial clearance, m), got {value!r}.")
    if not math.isfinite(v):
        raise ValueError(f"fits_covering: {name} must be finite (radial clearance, m), got {value!r}.")
    return v


def _candidates(lower_limit, upper_limit, diameter_mm, holes, shafts, basis, who):
    """The checked zone (m) and the (hole, shaft) pairs to try, with their radial clearance zones (µm)."""
    if basis not in ("hole", "shaft"):
        raise ValueError(f"{who}: basis must be 'hole' (H with shafts a-k) or 'shaft' (holes A-H with h), got {basis!r}.")
    holes = (DEFAULT_HOLES if basis == "hole" else SHAFT_BASIS_HOLES) if holes is None else holes
    shafts = (DEFAULT_SHAFTS if basis == "hole" else SHAFT_BASIS_SHAFTS) if shafts is None else shafts
    lower, upper = (_limit(v, name) for v, name in ((lower_limit, "lower_limit"), (upper_limit, "upper_limit")))
    if lower > upper:
        raise ValueError(f"{who}: lower_limit ({lower:g} m) is above upper_limit ({upper:g} m): give the "
                         "designed radial clearance zone as (smallest, largest).")
    _step(diameter_mm)  # the size checked before it is used
    if max(abs(lower), abs(upper)) > float(diameter_mm) * 1e-3:
        raise ValueError(f"{who}: a radial clearance limit ({lower:g}, {upper:g}) exceeds the journal diameter "
                         f"({float(diameter_mm):g} mm): the limits are in m (3.5e-6 for 3.5 µm), the diameter in mm.")
    pairs = [(Fit(h, sh), *Fit(h, sh)._clearance_um(diameter_mm))
             for h in _classes(holes, "hole", "holes") for sh in _classes(shafts, "shaft", "shafts")]
    return lower, upper, pairs


def fits_covering(lower_limit, upper_limit, diameter_mm, holes=None, shafts=None, basis: str = "hole") -> list[Fit]:
    """The fits whose radial-clearance zone lies inside a designed one, loosest first.

    **Arguments:**

    - `lower_limit`, `upper_limit`: the designed radial clearance zone (m); every journal made
      to a listed fit has a clearance in it (to `SLACK`, 0.05 µm). A negative lower limit admits
      transition fits.
    - `diameter_mm`: the journal's nominal diameter (mm), in [1, 500].
    - `holes`, `shafts`: the classes to combine (all pairs). By default, for `basis="hole"`:
      H6-H11 with a9-a11, b8-b11, c8-c11 and d, e, f, g, h, js, k of grades 5-11
      (`DEFAULT_HOLES`, `DEFAULT_SHAFTS`); for `basis="shaft"` (one journal in several
      bores): A-H of the same grades (A from 9, B and C from 8) with h5-h11.

    **Returns:**

    The `Fit`s inside the zone, cheapest first: by the two parts' costs at ISO 286's reciprocal
    law (x1.58 per grade tighter, IT7 = 1, `tolerax.design.cost.GRADE_RATIO`), then the wider
    zone, the larger margin to the nearer limit, the coarser hole. Empty where none fits:
    `why_no_fit` says why.
    """
    lower, upper, pairs = _candidates(lower_limit, upper_limit, diameter_mm, holes, shafts, basis, "fits_covering")
    found = []
    for fit, low_um, high_um in pairs:
        low, high = low_um / 1e6, high_um / 1e6
        if low >= lower - SLACK and high <= upper + SLACK:
            margin = min(low - lower, upper - high)
            hole, shaft = _parse_class(fit.hole, "hole")[1], _parse_class(fit.shaft, "shaft")[1]
            # Cheapest first: the two parts' costs by ISO 286's reciprocal law (x1.58 per grade
            # tighter, IT7 = 1: H8/f7 before H9/f5, whose IT5 shaft costs more than its coarse
            # bore saves); then the wider zone (quarter micrometres, exact), the larger margin.
            cost = round(GRADE_RATIO ** (7 - hole) + GRADE_RATIO ** (7 - shaft), 9)
            found.append(((cost, low_um - high_um, -margin, -hole, str(fit)), fit))
    return [fit for _, fit in sorted(found, key=lambda item: item[0])]


def nearest_fit(lower_limit, upper_limit, diameter_mm, holes=None, shafts=None, basis: str = "hole") -> Fit | None:
    """The cheapest fit inside the designed radial clearance zone (the first of `fits_covering`,
    same arguments), or None where none lies inside it."""
    found = fits_covering(lower_limit, upper_limit, diameter_mm, holes, shafts, basis)
    return found[0] if found else None


def why_no_fit(lower_limit, upper_limit, diameter_mm, holes=None, shafts=None, basis: str = "hole") -> str:
    """Why no fit of the classes (`fits_covering`'s arguments) lies inside the zone, in one
    sentence: the zone is narrower than the narrowest pair's; its smallest clearance is above
    the loosest position's; or it falls between two positions (the tighter one allows less
    clearance than the zone's lower limit, the looser one needs the zone to reach higher). ""
    where a fit lies inside."""
    lower, upper, pairs = _candidates(lower_limit, upper_limit, diameter_mm, holes, shafts, basis, "why_no_fit")
    if fits_covering(lower_limit, upper_limit, diameter_mm, holes, shafts, basis):
        return ""
    lo_um, hi_um, d = 1e6 * lower, 1e6 * upper, float(diameter_mm)
    if holes is None and shafts is None:  # a fit of grades ISO 286-2 does not print (c6), by ISO 286-1's rules
        every = [f"{letter}{grade}" for letter in (HOLE_LETTERS if basis == "shaft" else ("H",)) for grade in range(6, 12)]
        unprinted = fits_covering(lower, upper, d, every, [f"{letter}{grade}" for letter in SHAFT_LETTERS for grade in GRADES]
                                  if basis == "hole" else SHAFT_BASIS_SHAFTS, basis)
        if unprinted:
            fit = unprinted[0]
            low, high = (1e6 * v for v in fit.radial_clearance(d))
            return (f"none of the grades ISO 286-2 prints; {fit} ({low:g}-{high:g} µm at Ø{d:g} mm) lies inside by ISO 286-1's "
                    "rules (a, b, c are printed from IT9, IT8, IT8: agree the finer grade with the supplier)")
    narrow = min(pairs, key=lambda p: (p[2] - p[1], abs(p[1] - lo_um)))  # of the narrowest, the one nearest the zone
    if hi_um - lo_um < narrow[2] - narrow[1] - 1e6 * SLACK:
        return (f"too narrow: the zone is {hi_um - lo_um:.1f} µm wide, the narrowest fit of these grades ({narrow[0]} at "
                f"Ø{d:g} mm) spans {narrow[2] - narrow[1]:g} µm of radial clearance; widen the zone or allow finer grades")
    loosest = max(pairs, key=lambda p: p[1])
    if lo_um > loosest[1] + 1e6 * SLACK:
        return (f"too loose: the zone's smallest clearance {lo_um:.1f} µm is above the loosest position's ({loosest[0]}: "
                f"{loosest[1]:g} µm at Ø{d:g} mm); call out bore and journal diameters directly")
    above = min((p for p in pairs if p[1] >= lo_um - 1e6 * SLACK), key=lambda p: (p[1], p[2]))
    at = [p for p in pairs if p[1] == above[1]]
    reach = min(at, key=lambda p: p[2])
    below = [p for p in pairs if p[1] < lo_um - 1e6 * SLACK]
    tighter = f"; the next tighter ({max(below, key=lambda p: p[1])[0]}) allows {max(p[1] for p in below):g} µm" if below else ""
    return (f"between positions: the fits whose smallest clearance is at least the zone's {lo_um:.1f} µm start at "
            f"{above[1]:g} µm and reach at least {reach[2]:g} µm ({reach[0]} at Ø{d:g} mm), {reach[2] - hi_um:.2g} µm above "
            f"the zone's upper limit{tighter}; widen the zone or move its limits")
