"""The physics of the 2K-H planetary stage (one joint), docs/model.md §4: kinematics, inertia,
deflections and forces. The stage data are in `tolerax.physics.stage`, its linearisation in `tolerax.physics.modes`.

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

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree
from jaxtyping import Array
from . import contact as _contact
from . import mesh as _mesh
from . import smooth as _smooth
from .rigid import rot2, small_matmul
from .stage import Mesh, PlanetaryStage, as_float

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
    planets = p_c + small_matmul(local, rot2(q[lay.carrier_theta]).T)
    centres = [_xy(q, lay.sun_xy)[None], p_c[None], planets]
    angles = [q[:1], q[1:2], q[lay.planet_theta]]
    if lay.ring_theta is not None:
        centres.append(_xy(q, lay.ring_xy)[None])
        angles.append(q[lay.ring_theta][None])
    return jnp.concatenate(centres), jnp.concatenate(angles)


def body_inertia(stage: PlanetaryStage, added: AddedInertia):
    n = stage.n_planets
    masses = [stage.sun_mass, stage.carrier_mass + added.carrier_mass] + [stage.planet_mass] * n
    inertias = [stage.sun_inertia + added.sun_inertia, stage.carrier_inertia + added.carrier_inertia]
    inertias += [stage.planet_inertia] * n
    if stage.ring_support.kind == "spring":
        masses.append(stage.ring_mass)
        inertias.append(stage.ring_inertia)
    return jnp.stack([as_float(m) for m in masses]), jnp.stack([as_float(i) for i in inertias])


def mass_matrix(stage: PlanetaryStage, q: Array, added: AddedInertia = AddedInertia()) -> Array:
    """$M(q) = \\sum_b m_b J_b^TJ_b + I_b j_b^Tj_b$ (SI, mixed kg / kg m² / kg m)."""
    masses, inertias = body_inertia(stage, added)
    jac_p, jac_a = jax.jacfwd(lambda q_: body_positions(stage, q_))(q)
    return jnp.einsum("b,bin,bim->nm", masses, jac_p, jac_p) + jnp.einsum(
        "b,bn,bm->nm", inertias, jac_a, jac_a
    )


def velocity_forces(
    stage: PlanetaryStage, q: Array, qd: Array, added: AddedInertia = AddedInertia()
) -> Array:
    """$\\sum_b m_b J_b^T(\\dot J_b\\dot q)$: Coriolis and centripetal generalised forces."""
    masses, _ = body_inertia(stage, added)

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
    return deflections_and_jacobian(stage, q)[0]


def deflections_and_jacobian(stage: PlanetaryStage, q: Array) -> tuple[dict, dict]:
    """The deflections (`deflections`, m) and their Jacobian $\\partial d/\\partial q$ in closed form:
    each key's array with a last axis of the stage's coordinates (m/m or m/rad).

    The deflections are linear in the coordinates resolved in carrier axes, so the Jacobian is
    that linear map times the rotation into carrier axes and its derivative (on $\\theta_c$'s
    column); the only other nonlinear pieces are elementwise, each differentiated where it is
    evaluated (`jax.jvp` along its one argument): the profile error in the mesh phase, the
    centre distance's norm and the dynamic backlash in it. Equal to the forward-mode Jacobian
    to rounding (`tests/test_planetary.py`) and cheaper: forward mode carries every coordinate's
    tangent through every elementwise function, whose derivatives XLA:CPU then recomputes for
    each of them.
    """
    lay = stage.layout
    n_q, n = q.shape[-1], stage.n_planets
    eye = np.eye(n_q)

    def rows(sl, shape):  # the Jacobian of q[sl] (reshaped), zero for a coordinate block that does not exist
        return np.zeros((*shape, n_q)) if sl is None else eye[sl].reshape(*shape, n_q)

    psi = stage.planet_angles
    th_s, th_c, th_r = q[lay.sun_theta], q[lay.carrier_theta], _ring_theta(q, lay)
    th_p = q[lay.planet_theta]
    d_s, d_c, d_p = eye[lay.sun_theta], eye[lay.carrier_theta], eye[lay.planet_theta]
    d_r = np.zeros(n_q) if lay.ring_theta is None else eye[lay.ring_theta]
    to_carrier, turn = jax.jvp(lambda a: rot2(-a), (th_c,), (jnp.ones_like(th_c),))

    def in_carrier(sl):  # a housing-frame translation in carrier axes, and its Jacobian (2, n_q)
        x = _xy(q, sl)
        return small_matmul(to_carrier, x), small_matmul(to_carrier, rows(sl, (2,))) + small_matmul(turn, x)[:, None] * d_c

    (x_s, j_s), (x_r, j_r), (x_c, j_c) = (in_carrier(sl) for sl in (lay.sun_xy, lay.ring_xy, lay.carrier_xy))
    rel, j_rel = _planet_xy(stage, q, lay), rows(lay.planet_xy, (n, 2))
    cos_psi, sin_psi = jnp.cos(psi)[:, None], jnp.sin(psi)[:, None]
    # Planet displacement from its nominal carrier-frame position, radial / tangential.
    zeta = rel[:, 0] + x_c[0] * cos_psi[:, 0] + x_c[1] * sin_psi[:, 0]
    eta = rel[:, 1] - x_c[0] * sin_psi[:, 0] + x_c[1] * cos_psi[:, 0]
    j_zeta = j_rel[:, 0] + cos_psi * j_c[0] + sin_psi * j_c[1]
    j_eta = j_rel[:, 1] - sin_psi * j_c[0] + cos_psi * j_c[1]
    a_s, a_r = stage.sun_pressure_angle, stage.ring_pressure_angle
    rs, rp, rr, rc = (
        stage.sun_base_radius,
        stage.planet_base_radius,
        stage.ring_base_radius,
        stage.carrier_radius,
    )

    def line_of_action(x, j_x, psi_m, side, alpha, r_gear, th_gear, d_gear, planet_sign):
        """$-\\tilde x\\sin\\psi_m + \\tilde y\\cos\\psi_m \\mp \\zeta\\sin\\alpha - \\eta\\cos\\alpha
        + r\\theta \\pm r_p\\theta_n - r_c\\cos\\alpha\\,\\theta_c$ and its Jacobian."""
        sin_m, cos_m = jnp.sin(psi_m)[:, None], jnp.cos(psi_m)[:, None]
        g = (
            -x[0] * sin_m[:, 0]
            + x[1] * cos_m[:, 0]
            + side * zeta * jnp.sin(alpha)
            - eta * jnp.cos(alpha)
            + r_gear * th_gear
            + planet_sign * rp * th_p
            - rc * jnp.cos(alpha) * th_c
        )
        j = (
            -sin_m * j_x[0]
            + cos_m * j_x[1]
            + side * jnp.sin(alpha) * j_zeta
            - jnp.cos(alpha) * j_eta
            + r_gear * d_gear
            + planet_sign * rp * d_p
            - rc * jnp.cos(alpha) * d_c
        )
        return g, j

    g_s, j_gs = line_of_action(x_s, j_s, psi - a_s, -1.0, a_s, rs, th_s, d_s, 1.0)
    g_r, j_gr = line_of_action(x_r, j_r, psi + a_r, 1.0, a_r, rr, th_r, d_r, -1.0)
    out = {"sun_drive": g_s, "ring_drive": g_r}
    jac = {"sun_drive": j_gs, "ring_drive": j_gr}
    phase_s, phase_r = mesh_phases(stage, q)
    d_phase = {"sun": stage.sun_teeth * (d_s - d_c), "ring": stage.ring_teeth * (d_c - d_r)}
    for name, mesh, g, j_g, phase, other, j_other, internal, alpha in (
        ("sun", stage.sun_mesh, g_s, j_gs, phase_s, x_s, j_s, False, a_s),
        ("ring", stage.ring_mesh, g_r, j_gr, phase_r, x_r, j_r, True, a_r),
    ):
        if mesh.kind != "nonlinear":
            continue
        error, d_error = jax.jvp(
            lambda ph, m=mesh: _mesh.profile_error(m.profile_error, ph, m.profile_phase), (phase,), (jnp.ones_like(phase),)
        )
        j_back = j_g + d_error[:, None] * d_phase[name]
        if mesh.dynamic_backlash:
            # Planet centre relative to the other gear's centre, in carrier axes.
            planet = jnp.stack([(rc + zeta) * cos_psi[:, 0] - eta * sin_psi[:, 0], (rc + zeta) * sin_psi[:, 0] + eta * cos_psi[:, 0]], axis=-1)
            j_planet = jnp.stack([cos_psi * j_zeta - sin_psi * j_eta, sin_psi * j_zeta + cos_psi * j_eta], axis=1)
            offset = planet - other
            distance = _smooth.norm(offset, 0.0)
            # d|v| = (v/|v|) . dv; 0 at v = 0, as `_smooth.norm`'s own derivative there.
            unit = jnp.where(distance[:, None] > 0, offset / jnp.where(distance > 0, distance, 1.0)[:, None], 0.0)
            j_distance = jnp.sum(unit[:, :, None] * (j_planet - j_other[None]), axis=1)
            backlash, d_backlash = jax.jvp(
                lambda a, m=mesh, i=internal, al=alpha, e=error: _mesh.dynamic_backlash(a, rc, al, m.backlash, i, e),
                (distance,),
                (jnp.ones_like(distance),),
            )
            j_back = j_back + d_backlash[:, None] * j_distance
        else:
            backlash = mesh.backlash + error
        out[f"{name}_back"] = g + backlash
        jac[f"{name}_back"] = j_back
    for name, support in stage.supports():
        if support.translates:
            sl = getattr(lay, f"{name}_xy")
            out[f"{name}_e"] = rel if name == "planet" else q[sl]
            jac[f"{name}_e"] = j_rel if name == "planet" else eye[sl]
    rotation = {"sun": (rs * th_s, rs * d_s), "carrier": (rc * th_c, rc * d_c), "ring": (rr * th_r, rr * d_r)}
    for name, k in stage.torsions():
        if k is not None and not (name == "ring" and lay.ring_theta is None):
            out[f"{name}_u"], jac[f"{name}_u"] = rotation[name]
    return out, jac


def _mesh_damping(stage: PlanetaryStage, mesh: Mesh, stiffness, ring: bool):
    if ring:
        inertia_j = stage.ring_inertia if stage.ring_support.kind == "spring" else jnp.inf
        radius_j = stage.ring_base_radius
    else:
        inertia_j, radius_j = stage.sun_inertia, stage.sun_base_radius
    m_eq = _mesh.equivalent_mass(stage.planet_inertia, stage.planet_base_radius, inertia_j, radius_j)
    return 2.0 * mesh.damping_ratio * jnp.sqrt(m_eq * stiffness)


def _contact_bearings(stage: PlanetaryStage):
    """(name, deflection key, bearing, count) for each clearance contact, in state order (count:
    the number of planets for the pins, None for a single bearing)."""
    return [
        (name, f"{name}_e", support.bearing, stage.n_planets if name == "planet" else None)
        for name, support in stage.supports()
        if support.kind == "clearance"
    ]


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


def stage_forces(
    stage: PlanetaryStage, q: Array, qd: Array, impact_rates: Array, *, projection: str = "closed-form"
) -> StageForces:
    """Generalised forces of springs, meshes and contacts, $Q = -\\sum_k F_k\\,\\partial d_k/\\partial q$.

    `projection="closed-form"`: the deflections' Jacobian $D$ (n_deflections x n_q) in closed
    form (`deflections_and_jacobian`), the rates $D\\dot q$ and the forces $-D^TF$ one product
    each, $F$ as a row ($F^TD$): XLA:CPU fuses the producer of a matrix-vector product's operands
    into the product's loop, and with the vector on the right it evaluated the force laws once
    per coordinate. `"forward"`: the same with $D$ by forward-mode autodiff over the stage's
    coordinates (dearer: every coordinate's tangent goes through the elementwise force laws).
    `"jvp-vjp"`: a `jvp` for the rates and a `vjp` for the projection. Same values to rounding; the other two
    are kept for the equivalence test and the benchmarks."""
    width = stage.smoothing_width
    if projection == "closed-form":
        defl, parts = deflections_and_jacobian(stage, q)
        jac = jnp.concatenate([jnp.reshape(parts[k], (-1, q.shape[-1])) for k in sorted(parts)])  # ravel_pytree's order
        defl_dot = ravel_pytree(defl)[1]((jac @ qd[:, None])[:, 0])
        project = lambda cotangent: (ravel_pytree(cotangent)[0][None, :] @ jac)[0]  # noqa: E731
    elif projection == "forward":
        def flat(q_):
            d = deflections(stage, q_)
            return ravel_pytree(d)[0], d

        jac, defl = jax.jacfwd(flat, has_aux=True)(q)  # the deflections come with their Jacobian
        defl_dot = ravel_pytree(defl)[1](jac @ qd)
        project = lambda cotangent: jac.T @ ravel_pytree(cotangent)[0]  # noqa: E731
    elif projection == "jvp-vjp":
        defl, pullback = jax.vjp(lambda q_: deflections(stage, q_), q)
        defl_dot = jax.jvp(lambda q_: deflections(stage, q_), (q,), (qd,))[1]
        project = lambda cotangent: pullback(cotangent)[0]  # noqa: E731
    else:
        raise ValueError(f"projection={projection!r} is unknown; use 'closed-form', 'forward' or 'jvp-vjp'.")
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
    for name, support in stage.supports():
        if support.kind == "spring":
            key = f"{name}_e"
            forces[key] = support.stiffness * defl[key] + support.damping * defl_dot[key]
    for name, k in stage.torsions():
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
    q_force = project(cotangent)
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
    """Time derivative of the contacts' impact-rate states (m/s²), see `tolerax.physics.contact`."""
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
    for name, support in stage.supports():
        if support.kind == "spring":
            energy += 0.5 * support.stiffness * jnp.sum(defl[f"{name}_e"] ** 2)
    for name, k in stage.torsions():
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
