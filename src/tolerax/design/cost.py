"""What a tolerance band costs: ISO 286-1 standard tolerance grades and replaceable cost models.

**ISO 286-1 grades.** For nominal sizes up to 500 mm the standard tolerance of grades IT5 to IT11
is a multiple of the standard tolerance factor

$$i = 0.45\\,D^{1/3} + 0.001\\,D \\quad (\\mu\\mathrm{m}),$$

with $D$ (mm) the geometric mean of the limits of the nominal size step the size falls in
(ISO 286-1's main steps: up to 3, 3–6, 6–10, ..., 400–500 mm; for the first step $D =
\\sqrt{1\\cdot 3}$). The multipliers are 7, 10, 16, 25, 40, 64, 100 for IT5 ... IT11: from IT6 on
they follow the Renard R5 series, so each grade is $10^{1/5} \\approx 1.585$ times wider than the
one before. The published table rounds these values (to 1 µm below 60 µm, coarser above) and, for
a few small sizes, rounds up: `it_tolerance` returns the unrounded formula, within 0.75 µm or 2.5 %
of the table from 3 to 315 mm (tested), and up to 13 % narrower than the table at and below 3 mm.

**Cost models.** Cost-tolerance models in the literature are reciprocal $a + b/t$ (Chase and
Greenwood), reciprocal squared (Spotts), reciprocal power $a + b/t^k$ (Sutherland and Roth) and
exponential $a + b\\,e^{-t/t_0}$ (Speckhart); Chase, Greenwood, Loosli and Hauglund, "Least cost
tolerance allocation for mechanical assemblies with automated process selection", Manufacturing
Review 3(1):49–59, 1990, compare them (Hallmann, Schleich and Wartzack, Int. J. Adv. Manuf. Technol.
2020, review the field since). The default here, `IsoGrade`, is the reciprocal power law written
in ISO grades: relative cost 1 at a reference grade (IT7) and a stated factor per grade tighter,
$c = \\phi^{g_\\mathrm{ref} - g(t)}$ with $g(t)$ the R5 grade of the band. Written in the band this
is $c = (t_\\mathrm{ref}/t)^k$ with $k = \\ln\\phi/\\ln 10^{1/5}$: the default $\\phi = 10^{1/5}$
gives $k = 1$, Chase and Greenwood's reciprocal law (cost doubles when the band halves). We chose
the reciprocal-power family because it is smooth, convex and scale-free in the band
($c(\\alpha t) = \\alpha^{-k}c(t)$: a grade tighter costs the same factor at 1 µm as at 100 µm),
it diverges as the band closes (no free precision), and its one parameter, the factor per grade,
is a number a workshop can quote. Replace it by subclassing `AbstractCostModel`.

**Floor band.** Reciprocal laws diverge at $t = 0$. They are evaluated at
$t_\\mathrm{eff} = \\sqrt{t^2 + t_\\mathrm{floor}^2}$, smooth, $\\ge t_\\mathrm{floor}$ and within
$t_\\mathrm{floor}^2/(2t)$ of $t$. The default floor, 1 nm, is nearly three decades below the
narrowest IT1 (0.8 µm, sizes up to 3 mm): it changes the cost of a 1 µm band by 5e-7 relative,
and keeps the cost and its gradient finite at $t = 0$ (the gradient is exactly 0 there).
"""

import abc
import math

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float
from .. import _validate as V


# Upper limits (mm) of ISO 286-1's main nominal size steps up to 500 mm; the first step starts at 1.
SIZE_STEPS = (3.0, 6.0, 10.0, 18.0, 30.0, 50.0, 80.0, 120.0, 180.0, 250.0, 315.0, 400.0, 500.0)
# IT5 ... IT11 as multiples of the standard tolerance factor i.
GRADE_MULTIPLIERS = {5: 7.0, 6: 10.0, 7: 16.0, 8: 25.0, 9: 40.0, 10: 64.0, 11: 100.0}
# Band ratio per grade of the R5 series that IT6 ... IT18 follow.
GRADE_RATIO = 10.0 ** 0.2
DEFAULT_FLOOR = 1e-9  # m


