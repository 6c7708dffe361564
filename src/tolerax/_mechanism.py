"""The dual-axis antenna pointing mechanism (MODEL.md §5): spacecraft body → azimuth joint →
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

**Joint fidelity** (`Joint.fidelity`, structure):

- `"ideal"`: a rigid joint. Driven by a speed servo it follows the commanded angle exactly
  (prescribed motion, no coordinate); driven by a torque it has one coordinate, the output
  angle, with the gear train rigid (sun at $i\\theta_c$, planets rolling).
- `"lumped"`: the sun angle $\\theta_s$ and output angle $\\theta_c$ coupled by one equivalent
  mesh derived from the stage (`lumped_mesh`): torsional stiffness, backlash plus planet-pin
  play, and damping; plus the output bearing's in-plane translation $(x_c, y_c)$ in its radial
  clearance (or spring, or rigid, per `stage.carrier_support`). Planets roll rigidly on the ring.
- `"planetary"`: the full stage of `_planetary` (every support and mesh it models).
"""

import dataclasses
import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

from . import _contact, _mesh, _planetary, _smooth, _validate as V
from ._bench import SpeedServo
from ._planetary import AddedInertia, PlanetaryStage
from ._solve import DTMIN, SolverReport, raise_on_failure, solve

FIDELITIES = ("ideal", "lumped", "planetary")
DRAG_SPEED = 1e-3  # rad/s: drag torque T tanh(omega / DRAG_SPEED), smooth through zero speed


def _set_checked(module, values: dict, shape_of, unit_of):
    """Set real numbers of the expected shape as float arrays (ranges: `__check_init__`)."""
    owner = type(module).__name__
    for name, value in values.items():
        setattr(module, name, V.real(owner, name, value, unit_of(name), shape_of(name)))


class TorqueDrive(eqx.Module):
    """Prescribed drive torque $T(t) = A\\cos(2\\pi f t + \\varphi)$ at the joint output (N m).

    Applied to the sun as $T/i$ (the motor torque that gives $T$ at the output through a rigid
    stage). The paper's Table 2: $A$ = 1.5 N m (azimuth), 0.8 N m (pitch), $f$ = 1 Hz.
    """

    amplitude: Float[Array, ""]
    frequency: Float[Array, ""]
    phase: Float[Array, ""]

    def __init__(self, amplitude, frequency=1.0, phase=0.0):
        self.amplitude = V.real("TorqueDrive", "amplitude", amplitude, "N m")
        self.frequency = V.real("TorqueDrive", "frequency", frequency, "Hz")
        self.phase = V.real("TorqueDrive", "phase", phase, "rad")

    def __check_init__(self):
        V.check(self, amplitude=V.FINITE("N m"), frequency=V.NONNEGATIVE("Hz"), phase=V.FINITE("rad"))

    def torque(self, t):
        return self.amplitude * jnp.cos(2.0 * jnp.pi * self.frequency * t + self.phase)


class Joint(eqx.Module):
    """One planetary gear joint of the mechanism.

    - `stage`: the gear data (`PlanetaryStage`); every fidelity derives its values from it.
    - `fidelity`: `"ideal"`, `"lumped"` or `"planetary"` (static; see the module docstring).
    - `drive`: a `SpeedServo` on the motor (commanded output rate, rad/s; rate 0 holds the joint
      still, as the non-driven joint in the paper's single-axis runs) or a `TorqueDrive`.
    - `motor_inertia`: rotor inertia on the sun shaft (kg m²).
    - `drag_torque`: torque resisting the output's rotation relative to the housing (N m),
      $T\\tanh(\\omega/10^{-3})$ (harness and seal drag; it keeps the gear train loaded).
    """

    stage: PlanetaryStage
    drive: SpeedServo | TorqueDrive
    motor_inertia: Float[Array, ""]
    drag_torque: Float[Array, ""]
    fidelity: str = eqx.field(static=True)

    def __init__(self, stage=None, fidelity="planetary", drive=None, motor_inertia=2e-4, drag_torque=0.05):
        if fidelity not in FIDELITIES:
            raise ValueError(f"fidelity={fidelity!r} is unknown; use one of {FIDELITIES}.")
        self.stage = _planetary.default_stage() if stage is None else stage
        self.fidelity = fidelity
        self.drive = SpeedServo() if drive is None else drive
        if not isinstance(self.drive, (SpeedServo, TorqueDrive)):
            raise TypeError(f"drive must be a SpeedServo or a TorqueDrive, got {type(self.drive).__name__}.")
        self.motor_inertia = V.real("Joint", "motor_inertia", motor_inertia, "kg m^2")
        self.drag_torque = V.real("Joint", "drag_torque", drag_torque, "N m")

    def __check_init__(self):
        if not isinstance(self.stage, PlanetaryStage):
            raise TypeError(f"Joint.stage must be a PlanetaryStage, got {type(self.stage).__name__}.")
        V.check(self, motor_inertia=V.POSITIVE("kg m^2"), drag_torque=V.NONNEGATIVE("N m"))

    @property
    def layout(self) -> "JointLayout":
        return JointLayout.of(self)

    @property
    def contact_names(self) -> tuple[str, ...]:
        if self.fidelity == "planetary":
            return self.stage.contact_names
        if self.fidelity == "lumped" and self.stage.carrier_support.kind == "clearance":
            return ("carrier",)
        return ()


