"""The 2K-H planetary stage (one joint), MODEL.md §4.

Bodies: sun $s$ (input), carrier $c$ (output), $N$ planets $p_n$ at $\\psi_n$, ring $r$.

**Coordinates** (only those the scene's structure needs exist):

- rotations $\\theta_s$, $\\theta_c$, $\\theta_n$ (absolute, rad), and $\\theta_r$ if the ring is
  spring-mounted;
- translations of the sun, carrier and ring centres in the housing frame (m), if not rigid;
- planet translations $(\\zeta_n, \\eta_n)$ (m): radial/tangential displacement of the planet
  centre from its pin, in axes that turn with the carrier.

The kinetic energy is exact for large rotations: body positions are a function of $q$ (a planet
centre is $P_c + R(\\theta_c)[(r_c+\\zeta_n)e_{\\psi_n} + \\eta_n t_{\\psi_n}]$), the mass matrix is
$M = \\sum_b m_b J_b^TJ_b + I_b j_b^Tj_b$ with the Jacobians from autodiff, and the velocity terms
are $\\sum_b m_b J_b^T \\dot J_b\\dot q$, so Coriolis and centripetal terms of the rotating planets
are all there.

**Deflections** are functions of $q$; each carries a restoring force and the generalised force is
$Q = -\\sum_k F_k\\,\\partial d_k/\\partial q$ (one reverse-mode pass). The mesh deflections follow
Lin & Parker (1999): with $\\tilde x$ the translations resolved in carrier axes and
$\\tilde\\zeta_n, \\tilde\\eta_n$ the planet's displacement from its nominal carrier-frame position,

$g_{sn} = -\\tilde x_s\\sin\\psi_{sn} + \\tilde y_s\\cos\\psi_{sn} - \\tilde\\zeta_n\\sin\\alpha_s
- \\tilde\\eta_n\\cos\\alpha_s + r_s\\theta_s + r_p\\theta_n - r_c\\cos\\alpha_s\\,\\theta_c$,
$\\psi_{sn} = \\psi_n - \\alpha_s$;

$g_{rn} = -\\tilde x_r\\sin\\psi_{rn} + \\tilde y_r\\cos\\psi_{rn} + \\tilde\\zeta_n\\sin\\alpha_r
- \\tilde\\eta_n\\cos\\alpha_r + r_r\\theta_r - r_p\\theta_n - r_c\\cos\\alpha_r\\,\\theta_c$,
$\\psi_{rn} = \\psi_n + \\alpha_r$ ($r$ are base radii).

The carrier-rotation terms $-r_c\\cos\\alpha\\,\\theta_c$ are Lin & Parker's $-\\eta\\cos\\alpha$ with
$\\eta \\ni u_c = r_c\\theta_c$; for gear data that assemble ($r_{bs} + r_{bp} = r_c\\cos\\alpha_s$,
$r_{br} - r_{bp} = r_c\\cos\\alpha_r$) they equal the relative rotations $r_s(\\theta_s-\\theta_c) +
r_p(\\theta_n-\\theta_c)$, and for any data the linearisation is exactly Lin & Parker's model.
Mesh phases are $z_s(\\theta_s - \\theta_c)$ and $z_r(\\theta_c - \\theta_r)$ plus per-planet offsets.
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _contact, _mesh, _smooth, _validate as V

SUPPORT_KINDS = ("rigid", "spring", "clearance")
MESH_KINDS = ("linear", "nonlinear")


def _as_float(x):
    return jnp.asarray(x, dtype=float)


class Support(eqx.Module):
    """How a component's centre is held in its bearing.

    - `kind`: `"rigid"` (no translation coordinates), `"spring"` (linear bearing, the
      Lin–Parker model) or `"clearance"` (radial clearance with a contact law). Static.
    - `stiffness`: bearing stiffness $k$ (N/m), used by `"spring"`.
    - `damping`: bearing damping (N s/m), used by `"spring"`.
    - `bearing`: the `JournalBearing` (journal radius, clearance, length, $E^*$), used by
      `"clearance"`; its fields may have shape `(n_planets,)` for the planet pins.
    """

    kind: str = eqx.field(static=True)
    stiffness: Float[Array, ""]
    damping: Float[Array, ""]
    bearing: _contact.JournalBearing | None

    def __init__(self, kind="rigid", stiffness=0.0, damping=0.0, bearing=None):
        self.kind = kind
        self.stiffness = V.real("Support", "stiffness", stiffness, "N/m")
        self.damping = V.real("Support", "damping", damping, "N s/m")
        self.bearing = bearing

    def __check_init__(self):
        if self.kind not in SUPPORT_KINDS:
            raise ValueError(f"Support kind {self.kind!r} is unknown; use one of {SUPPORT_KINDS}.")
        if self.kind == "clearance" and self.bearing is None:
            raise ValueError("A 'clearance' support needs a JournalBearing (`bearing=`).")
        if self.bearing is not None and not isinstance(self.bearing, _contact.JournalBearing):
            raise TypeError(f"Support.bearing must be a JournalBearing, got {type(self.bearing).__name__}.")
        V.check(self, stiffness=V.NONNEGATIVE("N/m"), damping=V.NONNEGATIVE("N s/m"))

    @property
    def translates(self) -> bool:
        return self.kind != "rigid"


class Mesh(eqx.Module):
    """One family of meshes (all sun–planet, or all ring–planet meshes) of a stage.

    - `kind`: `"linear"` (constant stiffness $k_m$, no backlash) or `"nonlinear"` (dead zone,
      time-varying stiffness, profile error). Static.
    - `dynamic_backlash`: recompute the backlash from the displaced centres. Static.
    - `stiffness`: mean mesh stiffness $k_m$ (N/m).
    - `contact_ratio`: $\\varepsilon_c$ (time-varying stiffness amplitude $\\varepsilon_c - 1$).
    - `damping_ratio`: $\\xi$.
    - `backlash`: $b_0$ per planet (m), shape `(n_planets,)`.
    - `profile_error`: amplitude $E_e$ (m); `profile_phase`: $\\varphi_e$ (rad).
    - `stiffness_phase`: offset of each planet's mesh phase (rad), shape `(n_planets,)`.
    """

    kind: str = eqx.field(static=True)
    dynamic_backlash: bool = eqx.field(static=True)
    stiffness: Float[Array, ""]
    contact_ratio: Float[Array, ""]
    damping_ratio: Float[Array, ""]
    backlash: Float[Array, " n_planets"]
    profile_error: Float[Array, ""]
    profile_phase: Float[Array, ""]
    stiffness_phase: Float[Array, " n_planets"]

    def __init__(
        self,
        kind="nonlinear",
        stiffness=1e8,
        contact_ratio=1.6,
        damping_ratio=0.06,
        backlash=100e-6,
        profile_error=0.0,
        profile_phase=0.0,
        stiffness_phase=0.0,
        dynamic_backlash=True,
        n_planets=3,
    ):
        V.positive_integer("Mesh.n_planets", n_planets)
        self.kind = kind
        self.dynamic_backlash = bool(dynamic_backlash)
        self.stiffness = V.real("Mesh", "stiffness", stiffness, "N/m")
        self.contact_ratio = V.real("Mesh", "contact_ratio", contact_ratio, "-")
        self.damping_ratio = V.real("Mesh", "damping_ratio", damping_ratio, "-")
        per_planet = (int(n_planets),)
        self.backlash = jnp.broadcast_to(V.real("Mesh", "backlash", backlash, "m", per_planet, True), per_planet)
        self.profile_error = V.real("Mesh", "profile_error", profile_error, "m")
        self.profile_phase = V.real("Mesh", "profile_phase", profile_phase, "rad")
        phase = V.real("Mesh", "stiffness_phase", stiffness_phase, "rad", per_planet, True)
        self.stiffness_phase = jnp.broadcast_to(phase, per_planet)

    def __check_init__(self):
        if self.kind not in MESH_KINDS:
            raise ValueError(f"Mesh kind {self.kind!r} is unknown; use one of {MESH_KINDS}.")
        V.check(
            self,
            stiffness=V.POSITIVE("N/m"),
            contact_ratio=V.CONTACT_RATIO,
            damping_ratio=V.NONNEGATIVE("-"),
            backlash=V.NONNEGATIVE("m"),
            profile_error=V.FINITE("m"),
            profile_phase=V.FINITE("rad"),
            stiffness_phase=V.FINITE("rad"),
        )


class PlanetaryStage(eqx.Module):
    """A 2K-H planetary stage: structure (static) and values (arrays). See the module docstring.

    Masses (kg), inertias (kg m²), base radii and carrier radius (m), pressure angles (rad),
    torsional support stiffnesses on $u = r\\theta$ (N/m; `None` = free rotation), supports and
    meshes as `Support` / `Mesh`. The ring is `"rigid"` (fixed to the housing) or `"spring"`.
    Numerical options: `smoothing_width` $\\varepsilon$ (m) of every dead zone, ramp and switch;
    `impact_rate_floor` (m/s) and `impact_memory_time` (s) of the contacts' impact-rate states.
    Build a stage from gear data with `default_stage`.
    """

    n_planets: int = eqx.field(static=True)
    sun_teeth: int = eqx.field(static=True)
    planet_teeth: int = eqx.field(static=True)
    ring_teeth: int = eqx.field(static=True)
    sun_mass: Float[Array, ""]
    carrier_mass: Float[Array, ""]
    planet_mass: Float[Array, ""]
    ring_mass: Float[Array, ""]
    sun_inertia: Float[Array, ""]
    carrier_inertia: Float[Array, ""]
    planet_inertia: Float[Array, ""]
    ring_inertia: Float[Array, ""]
    sun_base_radius: Float[Array, ""]
    planet_base_radius: Float[Array, ""]
    ring_base_radius: Float[Array, ""]
    carrier_radius: Float[Array, ""]
    sun_pressure_angle: Float[Array, ""]
    ring_pressure_angle: Float[Array, ""]
    planet_angles: Float[Array, " n_planets"]
    sun_support: Support
    carrier_support: Support
    planet_support: Support
    ring_support: Support
    sun_torsion: Float[Array, ""] | None
    carrier_torsion: Float[Array, ""] | None
    ring_torsion: Float[Array, ""] | None
    sun_mesh: Mesh
    ring_mesh: Mesh
    contact_law: _contact.AbstractContactLaw | None  # None only for a stage without clearances
    smoothing_width: Float[Array, ""]
    impact_rate_floor: Float[Array, ""]
    impact_memory_time: Float[Array, ""]

    def __check_init__(self):
        _check_stage(self)
        if self.ring_support.kind == "clearance":
            raise ValueError("The ring support must be 'rigid' or 'spring' (no ring clearance).")
        if self.contact_names and self.contact_law is None:
            raise ValueError("A stage with a 'clearance' support needs a `contact_law`.")
        if self.ring_support.kind == "spring" and self.ring_torsion is None:
            raise ValueError("A spring-mounted ring needs `ring_torsion` (N/m on u = r theta).")

    # ----------------------------------------------------------------------------------------
    # Coordinates

    @property
    def layout(self) -> "Layout":
        return Layout.of(self)

    @property
    def ratio(self) -> float:
        """Rigid transmission ratio sun/carrier with the ring fixed, $1 + z_r/z_s$."""
        return 1.0 + self.ring_teeth / self.sun_teeth

    @property
    def contact_names(self) -> tuple[str, ...]:
        """The clearance contacts this stage has, in the order of the impact-rate states."""
        names = []
        if self.sun_support.kind == "clearance":
            names.append("sun")
        if self.carrier_support.kind == "clearance":
            names.append("carrier")
        if self.planet_support.kind == "clearance":
            names += [f"planet{n}" for n in range(self.n_planets)]
        return tuple(names)


def _check_stage(stage: PlanetaryStage) -> None:
    """Types, ranges and geometry of a stage (concrete values; traced ones are skipped)."""
    for name in ("n_planets", "sun_teeth", "planet_teeth", "ring_teeth"):
        V.positive_integer(f"PlanetaryStage.{name}", getattr(stage, name))
    if stage.ring_teeth != stage.sun_teeth + 2 * stage.planet_teeth:
        raise ValueError(
            f"Tooth counts do not assemble coaxially: ring_teeth={stage.ring_teeth} must equal "
            f"sun_teeth + 2*planet_teeth = {stage.sun_teeth + 2 * stage.planet_teeth}."
        )
    for name, cls in (
        ("sun_support", Support), ("carrier_support", Support), ("planet_support", Support),
        ("ring_support", Support), ("sun_mesh", Mesh), ("ring_mesh", Mesh),
    ):
        if not isinstance(getattr(stage, name), cls):
            raise TypeError(f"PlanetaryStage.{name} must be a {cls.__name__}, got {type(getattr(stage, name)).__name__}.")
    law = stage.contact_law
    if law is not None and not isinstance(law, _contact.AbstractContactLaw):
        raise TypeError(f"PlanetaryStage.contact_law must be a contact law (e.g. BaiZhao), got {type(law).__name__}.")
    n = stage.n_planets
    for name in ("sun_mesh", "ring_mesh"):
        for field in ("backlash", "stiffness_phase"):
            shape = jnp.shape(getattr(getattr(stage, name), field))
            if shape != (n,):
                raise ValueError(f"PlanetaryStage.{name}.{field} must have shape ({n},) (one per planet), got {shape}.")
    if jnp.shape(stage.planet_angles) != (n,):
        raise ValueError(f"PlanetaryStage.planet_angles must have shape ({n},) (rad), got {jnp.shape(stage.planet_angles)}.")
    bearing = stage.planet_support.bearing
    if bearing is not None:
        for field in ("journal_radius", "clearance", "length", "modulus"):
            shape = jnp.shape(getattr(bearing, field))
            if shape not in ((), (n,)):
                raise ValueError(
                    f"The planet pins' JournalBearing.{field} must be a scalar or shape ({n},), got {shape}."
                )
    for name in ("sun", "carrier", "ring"):
        if getattr(stage, f"{name}_support").bearing is not None:
            shape = jnp.shape(getattr(stage, f"{name}_support").bearing.clearance)
            if shape != ():
                raise ValueError(f"The {name} bearing's clearance must be a scalar (m), got shape {shape}.")
    mass, inertia, length = V.POSITIVE("kg"), V.POSITIVE("kg m^2"), V.POSITIVE("m")
    angle = V.PRESSURE_ANGLE
    V.check(
        stage,
        sun_mass=mass, carrier_mass=mass, planet_mass=mass, ring_mass=mass,
        sun_inertia=inertia, carrier_inertia=inertia, planet_inertia=inertia, ring_inertia=inertia,
        sun_base_radius=length, planet_base_radius=length, ring_base_radius=length, carrier_radius=length,
        sun_pressure_angle=angle, ring_pressure_angle=angle,
        planet_angles=V.FINITE("rad"),
        sun_torsion=V.Rule("N/m", low=0.0, low_open=True, optional=True),
        carrier_torsion=V.Rule("N/m", low=0.0, low_open=True, optional=True),
        ring_torsion=V.Rule("N/m", low=0.0, low_open=True, optional=True),
        smoothing_width=V.NONNEGATIVE("m"),
        impact_rate_floor=V.POSITIVE("m/s"),
        impact_memory_time=V.POSITIVE("s"),
    )
    if V.concrete(stage.planet_base_radius, stage.sun_pressure_angle, stage.carrier_radius, stage.planet_angles):
        # Neighbouring planets must not overlap: centre distance 2 r_c sin(dpsi/2) > tip diameter,
        # tip radius r_p (1 + 2/z_p) (addendum one module, m = 2 r_p / z_p).
        r_p = float(stage.planet_base_radius) / math.cos(float(stage.sun_pressure_angle))
        tip = r_p * (1.0 + 2.0 / stage.planet_teeth)
        psi = np.sort(np.mod(np.asarray(stage.planet_angles, dtype=float), 2 * math.pi))
        gaps = np.diff(np.append(psi, psi[0] + 2 * math.pi)) if n > 1 else np.array([2 * math.pi])
        distance = 2.0 * float(stage.carrier_radius) * math.sin(min(float(gaps.min()), 2 * math.pi) / 2.0)
        if n > 1 and not distance > 2.0 * tip:
            raise ValueError(
                f"The {n} planets do not fit: neighbouring planet centres are {distance * 1e3:.3g} mm apart "
                f"on the {float(stage.carrier_radius) * 1e3:.3g} mm carrier radius, less than a planet's tip "
                f"diameter {2 * tip * 1e3:.3g} mm. Use fewer or smaller planets, or spread planet_angles."
            )


@dataclasses.dataclass(frozen=True)
class Layout:
    """Index map of the generalised coordinates of a stage (pure Python, static)."""

    size: int
    sun_theta: int
    carrier_theta: int
    planet_theta: slice
    ring_theta: int | None
    sun_xy: slice | None
    carrier_xy: slice | None
    ring_xy: slice | None
    planet_xy: slice | None
    names: tuple[str, ...]

    @staticmethod
    def of(stage: PlanetaryStage) -> "Layout":
        n = stage.n_planets
        names = ["theta_s", "theta_c"] + [f"theta_p{k}" for k in range(n)]
        ring_theta = None
        if stage.ring_support.kind == "spring":
            ring_theta = len(names)
            names.append("theta_r")

        def block(flag, labels):
            if not flag:
                return None
            start = len(names)
            names.extend(labels)
            return slice(start, len(names))

        sun_xy = block(stage.sun_support.translates, ["x_s", "y_s"])
        carrier_xy = block(stage.carrier_support.translates, ["x_c", "y_c"])
        ring_xy = block(stage.ring_support.translates, ["x_r", "y_r"])
        planet_xy = block(
            stage.planet_support.translates,
            [f"{a}_p{k}" for k in range(n) for a in ("zeta", "eta")],
        )
        return Layout(
            size=len(names),
            sun_theta=0,
            carrier_theta=1,
            planet_theta=slice(2, 2 + n),
            ring_theta=ring_theta,
            sun_xy=sun_xy,
            carrier_xy=carrier_xy,
            ring_xy=ring_xy,
            planet_xy=planet_xy,
            names=tuple(names),
        )


def _rot(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.array([[c, -s], [s, c]])


def _xy(q, sl):
    return jnp.zeros(2) if sl is None else q[sl]


def _planet_xy(stage, q, lay):
    if lay.planet_xy is None:
        return jnp.zeros((stage.n_planets, 2))
    return q[lay.planet_xy].reshape(stage.n_planets, 2)


def _ring_theta(q, lay):
    return 0.0 if lay.ring_theta is None else q[lay.ring_theta]


# --------------------------------------------------------------------------------------------
# Inertia


@dataclasses.dataclass(frozen=True)
class AddedInertia:
    """Inertia a scene attaches rigidly to the sun (motor rotor) and carrier (load), kg / kg m²."""

    sun_inertia: float | Array = 0.0
    carrier_inertia: float | Array = 0.0
    carrier_mass: float | Array = 0.0


def body_positions(stage: PlanetaryStage, q: Array):
    """Centres (m, housing frame) and angles (rad) of the moving bodies: sun, carrier, planets,
    then the ring if it is spring-mounted."""
    lay = stage.layout
    psi = stage.planet_angles
    e_r = jnp.stack([jnp.cos(psi), jnp.sin(psi)], axis=-1)
    e_t = jnp.stack([-jnp.sin(psi), jnp.cos(psi)], axis=-1)
    p_c = _xy(q, lay.carrier_xy)
    zeta_eta = _planet_xy(stage, q, lay)
    local = (stage.carrier_radius + zeta_eta[:, :1]) * e_r + zeta_eta[:, 1:] * e_t
    planets = p_c + local @ _rot(q[lay.carrier_theta]).T
    centres = [_xy(q, lay.sun_xy)[None], p_c[None], planets]
    angles = [q[:1], q[1:2], q[lay.planet_theta]]
    if lay.ring_theta is not None:
        centres.append(_xy(q, lay.ring_xy)[None])
        angles.append(q[lay.ring_theta][None])
    return jnp.concatenate(centres), jnp.concatenate(angles)


def _body_inertia(stage: PlanetaryStage, added: AddedInertia):
    n = stage.n_planets
    masses = [stage.sun_mass, stage.carrier_mass + added.carrier_mass] + [stage.planet_mass] * n
    inertias = [stage.sun_inertia + added.sun_inertia, stage.carrier_inertia + added.carrier_inertia]
    inertias += [stage.planet_inertia] * n
    if stage.ring_support.kind == "spring":
        masses.append(stage.ring_mass)
        inertias.append(stage.ring_inertia)
    return jnp.stack([_as_float(m) for m in masses]), jnp.stack([_as_float(i) for i in inertias])


def mass_matrix(stage: PlanetaryStage, q: Array, added: AddedInertia = AddedInertia()) -> Array:
    """$M(q) = \\sum_b m_b J_b^TJ_b + I_b j_b^Tj_b$ (SI, mixed kg / kg m² / kg m)."""
    masses, inertias = _body_inertia(stage, added)
    jac_p, jac_a = jax.jacfwd(lambda q_: body_positions(stage, q_))(q)
    return jnp.einsum("b,bin,bim->nm", masses, jac_p, jac_p) + jnp.einsum(
        "b,bn,bm->nm", inertias, jac_a, jac_a
    )


def velocity_forces(
    stage: PlanetaryStage, q: Array, qd: Array, added: AddedInertia = AddedInertia()
) -> Array:
    """$\\sum_b m_b J_b^T(\\dot J_b\\dot q)$: Coriolis and centripetal generalised forces."""
    masses, _ = _body_inertia(stage, added)

    def centres(q_):
        return body_positions(stage, q_)[0]

    def velocity(q_):
        return jax.jvp(centres, (q_,), (qd,))[1]

    accel = jax.jvp(velocity, (q,), (qd,))[1]
    _, pullback = jax.vjp(centres, q)
    return pullback(masses[:, None] * accel)[0]


# --------------------------------------------------------------------------------------------
# Deflections and forces


def mesh_phases(stage: PlanetaryStage, q: Array) -> tuple[Array, Array]:
    """Mesh phases (rad) of the sun and ring meshes, shape `(n_planets,)` each."""
    lay = stage.layout
    th_s, th_c, th_r = q[lay.sun_theta], q[lay.carrier_theta], _ring_theta(q, lay)
    sun = stage.sun_teeth * (th_s - th_c) + stage.sun_mesh.stiffness_phase
    ring = stage.ring_teeth * (th_c - th_r) + stage.ring_mesh.stiffness_phase
    return sun, ring


def deflections(stage: PlanetaryStage, q: Array) -> dict:
    """Every deflection that carries a force, as a function of the coordinates only (m).

    Keys: `sun_drive`/`ring_drive` ($g$, shape `(N,)`), `sun_back`/`ring_back` ($g + b_t$,
    nonlinear meshes), `sun_e`, `carrier_e`, `ring_e` (2,), `planet_e` (N, 2) for translating
    supports, and `sun_u`, `carrier_u`, `ring_u` for torsional springs.
    """
    lay = stage.layout
    psi = stage.planet_angles
    th_s, th_c, th_r = q[lay.sun_theta], q[lay.carrier_theta], _ring_theta(q, lay)
    th_p = q[lay.planet_theta]
    to_carrier = _rot(-th_c)
    x_s = to_carrier @ _xy(q, lay.sun_xy)
    x_r = to_carrier @ _xy(q, lay.ring_xy)
    x_c = to_carrier @ _xy(q, lay.carrier_xy)
    rel = _planet_xy(stage, q, lay)
    # Planet displacement from its nominal carrier-frame position, radial / tangential.
    zeta = rel[:, 0] + x_c[0] * jnp.cos(psi) + x_c[1] * jnp.sin(psi)
    eta = rel[:, 1] - x_c[0] * jnp.sin(psi) + x_c[1] * jnp.cos(psi)
    a_s, a_r = stage.sun_pressure_angle, stage.ring_pressure_angle
    rs, rp, rr, rc = (
        stage.sun_base_radius,
        stage.planet_base_radius,
        stage.ring_base_radius,
        stage.carrier_radius,
    )
    psi_s = psi - a_s
    psi_r = psi + a_r
    g_s = (
        -x_s[0] * jnp.sin(psi_s)
        + x_s[1] * jnp.cos(psi_s)
        - zeta * jnp.sin(a_s)
        - eta * jnp.cos(a_s)
        + rs * th_s
        + rp * th_p
        - rc * jnp.cos(a_s) * th_c
    )
    g_r = (
        -x_r[0] * jnp.sin(psi_r)
        + x_r[1] * jnp.cos(psi_r)
        + zeta * jnp.sin(a_r)
        - eta * jnp.cos(a_r)
        + rr * th_r
        - rp * th_p
        - rc * jnp.cos(a_r) * th_c
    )
    out = {"sun_drive": g_s, "ring_drive": g_r}
    phase_s, phase_r = mesh_phases(stage, q)
    for name, mesh, g, phase, other, internal, alpha in (
        ("sun", stage.sun_mesh, g_s, phase_s, x_s, False, a_s),
        ("ring", stage.ring_mesh, g_r, phase_r, x_r, True, a_r),
    ):
        if mesh.kind != "nonlinear":
            continue
        error = _mesh.profile_error(mesh.profile_error, phase, mesh.profile_phase)
        if mesh.dynamic_backlash:
            # Planet centre relative to the other gear's centre, in carrier axes.
            planet = jnp.stack(
                [
                    (rc + zeta) * jnp.cos(psi) - eta * jnp.sin(psi),
                    (rc + zeta) * jnp.sin(psi) + eta * jnp.cos(psi),
                ],
                axis=-1,
            )
            distance = _smooth.norm(planet - other, 0.0)
            backlash = _mesh.dynamic_backlash(distance, rc, alpha, mesh.backlash, internal, error)
        else:
            backlash = mesh.backlash + error
        out[f"{name}_back"] = g + backlash
    for name, support, sl in (
        ("sun", stage.sun_support, lay.sun_xy),
        ("carrier", stage.carrier_support, lay.carrier_xy),
        ("ring", stage.ring_support, lay.ring_xy),
    ):
        if support.translates:
            out[f"{name}_e"] = q[sl]
    if stage.planet_support.translates:
        out["planet_e"] = rel
    for name, k, value in (
        ("sun", stage.sun_torsion, rs * th_s),
        ("carrier", stage.carrier_torsion, rc * th_c),
        ("ring", stage.ring_torsion, rr * th_r),
    ):
        if k is not None and not (name == "ring" and lay.ring_theta is None):
            out[f"{name}_u"] = value
    return out


def _mesh_damping(stage: PlanetaryStage, mesh: Mesh, stiffness, ring: bool):
    if ring:
        inertia_j = stage.ring_inertia if stage.ring_support.kind == "spring" else jnp.inf
        radius_j = stage.ring_base_radius
    else:
        inertia_j, radius_j = stage.sun_inertia, stage.sun_base_radius
    m_eq = _mesh.equivalent_mass(stage.planet_inertia, stage.planet_base_radius, inertia_j, radius_j)
    return 2.0 * mesh.damping_ratio * jnp.sqrt(m_eq * stiffness)


def _contact_bearings(stage: PlanetaryStage):
    """(name, deflection key, bearing) for each clearance contact, in state order."""
    out = []
    if stage.sun_support.kind == "clearance":
        out.append(("sun", "sun_e", stage.sun_support.bearing, None))
    if stage.carrier_support.kind == "clearance":
        out.append(("carrier", "carrier_e", stage.carrier_support.bearing, None))
    if stage.planet_support.kind == "clearance":
        out.append(("planet", "planet_e", stage.planet_support.bearing, stage.n_planets))
    return out


def _contact_e(stage, defl, defl_dot):
    """Stacked journal displacements and rates of all clearance contacts, shape (n_contacts, 2)."""
    es, eds = [], []
    for _, key, _, count in _contact_bearings(stage):
        e, ed = defl[key], defl_dot[key]
        es.append(e if count is not None else e[None])
        eds.append(ed if count is not None else ed[None])
    if not es:
        return jnp.zeros((0, 2)), jnp.zeros((0, 2))
    return jnp.concatenate(es), jnp.concatenate(eds)


def _stacked_bearing(stage):
    """One JournalBearing whose fields have shape (n_contacts,)."""
    parts = []
    for _, _, bearing, count in _contact_bearings(stage):
        shape = (count,) if count is not None else (1,)
        parts.append(jax.tree.map(lambda x: jnp.broadcast_to(x, shape), bearing))
    if not parts:
        return None
    return jax.tree.map(lambda *xs: jnp.concatenate(xs), *parts)


class StageForces(eqx.Module):
    """Generalised forces and the physical forces behind them, at one instant.

    - `generalised`: $Q$ on the stage coordinates (N or N m).
    - `sun_mesh`, `ring_mesh`: tooth force along the line of action per planet (N), positive
      on the drive flank, negative on the back flank.
    - `contact`: normal force of each clearance contact (N), in `stage.contact_names` order.
    - `contact_state`: the contacts' kinematics (penetration, normal, rate).
    """

    generalised: Array
    sun_mesh: Array
    ring_mesh: Array
    contact: Array
    contact_state: _contact.ContactState | None


def stage_forces(stage: PlanetaryStage, q: Array, qd: Array, impact_rates: Array) -> StageForces:
    """Generalised forces of springs, meshes and contacts, $Q = -\\sum_k F_k\\,\\partial d_k/\\partial q$."""
    width = stage.smoothing_width
    defl, pullback = jax.vjp(lambda q_: deflections(stage, q_), q)
    defl_dot = jax.jvp(lambda q_: deflections(stage, q_), (q,), (qd,))[1]
    phase_s, phase_r = mesh_phases(stage, q)
    forces = {}
    tooth = {}
    for name, mesh, phase, ring in (
        ("sun", stage.sun_mesh, phase_s, False),
        ("ring", stage.ring_mesh, phase_r, True),
    ):
        g, gd = defl[f"{name}_drive"], defl_dot[f"{name}_drive"]
        if mesh.kind == "linear":
            k = mesh.stiffness
            f = k * g + _mesh_damping(stage, mesh, k, ring) * gd
            forces[f"{name}_drive"] = f
            tooth[name] = f
        else:
            k = _mesh.mesh_stiffness(mesh.stiffness, mesh.contact_ratio, phase)
            d = _mesh_damping(stage, mesh, k, ring)
            h, hd = defl[f"{name}_back"], defl_dot[f"{name}_back"]
            f_drive, f_back = _mesh.flank_forces(g, gd, h, hd, k, d, width)
            forces[f"{name}_drive"] = f_drive
            forces[f"{name}_back"] = f_back
            tooth[name] = f_drive + f_back
    for name, support in (
        ("sun", stage.sun_support),
        ("carrier", stage.carrier_support),
        ("ring", stage.ring_support),
        ("planet", stage.planet_support),
    ):
        if support.kind == "spring":
            key = f"{name}_e"
            forces[key] = support.stiffness * defl[key] + support.damping * defl_dot[key]
    for name, k in (
        ("sun", stage.sun_torsion),
        ("carrier", stage.carrier_torsion),
        ("ring", stage.ring_torsion),
    ):
        key = f"{name}_u"
        if key in defl:
            forces[key] = k * defl[key]
    contact = jnp.zeros(0)
    state = None
    bearing = _stacked_bearing(stage)
    if bearing is not None:
        e, ed = _contact_e(stage, defl, defl_dot)
        state = _contact.contact_kinematics(bearing, e, ed, width)
        contact = _contact.normal_force(
            stage.contact_law, bearing, state, impact_rates, width, stage.impact_rate_floor
        )
        vec = contact[:, None] * state.normal
        start = 0
        for _, key, _, count in _contact_bearings(stage):
            size = 1 if count is None else count
            part = vec[start : start + size]
            forces[key] = part[0] if count is None else part
            start += size
    cotangent = {k: forces.get(k, jnp.zeros_like(v)) for k, v in defl.items()}
    (q_force,) = pullback(cotangent)
    return StageForces(
        generalised=-q_force,
        sun_mesh=tooth["sun"],
        ring_mesh=tooth["ring"],
        contact=contact,
        contact_state=state,
    )


def impact_rate_rates(
    stage: PlanetaryStage, q: Array, qd: Array, qdd: Array, impact_rates: Array
) -> Array:
    """Time derivative of the contacts' impact-rate states (m/s²), see `_contact`."""
    bearing = _stacked_bearing(stage)
    if bearing is None:
        return jnp.zeros(0)

    def e_of(q_):
        d = deflections(stage, q_)
        return _contact_e(stage, d, d)[0]

    def e_dot_of(q_):
        return jax.jvp(e_of, (q_,), (qd,))[1]

    e, e_dot = jax.jvp(e_of, (q,), (qd,))
    # e'' = J q'' + (dJ/dt) q'
    e_ddot = jax.jvp(e_of, (q,), (qdd,))[1] + jax.jvp(e_dot_of, (q,), (qd,))[1]
    width = stage.smoothing_width
    state = _contact.contact_kinematics(bearing, e, e_dot, width)
    rate_dot = _contact.rate_derivative(bearing, e, e_dot, e_ddot, width)
    return _contact.impact_rate_derivative(
        state, rate_dot, impact_rates, width, stage.impact_memory_time
    )


