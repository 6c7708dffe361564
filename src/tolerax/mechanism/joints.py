"""Joint fidelities of the mechanism (docs/model.md §5): one class per fidelity.

Every joint holds the same data (a `PlanetaryStage`, a drive, the motor inertia, the output's
drag) and differs in which coordinates, forces and contacts it models:

- `IdealJoint`: rigid. Servo-driven, it follows the commanded angle exactly (prescribed
  motion, no coordinate); torque-driven, it has one coordinate, the output angle, with the gear
  train rigid (sun at $i\\theta_c$, planets rolling).
- `LumpedJoint`: the sun angle $\\theta_s$ and output angle $\\theta_c$ coupled by one
  equivalent mesh derived from the stage (`lumped_mesh`: torsional stiffness, backlash plus
  planet-pin play, damping), plus the output bearing's in-plane translation $(x_c, y_c)$ in its
  radial clearance (or spring, or rigid, per `stage.carrier_support`). Planets roll rigidly.
- `PlanetaryJoint`: the full stage of `tolerax.physics.planetary` (every support and mesh it models).

A new fidelity is a new final subclass of `AbstractJoint` implementing its abstract methods
(the mechanism never asks which fidelity a joint is), plus, for the `antenna(fidelity=...)`
shorthand, an entry in `FIDELITIES`.

Coordinates are the joint's own, in its housing frame: `qj`, speeds `uj` (the same as
$\\dot q_j$), impact-rate states `vj`, one per clearance contact.
"""

import abc
import dataclasses
from typing import ClassVar

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float
from ..physics import contact as _contact
from ..physics import gears as _gears
from ..physics import mesh as _mesh
from ..physics import planetary as _planetary
from ..physics import smooth as _smooth
from .. import _validate as V
from .drives import AbstractServo, SpeedServo, TorqueDrive, drag
from ..physics.planetary import AddedInertia
from ..physics.stage import PlanetaryStage


@dataclasses.dataclass(frozen=True)
class JointLayout:
    """Index map of a joint's coordinates (static). `None`: the coordinate does not exist."""

    size: int
    sun: int | None
    carrier: int | None
    carrier_xy: slice | None
    names: tuple[str, ...]