@dataclasses.dataclass(frozen=True)
class JointLayout:
    """Index map of a joint's coordinates (static). `None`: the coordinate does not exist."""

    size: int
    sun: int | None
    carrier: int | None
    carrier_xy: slice | None
    names: tuple[str, ...]

    @staticmethod
    def of(joint: Joint) -> "JointLayout":
        if joint.fidelity == "planetary":
            lay = joint.stage.layout
            return JointLayout(lay.size, lay.sun_theta, lay.carrier_theta, lay.carrier_xy, lay.names)
        if joint.fidelity == "ideal":
            if isinstance(joint.drive, TorqueDrive):
                return JointLayout(1, None, 0, None, ("theta_c",))
            return JointLayout(0, None, None, None, ())
        if joint.stage.carrier_support.translates:
            return JointLayout(4, 0, 1, slice(2, 4), ("theta_s", "theta_c", "x_c", "y_c"))
        return JointLayout(2, 0, 1, None, ("theta_s", "theta_c"))


class LumpedMesh(eqx.Module):
    """The stage's two mesh families and planet pins condensed into one mesh between sun and carrier.

    Deflection $g = r(\\theta_s/i - \\theta_c)$ on the lever $r = i\\,r_{bs}$ (m), with stiffness
    `stiffness` $= \\sum_n k_{s}k_{r}/(k_{s}+k_{r})$ (N/m; each planet's sun and ring meshes in
    series, the planet free to turn: the static condensation of the stage with rigid supports),
    and damping $D = 2\\xi\\sqrt{\\bar m K}$ with $\\bar m = (I_s + I_{motor})/r_{bs}^2$ (the
    sun-side mode, output held).

    Dead zone (nonlinear lumped mesh): the drive flank is loaded while $g > $ `drive_gap`, the
    back flank while $g < -$`back_gap` (m). A planet's tangential pin offset $\\eta$ enters the
    sum of its two mesh deflections as $-\\eta(\\cos\\alpha_s + \\cos\\alpha_r)$, so a pin
    clearance $c_p$ lets the carrier float by $p = c_p(\\cos\\alpha_s + \\cos\\alpha_r)$ on
    either side: `drive_gap` $= \\min_n p_n$ and `back_gap` $= \\min_n(b_{s,n} + b_{r,n} + p_n)$
    (the first planet to take up its play carries the load). The output's lost motion with the
    sun held is (`drive_gap` + `back_gap`)$/r$. $p = 0$ for rigid or spring-mounted pins (a
    spring pin's compliance is not put in series).
    Mean stiffnesses: no TVMS, profile error or dynamic backlash (mesh-frequency effects that the
    lumped fidelity leaves out by design).
    """

    lever: Float[Array, ""]
    stiffness: Float[Array, ""]
    drive_gap: Float[Array, ""]
    back_gap: Float[Array, ""]
    damping: Float[Array, ""]
    nonlinear: bool = eqx.field(static=True)

    @property
    def lost_motion(self) -> Array:
        """Output rotation (rad) from drive-flank to back-flank contact with the sun held."""
        return (self.drive_gap + self.back_gap) / self.lever


def lumped_mesh(stage: PlanetaryStage, motor_inertia) -> LumpedMesh:
    """Derive the lumped joint's equivalent mesh from the stage data (see `LumpedMesh`)."""
    k_s, k_r = stage.sun_mesh.stiffness, stage.ring_mesh.stiffness
    n = stage.n_planets
    stiffness = n * k_s * k_r / (k_s + k_r)
    meshes_nonlinear = stage.sun_mesh.kind == "nonlinear"
    if meshes_nonlinear != (stage.ring_mesh.kind == "nonlinear"):
        raise ValueError("A lumped joint needs both mesh families linear or both nonlinear.")
    pins = stage.planet_support.kind == "clearance"
    play = jnp.zeros(n)
    if pins:
        kappa = jnp.cos(stage.sun_pressure_angle) + jnp.cos(stage.ring_pressure_angle)
        play = jnp.broadcast_to(stage.planet_support.bearing.clearance * kappa, (n,))
    backlash = jnp.zeros(n)
    if meshes_nonlinear:
        backlash = jnp.broadcast_to(stage.sun_mesh.backlash + stage.ring_mesh.backlash, (n,))
    m_eq = (stage.sun_inertia + motor_inertia) / stage.sun_base_radius**2
    damping = 2.0 * stage.sun_mesh.damping_ratio * jnp.sqrt(m_eq * stiffness)
    return LumpedMesh(
        stage.ratio * stage.sun_base_radius,
        stiffness,
        jnp.min(play),
        jnp.min(backlash + play),
        damping,
        meshes_nonlinear or pins,
    )


def _planet_spin_ratio(stage):
    """Planet spin per carrier turn when the planets roll on the fixed ring without deflection."""
    return -stage.carrier_radius * jnp.cos(stage.ring_pressure_angle) / stage.planet_base_radius