def initial_impact_rates(stage: PlanetaryStage, q: Array, qd: Array) -> Array:
    """Consistent initial impact-rate states: the current penetration rates (m/s)."""
    bearing = _stacked_bearing(stage)
    if bearing is None:
        return jnp.zeros(0)
    defl, defl_dot = jax.jvp(lambda q_: deflections(stage, q_), (q,), (qd,))
    e, ed = _contact_e(stage, defl, defl_dot)
    return _contact.contact_kinematics(bearing, e, ed, stage.smoothing_width).rate


def potential_energy(stage: PlanetaryStage, q: Array) -> Array:
    """Elastic energy (J) of a conservative stage: linear meshes, springs, and contact laws with a
    closed-form potential. Raises for nonlinear meshes (no closed-form smoothed potential)."""
    if stage.sun_mesh.kind != "linear" or stage.ring_mesh.kind != "linear":
        raise ValueError("potential_energy needs linear meshes (the smoothed dead zone has none).")
    defl = deflections(stage, q)
    energy = 0.5 * stage.sun_mesh.stiffness * jnp.sum(defl["sun_drive"] ** 2)
    energy += 0.5 * stage.ring_mesh.stiffness * jnp.sum(defl["ring_drive"] ** 2)
    for name, support in (
        ("sun", stage.sun_support),
        ("carrier", stage.carrier_support),
        ("ring", stage.ring_support),
        ("planet", stage.planet_support),
    ):
        if support.kind == "spring":
            energy += 0.5 * support.stiffness * jnp.sum(defl[f"{name}_e"] ** 2)
    for name, k in (("sun", stage.sun_torsion), ("carrier", stage.carrier_torsion), ("ring", stage.ring_torsion)):
        if f"{name}_u" in defl:
            energy += 0.5 * k * defl[f"{name}_u"] ** 2
    bearing = _stacked_bearing(stage)
    if bearing is not None:
        e, _ = _contact_e(stage, defl, defl)
        state = _contact.contact_kinematics(bearing, e, e, stage.smoothing_width)
        energy += jnp.sum(stage.contact_law.potential(bearing, state.penetration))
    return energy


