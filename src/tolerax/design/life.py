"""Pointing over a mission's life: the journal clearances grown by Archard wear from the simulated
contacts (`tolerax.physics.wear`), the dynamics re-simulated at a few life points as they grow.

A `MissionLife` says how long the mechanism runs its duty (`operating_time`, s: the time spent
in the regime the pointing objective simulates, e.g. scanning), how its contacts wear
(`ArchardWear`, per joint or for all) and at how many life points the growth is integrated.
Given to `PointingObjective(life=...)`, every output gains an end-of-life twin (`pointing_rms_eol`,
...) that requirements, designs and Monte Carlo runs read like any other output.

**The growth.** Over the objective's window $[t_s, T]$ each clearance contact wears at the mean
rate $\\bar r = h_{window}/(T - t_s)$ (m per operating second; `wear_over_run` over the window),
and the mission integrates $dc/d\\tau = \\bar r(c)$ over the operating time $\\tau$ by explicit
Euler steps at `points` life points, each re-simulating the scene with the clearances grown so
far (the contact forces change as the clearances grow): $c_{k+1} = c_k + \\bar r(c_k)\\,\\Delta\\tau$,
$\\Delta\\tau$ = `operating_time` / `points`; the end of life is simulated once more at $c_K$.
`benchmarks/life_convergence.py` measures the end-of-life error against the number of points.

**What wears.** The journal bearings of planetary joints (sun, carrier, each planet's pin, each
contact its own growth: the pins of one stage grow apart) and, with `ArchardWear(flanks=True)`
(the default) on meshes with backlash, the tooth flanks: each planet's sun-mesh and ring-mesh
backlash opens by the teeth thinned on both of its gears (`tolerax.physics.wear`'s module
docstring). Ideal and lumped joints do not wear (they have no contact forces of their own).
Everything is traceable: gradients of end-of-life outputs with respect to the as-built design
pass through the growth (`tests/test_life.py` checks them against central differences in a
start-up; over a chaotic rattle they are as noisy as any output's, and the design fits such
outputs by secants).

**The wear rate's spread.** Published rates for one lubricant span an order of magnitude
(`tolerax.physics.wear.LUBRICANTS`); `MissionLife(spread=(low, high))` makes the rate an
uncertain input of each unit: its logarithm, drawn over $[\\ln$ low$, \\ln$ high$]$, follows the
unit's design values (`WEAR_FACTOR`, `spread_tolerances`): Monte Carlo verifies the end of
life over the band, and a design draws it in every unit it fits its lines through, each line
carrying the factor as one more regressor and the quantile drawing it
(`tolerax.design.reliability.LinearisedYield`, uncertain inputs): a design over the band, not at
one estimate.
"""

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from .. import _validate as V
from ..physics import wear as _wear
from ..uncertainty.sampling import Tolerances

YEAR = 365.25 * 86400.0
"""One year (s)."""

WEAR_FACTOR = "life.log_wear_factor"
"""The name of a unit's drawn wear-rate factor (its natural logarithm) in Monte Carlo inputs
(`MissionLife(spread=...)`, `MissionLife.spread_tolerances`)."""