class AbstractJoint(eqx.Module):
    """One planetary gear joint of the mechanism (see the module docstring).

    - `stage`: the gear data (`PlanetaryStage`); every fidelity derives its values from it.
    - `drive`: a servo on the motor (`SpeedServo`: commanded output rate, rad/s, rate 0 holds
      the joint still; `ScanServo`: a back-and-forth scan) or a `TorqueDrive`.
    - `motor_inertia`: rotor inertia on the sun shaft (kg m²).
    - `drag_torque`: torque resisting the output's rotation relative to the housing (N m),
      $T\\tanh(\\omega/10^{-3})$ (harness and seal drag; it keeps the gear train loaded).
    """

    stage: PlanetaryStage
    drive: AbstractServo | TorqueDrive
    motor_inertia: Float[Array, ""]
    drag_torque: Float[Array, ""]
    # The stage's clearances and backlash this fidelity reads (see `tolerax.design.features`).
    design_features: ClassVar[tuple[str, ...]] = ()
    # Whether the fidelity carries the full stage's stiff, lightly damped mesh and bearing modes
    # (~1e5 1/s), which then hold an explicit step at its stability limit, where
    # `tolerax.solve.FAST_STAGE` is faster (`Mechanism.automatic_integrator` says so).
    stiff_contact_modes: ClassVar[bool] = False

    def __init__(self, stage=None, drive=None, motor_inertia=2e-4, drag_torque=0.05):
        self.stage = _gears.default_stage() if stage is None else stage
        self.drive = SpeedServo() if drive is None else drive
        if not isinstance(self.drive, (AbstractServo, TorqueDrive)):
            raise TypeError(f"drive must be a servo (SpeedServo, ScanServo, ProfileServo) or a TorqueDrive, got {type(self.drive).__name__}.")
        owner = type(self).__name__
        self.motor_inertia = V.real(owner, "motor_inertia", motor_inertia, "kg m^2")
        self.drag_torque = V.real(owner, "drag_torque", drag_torque, "N m")

    def __check_init__(self):
        if not isinstance(self.stage, PlanetaryStage):
            raise TypeError(f"{type(self).__name__}.stage must be a PlanetaryStage, got {type(self.stage).__name__}.")
        V.check(self, motor_inertia=V.POSITIVE("kg m^2"), drag_torque=V.NONNEGATIVE("N m"))

    # -- structure ------------------------------------------------------------------------

    @property
    @abc.abstractmethod
    def layout(self) -> JointLayout:
        """The joint's coordinates (static)."""

    @property
    def contact_names(self) -> tuple[str, ...]:
        """The clearance contacts this joint models, in the order of its impact-rate states."""
        return ()

    # -- kinematics and inertia -----------------------------------------------------------

    @abc.abstractmethod
    def planar(self, qj, t):
        """Housing-frame centres (nb, 2) and angles (nb,) of the gear bodies (sun, carrier,
        planets, then any further moving body), and the output's (carrier's) centre (2,) and
        angle."""

    @abc.abstractmethod
    def body_inertia(self):
        """Masses (nb,) and principal inertias (nb, 3) of the bodies of `planar`."""

    def body_coordinates(self) -> tuple[tuple[int, ...], ...]:
        """For each body of `planar` (the gear bodies, then the output), the indices of the
        joint's coordinates its pose depends on (static). The mechanism solves its equations of
        motion by blocks where a coordinate moves one body alone (`Mechanism.accelerations`), so
        a declared set must contain every coordinate the body moves with (a test checks each
        fidelity against the Jacobian of `planar`). Default: every coordinate, for every body
        (correct for any joint, and no blocks)."""
        every = tuple(range(self.layout.size))
        return (every,) * (int(jnp.shape(self.body_inertia()[0])[0]) + 1)

    def commanded_angle(self, t):
        """Commanded output angle (rad) of a servo; `None` for a torque drive."""
        return self.drive.angle(t) if isinstance(self.drive, AbstractServo) else None

    def output_angle(self, qj, t):
        """Output (carrier) angle (rad)."""
        lay = self.layout
        return self.commanded_angle(t) if lay.carrier is None else qj[lay.carrier]

    def runout(self, qj):
        """Radial runout of the output, $|(x_c, y_c)|$ (m); 0 without output translation."""
        xy = self.layout.carrier_xy
        return jnp.zeros(()) if xy is None else _smooth.norm(qj[xy], 0.0)

    def steady_speeds(self, t=0.0):
        """Speeds `uj` of rigid rolling at the servo's commanded rate at time `t` (zeros for a
        torque drive or a prescribed joint)."""
        lay = self.layout
        uj = jnp.zeros(lay.size)
        if lay.carrier is None or not isinstance(self.drive, AbstractServo):
            return uj
        rate = self.drive.rate(t)
        uj = uj.at[lay.carrier].set(rate)
        return uj if lay.sun is None else uj.at[lay.sun].set(self.stage.ratio * rate)

    def _loaded_sun(self, t):
        """`(T, theta_s)`: the drag torque $T$ (N m) at the commanded rate and the sun angle (rad)
        at which the servo's angle term supplies the sun torque $T/i$ that carries it,
        $\\theta_s = i\\theta^*(t) - T/(i k_i)$ (the rate term is zero at the commanded speed)."""
        i = self.stage.ratio
        torque = drag(self.drag_torque, self.drive.rate(t))
        return torque, i * self.drive.angle(t) - torque / (i * self.drive.integral)

    def loaded_coordinates(self, t=0.0):
        """Coordinates `qj` of the loaded steady state at time `t`, in closed form up to the
        meshes' and supports' elastic deflections (a first guess that `Mechanism.initial_state
        ("loaded")` polishes): a constant-rate servo lags its command by what the output drag
        needs, and the gear train's play is taken up on the loaded flanks. Zeros here (a joint
        with no coordinates, or no servo)."""
        return jnp.zeros(self.layout.size)

    # -- forces ---------------------------------------------------------------------------

    def drive_forces(self, qj, uj, t):
        """Generalised drive and drag forces on the joint's coordinates."""
        lay = self.layout
        force = jnp.zeros(lay.size)
        if lay.size == 0:
            return force
        # The drive's torque on the sun, or on the output of a rigid gear train (no sun coordinate).
        force = force.at[lay.carrier if lay.sun is None else lay.sun].add(self.motor_torque(qj, uj, t))
        return force.at[lay.carrier].add(-drag(self.drag_torque, uj[lay.carrier]))

    def motor_torque(self, qj, uj, t):
        """The torque the drive applies on its motor shaft (N m), as a test records it (the motor
        current times its torque constant): a servo's on the sun, a torque drive's through the
        ratio ($T/i$ on the sun; $T$ at the output of a joint with no sun coordinate). `None` where
        the model has no motor to read it from (an ideal joint under a servo: its motion is
        prescribed)."""
        lay = self.layout
        if isinstance(self.drive, TorqueDrive):
            torque = self.drive.torque(t)
            return torque if lay.sun is None else torque / self.stage.ratio
        if lay.sun is None:
            return None
        return self.drive.torque(self.stage.ratio, t, qj[lay.sun], uj[lay.sun])

    def forces(self, qj, uj, vj, t):
        """`(Q_j, contact forces)`: generalised forces on the joint's coordinates (N m or N) and
        the normal force of each of its clearance contacts (N, `contact_names` order)."""
        return self.drive_forces(qj, uj, t), jnp.zeros(0)

    def impact_rate_rates(self, qj, uj, udj, vj):
        """Time derivatives of the impact-rate states (m/s², see `tolerax.physics.contact`)."""
        return jnp.zeros(0)

    def initial_impact_rates(self, qj, uj):
        """Consistent impact-rate states: each contact's current penetration rate (m/s)."""
        return jnp.zeros(0)

    def potential_energy(self, qj):
        """Elastic energy (J) of a conservative joint; raises where the smoothed forces have no
        closed-form potential."""
        return jnp.zeros(())

    def added_inertia(self) -> Array | None:
        """A constant, symmetric positive semi-definite inertia (nj, nj) on the joint's own
        speeds, added to the mass matrix beyond what its bodies carry; `None` (the default):
        none. Kinetic energy $\\tfrac12 u_j^\\top A u_j$. It must only act on motion *relative*
        to the housing (as every joint coordinate is), so that the inertial forces it adds are
        internal: the physical bodies' momentum is still conserved."""
        return None


