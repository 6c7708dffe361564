"""Archard wear of the journal-bearing clearances and tooth flanks of a planetary stage
(docs/model.md §4): how much each clearance and each mesh's backlash grows over a simulated run;
`tolerax.design.life` integrates it over a mission's life.

**Which contacts, which relative rotation.** A stage's clearance contacts are, in
`PlanetaryStage.contact_names` order (`physics/stage.py`, `supports()` then `contact_names`),
`"sun"`, `"carrier"` and `"planet0"`, ... `"planet{N-1}"` (only those whose support is
`"clearance"`; the ring may not have one). The stage's rotations $\\theta_s$, $\\theta_c$,
$\\theta_n$ are *absolute*, i.e. measured in the housing (the body that carries the joint and
the fixed ring), `physics/planetary.py` module docstring and `body_positions` (each body's angle
is its own coordinate). The translations say what each bearing joins:

- `"sun"`: the sun's centre in the housing frame (`sun_e` = $(x_s, y_s)$): the sun journal in a
  bore of the housing. Relative rotation $\\omega_{rel} = \\dot\\theta_s$.
- `"carrier"`: the carrier (output) centre in the housing frame (`carrier_e` = $(x_c, y_c)$):
  the output journal in the housing. $\\omega_{rel} = \\dot\\theta_c$.
- `"planet{n}"`: the planet centre's displacement $(\\zeta_n, \\eta_n)$ from its pin, in axes
  turning with the carrier (`planet_e`): the planet turning on a pin of the carrier.
  $\\omega_{rel} = \\dot\\theta_n - \\dot\\theta_c$.

In rigid rolling on the fixed ring ($\\dot\\theta_s = i\\dot\\theta_c$, $i = 1 + z_r/z_s$,
$\\dot\\theta_n = \\rho\\dot\\theta_c$, $\\rho = 1 - z_r/z_p$ for gear data that assemble) the
relative speeds are $i\\,\\omega_c$, $\\omega_c$ and $-(z_r/z_p)\\,\\omega_c$.

**Archard's law, depth form** (SI units throughout):

$$\\frac{dh}{dt} = k\\,p\\,v, \\qquad p = \\frac{F}{2RL}, \\qquad v = R\\,|\\omega_{rel}|,
\\qquad\\text{so}\\qquad \\frac{dh}{dt} = \\frac{k\\,F\\,|\\omega_{rel}|}{2L},$$

- $h$: depth worn (m); the radial clearance $c$ grows by $h$;
- $k$: specific (dimensional) wear rate, m³/(N m) (tables give mm³/(N m): multiply by 1e-9);
- $F$: the contact's normal force (N), as the simulation computes it (`StageForces.contact`,
  `MechanismResult.azimuth_contact` / `pitch_contact`);
- $R$: journal radius (m, `JournalBearing.journal_radius`); $L$: bearing length (m,
  `JournalBearing.length`, 8 mm in `default_stage`, overridable here per contact with
  `ArchardWear(length=...)`);
- $p$: the mean pressure over the journal's projected area $2RL$ (Pa); $v$: sliding speed (m/s).

**Model choices** (to revisit as the issue goes on):

- The pressure is the projected-area mean, not the Hertzian or conformal contact pressure: for a
  conforming journal the worn depth then depends on the load per length and the sliding distance
  only ($R$ cancels). A local (Hertz line-contact) pressure over a narrower band would wear that
  band deeper.
- All wear is put on one member (the clearance grows by $h$, material removed from the loaded
  side of one surface); no split between journal and bore, no wear of the unloaded side.
- No running-in: $k$ is the steady-state rate, constant in time and load.
- The sliding speed is the surfaces' relative rotation, $R|\\omega_{rel}|$; the whirl of the
  journal centre inside its clearance (tangential $\\dot e$) is left out.
- The depth is nanometres per scan against clearances of tens of µm, so the geometry is not
  updated within a run: wear is computed after the run from its saved states (`wear_over_run`,
  trapezoid rule over the saves; `benchmarks/wear_convergence.py` measures its error against
  the save rate), and a mission's clearance growth is the per-run depth times the number of
  runs, with the clearance updated between runs by the caller.

**Tooth flanks** (`flank_backlash_rates`; `ArchardWear(flanks=True)`, the default, for stages
whose meshes have backlash, `Mesh(kind="nonlinear")`). Two involute flanks in contact at a
distance $s$ from the pitch point along the line of action slide at $|s|\\,|\\omega_a - \\omega_b|$
($\\omega$ the gears' absolute rates: the ring's 0 when rigid; the difference is the same in any
frame), for an external and an internal mesh alike. Over the path of contact $g = \\varepsilon_c
p_b$ ($p_b = 2\\pi r_b/z$ the base pitch) with approach and recess equal, the mean $|s|$ is
$g/4$; Archard's volume rate $k F \\bar v$ spread over one gear's $z$ teeth, each worn over the
active profile ($g$, measured along the line of action, where the backlash is measured too)
times the face width $b$, thins each tooth at

$$\\dot t = \\frac{k\\,|F|\\,|\\omega_a - \\omega_b|\\,g/4}{z\\,b\\,g} = \\frac{k\\,|F|\\,|\\omega_a -
\\omega_b|}{4\\,z\\,b}$$

per mesh it works in: the sun's over its $N$ planet meshes, the ring's likewise, each planet's over
its sun and ring meshes (opposite flanks of its teeth). A tooth thinned by $t$ on either flank
opens its meshes' backlash by $t$, so the backlash of planet $n$'s sun mesh grows at $\\dot t_s +
\\dot t_{p,n}$ and of its ring mesh at $\\dot t_r + \\dot t_{p,n}$ ($F$ the tooth force per
planet and mesh, drive or back flank, from the saved states: `stage_forces`). Model choices: the
flanks wear at the journals' rate $k$ (the MoS2 entries below are rolling-sliding disc tests,
the gear-like case); no local Hertz pressure or profile change (the mesh stays involute, its
stiffness and phase as built); `face_width` 10 mm (MODEL.md's default joint).

**Wear-rate data** (`LUBRICANTS`: name -> `Lubricant(median, low, high, source)`, m³/(N m)).
Published rates depend strongly on test rig, load and environment; each entry's `source` says
which number is from which publication and which band is an unsourced order-of-magnitude spread.
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from .. import _validate as V
from .stage import PlanetaryStage

MM3_PER_NM = 1e-9
"""One mm³/(N m) in m³/(N m)."""


ESTIMATES = ("median", "low", "high")


@dataclasses.dataclass(frozen=True)
class Lubricant:
    """Specific wear rates $k$ of one lubricated pair (m³/(N m)): a `median` estimate and a
    `low`/`high` band, with the `source` of each number."""

    median: float
    low: float
    high: float
    source: str

    def __post_init__(self):
        for name in ("median", "low", "high"):
            value = getattr(self, name)
            if not (isinstance(value, (int, float)) and math.isfinite(value) and value >= 0.0):
                raise ValueError(f"Lubricant.{name} must be a finite specific wear rate >= 0 (m^3/(N m)), got {value!r}.")
        if not self.low <= self.median <= self.high:
            raise ValueError(f"Lubricant rates must satisfy low <= median <= high, got {self.low}, {self.median}, {self.high}.")

    def at(self, estimate: str) -> float:
        """The rate (m³/(N m)) at `estimate`: `"median"`, `"low"` or `"high"`."""
        if estimate not in ESTIMATES:
            raise ValueError(f"estimate={estimate!r} is unknown; use one of {ESTIMATES}.")
        return getattr(self, estimate)


LUBRICANTS: dict[str, Lubricant] = {
    "MoS2 sputtered film, vacuum": Lubricant(
        median=4e-6 * MM3_PER_NM,
        low=1e-6 * MM3_PER_NM,
        high=1e-5 * MM3_PER_NM,
        source=(
            "median: PVD-MoS2 coatings on 100Cr6 in vacuum, two-disc rolling-sliding (10.5 % slip, 1.1-1.6 GPa), "
            "worn coatings' wear coefficient 4e-6 mm^3/(N m): Seynstahl, Polzer, Bartz, Wartzack, Tremmel (2023), "
            "'Effects of Nitrogen Modification of Porous PVD-MoS2 Coatings on the Tribological Behavior under "
            "Rolling-Sliding Conditions in Vacuum', Lubricants 11(8), 335. Kim, Ahn, Kim (2002), 'Tribological "
            "characteristics of magnetron sputtered MoS2 films in various atmospheric conditions', KSME Int. J. 16, "
            "1065-1071, report the specific wear rate much higher in air than in medium and high vacuum (their "
            "numbers were not available here). low/high (1e-6 to 1e-5 mm^3/(N m)): order of magnitude, unsourced."
        ),
    ),
    "MoS2/DLC multilayer, vacuum": Lubricant(
        median=6.5e-6 * MM3_PER_NM,
        low=2e-6 * MM3_PER_NM,
        high=2e-5 * MM3_PER_NM,
        source=(
            "median: MoS2/DLC multilayer coating in high vacuum, ~6.5e-6 mm^3/(N m), wear volume linear in time "
            "(Archard): Pu, Ren, Lu, Wang (2016), 'A feasible multilayer structure design for solid lubricant "
            "coatings in a lunar environment', RSC Advances 6, 65504-65517, doi:10.1039/c6ra14314h. "
            "low/high (x 1/3, x 3): order of magnitude, unsourced."
        ),
    ),
    "PFPE grease (Braycote-type), vacuum": Lubricant(
        median=8.5e-9 * MM3_PER_NM,
        low=1.05e-9 * MM3_PER_NM,
        high=8.5e-8 * MM3_PER_NM,
        source=(
            "Jones, Poslowski, Shogrin, Herrera-Fierro, Jansen (1999), 'Evaluation of Several Space Lubricants "
            "Using a Vacuum Four-Ball Tribometer', Tribology Transactions 42(2), 317-323: steel four-ball, "
            "<6.7e-4 Pa, 200 N, 28.8 mm/s, boundary regime, wear per sliding distance 1.7e-9 mm^3/mm for the "
            "linear PFPE Z-25 and 0.21e-9 mm^3/mm for the branched PFPE 143AC. Divided by the 200 N applied load: "
            "median 8.5e-9 (Z-25) and low 1.05e-9 (143AC) mm^3/(N m). These are the base oils, not the grease; that "
            "Braycote 601EF's base oil is a Z-type PFPE is from general knowledge, not checked against a source "
            "here, and the four-ball's load per ball (about 82 N on each lower ball) would raise k by up to 2.4x. "
            "high (x 10, degraded or starved grease): order of magnitude, unsourced."
        ),
    ),
}


def lubricant(name: str) -> Lubricant:
    """The `LUBRICANTS` entry `name`; `ValueError` listing the known names otherwise."""
    if name not in LUBRICANTS:
        raise ValueError(f"Unknown lubricant {name!r}; known: {sorted(LUBRICANTS)}.")
    return LUBRICANTS[name]


class ArchardWear(eqx.Module):
    """Archard wear data of one stage's clearance contacts and tooth flanks.

    - `rate`: specific wear rate $k$ (m³/(N m)), a scalar (every contact) or one per contact in
      `stage.contact_names` order, $\\ge 0$.
    - `length`: bearing length $L$ (m) per contact or a scalar, $> 0$; `None` (default): each
      contact's `JournalBearing.length` (8 mm in `default_stage`).
    - `flanks` (static, default `True`): the tooth flanks wear too, opening each planet's mesh
      backlash (`flank_backlash_rates`; meshes with backlash only), at `flank_rate`.
    - `flank_rate` (m³/(N m), optional): the flanks' $k$; default `rate` (a scalar `rate`).
    - `face_width` (m): the gears' face width $b$ (default 10 mm, MODEL.md's default joint).

    Build from the table with `ArchardWear.from_lubricant(name, estimate="median")`.
    """

    rate: Array
    length: Array | None
    flank_rate: Array | None
    face_width: Array
    flanks: bool = eqx.field(static=True, default=True)

    def __init__(self, rate, length=None, *, flanks: bool = True, flank_rate=None, face_width=10e-3):
        self.rate = V.real("ArchardWear", "rate", rate, "m^3/(N m)", shape=None)
        self.length = None if length is None else V.real("ArchardWear", "length", length, "m", shape=None)
        self.flank_rate = None if flank_rate is None else V.real("ArchardWear", "flank_rate", flank_rate, "m^3/(N m)")
        self.face_width = V.real("ArchardWear", "face_width", face_width, "m")
        if not isinstance(flanks, bool):
            raise TypeError(f"ArchardWear: flanks must be True or False (the tooth flanks wear), got {flanks!r}.")
        self.flanks = flanks

    def __check_init__(self):
        V.check(self, rate=V.NONNEGATIVE("m^3/(N m)"), length=V.Rule("m", low=0.0, low_open=True, optional=True),
                flank_rate=V.Rule("m^3/(N m)", low=0.0, optional=True), face_width=V.POSITIVE("m"))
        if self.flanks and self.flank_rate is None and jnp.ndim(self.rate) != 0:
            raise ValueError("ArchardWear: with one rate per contact, give the flanks' own flank_rate (a scalar), "
                             "or flanks=False.")
        for name in ("rate", "length"):
            value = getattr(self, name)
            if value is not None and jnp.ndim(value) > 1:
                raise ValueError(f"ArchardWear.{name} must be a scalar or one value per contact (1-D), got shape {jnp.shape(value)}.")

    @classmethod
    def from_lubricant(cls, name: str, estimate: str = "median", length=None, **options) -> "ArchardWear":
        """The rate of `LUBRICANTS[name]` at `estimate` (`"median"`, `"low"` or `"high"`) for every
        contact and flank; `options`: `flanks`, `face_width`."""
        return cls(lubricant(name).at(estimate), length, **options)

    @property
    def flank_k(self) -> Array:
        """The flanks' specific wear rate (m³/(N m))."""
        return self.rate if self.flank_rate is None else self.flank_rate


