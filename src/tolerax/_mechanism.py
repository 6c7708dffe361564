"""The dual-axis antenna pointing mechanism (docs/MODEL.md §5): spacecraft body → azimuth joint →
link 1 → pitch joint → link 2 → reflector, with a fidelity choice per joint.

**Formulation.** Minimal coordinates and Kane's equations. Every rigid body's pose (centre
$p_b$, rotation $R_b$, world frame) is a function of the generalised coordinates $q$ and time
(prescribed ideal joints). With generalised speeds $u$ ($\\dot q = N(q)u$: the identity except
for the base quaternion), body twists are $v_b = J_b u + \\partial_t p_b$ and
$\\omega_b = J^\\omega_b u + \\ldots$, with the Jacobians from forward-mode autodiff of the
kinematics. Then
$$M(q)\\dot u = Q - \\sum_b J_b^T m_b a_b^0 - \\sum_b J_b^{\\omega T}(I_b\\alpha^0_b + \\omega_b\\times I_b\\omega_b),$$
$M = \\sum_b m_bJ_b^TJ_b + J^{\\omega T}_bI_bJ^\\omega_b$, and $a^0_b, \\alpha^0_b$ the
accelerations at $\\dot u = 0$ (one more jvp). Nothing is linearised: the gears spin inside a
housing that turns (gyroscopic terms included), and the base reacts. Internal forces (meshes,
contacts, servo and drive torques, drag) act on *relative* coordinates, so with a free base and
no external load linear and angular momentum are conserved exactly by the equations (a test).

**Bodies.** The base (the spacecraft, 1500 kg); per joint the sun (plus the motor rotor), the
carrier and the planets as thin discs (transverse inertia half the polar one); link 1, link 2 and
the reflector with the paper's Table 1 data. The ring and the gear housing are part of the body
that carries the joint (base or link 1).

**Default geometry** (all offsets are parameters of `Geometry`; base frame B at the spacecraft's
centre of mass, zero joint angles)::

                        z_B (azimuth axis)
                         ^
                         |   pitch joint P at 0.6 m up link 1; pitch axis = x_B (at zero azimuth)
           reflector  R  +--[P]=====  link 2: a 0.6 m shaft along the pitch axis, centred on P
   boresight y_B <---o---|
       (0.25 m in front  |  link 1: 0.6 m boom along z, centre 0.3 m above A
        of the pitch     |
        axis)           [A]  azimuth joint, 1.5 m above the base centre (top face)
                  +------+------+
                  |  spacecraft |  1500 kg, (2100, 1700, 2400) kg m²
                  +-------------+

Azimuth axis: $z_B$. Pitch axis: the $x$ axis of link 1 (perpendicular to and intersecting the
azimuth axis). Boresight: the reflector's $y$ axis (its largest inertia), horizontal along $y_B$
at zero angles; pitch tilts it in elevation, azimuth turns it about $z_B$. Table 1's "azimuth
joint" and "pitch joint" bodies (3.77 kg, small inertia about their own $z$) are the joints'
rotating output members: link 1 with its $z$ along the azimuth axis, link 2 with its $z$ along
the pitch axis. These inertias fit 0.6 m rods ($\\sqrt{12\\cdot0.11545/3.77}$ = 0.61 m).

**Joint fidelity** per joint is its class (`IdealJoint`, `LumpedJoint`, `PlanetaryJoint`, see
`_joint`); the mechanism asks each joint for its coordinates, bodies, forces and contacts.
"""

import dataclasses
from collections.abc import Iterator

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import _outputs, _validate as V
from ._joint import AbstractJoint, PlanetaryJoint
from ._rigid import PITCH_HOUSING, planar_to_world, quat_matrix, quat_rate, rz, vee, world_inertia
from ._scene import AbstractScene


def _set_checked(module, values: dict, shape_of, unit_of):
    """Set real numbers of the expected shape as float arrays (ranges: `__check_init__`)."""
    owner = type(module).__name__
    for name, value in values.items():
        setattr(module, name, V.real(owner, name, value, unit_of(name), shape_of(name)))