def commanded_angle(joint: Joint, t):
    """Commanded output angle (rad): $\\Omega t$ for a speed servo; `None` for a torque drive."""
    if isinstance(joint.drive, SpeedServo):
        return joint.drive.output_rate * t
    return None


def _joint_planar(joint: Joint, qj, t):
    """Housing-frame centres (nb, 2), angles (nb,) of the gear bodies, and the output's (carrier's)
    centre (2,) and angle. Bodies: sun, carrier, planets (, ring if spring-mounted)."""
    stage = joint.stage
    lay = joint.layout
    if joint.fidelity == "planetary":
        centres, angles = _planetary.body_positions(stage, qj)
        return centres, angles, centres[1], angles[1]
    theta_c = commanded_angle(joint, t) if lay.carrier is None else qj[lay.carrier]
    theta_s = stage.ratio * theta_c if lay.sun is None else qj[lay.sun]
    p_c = jnp.zeros(2) if lay.carrier_xy is None else qj[lay.carrier_xy]
    psi = stage.planet_angles + theta_c
    planets = p_c + stage.carrier_radius * jnp.stack([jnp.cos(psi), jnp.sin(psi)], axis=-1)
    theta_p = jnp.broadcast_to(_planet_spin_ratio(stage) * theta_c, psi.shape)
    centres = jnp.concatenate([jnp.zeros((1, 2)), p_c[None], planets])
    angles = jnp.concatenate([jnp.stack([theta_s, theta_c]), theta_p])
    return centres, angles, p_c, theta_c


def _joint_inertia(joint: Joint):
    masses, inertias = _planetary._body_inertia(joint.stage, AddedInertia(sun_inertia=joint.motor_inertia))
    if joint.fidelity != "planetary":  # the ring, if spring-mounted, is fixed in these fidelities
        nb = 2 + joint.stage.n_planets
        masses, inertias = masses[:nb], inertias[:nb]
    # Thin discs: transverse inertia half the polar inertia.
    tensors = jnp.stack([0.5 * inertias, 0.5 * inertias, inertias], axis=-1)
    return masses, tensors


# --------------------------------------------------------------------------------------------
# The mechanism


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


# Fixed orientations (structure, not parameters): pitch housing axis z -> link 1's x axis.
_PITCH_HOUSING = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def _rz(angle):
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [jnp.stack([c, -s, zero], -1), jnp.stack([s, c, zero], -1), jnp.stack([zero, zero, one], -1)], -2
    )


def _quat_matrix(quat):
    w, x, y, z = quat / jnp.sqrt(jnp.sum(quat**2))
    return jnp.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def _vee(w):
    """Vector of the skew part of `w` (..., 3, 3)."""
    return 0.5 * jnp.stack(
        [w[..., 2, 1] - w[..., 1, 2], w[..., 0, 2] - w[..., 2, 0], w[..., 1, 0] - w[..., 0, 1]], -1
    )


def _world_inertia(rot, principal):
    """$R\\,\\mathrm{diag}(I)R^T$ per body (nb, 3, 3)."""
    return jnp.einsum("bij,bj,bkj->bik", rot, principal, rot)


def _planar_to_world(p_h, r_h, centres, angles):
    pos = p_h + jnp.concatenate([centres, jnp.zeros((centres.shape[0], 1))], axis=1) @ r_h.T
    return pos, r_h @ _rz(angles)


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