class MissionLife(eqx.Module):
    """A mission's life for `PointingObjective(life=...)`.

    - `operating_time` (s): the time the mechanism spends in the simulated regime over the
      whole life ($\\ge 0$). `MissionLife.from_years(years, duty)` and
      `MissionLife.from_cycles(cycles, period)` build it from a mission's terms.
    - `wear`: an `ArchardWear` for every planetary joint, or a dict joint name ->
      `ArchardWear` (joints missing from it do not wear); e.g.
      `ArchardWear.from_lubricant("MoS2 sputtered film, vacuum")`.
    - `points`: Euler steps of the growth over the life, each one more simulation (default 2;
      end-of-life outputs cost `points + 1` simulations of the window).
    - `spread` (optional, `(low, high)`, factors on every wear rate, $0 <$ low $\\le$ high): the
      wear rate is uncertain from unit to unit: each unit's rates are multiplied by
      $e^x$, $x$ drawn with the unit's other inputs over $[\\ln$ low$, \\ln$ high$]$ (log-uniform
      for uniform tolerances; `spread_tolerances`), read by `PointingObjective` as one more value
      after the design's (`WEAR_FACTOR`). `spread_of_lubricant` gives a `LUBRICANTS` entry's band.
      A design vector without it is at factor 1; `propose_design` draws it in its secant units.
    """

    operating_time: Array
    wear: _wear.ArchardWear | dict
    points: int = eqx.field(static=True, default=2)
    spread: tuple[float, float] | None = eqx.field(static=True, default=None)

    def __init__(self, operating_time, wear, points: int = 2, spread=None):
        self.operating_time = V.real("MissionLife", "operating_time", operating_time, "s")
        if isinstance(wear, dict):
            bad = {k: type(v).__name__ for k, v in wear.items() if not isinstance(v, _wear.ArchardWear)}
            if bad:
                raise TypeError(f"MissionLife: wear must map joint names to ArchardWear, got {bad}.")
        elif not isinstance(wear, _wear.ArchardWear):
            raise TypeError(f"MissionLife: wear must be an ArchardWear (e.g. ArchardWear.from_lubricant(...)) or a dict of them, "
                            f"got {type(wear).__name__}.")
        self.wear = wear
        if isinstance(points, bool) or not isinstance(points, (int, np.integer)) or points < 1:
            raise ValueError(f"MissionLife: points must be an integer >= 1 (Euler steps over the life), got {points!r}.")
        self.points = int(points)
        if spread is not None:
            try:
                low, high = (float(v) for v in spread)
            except (TypeError, ValueError):
                raise ValueError(f"MissionLife: spread must be (low, high), factors on the wear rates, got {spread!r}.") from None
            if not (np.isfinite(low) and np.isfinite(high) and 0.0 < low <= high):
                raise ValueError(f"MissionLife: spread must be (low, high) with 0 < low <= high (factors on the wear rates), "
                                 f"got {spread!r}.")
            spread = (low, high)
        self.spread = spread

    def __check_init__(self):
        V.check(self, operating_time=V.NONNEGATIVE("s"))

    @classmethod
    def from_years(cls, years, duty=1.0, wear=None, points: int = 2, spread=None) -> "MissionLife":
        """`years` in orbit (365.25 days) spending the fraction `duty` (0-1) of the time in the
        simulated regime."""
        if not (0.0 <= float(duty) <= 1.0):
            raise ValueError(f"MissionLife.from_years: duty is the fraction of time in the simulated regime, 0-1; got {duty!r}.")
        return cls(float(years) * YEAR * float(duty), wear, points, spread)

    @classmethod
    def from_cycles(cls, cycles, period, wear=None, points: int = 2, spread=None) -> "MissionLife":
        """`cycles` duty cycles (scans) of `period` s each."""
        if not float(period) > 0:
            raise ValueError(f"MissionLife.from_cycles: period must be > 0 (s), got {period!r}.")
        return cls(float(cycles) * float(period), wear, points, spread)

    def spread_tolerances(self, distribution: str = "uniform") -> Tolerances:
        """The unit-to-unit wear-rate factor as one more Monte Carlo input: `WEAR_FACTOR`, the
        factor's logarithm over $[\\ln$ low$, \\ln$ high$]$ (`distribution` as the design's
        zones: uniform, or normal truncated at the ends); join it to the design's zones with
        `Tolerances.joined`."""
        if self.spread is None:
            raise ValueError("MissionLife.spread_tolerances: this life has no spread (MissionLife(..., spread=(low, high))).")
        low, high = (float(np.log(v)) for v in self.spread)
        return Tolerances((WEAR_FACTOR,), [0.5 * (low + high)], [0.5 * (high - low)], distribution, lower=None)

    def model(self, joint: str):
        """The `ArchardWear` of `joint` (`None`: it does not wear)."""
        return self.wear.get(joint) if isinstance(self.wear, dict) else self.wear


def spread_of_lubricant(name: str, estimate: str = "median") -> tuple[float, float]:
    """`MissionLife(spread=...)` for `LUBRICANTS[name]`'s band: the factors that take its rate at
    `estimate` to its `low` and `high` rates."""
    lub = _wear.lubricant(name)
    rate = lub.at(estimate)
    return lub.low / rate, lub.high / rate