class Geometry(eqx.Module):
    """Offsets of the chain (m); see the drawing in the module docstring.

    - `azimuth_position`: azimuth joint centre in the base frame.
    - `link1_centre`: link 1's centre of mass in the azimuth output frame.
    - `pitch_position`: pitch joint centre in the azimuth output frame.
    - `link2_centre`: link 2's centre of mass in the pitch output frame.
    - `reflector_centre`: reflector's centre of mass in the pitch output frame (along the
      boresight $y$).
    """

    azimuth_position: Float[Array, "3"]
    link1_centre: Float[Array, "3"]
    pitch_position: Float[Array, "3"]
    link2_centre: Float[Array, "3"]
    reflector_centre: Float[Array, "3"]

    def __init__(
        self,
        azimuth_position=(0.0, 0.0, 1.5),
        link1_centre=(0.0, 0.0, 0.3),
        pitch_position=(0.0, 0.0, 0.6),
        link2_centre=(0.0, 0.0, 0.0),
        reflector_centre=(0.0, 0.25, 0.0),
    ):
        values = dict(
            azimuth_position=azimuth_position,
            link1_centre=link1_centre,
            pitch_position=pitch_position,
            link2_centre=link2_centre,
            reflector_centre=reflector_centre,
        )
        _set_checked(self, values, lambda name: (3,), lambda name: "m")

    def __check_init__(self):
        V.check(self, **{f.name: V.FINITE("m") for f in dataclasses.fields(self)})


class Inertias(eqx.Module):
    """Masses (kg) and principal inertias (kg m², about each body's own axes) of the paper's
    Table 1. Link 1 = the paper's "azimuth joint", link 2 = its "pitch joint"."""

    base_mass: Float[Array, ""]
    base_inertia: Float[Array, "3"]
    link1_mass: Float[Array, ""]
    link1_inertia: Float[Array, "3"]
    link2_mass: Float[Array, ""]
    link2_inertia: Float[Array, "3"]
    reflector_mass: Float[Array, ""]
    reflector_inertia: Float[Array, "3"]

    def __init__(
        self,
        base_mass=1500.0,
        base_inertia=(2100.0, 1700.0, 2400.0),
        link1_mass=3.77,
        link1_inertia=(0.11545, 0.11545, 0.004712),
        link2_mass=3.77,
        link2_inertia=(0.11545, 0.11545, 0.004712),
        reflector_mass=8.005,
        reflector_inertia=(0.68297, 1.05956, 0.68297),
    ):
        values = dict(
            base_mass=base_mass,
            base_inertia=base_inertia,
            link1_mass=link1_mass,
            link1_inertia=link1_inertia,
            link2_mass=link2_mass,
            link2_inertia=link2_inertia,
            reflector_mass=reflector_mass,
            reflector_inertia=reflector_inertia,
        )
        is_mass = lambda name: name.endswith("mass")  # noqa: E731
        _set_checked(self, values, lambda n: () if is_mass(n) else (3,), lambda n: "kg" if is_mass(n) else "kg m^2")

    def __check_init__(self):
        V.check(self, **{f.name: V.POSITIVE("kg" if f.name.endswith("mass") else "kg m^2") for f in dataclasses.fields(self)})


@dataclasses.dataclass(frozen=True)
class MechanismLayout:
    """Index map of the mechanism's coordinates `q` and speeds `u` (static)."""

    base_q: int  # 7 (position, unit quaternion) for a free base, else 0
    base_u: int  # 6 (velocity in the world frame, angular velocity in the base frame) or 0
    azimuth_q: slice
    pitch_q: slice
    azimuth_u: slice
    pitch_u: slice
    azimuth_v: slice  # impact-rate states
    pitch_v: slice
    size_q: int
    size_u: int
    size_v: int


BASES = ("free", "fixed")


