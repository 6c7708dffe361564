"""The full planetary stage as a joint (docs/model.md §5): `PlanetaryJoint` with every
support and mesh of `tolerax.physics.planetary`, and `MassScaledPlanetaryJoint`, the same stage
with the inertia of its fastest coordinate families scaled up for larger explicit steps."""

from typing import ClassVar

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float

from .. import _validate as V
from ..physics import planetary as _planetary
from ..physics.stage import DESIGN_FEATURES
from .drives import AbstractServo
from .joints import AbstractJoint, JointLayout, disc_tensors, planet_spin_ratio


class _AbstractStageJoint(AbstractJoint):
    """The full planetary stage (`tolerax.physics.planetary`) as a joint: coordinates, forces and contacts."""

    design_features = DESIGN_FEATURES

    @property
    def layout(self):
        lay = self.stage.layout
        return JointLayout(lay.size, lay.sun_theta, lay.carrier_theta, lay.carrier_xy, lay.names)

    @property
    def contact_names(self):
        return self.stage.contact_names

    def planar(self, qj, t):
        centres, angles = _planetary.body_positions(self.stage, qj)
        return centres, angles, centres[1], angles[1]

    def body_inertia(self):
        n_bodies = 2 + self.stage.n_planets + (self.stage.layout.ring_theta is not None)
        return disc_tensors(self.stage, self.motor_inertia, n_bodies)

    def body_coordinates(self):
        lay = self.stage.layout

        def xy(block, k=0):  # the k-th (x, y) pair of a translation block, if it exists
            return () if block is None else (block.start + 2 * k, block.start + 2 * k + 1)

        carrier = (lay.carrier_theta, *xy(lay.carrier_xy))
        planets = tuple((*carrier, lay.planet_theta.start + n, *xy(lay.planet_xy, n)) for n in range(self.stage.n_planets))
        ring = () if lay.ring_theta is None else ((lay.ring_theta, *xy(lay.ring_xy)),)
        return ((lay.sun_theta, *xy(lay.sun_xy)), carrier, *planets, *ring, carrier)

    def steady_speeds(self, t=0.0):
        uj = super().steady_speeds(t)
        if isinstance(self.drive, AbstractServo):
            planets = self.stage.layout.planet_theta
            uj = uj.at[planets].set(planet_spin_ratio(self.stage) * self.drive.rate(t))
        return uj

    def loaded_coordinates(self, t=0.0):
        """Sun at the servo lag (`_loaded_sun`); the train rolled rigidly with it; then, turning
        forwards, each planet against its pin on the trailing side ($\\eta_n = c$, the smallest
        pin clearance) with the carrier behind by $c/r_c$, which leaves both meshes of every
        planet at zero deflection (the lumped joint's play $c(\\cos\\alpha_s+\\cos\\alpha_r)$ on
        the lever $i r_{bs} = r_c(\\cos\\alpha_s+\\cos\\alpha_r)$). Turning backwards the same
        mirrored, and the carrier and planets turned further until both back flanks touch:
        $\\Delta\\theta_c = \\min_n(b_{s,n} + b_{r,n})/(r_c(\\cos\\alpha_s+\\cos\\alpha_r))$,
        $\\Delta\\theta_n = (r_c\\cos\\alpha_s\\Delta\\theta_c - b_s)/r_{bp}$. Translations of sun
        and carrier zero; mesh deflections under load left to the polish."""
        stage, lay = self.stage, self.stage.layout
        torque, theta_s = self._loaded_sun(t)
        ahead = jnp.where(torque >= 0, 1.0, -1.0)
        theta_c = theta_s / stage.ratio
        theta_p = planet_spin_ratio(stage) * theta_c
        if stage.planet_support.kind == "clearance" and lay.planet_xy is not None:
            c = jnp.min(jnp.broadcast_to(stage.planet_support.bearing.clearance, (stage.n_planets,)))
            theta_c = theta_c - ahead * c / stage.carrier_radius
            eta = ahead * c
        else:
            eta = 0.0
        if stage.sun_mesh.kind == "nonlinear":
            n = stage.n_planets
            b_s, b_r = (jnp.broadcast_to(m.backlash, (n,)) for m in (stage.sun_mesh, stage.ring_mesh))
            kappa = jnp.cos(stage.sun_pressure_angle) + jnp.cos(stage.ring_pressure_angle)
            # The first planet whose two back flanks close carries the load (backlash per planet).
            d_c = jnp.min(b_s + b_r) / (stage.carrier_radius * kappa)
            d_p = (stage.carrier_radius * jnp.cos(stage.sun_pressure_angle) * d_c - b_s) / stage.planet_base_radius
            backwards = torque < 0
            theta_c = theta_c + jnp.where(backwards, d_c, 0.0)
            theta_p = theta_p + jnp.where(backwards, d_p, 0.0)
        qj = jnp.zeros(lay.size).at[lay.sun_theta].set(theta_s).at[lay.carrier_theta].set(theta_c)
        qj = qj.at[lay.planet_theta].set(theta_p)
        if lay.planet_xy is not None:
            qj = qj.at[lay.planet_xy.start + 1 : lay.planet_xy.stop : 2].set(eta)
        return qj

    def forces(self, qj, uj, vj, t):
        f = _planetary.stage_forces(self.stage, qj, uj, vj)
        return f.generalised + self.drive_forces(qj, uj, t), f.contact

    def impact_rate_rates(self, qj, uj, udj, vj):
        if not self.contact_names:
            return jnp.zeros(0)
        return _planetary.impact_rate_rates(self.stage, qj, uj, udj, vj)

    def initial_impact_rates(self, qj, uj):
        return _planetary.initial_impact_rates(self.stage, qj, uj)

    def potential_energy(self, qj):
        return _planetary.potential_energy(self.stage, qj)