# ---------------------------------------------------------------------------------------------
# Per contact, at one instant


def _contact_parts(stage: PlanetaryStage):
    """(name, bearing, count) for each clearance support, in `contact_names` order (count: the
    number of planets for the pins, None for a single bearing)."""
    return [
        (name, support.bearing, stage.n_planets if name == "planet" else None)
        for name, support in stage.supports()
        if support.kind == "clearance"
    ]


def _per_contact(stage: PlanetaryStage, field: str) -> Array:
    """A `JournalBearing` field per contact, shape (n_contacts,)."""
    parts = [jnp.broadcast_to(getattr(bearing, field), (count or 1,)) for _, bearing, count in _contact_parts(stage)]
    return jnp.concatenate(parts) if parts else jnp.zeros(0)


def relative_angular_velocities(stage: PlanetaryStage, q: Array, u: Array) -> Array:
    """$\\omega_{rel}$ (rad/s) of journal and bore at each clearance contact, `stage.contact_names`
    order: $\\dot\\theta_s$ (sun in housing), $\\dot\\theta_c$ (carrier in housing),
    $\\dot\\theta_n - \\dot\\theta_c$ (planet on its carrier pin). `q` is unused (the speeds do not
    depend on the configuration) and kept for a uniform signature; `u` = $\\dot q$ of the stage."""
    del q
    lay = stage.layout
    u = jnp.asarray(u)
    parts = []
    for name, _, _ in _contact_parts(stage):
        if name == "sun":
            parts.append(u[..., lay.sun_theta][..., None])
        elif name == "carrier":
            parts.append(u[..., lay.carrier_theta][..., None])
        elif name == "planet":
            parts.append(u[..., lay.planet_theta] - u[..., lay.carrier_theta][..., None])
        else:  # a support whose members do not turn against each other (none today: the ring has no clearance)
            parts.append(jnp.zeros(u.shape[:-1] + (1,)))
    return jnp.concatenate(parts, axis=-1) if parts else jnp.zeros(u.shape[:-1] + (0,))