class Mechanism(eqx.Module):
    """The antenna pointing mechanism: two joints, geometry, inertias and the base (static:
    `"free"` floating, 6 DOF, the on-orbit case; or `"fixed"`, a ground test stand)."""

    azimuth: Joint
    pitch: Joint
    geometry: Geometry
    inertias: Inertias
    base: str = eqx.field(static=True)

    def __init__(self, azimuth=None, pitch=None, geometry=None, inertias=None, base="free"):
        if base not in ("free", "fixed"):
            raise ValueError(f"base={base!r} is unknown; use 'free' (floating spacecraft) or 'fixed'.")
        self.azimuth = Joint() if azimuth is None else azimuth
        self.pitch = Joint() if pitch is None else pitch
        self.geometry = Geometry() if geometry is None else geometry
        self.inertias = Inertias() if inertias is None else inertias
        self.base = base
        for name, cls in (("azimuth", Joint), ("pitch", Joint), ("geometry", Geometry), ("inertias", Inertias)):
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

    # ---------------------------------------------------------------------------------------
    # Kinematics

    def base_pose(self, q):
        if self.base == "fixed":
            return jnp.zeros(3), jnp.eye(3)
        return q[:3], _quat_matrix(q[3:7])

    def qdot(self, q, u):
        """$\\dot q = N(q)u$: the quaternion rate $\\tfrac12 q\\otimes(0,\\omega_B)$."""
        lay = self.layout
        if self.base == "fixed":
            return u
        w, x, y, z = q[3], q[4], q[5], q[6]
        wx, wy, wz = u[3], u[4], u[5]
        quat_dot = 0.5 * jnp.stack(
            [-x * wx - y * wy - z * wz, w * wx + y * wz - z * wy, w * wy + z * wx - x * wz, w * wz + x * wy - y * wx]
        )
        return jnp.concatenate([u[:3], quat_dot, u[lay.base_u :]])

    def chain(self, p_b, r_b, q, t):
        """World poses of every body, given the base pose. Returns `(positions (nb, 3),
        rotations (nb, 3, 3))` in the order of `body_inertia`: base, azimuth gears, link 1,
        pitch gears, link 2, reflector."""
        lay, g = self.layout, self.geometry
        p_ha, r_ha = p_b + r_b @ g.azimuth_position, r_b
        ca, aa, out_c, out_a = _joint_planar(self.azimuth, q[lay.azimuth_q], t)
        pa, ra = _planar_to_world(p_ha, r_ha, ca, aa)
        p_oa, r_oa = _planar_to_world(p_ha, r_ha, out_c[None], out_a[None])
        p_oa, r_oa = p_oa[0], r_oa[0]
        p_l1 = p_oa + r_oa @ g.link1_centre
        p_hp, r_hp = p_oa + r_oa @ g.pitch_position, r_oa @ jnp.asarray(_PITCH_HOUSING)
        cp, ap, out_c, out_a = _joint_planar(self.pitch, q[lay.pitch_q], t)
        pp, rp = _planar_to_world(p_hp, r_hp, cp, ap)
        p_op, r_op = _planar_to_world(p_hp, r_hp, out_c[None], out_a[None])
        p_op, r_op = p_op[0], r_op[0]
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
        ma, ia = _joint_inertia(self.azimuth)
        mp, ip = _joint_inertia(self.pitch)
        masses = jnp.concatenate([i.base_mass[None], ma, i.link1_mass[None], mp, i.link2_mass[None], i.reflector_mass[None]])
        tensors = jnp.concatenate(
            [i.base_inertia[None], ia, i.link1_inertia[None], ip, i.link2_inertia[None], i.reflector_inertia[None]]
        )
        return masses, tensors

    def twists(self, q, u, t):
        """Body velocities (nb, 3) and angular velocities (nb, 3), world frame."""
        (p, r), (pd, rd) = jax.jvp(lambda q_, t_: self.poses(q_, t_), (q, t), (self.qdot(q, u), jnp.ones_like(t)))
        return pd, _vee(jnp.einsum("bij,bkj->bik", rd, r))  # skew(omega) = R' R^T

    def dynamics(self, q, u, t):
        """Mass matrix $M(q)$ and the velocity-product and inertial terms $b(q,u)$ with
        $M\\dot u = Q - b$."""
        masses, principal = self.body_inertia()
        _, rot = self.poses(q, t)
        inertia = _world_inertia(rot, principal)
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
        inertia = _world_inertia(rot, principal)
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
        lay = self.layout
        energy = 0.0
        for joint, sl in ((self.azimuth, lay.azimuth_q), (self.pitch, lay.pitch_q)):
            qj = q[sl]
            if joint.fidelity == "planetary":
                energy += _planetary.potential_energy(joint.stage, qj)
            elif joint.fidelity == "lumped":
                lm = lumped_mesh(joint.stage, joint.motor_inertia)
                if lm.nonlinear:
                    raise ValueError(
                        "potential_energy needs linear meshes and no pin clearance (the smoothed dead zone has none)."
                    )
                energy += 0.5 * lm.stiffness * _lumped_deflection(joint, lm, qj) ** 2
                energy += _lumped_support_energy(joint, qj)
        return energy

    # ---------------------------------------------------------------------------------------
    # Forces

    def joint_forces(self, q, u, v, t):
        """Generalised forces on the joints' coordinates and the contact forces, per joint."""
        lay = self.layout
        out = []
        for joint, sq, su, sv in (
            (self.azimuth, lay.azimuth_q, lay.azimuth_u, lay.azimuth_v),
            (self.pitch, lay.pitch_q, lay.pitch_u, lay.pitch_v),
        ):
            out.append(_joint_forces(joint, q[sq], u[su], v[sv], t))
        return out

    def accelerations(self, t, q, u, v):
        lay = self.layout
        mass, bias = self.dynamics(q, u, t)
        (qa, ca), (qp, cp) = self.joint_forces(q, u, v, t)
        force = jnp.concatenate([jnp.zeros(lay.base_u), qa, qp]) - bias
        return jnp.linalg.solve(mass, force), (ca, cp)

    def vector_field(self, t, y, args):
        q, u, v = y
        lay = self.layout
        with jax.named_scope("mechanism_dynamics"):
            ud, _ = self.accelerations(t, q, u, v)
        with jax.named_scope("impact_memory"):
            vd = jnp.concatenate(
                [
                    _joint_impact_rate_rates(self.azimuth, q[lay.azimuth_q], u[lay.azimuth_u], ud[lay.azimuth_u], v[lay.azimuth_v]),
                    _joint_impact_rate_rates(self.pitch, q[lay.pitch_q], u[lay.pitch_u], ud[lay.pitch_u], v[lay.pitch_v]),
                ]
            )
        return self.qdot(q, u), ud, vd

    def observe(self, t, y):
        """Instantaneous outputs at a state (see `MechanismResult`)."""
        q, u, v = y
        _, contacts = self.accelerations(t, q, u, v)
        return _observe(self, t, q, u, contacts)

    def initial_state(self, steady: bool = False):
        """`(q, u, impact_rates)` at t = 0: everything centred, joint angles 0, base at rest.

        `steady=False`: the joints at rest (a servo start-up follows). `steady=True`: each
        servo-driven joint already turning at its commanded rate in rigid kinematics (sun at
        $i\\Omega$, planets rolling), so a short run skips most of the start-up transient.
        Prescribed (ideal) joints are at their commanded state either way."""
        lay = self.layout
        q = jnp.zeros(lay.size_q)
        if self.base == "free":
            q = q.at[3].set(1.0)  # identity quaternion
        u = jnp.zeros(lay.size_u)
        if steady:
            for joint, sl in ((self.azimuth, lay.azimuth_u), (self.pitch, lay.pitch_u)):
                jl = joint.layout
                if jl.carrier is None or not isinstance(joint.drive, SpeedServo):
                    continue
                rate = joint.drive.output_rate
                uj = jnp.zeros(jl.size).at[jl.carrier].set(rate)
                if jl.sun is not None:
                    uj = uj.at[jl.sun].set(joint.stage.ratio * rate)
                if joint.fidelity == "planetary":
                    planets = joint.stage.layout.planet_theta
                    uj = uj.at[planets].set(_planet_spin_ratio(joint.stage) * rate)
                u = u.at[sl].set(uj)
        return q, u, initial_impact_rates(self, q, u)


