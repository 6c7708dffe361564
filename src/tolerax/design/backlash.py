"""A designed backlash zone as the gear drawings call it out: tooth-thickness allowances.

The model's backlash $b$ of a mesh is the gap along its line of action (docs/model.md §3): the
normal backlash $j_n$ of a spur mesh (ISO 21771, ISO/TR 10064-2). A drawing does not carry a
backlash; each gear carries its tooth thickness on the reference circle with an upper and a
lower allowance ($E_{sns}$, $E_{sni}$ in DIN 3967's and ISO 21771's notation, negative: a thinner
tooth), and the backlash follows from the two gears of the mesh (at the exact centre distance):

$$j_n = -(E_{sn,1} + E_{sn,2}) \\cos\\alpha, \\qquad j_t = j_n / \\cos\\alpha,$$

$j_t$ the circumferential backlash on the reference circle, $\\alpha$ the pressure angle (an arc
$\\Delta s$ on the reference circle is $\\Delta s \\cos\\alpha$ on the base circle, along which
the line of action runs). An internal gear's (the ring's) allowance is written the same way: a
thinner ring tooth, a wider space, more backlash.

In a 2K-H stage the planet meshes with the sun and the ring, so its one tooth thickness enters
both backlashes. `stage_allowances` splits the two zones among sun, planet and ring: the planet
takes half of the smaller of the two required thinnings and half of the narrower zone's width,
the sun and the ring the rest of theirs, so each mesh's backlash from its two gears' allowances
fills its zone; allowances are then rounded to whole micrometres inward (the upper allowance
away from zero, the lower towards it), so the backlash drawn lies inside the zone.

Not done here: DIN 3967's named allowance series (a ... h) and tolerance series (21 ... 30) are
not tabulated, so the allowances are the ones the zone needs, not the nearest series; the
centre distance's tolerance $\\pm A_a$ (it moves $j_n$ by $\\pm 2 A_a \\sin\\alpha$ per mesh, the
ring mesh's the other way) is taken as zero: leave room for it in the zone; the pressure angle is
the stage's (its reference angle for gears without profile shift).
"""

import dataclasses
import math

UM = 1e-6


@dataclasses.dataclass(frozen=True)
class Allowances:
    """One gear's tooth-thickness allowances (m, on the reference circle, normal plane): upper
    `upper` and lower `lower`, both <= 0 (a thinner tooth); the tolerance is `upper - lower`."""

    gear: str
    upper: float
    lower: float

    def text(self) -> str:
        """`"sun -11/-23"`: the allowances in whole µm (an allowance of zero unsigned)."""
        return f"{self.gear} {_um(self.upper)}/{_um(self.lower)}"


def _um(value: float) -> str:
    whole = round(value / UM)
    return "0" if whole == 0 else f"{whole:+d}"


def backlash_range(first: Allowances, second: Allowances, pressure_angle: float) -> tuple[float, float]:
    """(smallest, largest) normal backlash $j_n$ (m) of a mesh between two gears made to their
    allowances, at the exact centre distance: $-(E_{sns,1} + E_{sns,2})\\cos\\alpha$ and
    $-(E_{sni,1} + E_{sni,2})\\cos\\alpha$."""
    c = math.cos(pressure_angle)
    return -(first.upper + second.upper) * c, -(first.lower + second.lower) * c


def _inward(thinning_min: float, thinning_max: float) -> tuple[float, float]:
    """Allowances (upper, lower) (m) for a thinning zone [min, max] (m, >= 0), rounded inward to whole µm."""
    return -math.ceil(thinning_min / UM - 1e-9) * UM, -math.floor(thinning_max / UM + 1e-9) * UM


def stage_allowances(sun_zone=None, ring_zone=None, sun_pressure_angle=math.radians(20.0),
                     ring_pressure_angle=math.radians(20.0)) -> tuple[Allowances, ...]:
    """Tooth-thickness allowances of the sun, planet and ring (those meshes given) for designed
    backlash zones (module docstring).

    **Arguments:**

    - `sun_zone`, `ring_zone`: (smallest, largest) normal backlash $j_n$ (m) of the sun-planet
      and ring-planet meshes, or None for a mesh whose backlash is not designed (then only the
      other mesh's two gears are given allowances).
    - `sun_pressure_angle`, `ring_pressure_angle`: the meshes' pressure angles (rad).

    **Returns:**

    `Allowances` for the gears of the given meshes, in the order sun, planet, ring. Raises
    `ValueError` where a zone is too narrow to split into whole-micrometre allowances (under
    about 2 µm per gear).
    """
    zones = {}
    for mesh, zone, angle in (("sun", sun_zone, sun_pressure_angle), ("ring", ring_zone, ring_pressure_angle)):
        if zone is None:
            continue
        low, high = (float(v) for v in zone)
        if not (math.isfinite(low) and math.isfinite(high) and 0 <= low <= high):
            raise ValueError(f"stage_allowances: the {mesh} mesh's backlash zone must be (smallest, largest) with "
                             f"0 <= smallest <= largest (m), got {zone!r}.")
        c = math.cos(float(angle))
        zones[mesh] = (low / c, high / c)  # the two gears' summed thinning on the reference circle
    if not zones:
        raise ValueError("stage_allowances: give the sun mesh's or the ring mesh's backlash zone (m).")
    # The planet's share: half the smaller required thinning, half the narrower zone's width.
    planet_min = 0.5 * min(lo for lo, _ in zones.values())
    planet_max = planet_min + 0.5 * min(hi - lo for lo, hi in zones.values())
    up, low = _inward(planet_min, planet_max)
    out = {"planet": Allowances("planet", up, low)}
    for mesh, (lo, hi) in zones.items():  # the mesh's other gear takes the rest of its zone
        out[mesh] = Allowances(mesh, *_inward(lo + up, hi + low))
    for gear, a in out.items():
        if a.lower > a.upper:
            raise ValueError(f"stage_allowances: the backlash zone is too narrow to split into whole-micrometre tooth "
                             f"thickness allowances ({a.text()} µm); widen it.")
    return tuple(out[g] for g in ("sun", "planet", "ring") if g in out)


def callout_text(mesh: str, allowances: tuple[Allowances, ...], pressure_angle: float) -> str:
    """One line for a drawing table: the mesh's normal backlash from its gears' allowances, the
    allowances, and the circumferential backlash: `"jn 20.5–44.9 µm: sun -11/-23, planet
    -11/-23 µm tooth thickness (jt 21.8–47.8 µm)"`."""
    by = {a.gear: a for a in allowances}
    pair = (by[mesh], by["planet"])
    lo, hi = backlash_range(*pair, pressure_angle)
    c = math.cos(pressure_angle)
    return (f"jn {lo / UM:.1f}–{hi / UM:.1f} µm: {pair[0].text()}, {pair[1].text()} µm tooth thickness "
            f"(jt {lo / c / UM:.1f}–{hi / c / UM:.1f} µm)")