def sliding_speeds(stage: PlanetaryStage, q: Array, u: Array) -> Array:
    """Sliding speed $v = R|\\omega_{rel}|$ (m/s) at each clearance contact, shape
    `(..., n_contacts)` in `stage.contact_names` order; `q`, `u` the stage's coordinates and speeds
    (any leading batch shape)."""
    return _per_contact(stage, "journal_radius") * jnp.abs(relative_angular_velocities(stage, q, u))


def _model_arrays(stage: PlanetaryStage, model: ArchardWear):
    n = len(stage.contact_names)
    names = stage.contact_names
    length = _per_contact(stage, "length") if model.length is None else model.length
    out = []
    for label, value in (("rate", model.rate), ("length", length)):
        if jnp.ndim(value) == 1 and jnp.shape(value)[0] != n:
            raise ValueError(f"ArchardWear.{label} has {jnp.shape(value)[0]} values for the stage's {n} contacts {names}: "
                             "give a scalar or one per contact.")
        out.append(jnp.broadcast_to(value, (n,)))
    return out


def wear_depth_rates(stage: PlanetaryStage, q: Array, u: Array, forces: Array, model: ArchardWear) -> Array:
    """Archard depth rate $dh/dt = k\\,F/(2RL)\\cdot R|\\omega_{rel}|$ (m/s) per clearance contact,
    shape `(..., n_contacts)`: `forces` the contacts' normal forces (N) in `stage.contact_names`
    order (negative values, which the contact laws never give, count as 0)."""
    if not isinstance(model, ArchardWear):
        raise TypeError(f"model must be an ArchardWear, got {type(model).__name__}.")
    rate, length = _model_arrays(stage, model)
    radius = _per_contact(stage, "journal_radius")
    forces = jnp.asarray(forces, dtype=float)
    n = len(stage.contact_names)
    if forces.shape[-1:] != (n,):
        raise ValueError(f"forces must end in one column per contact, {n} ({stage.contact_names}), got shape {forces.shape}.")
    pressure = jnp.maximum(forces, 0.0) / (2.0 * radius * length)
    return rate * pressure * sliding_speeds(stage, q, u)