# --------------------------------------------------------------------------------------------
# Joint forces per fidelity


def _drive_torques(joint: Joint, lay: JointLayout, qj, uj, t):
    """Generalised drive and drag forces on the joint's coordinates."""
    stage = joint.stage
    force = jnp.zeros(lay.size)
    if lay.size == 0:
        return force
    if isinstance(joint.drive, TorqueDrive):
        torque = joint.drive.torque(t)
        if lay.sun is None:  # ideal: rigid gear train, the output torque acts directly
            force = force.at[lay.carrier].add(torque)
        else:
            force = force.at[lay.sun].add(torque / stage.ratio)
    else:
        force = force.at[lay.sun].add(joint.drive.torque(stage.ratio, t, qj[lay.sun], uj[lay.sun]))
    drag = joint.drag_torque * jnp.tanh(uj[lay.carrier] / DRAG_SPEED)
    return force.at[lay.carrier].add(-drag)


def _lumped_deflection(joint, lm, qj):
    lay = joint.layout
    return lm.lever * (qj[lay.sun] / joint.stage.ratio - qj[lay.carrier])


def _lumped_bearing(joint):
    return jax.tree.map(lambda x: x[None], joint.stage.carrier_support.bearing)


def _lumped_support_energy(joint, qj):
    support, lay = joint.stage.carrier_support, joint.layout
    if support.kind == "spring":
        return 0.5 * support.stiffness * jnp.sum(qj[lay.carrier_xy] ** 2)
    if support.kind == "clearance":
        stage = joint.stage
        state = _contact.contact_kinematics(_lumped_bearing(joint), qj[lay.carrier_xy][None], jnp.zeros((1, 2)), stage.smoothing_width)
        return jnp.sum(stage.contact_law.potential(_lumped_bearing(joint), state.penetration))
    return 0.0


def _joint_forces(joint: Joint, qj, uj, vj, t):
    """`(Q_j, contact forces)` of one joint: generalised forces on its coordinates (N m or N)
    and the normal force of each of its clearance contacts (N, `joint.contact_names` order)."""
    lay = joint.layout
    stage = joint.stage
    drive = _drive_torques(joint, lay, qj, uj, t)
    if joint.fidelity == "planetary":
        f = _planetary.stage_forces(stage, qj, uj, vj)
        return f.generalised + drive, f.contact
    if joint.fidelity == "ideal":
        return drive, jnp.zeros(0)
    lm = lumped_mesh(stage, joint.motor_inertia)
    width = stage.smoothing_width
    g = _lumped_deflection(joint, lm, qj)
    gd = _lumped_deflection(joint, lm, uj)
    if lm.nonlinear:
        f_drive, f_back = _mesh.flank_forces(g - lm.drive_gap, gd, g + lm.back_gap, gd, lm.stiffness, lm.damping, width)
        tooth = f_drive + f_back
    else:
        tooth = lm.stiffness * g + lm.damping * gd
    # Q = -F dg/dq: dg/dtheta_s = r/i, dg/dtheta_c = -r.
    force = drive.at[lay.sun].add(-tooth * lm.lever / stage.ratio).at[lay.carrier].add(tooth * lm.lever)
    contact = jnp.zeros(0)
    support = stage.carrier_support
    if support.kind == "spring":
        e, ed = qj[lay.carrier_xy], uj[lay.carrier_xy]
        force = force.at[lay.carrier_xy].add(-support.stiffness * e - support.damping * ed)
    elif support.kind == "clearance":
        bearing = _lumped_bearing(joint)
        state = _contact.contact_kinematics(bearing, qj[lay.carrier_xy][None], uj[lay.carrier_xy][None], width)
        contact = _contact.normal_force(stage.contact_law, bearing, state, vj, width, stage.impact_rate_floor)
        force = force.at[lay.carrier_xy].add(-contact[0] * state.normal[0])
    return force, contact