def kinetic_energy(stage, q, qd, added: AddedInertia = AddedInertia()) -> Array:
    """$\\tfrac12\\dot q^TM(q)\\dot q$ (J)."""
    return 0.5 * qd @ mass_matrix(stage, q, added) @ qd


# --------------------------------------------------------------------------------------------
# Linearisation


class Modes(eqx.Module):
    """Undamped natural frequencies (Hz, ascending) and mass-normalised mode shapes (columns),
    with the coordinate names of the rows."""

    frequencies: Array
    shapes: Array
    names: tuple[str, ...] = eqx.field(static=True)


def stiffness_matrix(stage: PlanetaryStage, q: Array) -> Array:
    """Tangent stiffness $K = -\\partial Q/\\partial q$ at rest ($\\dot q = 0$), N/m-type units."""
    n_contacts = len(stage.contact_names)
    rates = jnp.full((n_contacts,), 1.0)

    def force(q_):
        return stage_forces(stage, q_, jnp.zeros_like(q_), rates).generalised

    return -jax.jacfwd(force)(q)


def natural_frequencies(
    stage: PlanetaryStage, q: Array | None = None, added: AddedInertia = AddedInertia()
) -> Modes:
    """Linearise about the operating point `q` (default: nominal, all coordinates 0) and solve
    $K\\phi = \\omega^2 M\\phi$. Damping and gyroscopic terms are left out (undamped modes of the
    Lin–Parker model at zero carrier speed). A clearance support contributes its tangent contact
    stiffness at `q` (none if the clearance is open there: close it via `q` or use `"spring"`).
    """
    lay = stage.layout
    if q is None:
        q = jnp.zeros(lay.size)
    m = mass_matrix(stage, q, added)
    k = stiffness_matrix(stage, q)
    k = 0.5 * (k + k.T)
    l_inv = jnp.linalg.inv(jnp.linalg.cholesky(m))
    lam, vec = jnp.linalg.eigh(l_inv @ k @ l_inv.T)
    freqs = jnp.sqrt(jnp.clip(lam, 0.0, None)) / (2.0 * jnp.pi)
    return Modes(frequencies=freqs, shapes=l_inv.T @ vec, names=lay.names)