def flank_names(stage: PlanetaryStage, model: "ArchardWear") -> tuple[str, ...]:
    """The meshes whose backlash `model` wears on `stage`: `sun_mesh0..N-1`, `ring_mesh0..N-1`
    (one per planet and mesh), or none (`flanks=False`, or meshes without backlash)."""
    if not model.flanks or stage.sun_mesh.kind != "nonlinear" or stage.ring_mesh.kind != "nonlinear":
        return ()
    return tuple(f"{mesh}_mesh{n}" for mesh in ("sun", "ring") for n in range(stage.n_planets))


def wear_names(stage: PlanetaryStage, model: "ArchardWear") -> tuple[str, ...]:
    """What `model` wears on `stage`, in the order of `wear_over_run`'s entries and of the growth
    arrays of `tolerax.design.life`: the clearance contacts (`contact_names`), then `flank_names`."""
    return stage.contact_names + flank_names(stage, model)


def flank_backlash_rates(stage: PlanetaryStage, q: Array, u: Array, v: Array, model: ArchardWear) -> Array:
    """The rate (m/s) at which each planet's sun-mesh and ring-mesh backlash opens by flank wear
    (the module docstring's $\\dot t_s + \\dot t_{p,n}$ and $\\dot t_r + \\dot t_{p,n}$), shape
    `(..., 2N)`: the sun meshes, then the ring meshes (`flank_names`). `q`, `u`, `v`: the stage's
    coordinates, speeds and impact-rate states (any leading batch shape); the tooth forces are
    the stage's own (`stage_forces`)."""
    from . import planetary as _planetary

    lead = jnp.shape(q)[:-1]
    flat = [jnp.reshape(x, (-1, jnp.shape(x)[-1])) for x in (q, u, v)]
    forces = jax.vmap(lambda q_, u_, v_: _planetary.stage_forces(stage, q_, u_, v_))(*flat)
    lay, n = stage.layout, stage.n_planets
    speeds = flat[1]
    w_s, w_p = speeds[:, lay.sun_theta], speeds[:, lay.planet_theta]
    w_r = speeds[:, lay.ring_theta] if lay.ring_theta is not None else jnp.zeros_like(w_s)
    k, b = model.flank_k, model.face_width
    sun_mesh = k * jnp.abs(jnp.reshape(forces.sun_mesh, (-1, n))) * jnp.abs(w_s[:, None] - w_p) / 4.0  # k |F| |dw| / 4: per mesh
    ring_mesh = k * jnp.abs(jnp.reshape(forces.ring_mesh, (-1, n))) * jnp.abs(w_r[:, None] - w_p) / 4.0
    sun = jnp.sum(sun_mesh, axis=-1, keepdims=True) / (stage.sun_teeth * b)
    ring = jnp.sum(ring_mesh, axis=-1, keepdims=True) / (stage.ring_teeth * b)
    planet = (sun_mesh + ring_mesh) / (stage.planet_teeth * b)
    return jnp.reshape(jnp.concatenate([sun + planet, ring + planet], axis=-1), (*lead, 2 * n))