def _check_sizes(size_mm) -> None:
    if V.concrete(size_mm):
        arr = np.asarray(size_mm, dtype=float)
        if not np.all(np.isfinite(arr) & (arr > 0) & (arr <= SIZE_STEPS[-1])):
            raise ValueError(
                f"size must be a nominal size in (0, {SIZE_STEPS[-1]:g}] mm (ISO 286-1 as "
                f"implemented here), got {np.array2string(arr, precision=6)}."
            )


def tolerance_factor(size_mm: ArrayLike) -> Float[Array, "..."]:
    """ISO 286-1's standard tolerance factor $i = 0.45 D^{1/3} + 0.001 D$ (µm), $D$ the geometric
    mean of the size step `size_mm` falls in ("over ... up to and including").

    **Arguments:**

    - `size_mm`: nominal size (mm), in (0, 500]; any shape. Concrete values outside raise
      `ValueError`; traced values are clamped to the first or last step.

    **Returns:**

    $i$ (µm), the shape of `size_mm`.
    """
    _check_sizes(size_mm)
    upper = jnp.asarray(SIZE_STEPS)
    lower = jnp.concatenate([jnp.array([1.0]), upper[:-1]])
    step = jnp.clip(jnp.searchsorted(upper, jnp.asarray(size_mm, dtype=float), side="left"), 0, len(SIZE_STEPS) - 1)
    mean = jnp.sqrt(lower[step] * upper[step])
    return 0.45 * jnp.cbrt(mean) + 0.001 * mean


def it_tolerance(grade: int, size_mm: ArrayLike) -> Float[Array, "..."]:
    """Standard tolerance (band width) of ISO 286-1 grade IT`grade` at nominal size `size_mm`.

    **Arguments:**

    - `grade`: 5 ... 11 (Python int; IT5 = 7i, IT6 = 10i, ..., IT11 = 100i).
    - `size_mm`: nominal size (mm), in (0, 500]: the journal diameter of a bearing fit, the
      pitch diameter of a gear mesh.

    **Returns:**

    The tolerance (m), unrounded (see the module docstring for its agreement with the table).
    """
    if grade not in GRADE_MULTIPLIERS:
        raise ValueError(f"it_tolerance: grade must be one of {sorted(GRADE_MULTIPLIERS)}, got {grade!r}.")
    return GRADE_MULTIPLIERS[grade] * tolerance_factor(size_mm) * 1e-6


def grade_of(band: ArrayLike, size_mm: ArrayLike) -> Float[Array, "..."]:
    """Fractional ISO 286 grade of a band: the inverse of `it_tolerance` in the grade.

    Interpolates $\\ln(t/i)$ linearly between the tabulated multipliers of IT5 ... IT11, so that
    `grade_of(it_tolerance(g, D), D) == g` for each of them; outside that range it extrapolates
    at the R5 ratio ($10^{1/5}$ per grade). Differentiable in `band` (piecewise smooth: its slope
    changes at the integer grades).

    **Arguments:**

    - `band`: tolerance band (m), positive; any shape broadcasting with `size_mm`.
    - `size_mm`: nominal size (mm), in (0, 500].

    **Returns:**

    The grade (dimensionless, e.g. 7.0 for an IT7 band, 6.5 halfway to IT6 on a log scale).
    """
    grades = jnp.asarray(sorted(GRADE_MULTIPLIERS), dtype=float)
    log_m = jnp.log(jnp.asarray([GRADE_MULTIPLIERS[g] for g in sorted(GRADE_MULTIPLIERS)]))
    x = jnp.log(jnp.asarray(band, dtype=float) * 1e6 / tolerance_factor(size_mm))
    slope = 1.0 / math.log(GRADE_RATIO)
    below = grades[0] + (x - log_m[0]) * slope
    above = grades[-1] + (x - log_m[-1]) * slope
    inside = jnp.interp(x, log_m, grades)
    return jnp.where(x < log_m[0], below, jnp.where(x > log_m[-1], above, inside))