def _joint_impact_rate_rates(joint: Joint, qj, uj, udj, vj):
    if not joint.contact_names:
        return jnp.zeros(0)
    stage = joint.stage
    if joint.fidelity == "planetary":
        return _planetary.impact_rate_rates(stage, qj, uj, udj, vj)
    sl = joint.layout.carrier_xy
    bearing = _lumped_bearing(joint)
    width = stage.smoothing_width
    e, ed, edd = qj[sl][None], uj[sl][None], udj[sl][None]
    state = _contact.contact_kinematics(bearing, e, ed, width)
    rate_dot = _contact.rate_derivative(bearing, e, ed, edd, width)
    return _contact.impact_rate_derivative(state, rate_dot, vj, width, stage.impact_memory_time)


def initial_impact_rates(mech: Mechanism, q, u):
    """Consistent impact-rate states: each contact's current penetration rate (m/s)."""
    lay = mech.layout
    parts = []
    for joint, sq, su in ((mech.azimuth, lay.azimuth_q, lay.azimuth_u), (mech.pitch, lay.pitch_q, lay.pitch_u)):
        if not joint.contact_names:
            continue
        if joint.fidelity == "planetary":
            parts.append(_planetary.initial_impact_rates(joint.stage, q[sq], u[su]))
        else:
            sl = joint.layout.carrier_xy
            state = _contact.contact_kinematics(_lumped_bearing(joint), q[sq][sl][None], u[su][sl][None], joint.stage.smoothing_width)
            parts.append(state.rate)
    return jnp.concatenate(parts) if parts else jnp.zeros(0)


# --------------------------------------------------------------------------------------------
# Outputs (MODEL.md §6)


def _output_angle(joint: Joint, qj, t):
    lay = joint.layout
    return commanded_angle(joint, t) if lay.carrier is None else qj[lay.carrier]


def _reference_angles(mech: Mechanism, q, t):
    """Commanded joint angles: $\\Omega t$ for a servo; the measured output angle for a torque
    drive (its pointing error is then the error from clearances and deflections alone)."""
    lay = mech.layout
    out = []
    for joint, sl in ((mech.azimuth, lay.azimuth_q), (mech.pitch, lay.pitch_q)):
        cmd = commanded_angle(joint, t)
        out.append(_output_angle(joint, q[sl], t) if cmd is None else cmd)
    return jnp.stack(out)


def ideal_reflector(mech: Mechanism, angles):
    """Reflector centre (m) and rotation in the *base* frame for ideal joints at `angles`
    (azimuth, pitch; rad): the commanded pose."""
    g = mech.geometry
    r_oa = _rz(angles[0])
    p_oa = g.azimuth_position
    r_hp = r_oa @ jnp.asarray(_PITCH_HOUSING)
    p_hp = p_oa + r_oa @ g.pitch_position
    r_op = r_hp @ _rz(angles[1])
    return p_hp + r_op @ g.reflector_centre, r_op


def _reflector_in_base(mech: Mechanism, q, t):
    """Actual reflector centre and rotation relative to the base (base frame)."""
    pos, rot = mech.chain(jnp.zeros(3), jnp.eye(3), q, t)
    return pos[-1], rot[-1]




class Observation(eqx.Module):
    """Instantaneous outputs (see `MechanismResult` for definitions)."""

    joint_angle: Array
    commanded_angle: Array
    pointing_error: Array
    position_error: Array
    tracking_speed_error: Array
    runout: Array
    azimuth_contact: Array
    pitch_contact: Array
    momentum: Array
    angular_momentum: Array
    kinetic_energy: Array


def _observe(mech: Mechanism, t, q, u, contacts):
    lay = mech.layout
    qd = mech.qdot(q, u)
    # Motion relative to the base: the base-frame chain and its time derivative.
    (p_act, r_act), (v_act, rd_act) = jax.jvp(lambda q_, t_: _reflector_in_base(mech, q_, t_), (q, t), (qd, jnp.ones_like(t)))
    angles = _reference_angles(mech, q, t)
    rates = jax.jvp(lambda t_: _reference_angles(mech, q, t_), (t,), (jnp.ones_like(t),))[1]
    # For a torque drive the reference follows the measured angle: its rate is the measured rate.
    actual, actual_rate = jax.jvp(
        lambda q_, t_: jnp.stack([_output_angle(mech.azimuth, q_[lay.azimuth_q], t_), _output_angle(mech.pitch, q_[lay.pitch_q], t_)]),
        (q, t),
        (qd, jnp.ones_like(t)),
    )
    for k, joint in enumerate((mech.azimuth, mech.pitch)):
        if commanded_angle(joint, t) is None:
            rates = rates.at[k].set(actual_rate[k])
    (p_cmd, r_cmd), (v_cmd, rd_cmd) = jax.jvp(lambda a: ideal_reflector(mech, a), (angles,), (rates,))
    boresight = r_act[:, 1]
    commanded = r_cmd[:, 1]
    cross = _smooth.norm(jnp.cross(boresight, commanded), 0.0)
    pointing = jnp.arctan2(cross, jnp.dot(boresight, commanded))
    omega_act = _vee(rd_act @ r_act.T)
    omega_cmd = _vee(rd_cmd @ r_cmd.T)
    runout = []
    for joint, sl in ((mech.azimuth, lay.azimuth_q), (mech.pitch, lay.pitch_q)):
        xy = joint.layout.carrier_xy
        runout.append(_smooth.norm(q[sl][xy], 0.0) if xy is not None else jnp.zeros(()))
    lin, ang = mech.momentum(q, u, t)
    return Observation(
        joint_angle=actual,
        commanded_angle=angles,
        pointing_error=pointing,
        position_error=p_act - p_cmd,
        tracking_speed_error=omega_act - omega_cmd,
        runout=jnp.stack(runout),
        azimuth_contact=contacts[0],
        pitch_contact=contacts[1],
        momentum=lin,
        angular_momentum=ang,
        kinetic_energy=mech.kinetic_energy(q, u, t),
    )


