"""Joint fidelities as classes: a new fidelity is one subclass of `AbstractJoint`.

The toy fidelity below (`TorsionSpringJoint`, ~30 lines) couples motor and output by one linear
torsional spring and holds the output bearing rigid. It is written from the physics alone, not
from `LumpedJoint`'s code; with the lumped joint's stiffness and damping and a stage whose
meshes are linear and whose supports are rigid, the two must give the same motion (the lumped
joint then *is* a linear torsional spring): an independent check of `LumpedJoint` and a
demonstration that the mechanism never asks which fidelity a joint is.
"""

import math

import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax._joint import JointLayout


class TorsionSpringJoint(tx.AbstractJoint):
    """Motor (sun) and output coupled by a torsional spring-damper on the output side:
    torque $k_\\theta(\\theta_s/i - \\theta_c) + c_\\theta(\\dot\\theta_s/i - \\dot\\theta_c)$;
    planets roll rigidly, output bearing rigid."""

    @property
    def layout(self):
        return JointLayout(2, 0, 1, None, ("theta_s", "theta_c"))

    def planar(self, qj, t):
        stage = self.stage
        theta_s, theta_c = qj[0], qj[1]
        psi = stage.planet_angles + theta_c
        planets = stage.carrier_radius * jnp.stack([jnp.cos(psi), jnp.sin(psi)], axis=-1)
        spin = -stage.carrier_radius * jnp.cos(stage.ring_pressure_angle) / stage.planet_base_radius
        centres = jnp.concatenate([jnp.zeros((2, 2)), planets])
        angles = jnp.concatenate([jnp.stack([theta_s, theta_c]), spin * theta_c * jnp.ones_like(psi)])
        return centres, angles, jnp.zeros(2), theta_c

    def body_inertia(self):
        masses, polar = tx.planetary.body_inertia(self.stage, tx.AddedInertia(sun_inertia=self.motor_inertia))
        return masses, jnp.stack([0.5 * polar, 0.5 * polar, polar], axis=-1)

    def forces(self, qj, uj, vj, t):
        lm = tx.lumped_mesh(self.stage, self.motor_inertia)
        k, c, i = lm.stiffness * lm.lever**2, lm.damping * lm.lever**2, self.stage.ratio
        torque = k * (qj[0] / i - qj[1]) + c * (uj[0] / i - uj[1])
        return self.drive_forces(qj, uj, t) + jnp.stack([-torque / i, torque]), jnp.zeros(0)


def test_a_fourth_fidelity_is_one_class_and_matches_the_lumped_joint():
    stage = tx.default_stage(mesh="linear", sun_support="rigid", carrier_support="rigid", planet_support="rigid")
    drive = tx.ScanServo(math.radians(0.2), 0.5)  # reverses twice in the run
    runs = {}
    for name, cls in (("toy", TorsionSpringJoint), ("lumped", tx.LumpedJoint)):
        mech = tx.Mechanism(cls(stage, drive), tx.IdealJoint(stage, tx.SpeedServo(0.0)), base="fixed")
        runs[name] = tx.simulate(mech, 0.5, n_save=101, rtol=1e-10, atol=1e-13)
    toy, lumped = runs["toy"], runs["lumped"]
    assert toy.success and lumped.success
    # The scan moved the joint (the ~1 Hz servo lags the 2 Hz scan: more than a quarter of the
    # commanded 0.4 deg swing) and the compliance shows in the pointing error.
    assert np.ptp(np.asarray(lumped.joint_angle[:, 0])) > math.radians(0.1)
    assert float(jnp.max(lumped.pointing_error)) > 1e-7
    for field in ("joint_angle", "pointing_error", "tracking_speed_error", "position_error"):
        a, b = np.asarray(getattr(toy, field)), np.asarray(getattr(lumped, field))
        # Same equations written twice; the step sequences may differ by rounding: tolerance of
        # the integrator (rtol 1e-10) on the signal's scale.
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-8 * max(np.abs(b).max(), 1e-12), err_msg=field)


def test_fidelity_registry_names_the_classes():
    assert tx.FIDELITIES == {
        "ideal": tx.IdealJoint,
        "lumped": tx.LumpedJoint,
        "planetary": tx.PlanetaryJoint,
        "planetary-scaled": tx.MassScaledPlanetaryJoint,
    }
    mech = tx.antenna("dual", fidelity=("lumped", "planetary"))
    assert type(mech.azimuth) is tx.LumpedJoint and type(mech.pitch) is tx.PlanetaryJoint
    mech = tx.antenna("dual", fidelity="planetary-scaled")
    assert type(mech.pitch) is tx.MassScaledPlanetaryJoint and float(mech.pitch.mass_scaling) == 10.0