# ---------------------------------------------------------------------------------------------
# Over a run


def wear_over_run(mechanism, result, models, saves: slice = slice(None)) -> dict[str, dict[str, Array]]:
    """Depth worn (m) at each clearance contact of each planetary joint over a run, and each
    mesh's backlash growth by flank wear (`ArchardWear.flanks`).

    For each joint with a `.stage` (azimuth, pitch) and clearance contacts, the depth rate
    `wear_depth_rates` at every save of `result` (its `states` $(q, u, \\cdot)$, the joint's slices
    of them, and its contact forces `result.<joint>_contact`) integrated over `result.ts` by the
    trapezoid rule; likewise `flank_backlash_rates` (the tooth forces from the saved states). The saves must resolve the contact-force history (impacts last fractions of
    a millisecond): see `benchmarks/wear_convergence.py` for the error against the save rate.

    - `mechanism`: the `Mechanism` that was simulated; `result`: its `MechanismResult` (one run,
      or a batch: leading axes are kept).
    - `models`: one `ArchardWear` for every joint, or a dict joint name -> `ArchardWear` (a joint
      missing from it is skipped).
    - `saves` (optional): the saves to integrate over (a slice of the save axis; default all),
      e.g. a pointing window's (`tolerax.design.life.window_wear_rates`).

    Returns `{joint name: {name: depth (m)}}` over `wear_names` (the contacts, then the meshes'
    backlash growth `sun_mesh0`, ..., `ring_mesh0`, ...), joints without clearance contacts left
    out.
    """
    from ..mechanism.stage_joints import (  # mechanism imports physics: import here
        MassScaledPlanetaryJoint,
        PlanetaryJoint,
    )

    ts = jnp.asarray(result.ts)[..., saves]
    if V.concrete(ts) and not bool(np.all(np.isfinite(np.asarray(ts)))):
        raise ValueError("result.ts has non-finite save times (a failed run?): the wear needs a complete run; "
                         "check result.success first.")
    if ts.shape[-1] < 2:
        raise ValueError(f"wear_over_run needs at least 2 saves to integrate over, got {ts.shape[-1]}.")
    q_all, u_all = result.states[0][..., saves, :], result.states[1][..., saves, :]
    out = {}
    for (name, _), (joint, sq, su, sv) in zip(mechanism.named_joints(), mechanism.joints()):
        if not isinstance(joint, (PlanetaryJoint, MassScaledPlanetaryJoint)):
            continue  # ideal or lumped: its coordinates are not the stage's
        stage = joint.stage
        if not stage.contact_names:
            continue
        if isinstance(models, dict):
            if name not in models:
                continue
            model = models[name]
        else:
            model = models
        names = getattr(result, f"{name}_contact_names")
        if tuple(names) != stage.contact_names:
            raise ValueError(f"result.{name}_contact_names {names} differ from the stage's {stage.contact_names}.")
        forces = jnp.asarray(getattr(result, f"{name}_contact"))[..., saves, :]
        rates = wear_depth_rates(stage, q_all[..., sq], u_all[..., su], forces, model)
        if flank_names(stage, model):
            v_all = result.states[2][..., saves, :][..., sv]
            rates = jnp.concatenate([rates, flank_backlash_rates(stage, q_all[..., sq], u_all[..., su], v_all, model)], axis=-1)
        dt = jnp.diff(ts, axis=-1)[..., None]
        depth = jnp.sum(0.5 * dt * (rates[..., 1:, :] + rates[..., :-1, :]), axis=-2)  # trapezoid rule
        out[name] = {label: depth[..., k] for k, label in enumerate(wear_names(stage, model))}
    return out