# --------------------------------------------------------------------------------------------
# Construction from gear data


STEEL = dict(young=206e9, poisson=0.3, density=7850.0)


_GEAR_RULES = dict(
    module=V.POSITIVE("m"),
    pressure_angle=V.PRESSURE_ANGLE,
    face_width=V.POSITIVE("m"),
    carrier_radius=V.Rule("m", low=0.0, low_open=True, optional=True),
    density=V.POSITIVE("kg/m^3"),
    young=V.POSITIVE("Pa"),
    poisson=V.Rule("-", low=-1.0, high=0.5, low_open=True, high_open=True),
    mesh_stiffness=V.POSITIVE("N/m"),
    contact_ratio=V.CONTACT_RATIO,
    mesh_damping_ratio=V.NONNEGATIVE("-"),
    backlash=V.NONNEGATIVE("m"),
    profile_error=V.FINITE("m"),
    sun_clearance=V.NONNEGATIVE("m"),
    carrier_clearance=V.NONNEGATIVE("m"),
    planet_clearance=V.NONNEGATIVE("m"),
    sun_journal_radius=V.POSITIVE("m"),
    carrier_journal_radius=V.POSITIVE("m"),
    planet_journal_radius=V.POSITIVE("m"),
    bearing_length=V.POSITIVE("m"),
    bearing_stiffness=V.NONNEGATIVE("N/m"),
    bearing_damping=V.NONNEGATIVE("N s/m"),
    restitution=V.RESTITUTION,
    smoothing_width=V.NONNEGATIVE("m"),
    impact_rate_floor=V.POSITIVE("m/s"),
    impact_memory_time=V.POSITIVE("s"),
)