def effective_band(band: ArrayLike, floor: ArrayLike) -> Float[Array, "..."]:
    """$\\sqrt{t^2 + t_\\mathrm{floor}^2}$ (m): the band a reciprocal cost law sees (module docstring)."""
    band = jnp.asarray(band)
    return jnp.sqrt(band * band + floor * floor)


class AbstractCostModel(eqx.Module):
    """Cost of manufacturing each feature to its tolerance band.

    Subclass it and implement `__call__` to supply your own: it must be positive, non-increasing
    in the band, differentiable, and finite for every band $\\ge 0$. Keep its parameters as
    arrays (the constructors here convert them) so that changing their values does not retrace
    a jitted optimiser.
    """

    @abc.abstractmethod
    def __call__(self, band: Float[Array, " n"], size_mm: Float[Array, " n"]) -> Float[Array, " n"]:
        """Cost of each feature.

        **Arguments:**

        - `band`: tolerance band of each feature (m).
        - `size_mm`: nominal size of each feature (mm); models that do not need it ignore it.

        **Returns:**

        The cost of each feature, in the model's cost unit.
        """

    def total(self, band: Float[Array, " n"], size_mm: Float[Array, " n"]) -> Float[Array, ""]:
        """Total cost: the sum over features of `self(band, size_mm)`."""
        return jnp.sum(self(band, size_mm))

    @property
    def unit(self) -> str:
        """What one unit of this model's cost is, for reports and plot axes."""
        return f"{type(self).__name__}'s cost units"

    @property
    def grade_range(self) -> tuple[float, float] | None:
        """The ISO grades the model's prices were given for (a shop's table), or `None` where
        it is a law over every grade; a design outside them is priced by extrapolation."""
        return None


class ReciprocalPower(AbstractCostModel):
    """$c = a + b\\,(t_\\mathrm{ref}/t_\\mathrm{eff})^k$ (Sutherland and Roth's reciprocal power law;
    $k = 1$ is Chase and Greenwood's reciprocal, $k = 2$ Spotts' reciprocal squared).

    **Arguments** (each a scalar or one value per feature):

    - `fixed`: $a$, the cost that no band saves (cost unit); $\\ge 0$.
    - `scale`: $b$, the variable cost at $t = t_\\mathrm{ref}$ (cost unit); $> 0$.
    - `exponent`: $k > 0$.
    - `reference_band`: $t_\\mathrm{ref}$ (m); $> 0$. Only $b\\,t_\\mathrm{ref}^k$ matters; writing
      the law this way keeps $b$ a plain cost instead of a cost times m$^k$.
    - `floor`: $t_\\mathrm{floor}$ (m) in $t_\\mathrm{eff} = \\sqrt{t^2 + t_\\mathrm{floor}^2}$; $> 0$.
    """

    fixed: Float[Array, "*n"]
    scale: Float[Array, "*n"]
    exponent: Float[Array, "*n"]
    reference_band: Float[Array, "*n"]
    floor: Float[Array, "*n"]

    def __init__(self, fixed=0.0, scale=1.0, exponent=1.0, reference_band=1e-6, floor=DEFAULT_FLOOR):
        self.fixed = V.real("ReciprocalPower", "fixed", fixed, "cost", shape=None)
        self.scale = V.real("ReciprocalPower", "scale", scale, "cost", shape=None)
        self.exponent = V.real("ReciprocalPower", "exponent", exponent, "1", shape=None)
        self.reference_band = V.real("ReciprocalPower", "reference_band", reference_band, "m", shape=None)
        self.floor = V.real("ReciprocalPower", "floor", floor, "m", shape=None)

    def __check_init__(self):
        V.check(
            self,
            fixed=V.NONNEGATIVE("cost"),
            scale=V.POSITIVE("cost"),
            exponent=V.POSITIVE("1"),
            reference_band=V.POSITIVE("m"),
            floor=V.POSITIVE("m"),
        )

    def __call__(self, band, size_mm=None):
        ratio = self.reference_band / effective_band(band, self.floor)
        return self.fixed + self.scale * ratio**self.exponent