def worn_joints(scene, life: MissionLife) -> tuple[tuple[str, tuple[str, ...]], ...]:
    """`(joint, names)` for each joint of `scene` that wears under `life`: a planetary joint
    (full or mass-scaled) with clearance contacts and a wear model; `names` what wears
    (`tolerax.physics.wear.wear_names`: the contacts, then each planet's meshes)."""
    from ..mechanism.stage_joints import MassScaledPlanetaryJoint, PlanetaryJoint

    out = []
    for joint, stage_of, _ in scene.named_stages():
        holder = getattr(scene, joint, None) if joint else None
        if not isinstance(holder, (PlanetaryJoint, MassScaledPlanetaryJoint)) or life.model(joint) is None:
            continue
        stage = stage_of(scene)
        if stage.contact_names:
            out.append((joint, _wear.wear_names(stage, life.model(joint))))
    return tuple(out)


def worn_scene(scene, depth: dict):
    """`scene` with each clearance grown by the depth worn and, where given, each mesh's
    backlash by its flanks' wear: `depth` maps a joint name to its growths (m) in `wear_names`
    order (the stage's `contact_names`, then `sun_mesh0..N-1`, `ring_mesh0..N-1` where the
    flanks wear). A planet-pin clearance and a mesh's backlash become one value per planet (each
    wears on its own). Traceable."""
    for joint, stage_of, _ in scene.named_stages():
        if joint not in depth:
            continue
        d, k = depth[joint], 0
        stage = stage_of(scene)
        for name, bearing, count in _wear._contact_parts(stage):
            n = count or 1
            grown = jnp.broadcast_to(bearing.clearance, (n,)) + d[k : k + n] if count else bearing.clearance + d[k]
            k += n
            scene = eqx.tree_at(lambda s, st=stage_of, nm=name: getattr(st(s), f"{nm}_support").bearing.clearance, scene, grown)
        n = stage.n_planets
        if d.shape[0] == k + 2 * n:  # the flanks wear too
            for m, mesh in enumerate(("sun_mesh", "ring_mesh")):
                grown = jnp.broadcast_to(getattr(stage, mesh).backlash, (n,)) + d[k + m * n : k + (m + 1) * n]
                scene = eqx.tree_at(lambda s, st=stage_of, ms=mesh: getattr(st(s), ms).backlash, scene, grown)
        elif d.shape[0] != k:
            raise ValueError(f"worn_scene: {joint} has {d.shape[0]} growths; its stage wears {k} contacts (and {2 * n} meshes with "
                             "flank wear).")
    return scene


def window_wear_rates(scene, result, window, life: MissionLife) -> dict:
    """The mean wear rate (m per operating second) of each worn contact over the saves `window`
    (NumPy bool per save, contiguous): `{joint: rates (n_contacts,)}`."""
    window = np.asarray(window, dtype=bool)
    first, last = int(np.argmax(window)), int(window.size - 1 - np.argmax(window[::-1]))
    if last <= first or not np.all(window[first : last + 1]):
        raise ValueError("window_wear_rates: the window must be one run of at least 2 saves.")
    saves = slice(first, last + 1)
    joints = worn_joints(scene, life)
    depths = _wear.wear_over_run(scene, result, {j: life.model(j) for j, _ in joints}, saves)
    length = result.ts[last] - result.ts[first]
    return {joint: jnp.stack([depths[joint][c] for c in names]) / length for joint, names in joints}


def feature_growth(pointing, values) -> dict[str, tuple[float, float]]:
    """Each design feature's growth by wear over `pointing`'s life (`PointingObjective(life=...)`)
    from the as-built design `values` (m, `design_names` order), at the life's rate estimate
    (factor 1): `{feature: (least, most)}` (m) over the contacts or meshes it stands for (a
    planet-pin clearance and a mesh's backlash wear planet by planet), from `over_life`'s end
    point. Features that do not wear are left out."""
    from .features import design_names

    names = set(design_names(pointing.scene))
    _, depths = eqx.filter_jit(lambda p, v: p.over_life(v))(pointing, jnp.asarray(values, dtype=float))
    out: dict[str, tuple[float, float]] = {}
    for joint, worn in worn_joints(pointing.scene, pointing.life):
        for name, grown in zip(worn, np.asarray(depths[joint][-1], dtype=float)):
            base = name.rstrip("0123456789")
            feature = base.replace("_mesh", "_backlash") if base.endswith("_mesh") else f"{base}_clearance"
            index = name[len(base) :]
            key = f"{joint}.{feature}[{index}]" if f"{joint}.{feature}[{index}]" in names else f"{joint}.{feature}"
            least, most = out.get(key, (np.inf, -np.inf))
            out[key] = (min(least, grown), max(most, grown))
    return out