class MechanismResult(SolverReport):
    """Time series of a mechanism run. SI units, angles in rad, vectors in the base frame.

    - `ts` (s). `joint_angle`, `commanded_angle`: (n, 2) azimuth and pitch output angles; the
      commanded angle is $\\Omega t$ for a servo, the measured angle for a torque drive.
    - `pointing_error`: angle (rad) between the actual boresight and the commanded one (ideal
      joints at the commanded angles), both in the base (spacecraft) frame.
    - `position_error`: reflector centre minus its commanded position (m), (n, 3).
    - `tracking_speed_error`: reflector angular velocity relative to the base minus the
      commanded one (rad/s), (n, 3).
    - `runout`: radial runout of each joint output, $|(x_c, y_c)|$ (m), (n, 2); 0 where the
      fidelity has no output translation.
    - `azimuth_contact`, `pitch_contact`: normal force of each clearance contact (N), columns
      `azimuth_contact_names` / `pitch_contact_names`; `output_force` (property) is the output
      bearing's (carrier's) radial contact force per joint.
    - `momentum`, `angular_momentum` (about the world origin), `kinetic_energy`: invariants.
    - `states`: `(q, u, impact_rates)`.
    - solver report (`SolverReport`): `result`, `t_reached`, `num_steps`, `num_rejected`,
      `duration`; `success`, `failures()`, `report()` (per sample for a batch).
    """

    _what = "mechanism"

    ts: Array
    joint_angle: Array
    commanded_angle: Array
    pointing_error: Array
    position_error: Array
    tracking_speed_error: Array
    runout: Array
    azimuth_contact: Array
    pitch_contact: Array
    momentum: Array
    angular_momentum: Array
    kinetic_energy: Array
    states: tuple
    azimuth_contact_names: tuple[str, ...] = eqx.field(static=True)
    pitch_contact_names: tuple[str, ...] = eqx.field(static=True)

    @property
    def output_force(self) -> Array:
        """(n, 2) radial contact force at the azimuth and pitch outputs (N); 0 without clearance."""
        cols = []
        for force, names in ((self.azimuth_contact, self.azimuth_contact_names), (self.pitch_contact, self.pitch_contact_names)):
            cols.append(force[:, names.index("carrier")] if "carrier" in names else jnp.zeros(force.shape[0]))
        return jnp.stack(cols, axis=1)


def simulate(
    mechanism: Mechanism | None = None,
    duration: float = 1.0,
    *,
    n_save: int = 1001,
    solver: diffrax.AbstractSolver | None = None,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    dt0: float = 1e-6,
    dtmax: float = 1e-3,
    max_steps: int = 4_000_000,
    throw: bool = True,
    y0: tuple | None = None,
    steady: bool = False,
    progress: bool = False,
    fixed_step: float | None = None,
    dtmin: float = DTMIN,
) -> MechanismResult:
    """Run the mechanism from rest (or `y0`) for `duration` seconds.

    Arguments as `simulate_bench`: `solver` (default `Tsit5`), `rtol`/`atol` (SI state units:
    m, rad, m/s, rad/s), `dt0`, `dtmax` (s), `max_steps`, `throw` (raise `SimulationError` on
    failure, else return with `result` set), `y0 = (q, u, impact_rates)` (default
    `mechanism.initial_state(steady)`: from rest, or already turning at the commanded rates),
    `dtmin` (s: a step-size collapse below it ends the run with `RESULTS.dt_min_reached`),
    `progress` (diffrax's text meter), `fixed_step` (s: constant steps instead of adaptive ones,
    see `_solve.solve`). Only structure recompiles (fidelities, supports, solver, `n_save`).
    """
    mech = Mechanism() if mechanism is None else mechanism
    if not isinstance(mech, Mechanism):
        raise TypeError(f"mechanism must be a Mechanism (see `antenna`), got {type(mech).__name__}.")
    if mech.layout.size_u == 0:
        raise ValueError(
            "This mechanism has nothing to integrate: a fixed base with both joints ideal and "
            "speed-driven is pure prescribed kinematics. Use base='free', a torque drive, or a "
            "lumped/planetary joint."
        )
    solver = diffrax.Tsit5() if solver is None else solver
    if y0 is None:
        y0 = mech.initial_state(steady)
    else:
        V.state_like(y0, mech.initial_state(steady))
    sol, obs = solve(mech, y0, duration, n_save, solver, rtol, atol, dt0, dtmax, max_steps, progress, fixed_step, dtmin)
    result = MechanismResult(
        ts=sol.ts,
        **{f.name: getattr(obs, f.name) for f in dataclasses.fields(Observation)},
        states=sol.ys,
        result=sol.result,
        t_reached=sol.stats["t_reached"],
        num_steps=sol.stats["num_accepted_steps"],
        num_rejected=sol.stats["num_rejected_steps"],
        duration=float(duration),
        azimuth_contact_names=mech.azimuth.contact_names,
        pitch_contact_names=mech.pitch.contact_names,
    )
    if throw:
        raise_on_failure(sol, duration, "mechanism")
    return result