class Mechanism(AbstractScene):
    """The antenna pointing mechanism: two joints (any `AbstractJoint`: the fidelity is the
    joint's class), geometry, inertias and the base (static: `"free"` floating, 6 DOF, the
    on-orbit case; or `"fixed"`, a ground test stand). Build the paper's scenes with `antenna`."""

    azimuth: AbstractJoint
    pitch: AbstractJoint
    geometry: Geometry
    inertias: Inertias
    base: str = eqx.field(static=True)
    _what = "mechanism"

    def __init__(self, azimuth=None, pitch=None, geometry=None, inertias=None, base="free"):
        if base not in BASES:
            raise ValueError(f"base={base!r} is unknown; use 'free' (floating spacecraft) or 'fixed'.")
        self.azimuth = PlanetaryJoint() if azimuth is None else azimuth
        self.pitch = PlanetaryJoint() if pitch is None else pitch
        self.geometry = Geometry() if geometry is None else geometry
        self.inertias = Inertias() if inertias is None else inertias
        self.base = base
        for name, cls in (("azimuth", AbstractJoint), ("pitch", AbstractJoint), ("geometry", Geometry), ("inertias", Inertias)):
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"Mechanism.{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}.")

    @property
    def layout(self) -> MechanismLayout:
        bq, bu = (7, 6) if self.base == "free" else (0, 0)
        na, npi = self.azimuth.layout.size, self.pitch.layout.size
        ca, cp = len(self.azimuth.contact_names), len(self.pitch.contact_names)
        return MechanismLayout(
            base_q=bq,
            base_u=bu,
            azimuth_q=slice(bq, bq + na),
            pitch_q=slice(bq + na, bq + na + npi),
            azimuth_u=slice(bu, bu + na),
            pitch_u=slice(bu + na, bu + na + npi),
            azimuth_v=slice(0, ca),
            pitch_v=slice(ca, ca + cp),
            size_q=bq + na + npi,
            size_u=bu + na + npi,
            size_v=ca + cp,
        )

    def joints(self) -> Iterator[tuple[AbstractJoint, slice, slice, slice]]:
        """`(joint, q slice, u slice, impact-rate slice)` for the azimuth, then the pitch joint."""
        lay = self.layout
        yield self.azimuth, lay.azimuth_q, lay.azimuth_u, lay.azimuth_v
        yield self.pitch, lay.pitch_q, lay.pitch_u, lay.pitch_v

    # ---------------------------------------------------------------------------------------
    # Kinematics

    def base_pose(self, q):
        if self.base == "fixed":
            return jnp.zeros(3), jnp.eye(3)
        return q[:3], quat_matrix(q[3:7])

    def qdot(self, q, u):
        """$\\dot q = N(q)u$: the quaternion rate $\\tfrac12 q\\otimes(0,\\omega_B)$."""
        if self.base == "fixed":
            return u
        return jnp.concatenate([u[:3], quat_rate(q[3:7], u[3:6]), u[self.layout.base_u :]])

    def chain(self, p_b, r_b, q, t):
        """World poses of every body, given the base pose. Returns `(positions (nb, 3),
        rotations (nb, 3, 3))` in the order of `body_inertia`: base, azimuth gears, link 1,
        pitch gears, link 2, reflector."""
        lay, g = self.layout, self.geometry

        def joint_poses(joint, qj, p_h, r_h):
            centres, angles, out_c, out_a = joint.planar(qj, t)
            gears = planar_to_world(p_h, r_h, centres, angles)
            p_o, r_o = planar_to_world(p_h, r_h, out_c[None], out_a[None])
            return gears, p_o[0], r_o[0]

        (pa, ra), p_oa, r_oa = joint_poses(self.azimuth, q[lay.azimuth_q], p_b + r_b @ g.azimuth_position, r_b)
        p_l1 = p_oa + r_oa @ g.link1_centre
        p_hp, r_hp = p_oa + r_oa @ g.pitch_position, r_oa @ jnp.asarray(PITCH_HOUSING)
        (pp, rp), p_op, r_op = joint_poses(self.pitch, q[lay.pitch_q], p_hp, r_hp)
        p_l2 = p_op + r_op @ g.link2_centre
        p_rf = p_op + r_op @ g.reflector_centre
        positions = jnp.concatenate([p_b[None], pa, p_l1[None], pp, p_l2[None], p_rf[None]])
        rotations = jnp.concatenate([r_b[None], ra, r_oa[None], rp, r_op[None], r_op[None]])
        return positions, rotations

    def poses(self, q, t):
        p_b, r_b = self.base_pose(q)
        return self.chain(p_b, r_b, q, t)

    def body_inertia(self):
        """Masses (nb,) and principal inertias (nb, 3) in the order of `chain`."""
        i = self.inertias
        ma, ia = self.azimuth.body_inertia()
        mp, ip = self.pitch.body_inertia()
        masses = jnp.concatenate([i.base_mass[None], ma, i.link1_mass[None], mp, i.link2_mass[None], i.reflector_mass[None]])
        tensors = jnp.concatenate(
            [i.base_inertia[None], ia, i.link1_inertia[None], ip, i.link2_inertia[None], i.reflector_inertia[None]]
        )
        return masses, tensors

    def twists(self, q, u, t):
        """Body velocities (nb, 3) and angular velocities (nb, 3), world frame."""
        (p, r), (pd, rd) = jax.jvp(lambda q_, t_: self.poses(q_, t_), (q, t), (self.qdot(q, u), jnp.ones_like(t)))
        return pd, vee(jnp.einsum("bij,bkj->bik", rd, r))  # skew(omega) = R' R^T

    def dynamics(self, q, u, t):
        """Mass matrix $M(q)$ and the velocity-product and inertial terms $b(q,u)$ with
        $M\\dot u = Q - b$."""
        masses, principal = self.body_inertia()
        _, rot = self.poses(q, t)
        inertia = world_inertia(rot, principal)
        jac_v, jac_w = jax.jacfwd(lambda u_: self.twists(q, u_, t))(u)
        (v, w), (a0, alpha0) = jax.jvp(
            lambda q_, t_: self.twists(q_, u, t_), (q, t), (self.qdot(q, u), jnp.ones_like(t))
        )
        mass = jnp.einsum("b,bin,bim->nm", masses, jac_v, jac_v) + jnp.einsum(
            "bin,bij,bjm->nm", jac_w, inertia, jac_w
        )
        iw = jnp.einsum("bij,bj->bi", inertia, w)
        rot_term = jnp.einsum("bij,bj->bi", inertia, alpha0) + jnp.cross(w, iw)
        bias = jnp.einsum("b,bin,bi->n", masses, jac_v, a0) + jnp.einsum("bin,bi->n", jac_w, rot_term)
        return mass, bias

    def momentum(self, q, u, t):
        """Total linear (kg m/s) and angular momentum about the world origin (kg m²/s)."""
        masses, principal = self.body_inertia()
        pos, rot = self.poses(q, t)
        v, w = self.twists(q, u, t)
        inertia = world_inertia(rot, principal)
        lin = masses[:, None] * v
        ang = jnp.cross(pos, lin) + jnp.einsum("bij,bj->bi", inertia, w)
        return jnp.sum(lin, 0), jnp.sum(ang, 0)

    def kinetic_energy(self, q, u, t):
        masses, principal = self.body_inertia()
        _, rot = self.poses(q, t)
        v, w = self.twists(q, u, t)
        w_body = jnp.einsum("bji,bj->bi", rot, w)
        return 0.5 * jnp.sum(masses * jnp.sum(v**2, -1)) + 0.5 * jnp.sum(principal * w_body**2)

    def potential_energy(self, q):
        """Elastic energy (J) of conservative joints (linear meshes; contact laws with a
        potential). Raises for joints whose smoothed forces have no closed-form potential."""
        return sum(joint.potential_energy(q[sq]) for joint, sq, _, _ in self.joints())

    def reference_angles(self, q, t):
        """Commanded joint angles (azimuth, pitch; rad): the servo's $\\theta^*(t)$; the measured
        output angle for a torque drive (its pointing error is then the error from clearances and
        deflections alone)."""
        out = []
        for joint, sq, _, _ in self.joints():
            cmd = joint.commanded_angle(t)
            out.append(joint.output_angle(q[sq], t) if cmd is None else cmd)
        return jnp.stack(out)

    def output_angles(self, q, t):
        """Measured output angles (azimuth, pitch; rad)."""
        return jnp.stack([joint.output_angle(q[sq], t) for joint, sq, _, _ in self.joints()])

    def ideal_reflector(self, angles):
        """Reflector centre (m) and rotation in the *base* frame for ideal joints at `angles`
        (azimuth, pitch; rad): the commanded pose."""
        g = self.geometry
        r_oa = rz(angles[0])
        r_hp = r_oa @ jnp.asarray(PITCH_HOUSING)
        p_hp = g.azimuth_position + r_oa @ g.pitch_position
        r_op = r_hp @ rz(angles[1])
        return p_hp + r_op @ g.reflector_centre, r_op

    def reflector_in_base(self, q, t):
        """Actual reflector centre and rotation relative to the base (base frame)."""
        pos, rot = self.chain(jnp.zeros(3), jnp.eye(3), q, t)
        return pos[-1], rot[-1]

    # ---------------------------------------------------------------------------------------
    # Forces and the equations of motion

    def joint_forces(self, q, u, v, t):
        """Generalised forces on the joints' coordinates and the contact forces, per joint."""
        return [joint.forces(q[sq], u[su], v[sv], t) for joint, sq, su, sv in self.joints()]

    def accelerations(self, t, q, u, v):
        lay = self.layout
        mass, bias = self.dynamics(q, u, t)
        (qa, ca), (qp, cp) = self.joint_forces(q, u, v, t)
        force = jnp.concatenate([jnp.zeros(lay.base_u), qa, qp]) - bias
        return jnp.linalg.solve(mass, force), (ca, cp)

    def vector_field(self, t, y, args):
        q, u, v = y
        with jax.named_scope("mechanism_dynamics"):
            ud, _ = self.accelerations(t, q, u, v)
        with jax.named_scope("impact_memory"):
            vd = [joint.impact_rate_rates(q[sq], u[su], ud[su], v[sv]) for joint, sq, su, sv in self.joints()]
        return self.qdot(q, u), ud, jnp.concatenate(vd)

    def observe(self, t, y):
        """Instantaneous outputs at a state (see `MechanismResult`)."""
        q, u, v = y
        _, contacts = self.accelerations(t, q, u, v)
        return _outputs.observe(self, t, q, u, contacts)

    def initial_impact_rates(self, q, u):
        """Consistent impact-rate states: each contact's current penetration rate (m/s)."""
        parts = [joint.initial_impact_rates(q[sq], u[su]) for joint, sq, su, _ in self.joints()]
        return jnp.concatenate(parts)

    def initial_state(self, start: str = "rest"):
        """`(q, u, impact_rates)` at t = 0: everything centred, joint angles 0, base at rest.

        `start="rest"`: the joints at rest (a servo start-up follows). `"steady"`: each
        servo-driven joint already turning at its commanded rate in rigid kinematics (sun at
        $i\\Omega$, planets rolling), so a short run skips most of the start-up transient.
        Prescribed (ideal) joints are at their commanded state either way."""
        lay = self.layout
        q = jnp.zeros(lay.size_q)
        if self.base == "free":
            q = q.at[3].set(1.0)  # identity quaternion
        u = jnp.zeros(lay.size_u)
        if start == "steady":
            for joint, _, su, _ in self.joints():
                u = u.at[su].set(joint.steady_speeds())
        return q, u, self.initial_impact_rates(q, u)

    def check_runnable(self):
        if self.layout.size_u == 0:
            raise ValueError(
                "This mechanism has nothing to integrate: a fixed base with both joints ideal and "
                "speed-driven is pure prescribed kinematics. Use base='free', a torque drive, or a "
                "lumped/planetary joint."
            )

    def result(self, sol, observed, duration):
        return _outputs.MechanismResult.from_solution(
            sol,
            duration,
            ts=sol.ts,
            **{f.name: getattr(observed, f.name) for f in dataclasses.fields(observed)},
            states=sol.ys,
            azimuth_contact_names=self.azimuth.contact_names,
            pitch_contact_names=self.pitch.contact_names,
        )