def _check_gear_data(args: dict) -> None:
    """`default_stage`'s arguments, named as the caller wrote them."""
    for name in ("sun_teeth", "planet_teeth", "ring_teeth", "n_planets"):
        V.positive_integer(f"default_stage({name}=...)", args[name])
    if args["planet_spacing"] not in ("equal", "assembled"):
        raise ValueError(f"planet_spacing={args['planet_spacing']!r} is unknown; use 'equal' or 'assembled'.")
    for name in ("mesh", "sun_support", "carrier_support", "planet_support"):
        allowed = MESH_KINDS if name == "mesh" else SUPPORT_KINDS
        if args[name] not in allowed:
            raise ValueError(f"default_stage({name}={args[name]!r}) is unknown; use one of {allowed}.")
    holder = type("default_stage", (), {})()
    for name, rule in _GEAR_RULES.items():
        value = args[name]
        if value is not None:
            value = V.real("default_stage", name, value, rule.unit, shape=None)
        setattr(holder, name, value)
    V.check(holder, **_GEAR_RULES)
    for part in ("sun", "carrier", "planet"):
        c, r = np.asarray(args[f"{part}_clearance"]), np.asarray(args[f"{part}_journal_radius"])
        if not np.all(c < r):
            raise ValueError(
                f"default_stage({part}_clearance={args[part + '_clearance']!r}) must be smaller than "
                f"{part}_journal_radius={args[part + '_journal_radius']!r} (m): clearances are µm, journals mm."
            )