# --------------------------------------------------------------------------------------------
# Scenes


DRIVE_MODES = ("azimuth", "pitch", "dual")


def antenna(
    mode: str = "azimuth",
    *,
    fidelity: str | tuple[str, str] = "planetary",
    rate: float = math.radians(0.98),
    drive: str = "speed",
    base: str = "free",
    azimuth_stage: PlanetaryStage | None = None,
    pitch_stage: PlanetaryStage | None = None,
    torques: tuple[float, float] = (1.5, 0.8),
    servo_gains: tuple[float, float] = (0.2, 2.0),
    drag_torque: float = 0.05,
    motor_inertia: float = 2e-4,
) -> Mechanism:
    """A scene of the paper: driving `mode` `"azimuth"`, `"pitch"` (single-axis) or `"dual"`.

    - `fidelity`: one for both joints or `(azimuth, pitch)`; `"ideal"`, `"lumped"`, `"planetary"`.
    - `rate`: commanded output rate of each driven joint (rad/s; the paper's 0.49, 0.98,
      1.96 °/s). A non-driven joint is held by its servo at angle 0 (`drive="speed"`).
    - `drive`: `"speed"` (PI servo on each motor) or `"torque"` (the paper's Table 2 torques
      `torques` = $(T_a, T_p)$ N m at 1 Hz on the driven joints). Either way a non-driven joint
      is held at angle 0 by its servo (an ideal one is locked).
    - `base`: `"free"` (floating spacecraft) or `"fixed"`.
    - `azimuth_stage`, `pitch_stage`: gear data (default `default_stage()`: 100 µm clearances
      and backlash).
    - `servo_gains`: $(k_p, k_i)$ of the motor servos (N m s/rad, N m/rad).
    """
    if mode not in DRIVE_MODES:
        raise ValueError(f"mode={mode!r} is unknown; use one of {DRIVE_MODES}.")
    if drive not in ("speed", "torque"):
        raise ValueError(f"drive={drive!r} is unknown; use 'speed' or 'torque'.")
    fids = (fidelity, fidelity) if isinstance(fidelity, str) else tuple(fidelity)
    if len(fids) != 2:
        raise ValueError(f"fidelity must be one name or an (azimuth, pitch) pair, got {fidelity!r}.")
    for name, pair in (("torques", torques), ("servo_gains", servo_gains)):
        if np.shape(pair) != (2,):
            raise ValueError(f"antenna({name}=...) must be a pair of numbers, got {pair!r}.")
    driven = (mode in ("azimuth", "dual"), mode in ("pitch", "dual"))
    joints = []
    for k, (stage, fid, on) in enumerate(zip((azimuth_stage, pitch_stage), fids, driven)):
        if drive == "torque" and on:
            drv = TorqueDrive(torques[k])
        else:
            drv = SpeedServo(rate if on else 0.0, *servo_gains)
        joints.append(Joint(stage, fid, drv, motor_inertia=motor_inertia, drag_torque=drag_torque))
    return Mechanism(joints[0], joints[1], base=base)


def vibration_amplitude(signal, ts, min_frequency: float = 1.0):
    """Peak of the single-sided amplitude spectrum of `signal` above `min_frequency` (Hz).

    The signal (uniformly sampled at `ts`) has its mean and linear trend removed, then
    $A(f_k) = 2|X_k|/n$ (a sinusoid of amplitude $a$ at a bin frequency gives $a$). Below
    `min_frequency` lie the servo's start-up and drift, which are not vibration. Same units as
    `signal`. This is how the reflector's radial and torsional vibration amplitudes are defined.
    """
    signal = jnp.asarray(signal)
    ts = jnp.asarray(ts)
    n = signal.shape[0]
    tc = ts - jnp.mean(ts)
    slope = jnp.sum(tc * (signal - jnp.mean(signal))) / jnp.sum(tc**2)
    detrended = signal - jnp.mean(signal) - slope * tc
    spectrum = 2.0 * jnp.abs(jnp.fft.rfft(detrended)) / n
    freqs = jnp.fft.rfftfreq(n, d=(ts[1] - ts[0]))
    return jnp.max(jnp.where(freqs >= min_frequency, spectrum, 0.0))