class Exponential(AbstractCostModel):
    """$c = a + b\\,e^{-t/t_0}$ (Speckhart's exponential law). Finite at $t = 0$ ($a + b$), so it
    needs no floor; it flattens rather than diverges as the band closes, so on its own it never
    forbids an arbitrarily tight band.

    **Arguments** (each a scalar or one value per feature):

    - `fixed`: $a$ (cost unit); $\\ge 0$.
    - `scale`: $b$, the variable cost at $t = 0$ (cost unit); $> 0$.
    - `decay_band`: $t_0$ (m), the band over which the variable cost falls by $e$; $> 0$.
    """

    fixed: Float[Array, "*n"]
    scale: Float[Array, "*n"]
    decay_band: Float[Array, "*n"]

    def __init__(self, fixed=0.0, scale=1.0, decay_band=1e-5):
        self.fixed = V.real("Exponential", "fixed", fixed, "cost", shape=None)
        self.scale = V.real("Exponential", "scale", scale, "cost", shape=None)
        self.decay_band = V.real("Exponential", "decay_band", decay_band, "m", shape=None)

    def __check_init__(self):
        V.check(self, fixed=V.NONNEGATIVE("cost"), scale=V.POSITIVE("cost"), decay_band=V.POSITIVE("m"))

    def __call__(self, band, size_mm=None):
        return self.fixed + self.scale * jnp.exp(-jnp.asarray(band) / self.decay_band)


class IsoGrade(AbstractCostModel):
    """Cost anchored on ISO 286 grades: $c = a + \\phi^{\\,g_\\mathrm{ref} - g(t)}$, relative cost 1
    (plus $a$) at grade IT$g_\\mathrm{ref}$ and $\\phi$ times more per grade tighter.

    $g(t) = g_\\mathrm{ref} + \\ln(t_\\mathrm{eff}/\\mathrm{IT}g_\\mathrm{ref}(D))/\\ln 10^{1/5}$ is the
    grade on the ideal R5 progression through the tabulated reference grade (smooth, unlike
    `grade_of`, which follows the table's 7 → 10 step below IT6), so
    $c = a + (\\mathrm{IT}g_\\mathrm{ref}(D)/t_\\mathrm{eff})^k$, $k = \\ln\\phi/\\ln 10^{1/5}$. The
    cost unit is "one feature at the reference grade". See the module docstring for the choice.

    **Arguments:**

    - `reference_grade`: $g_\\mathrm{ref}$, 5 ... 11 (Python int); IT7, the usual grade of a
      turned or reamed bearing seat, by default.
    - `factor_per_grade`: $\\phi > 1$; $10^{1/5} \\approx 1.585$ (reciprocal law) by default.
      A shop's quote for one grade tighter at the same size is the number to put here.
    - `fixed`: $a \\ge 0$, cost per feature that no band saves (reference-grade units).
    - `floor`: $t_\\mathrm{floor}$ (m); $> 0$.
    """

    reference_grade: int = eqx.field(static=True)
    factor_per_grade: Float[Array, ""]
    fixed: Float[Array, "*n"]
    floor: Float[Array, ""]

    def __init__(self, reference_grade=7, factor_per_grade=GRADE_RATIO, fixed=0.0, floor=DEFAULT_FLOOR):
        if isinstance(reference_grade, bool) or reference_grade not in GRADE_MULTIPLIERS:
            raise ValueError(
                f"IsoGrade.reference_grade must be one of {sorted(GRADE_MULTIPLIERS)}, got {reference_grade!r}."
            )
        self.reference_grade = int(reference_grade)
        self.factor_per_grade = V.real("IsoGrade", "factor_per_grade", factor_per_grade, "1")
        self.fixed = V.real("IsoGrade", "fixed", fixed, "reference-grade cost", shape=None)
        self.floor = V.real("IsoGrade", "floor", floor, "m")

    def __check_init__(self):
        V.check(
            self,
            factor_per_grade=V.Rule("1", low=1.0, low_open=True),
            fixed=V.NONNEGATIVE("reference-grade cost"),
            floor=V.POSITIVE("m"),
        )

    @property
    def exponent(self) -> Float[Array, ""]:
        """$k = \\ln\\phi / \\ln 10^{1/5}$, the reciprocal-power exponent in the band."""
        return jnp.log(self.factor_per_grade) / math.log(GRADE_RATIO)

    @property
    def unit(self) -> str:
        return (f"relative, 1 per feature at IT{self.reference_grade}, x{float(self.factor_per_grade):.3g} per grade tighter "
                "(ISO 286 reciprocal law)")

    def __call__(self, band, size_mm):
        if size_mm is None:
            raise ValueError("IsoGrade needs the nominal size (mm) of every feature, got size_mm=None.")
        reference = it_tolerance(self.reference_grade, size_mm)
        return self.fixed + (reference / effective_band(band, self.floor)) ** self.exponent