def planet_spin_ratio(stage):
    """Planet spin per carrier turn when the planets roll on the fixed ring without deflection."""
    return -stage.carrier_radius * jnp.cos(stage.ring_pressure_angle) / stage.planet_base_radius


class _AbstractRigidTrainJoint(AbstractJoint):
    """Shared kinematics of the fidelities whose planets roll rigidly on the fixed ring."""

    def planar(self, qj, t):
        stage, lay = self.stage, self.layout
        theta_c = self.output_angle(qj, t)
        theta_s = stage.ratio * theta_c if lay.sun is None else qj[lay.sun]
        p_c = jnp.zeros(2) if lay.carrier_xy is None else qj[lay.carrier_xy]
        psi = stage.planet_angles + theta_c
        planets = p_c + stage.carrier_radius * jnp.stack([jnp.cos(psi), jnp.sin(psi)], axis=-1)
        theta_p = jnp.broadcast_to(planet_spin_ratio(stage) * theta_c, psi.shape)
        centres = jnp.concatenate([jnp.zeros((1, 2)), p_c[None], planets])
        angles = jnp.concatenate([jnp.stack([theta_s, theta_c]), theta_p])
        return centres, angles, p_c, theta_c

    def body_inertia(self):
        # The ring, if spring-mounted in the stage data, is fixed in these fidelities.
        return disc_tensors(self.stage, self.motor_inertia, 2 + self.stage.n_planets)

    def body_coordinates(self):
        lay = self.layout
        carrier = () if lay.carrier is None else (lay.carrier,)
        carried = carrier + (() if lay.carrier_xy is None else tuple(range(lay.carrier_xy.start, lay.carrier_xy.stop)))
        sun = carrier if lay.sun is None else (lay.sun,)
        # sun, carrier, the planets (rolling with the carrier), the output (the carrier)
        return (sun, carried) + (carried,) * self.stage.n_planets + (carried,)


def disc_tensors(stage, motor_inertia, n_bodies):
    masses, inertias = _planetary.body_inertia(stage, AddedInertia(sun_inertia=motor_inertia))
    masses, inertias = masses[:n_bodies], inertias[:n_bodies]
    # Thin discs: transverse inertia half the polar inertia.
    return masses, jnp.stack([0.5 * inertias, 0.5 * inertias, inertias], axis=-1)


class IdealJoint(_AbstractRigidTrainJoint):
    """A rigid joint (see the module docstring)."""

    @property
    def layout(self):
        if isinstance(self.drive, TorqueDrive):
            return JointLayout(1, None, 0, None, ("theta_c",))
        return JointLayout(0, None, None, None, ())


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