class PlanetaryJoint(_AbstractStageJoint):
    """The full planetary stage (`tolerax.physics.planetary`) as a joint."""

    stiff_contact_modes: ClassVar[bool] = True


SCALED_FAMILIES = ("sun_translation", "planet_translation", "planet_spin", "sun_rotation", "carrier_translation")


class MassScaledPlanetaryJoint(_AbstractStageJoint):
    """The full planetary stage with selective mass scaling: its fastest modes made slower.

    Same coordinates, meshes, supports and clearance contacts as `PlanetaryJoint`; the only
    change is a constant inertia added to motion *relative* to the rigid gear train,
    `mass_scaling` $s \\ge 1$ times what the bodies concerned carry, for each family in
    `families` (static; default: the sun's and planets' translations and the planets' spin):

    $$T_{add} = \\tfrac{s-1}{2}\\Big[m_s(\\dot x_s^2 + \\dot y_s^2)
      + \\sum_n m_p(\\dot\\zeta_n^2 + \\dot\\eta_n^2)
      + \\sum_n I_p(\\dot\\theta_{p,n} - \\rho\\,\\dot\\theta_c)^2
      + (I_s + I_m)(\\dot\\theta_s - i\\,\\dot\\theta_c)^2 + (m_c + N m_p)(\\dot x_c^2 + \\dot y_c^2)\\Big],$$

    the terms being `"sun_translation"`, `"planet_translation"`, `"planet_spin"`,
    `"sun_rotation"` (the sun and motor turning against the train: $i$ the ratio) and
    `"carrier_translation"` (the carrier with its $N$ planets; not what the output carries
    downstream); $\\rho$ the planets' spin per carrier turn when rolling on the fixed ring.
    Terms whose coordinates the stage does not have (a rigid support) are absent.
    Rigid rolling ($\\dot\\theta_s = i\\dot\\theta_c$, $\\dot\\theta_{p,n} = \\rho\\dot\\theta_c$, no
    translation) carries no added inertia, so the joint's motion as a gear train, its reflected
    inertia and the output's dynamics below the scaled modes are unchanged; and every added force
    is internal (between a gear and the housing or carrier), so momentum is conserved.

    **Why.** The planetary antenna's explicit steps are held by stability, not accuracy, by the
    stage's fastest modes (the sun translating on its meshes with the planets spinning, and the
    planet pins). Scaling their inertia by $s$ lowers them by $\\sqrt s$. Making them
    quasi-static instead (the singular-perturbation limit) needs the force balance of the
    floating sun and planets solved inside every right-hand side, and it is badly posed: a sun
    or planet floating in its clearance with its teeth in backlash has no unique position
    (though the forces it transmits are unique). This is explicit dynamics' *selective mass
    scaling* (Olovsson, Simonsson & Unosson, IJNME 63 (2005) 1436): added mass that leaves
    rigid-body motion alone.

    **What it keeps.** The pointing error, tracking speed error and mean bearing loads stay
    close to the full stage's; vibration amplitude and contact-force peaks do not, so verify a
    result at full fidelity. `benchmarks/mass_scaling.py` measures the speed-up and every
    output's difference against the full stage, by scaling and tolerance; the default families
    are the relative motions of the stage's fastest modes named above.
    **`mass_scaling`**: $s \\ge 1$ (1: the full stage).
    **`families`**: which relative motions are scaled (static), from `SCALED_FAMILIES`.
    """

    mass_scaling: Float[Array, ""]
    families: tuple[str, ...] = eqx.field(static=True)

    def __init__(
        self,
        stage=None,
        drive=None,
        motor_inertia=2e-4,
        drag_torque=0.05,
        mass_scaling=10.0,
        families=("sun_translation", "planet_translation", "planet_spin"),
    ):
        super().__init__(stage, drive, motor_inertia, drag_torque)
        self.mass_scaling = V.real(type(self).__name__, "mass_scaling", mass_scaling, "-")
        self.families = tuple(families)

    def __check_init__(self):
        unknown = [f for f in self.families if f not in SCALED_FAMILIES]
        if unknown:
            raise ValueError(f"MassScaledPlanetaryJoint.families: {unknown} unknown; choose from {SCALED_FAMILIES}.")
        V.check(self, mass_scaling=V.Rule("-", low=1.0))

    def added_inertia(self):
        stage, lay = self.stage, self.stage.layout
        extra = self.mass_scaling - 1.0
        added = jnp.zeros((lay.size, lay.size))

        def translation(block, mass):
            if block is None:
                return jnp.zeros_like(added)
            width = block.stop - block.start
            return jnp.zeros_like(added).at[block, block].set(mass * jnp.eye(width))

        def against_train(rows, ratio, inertia):
            # Rotation relative to rigid rolling: d = e_row - ratio e_c, inertia d d^T.
            d = jnp.zeros((len(rows), lay.size)).at[jnp.arange(len(rows)), jnp.asarray(rows)].set(1.0)
            d = d.at[:, lay.carrier_theta].add(-ratio)
            return inertia * d.T @ d

        terms = {
            "sun_translation": lambda: translation(lay.sun_xy, stage.sun_mass),
            "planet_translation": lambda: translation(lay.planet_xy, stage.planet_mass),
            # The carrier's translation carries its planets along.
            "carrier_translation": lambda: translation(lay.carrier_xy, stage.carrier_mass + stage.n_planets * stage.planet_mass),
            "planet_spin": lambda: against_train(
                list(range(lay.planet_theta.start, lay.planet_theta.stop)), planet_spin_ratio(stage), stage.planet_inertia
            ),
            "sun_rotation": lambda: against_train([lay.sun_theta], stage.ratio, stage.sun_inertia + self.motor_inertia),
        }
        for family in self.families:
            added = added + extra * terms[family]()
        return added