def default_stage(
    *,
    module: float = 1e-3,
    sun_teeth: int = 20,
    planet_teeth: int = 30,
    ring_teeth: int = 80,
    n_planets: int = 3,
    pressure_angle: float = math.radians(20.0),
    face_width: float = 10e-3,
    carrier_radius: float | None = None,
    density: float = STEEL["density"],
    young: float = STEEL["young"],
    poisson: float = STEEL["poisson"],
    mesh_stiffness: float = 1e8,
    contact_ratio: float = 1.6,
    mesh_damping_ratio: float = 0.06,
    backlash: float = 100e-6,
    profile_error: float = 0.0,
    mesh: str = "nonlinear",
    dynamic_backlash: bool = True,
    sun_support: str = "clearance",
    carrier_support: str = "clearance",
    planet_support: str = "clearance",
    sun_clearance: float = 100e-6,
    carrier_clearance: float = 100e-6,
    planet_clearance: float = 100e-6,
    sun_journal_radius: float = 5e-3,
    carrier_journal_radius: float = 15e-3,
    planet_journal_radius: float = 4e-3,
    bearing_length: float = 8e-3,
    bearing_stiffness: float = 1e8,
    bearing_damping: float = 0.0,
    restitution: float = 0.9,
    contact_law: _contact.AbstractContactLaw | None = None,
    smoothing_width: float = 1e-9,
    impact_rate_floor: float = 1e-3,
    impact_memory_time: float = 1e-4,
    planet_spacing: str = "equal",
) -> PlanetaryStage:
    """The default joint of MODEL.md §4 (all values overridable; SI units).

    Module 1 mm, $z_s, z_p, z_r$ = 20, 30, 80 (ratio 5), $\\alpha_0$ = 20°, face width 10 mm,
    steel; solid-disc masses and inertias of the pitch circles; carrier a solid disc of radius
    $r_c$ = 25 mm (the centre distance); ring fixed. $k_m = 10^8$ N/m, $\\varepsilon_c$ = 1.6,
    $\\xi$ = 0.06, $c_e$ = 0.9 (Bai–Zhao law). Journals: sun 5 mm, carrier output 15 mm, planet pins
    4 mm radius, 8 mm long. Clearances and backlash 100 µm (the paper's cases). Support kinds
    `"rigid"`, `"spring"` (stiffness `bearing_stiffness`) or `"clearance"`.

    `impact_memory_time` $\\tau$ = 0.1 ms: after a contact separates, the offset between the
    impact-rate state and $\\dot\\delta$ decays as $e^{-t/\\tau}$ (1 % after 0.46 ms), which is short
    against a flight across a 10–100 µm clearance at the mm/s speeds of these joints. Its
    eigenvalue $-1/\\tau$ bounds an explicit solver's step (3.5e-4 s for Tsit5); 10 µs made it the
    step limit of the lumped joint (9x more steps, measured). The restitution tests pass with both.

    `planet_spacing`: `"equal"` puts the planets at $\\psi_n = 2\\pi n/N$ (MODEL.md and the paper),
    whatever the tooth counts; `"assembled"` also requires that real gears can be assembled that
    way, $(z_s + z_r)/N$ an integer, and raises otherwise. The paper's 20/30/80 with three planets
    is *not* assemblable equally spaced ((20 + 80)/3 is not an integer): the default keeps the
    paper's idealisation, in which each planet's mesh phases are $z_s\\psi_n$ and $-z_r\\psi_n$.

    Every argument is checked before anything is built (`ValueError`/`TypeError` naming it).
    """
    _check_gear_data(locals())
    if planet_spacing == "assembled" and (sun_teeth + ring_teeth) % n_planets:
        raise ValueError(
            f"{n_planets} planets cannot be equally spaced with sun_teeth={sun_teeth}, "
            f"ring_teeth={ring_teeth}: (sun_teeth + ring_teeth) / n_planets = "
            f"{(sun_teeth + ring_teeth) / n_planets:.4g} must be an integer. Change the tooth counts "
            f"or use planet_spacing='equal' (the idealisation of MODEL.md)."
        )
    r_s, r_p, r_r = (module * z / 2 for z in (sun_teeth, planet_teeth, ring_teeth))
    if carrier_radius is None:
        carrier_radius = r_s + r_p
    cos_a = math.cos(pressure_angle)

    def disc(r):
        m = density * math.pi * r**2 * face_width
        return m, 0.5 * m * r**2

    m_s, i_s = disc(r_s)
    m_p, i_p = disc(r_p)
    m_c, i_c = disc(carrier_radius)
    r_out = r_r + 3 * module
    m_r = density * math.pi * (r_out**2 - r_r**2) * face_width
    i_r = 0.5 * m_r * (r_out**2 + r_r**2)
    e_star = _contact.composite_modulus(young, poisson, young, poisson)

    def support(kind, clearance, journal):
        bearing = _contact.JournalBearing(journal, clearance, bearing_length, e_star)
        return Support(kind, bearing_stiffness, bearing_damping, bearing if kind == "clearance" else None)

    def family():
        return Mesh(
            kind=mesh,
            stiffness=mesh_stiffness,
            contact_ratio=contact_ratio,
            damping_ratio=mesh_damping_ratio,
            backlash=backlash,
            profile_error=profile_error,
            dynamic_backlash=dynamic_backlash,
            n_planets=n_planets,
        )

    psi = 2 * np.pi * np.arange(n_planets) / n_planets
    sun_mesh = family()
    ring_mesh = family()
    # Each planet meets the sun and ring teeth at its own phase: z * psi_n.
    sun_mesh = eqx.tree_at(lambda m: m.stiffness_phase, sun_mesh, _as_float(sun_teeth * psi))
    ring_mesh = eqx.tree_at(lambda m: m.stiffness_phase, ring_mesh, _as_float(-ring_teeth * psi))
    return PlanetaryStage(
        n_planets=n_planets,
        sun_teeth=sun_teeth,
        planet_teeth=planet_teeth,
        ring_teeth=ring_teeth,
        sun_mass=_as_float(m_s),
        carrier_mass=_as_float(m_c),
        planet_mass=_as_float(m_p),
        ring_mass=_as_float(m_r),
        sun_inertia=_as_float(i_s),
        carrier_inertia=_as_float(i_c),
        planet_inertia=_as_float(i_p),
        ring_inertia=_as_float(i_r),
        sun_base_radius=_as_float(r_s * cos_a),
        planet_base_radius=_as_float(r_p * cos_a),
        ring_base_radius=_as_float(r_r * cos_a),
        carrier_radius=_as_float(carrier_radius),
        sun_pressure_angle=_as_float(pressure_angle),
        ring_pressure_angle=_as_float(pressure_angle),
        planet_angles=_as_float(psi),
        sun_support=support(sun_support, sun_clearance, sun_journal_radius),
        carrier_support=support(carrier_support, carrier_clearance, carrier_journal_radius),
        planet_support=support(planet_support, planet_clearance, planet_journal_radius),
        ring_support=Support("rigid"),
        sun_torsion=None,
        carrier_torsion=None,
        ring_torsion=None,
        sun_mesh=sun_mesh,
        ring_mesh=ring_mesh,
        contact_law=_contact.BaiZhao(restitution) if contact_law is None else contact_law,
        smoothing_width=_as_float(smoothing_width),
        impact_rate_floor=_as_float(impact_rate_floor),
        impact_memory_time=_as_float(impact_memory_time),
    )