class LumpedJoint(_AbstractRigidTrainJoint):
    """Sun and output coupled by one equivalent mesh, plus the output bearing (see the module
    docstring and `LumpedMesh`)."""

    design_features = ("carrier_clearance", "planet_clearance", "sun_backlash", "ring_backlash")

    @property
    def layout(self):
        if self.stage.carrier_support.translates:
            return JointLayout(4, 0, 1, slice(2, 4), ("theta_s", "theta_c", "x_c", "y_c"))
        return JointLayout(2, 0, 1, None, ("theta_s", "theta_c"))

    @property
    def contact_names(self):
        return ("carrier",) if self.stage.carrier_support.kind == "clearance" else ()

    @property
    def mesh(self) -> LumpedMesh:
        return lumped_mesh(self.stage, self.motor_inertia)

    def _deflection(self, lm, qj):
        lay = self.layout
        return lm.lever * (qj[lay.sun] / self.stage.ratio - qj[lay.carrier])

    def loaded_coordinates(self, t=0.0):
        """Sun at the servo lag (`_loaded_sun`), output behind the sun's rigid position by the
        equivalent mesh's gap on the loaded flank plus its deflection: $g = $ `drive_gap`
        $+ F/K$ (or $-$`back_gap`$ + F/K$ turning backwards), $F = T/r$; output bearing centred."""
        lay = self.layout
        torque, theta_s = self._loaded_sun(t)
        lm = self.mesh
        force = torque / lm.lever
        g = jnp.where(torque >= 0, lm.drive_gap, -lm.back_gap) + force / lm.stiffness
        theta_c = theta_s / self.stage.ratio - g / lm.lever
        return jnp.zeros(lay.size).at[lay.sun].set(theta_s).at[lay.carrier].set(theta_c)

    def _bearing(self):
        return jax.tree.map(lambda x: x[None], self.stage.carrier_support.bearing)

    def _contact_state(self, qj, uj):
        sl = self.layout.carrier_xy
        return _contact.contact_kinematics(self._bearing(), qj[sl][None], uj[sl][None], self.stage.smoothing_width)

    def forces(self, qj, uj, vj, t):
        lay, stage = self.layout, self.stage
        force = self.drive_forces(qj, uj, t)
        lm = self.mesh
        g, gd = self._deflection(lm, qj), self._deflection(lm, uj)
        if lm.nonlinear:
            f_drive, f_back = _mesh.flank_forces(
                g - lm.drive_gap, gd, g + lm.back_gap, gd, lm.stiffness, lm.damping, stage.smoothing_width
            )
            tooth = f_drive + f_back
        else:
            tooth = lm.stiffness * g + lm.damping * gd
        # Q = -F dg/dq: dg/dtheta_s = r/i, dg/dtheta_c = -r.
        force = force.at[lay.sun].add(-tooth * lm.lever / stage.ratio).at[lay.carrier].add(tooth * lm.lever)
        contact = jnp.zeros(0)
        support = stage.carrier_support
        if support.kind == "spring":
            e, ed = qj[lay.carrier_xy], uj[lay.carrier_xy]
            force = force.at[lay.carrier_xy].add(-support.stiffness * e - support.damping * ed)
        elif support.kind == "clearance":
            state = self._contact_state(qj, uj)
            contact = _contact.normal_force(
                stage.contact_law, self._bearing(), state, vj, stage.smoothing_width, stage.impact_rate_floor
            )
            force = force.at[lay.carrier_xy].add(-contact[0] * state.normal[0])
        return force, contact

    def impact_rate_rates(self, qj, uj, udj, vj):
        if not self.contact_names:
            return jnp.zeros(0)
        sl, width = self.layout.carrier_xy, self.stage.smoothing_width
        rate_dot = _contact.rate_derivative(self._bearing(), qj[sl][None], uj[sl][None], udj[sl][None], width)
        return _contact.impact_rate_derivative(
            self._contact_state(qj, uj), rate_dot, vj, width, self.stage.impact_memory_time
        )

    def initial_impact_rates(self, qj, uj):
        return self._contact_state(qj, uj).rate if self.contact_names else jnp.zeros(0)

    def potential_energy(self, qj):
        lm = self.mesh
        if lm.nonlinear:
            raise ValueError("potential_energy needs linear meshes and no pin clearance (the smoothed dead zone has none).")
        energy = 0.5 * lm.stiffness * self._deflection(lm, qj) ** 2
        support, lay = self.stage.carrier_support, self.layout
        if support.kind == "spring":
            energy += 0.5 * support.stiffness * jnp.sum(qj[lay.carrier_xy] ** 2)
        elif support.kind == "clearance":
            penetration = self._contact_state(qj, jnp.zeros_like(qj)).penetration
            energy += jnp.sum(self.stage.contact_law.potential(self._bearing(), penetration))
        return energy