def life_comparison(pointing, designed, alone, requirements: dict, units: int, key, chunk: int | None = None, progress: bool = False):
    """Markdown: what designing for the end of life takes, against designing for the beginning of
    life alone. `designed`, `alone`: the two `DesignReport`s (the first designed for the end of
    life too, its status said in the text); `pointing`: the objective with the life (`PointingObjective(life=...)`);
    `requirements`: output -> limit for the Monte Carlo (e.g. `{"pointing_rms": R,
    "pointing_rms_eol": R}`). Per feature the two designs' zones and the growth by wear over the
    life at the first's zone middles (`feature_growth`): the wear allowance; then both designs
    simulated on `units` fresh units each (the same draws, `tolerax.monte_carlo` with `key`;
    each unit's wear rate drawn where the life has a spread) at both ends of life, with 95 %
    Wilson intervals. Returns `(text, {label: MonteCarloResult})`."""
    from ..uncertainty.montecarlo import monte_carlo
    from .features import design_names

    growth = feature_growth(pointing, designed.nominal)
    rows = ["| feature | zone designed for both ends (um) | zone for the beginning of life alone (um) | "
            "grown by wear over the life at the first's middles (um) |", "|---|---|---|---|"]
    for j, name in enumerate(design_names(pointing.scene)):
        zone = [f"{(float(r.nominal[j]) - float(r.band[j])) * 1e6:.1f}-{(float(r.nominal[j]) + float(r.band[j])) * 1e6:.1f}"
                for r in (designed, alone)]
        g = growth.get(name)
        grown = "-" if g is None else (f"{g[0] * 1e6:.3g}" if g[1] - g[0] <= 1e-3 * abs(g[1]) else f"{g[0] * 1e6:.3g}-{g[1] * 1e6:.3g}")
        rows.append(f"| {name} | {zone[0]} | {zone[1]} | {grown} |")
    results, lines = {}, []
    for label, report in (("designed for both ends", designed), ("for the beginning of life alone", alone)):
        tolerances = report.tolerances
        if pointing.uncertain_inputs:
            tolerances = tolerances.joined(pointing.life.spread_tolerances(tolerances.distribution))
        mc = monte_carlo(pointing, tolerances, int(units), key, chunk_size=chunk, progress=progress, requirement=requirements)
        results[label] = mc
        summary = mc.summary()
        cells = [f"{name} {summary[name]['yield']:.3f} [{summary[name]['yield_low']:.3f}, {summary[name]['yield_high']:.3f}]"
                 for name in requirements]
        lines.append(f"- {label} (cost {report.cost:.3f}): " + "; ".join(cells) + f" ({summary[next(iter(requirements))]['n_used']} "
                     "units used)")
    spread = "" if not pointing.uncertain_inputs else (f", each unit's wear rate drawn over x{pointing.life.spread[0]:.3g} to "
                                                       f"x{pointing.life.spread[1]:.3g}")
    status = getattr(designed, "status", None)
    text = "\n".join([
        "## Over the mission's life: the wear allowance", "",
        f"The design for the end of life too{'' if status is None else f' ({status})'} beside the same requirements at the "
        f"beginning of life alone{'' if getattr(alone, 'status', None) is None else f' ({alone.status})'}. The growth is the wear "
        f"over the life ({float(pointing.life.operating_time) / YEAR:.3g} operating years) from the first design's zone middles "
        "at the lubricant's estimate.", "", *rows, "",
        f"Both designs on the same {int(units)} fresh units{spread}, yield at each end of life [95 % Wilson]:", "", *lines,
    ])
    return text, results