class GradeTable(AbstractCostModel):
    """A shop's own prices per ISO grade: relative cost $c_j$ at grade IT$g_j$, interpolated
    log-linearly in the grade $g(t)$ (the smooth R5 grade of `IsoGrade`, anchored on IT7) and
    extended beyond the table along its end segments. Between two quoted grades the law is a
    reciprocal power of the band, so a table with a constant factor per grade is `IsoGrade`
    exactly (`tests/test_cost.py`); a real quote bends where the process changes (turning to
    grinding, say).

    **Arguments:**

    - `grades`: the quoted grades, increasing (e.g. 5 ... 11); at least two.
    - `costs`: the relative cost at each grade, > 0 and not increasing with the grade (a looser
      grade never costs more), e.g. a quote per part normalised to the IT7 price.
    - `floor`: $t_\\mathrm{floor}$ (m); $> 0$.
    """

    grades: Float[Array, " k"]
    log_costs: Float[Array, " k"]
    floor: Float[Array, ""]

    def __init__(self, grades, costs, floor=DEFAULT_FLOOR):
        g, c = np.asarray(grades, dtype=float), np.asarray(costs, dtype=float)
        if g.ndim != 1 or g.shape != c.shape or g.size < 2:
            raise ValueError(f"GradeTable: grades and costs must be two lists of the same length >= 2, got {grades!r} and {costs!r}.")
        if not (np.all(np.isfinite(g)) and np.all(np.diff(g) > 0)):
            raise ValueError(f"GradeTable: grades must be finite and increasing, got {grades!r}.")
        if not (np.all(np.isfinite(c)) and np.all(c > 0) and np.all(np.diff(c) <= 0)):
            raise ValueError(f"GradeTable: costs must be finite, > 0 and not increase with the grade (a looser grade never "
                             f"costs more), got {costs!r}.")
        self.grades, self.log_costs = jnp.asarray(g), jnp.asarray(np.log(c))
        self.floor = V.real("GradeTable", "floor", floor, "m")

    def __check_init__(self):
        V.check(self, floor=V.POSITIVE("m"))

    @property
    def unit(self) -> str:
        pairs = ", ".join(f"IT{g:g} {c:.3g}" for g, c in zip(np.asarray(self.grades), np.exp(np.asarray(self.log_costs))))
        return f"the shop's price table's units ({pairs})"

    @property
    def grade_range(self) -> tuple[float, float]:
        return float(self.grades[0]), float(self.grades[-1])

    def __call__(self, band, size_mm):
        if size_mm is None:
            raise ValueError("GradeTable needs the nominal size (mm) of every feature, got size_mm=None.")
        reference = it_tolerance(7, size_mm)
        grade = 7.0 + jnp.log(effective_band(band, self.floor) / reference) / math.log(GRADE_RATIO)
        g, lc = self.grades, self.log_costs
        # Piecewise linear in the grade, the end segments extended.
        k = jnp.clip(jnp.searchsorted(g, grade) - 1, 0, g.shape[0] - 2)
        slope = (lc[k + 1] - lc[k]) / (g[k + 1] - g[k])
        return jnp.exp(lc[k] + slope * (grade - g[k]))
