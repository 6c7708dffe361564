"""Joint fidelities as classes: a new fidelity is one subclass of `AbstractJoint`.

The toy fidelity below (`TorsionSpringJoint`, ~30 lines) couples motor and output by one linear
torsional spring and holds the output bearing rigid. It is written from the physics alone, not
from `LumpedJoint`'s code; with the lumped joint's stiffness and damping and a stage whose
meshes are linear and whose supports are rigid, the two must give the same motion (the lumped
joint then *is* a linear torsional spring): an independent check of `LumpedJoint` and a
demonstration that the mechanism never asks which fidelity a joint is. Then the fidelity
registry, and the mass-scaled joint's added inertia against closed forms (its momentum and energy
invariants are in `tests/test_mechanism.py` with the other fidelities').
"""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from _kane_reference import twisted_scan_state
from tolerax.mechanism.joints import JointLayout


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


@eqx.filter_jit
def _field(mech, t, y):
    return mech.vector_field(t, y, None)


def _toy_and_lumped():
    stage = tx.default_stage(mesh="linear", sun_support="rigid", carrier_support="rigid", planet_support="rigid")
    drive = tx.ScanServo(math.radians(0.2), 0.5)  # reverses twice in 0.5 s
    return {
        name: tx.Mechanism(cls(stage, drive), tx.IdealJoint(stage, tx.SpeedServo(0.0)), base="fixed")
        for name, cls in (("toy", TorsionSpringJoint), ("lumped", tx.LumpedJoint))
    }


def test_a_fourth_fidelity_is_one_class_and_matches_the_lumped_joint():
    # The same equations written twice: equal vector fields to rounding at random states (the
    # motor and output anywhere, twisted against each other by up to 1 mrad, speeds of order
    # 1 rad/s, times across the scan's reversals). The run: the slow
    # `test_a_fourth_fidelity_run_matches_the_lumped_joint`, and `tests/test_extending.py`'s
    # recipe joint against the lumped one over a scan.
    mechs = _toy_and_lumped()
    lay, i = mechs["lumped"].layout, float(mechs["lumped"].azimuth.stage.ratio)
    assert mechs["toy"].layout == lay
    for k, t in enumerate((0.0, 0.13, 0.41)):
        y = twisted_scan_state(lay, i, jax.random.key(k))
        got, want = (_field(mechs[name], jnp.asarray(t), y) for name in ("toy", "lumped"))
        assert float(jnp.abs(want[1]).max()) > 1.0  # the mesh torque accelerates the gears
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * float(jnp.abs(b).max(initial=0.0)))


@pytest.mark.slow
def test_a_fourth_fidelity_run_matches_the_lumped_joint():
    """Enlarges `test_a_fourth_fidelity_is_one_class_and_matches_the_lumped_joint` (the vector
    field at random states) to a scan that reverses twice."""
    tight = tx.Integrator(rtol=1e-10, atol=1e-13)
    runs = {name: tx.simulate(mech, 0.5, n_save=101, integrator=tight) for name, mech in _toy_and_lumped().items()}
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
    mech = tx.antenna("dual", fidelity=("planetary-scaled", "lumped"), mass_scaling=100.0)
    assert float(mech.azimuth.mass_scaling) == 100.0 and type(mech.pitch) is tx.LumpedJoint
    with pytest.raises(ValueError, match="needs a 'planetary-scaled' joint"):
        tx.antenna("dual", fidelity="planetary", mass_scaling=100.0)
    with pytest.raises(ValueError, match="mass_scaling"):
        tx.antenna("dual", fidelity="planetary-scaled", mass_scaling=0.5)


@eqx.filter_jit
def _mass_terms(mech, t, y, us):
    """The kinetic energy at (q, u) for each row u of `us`, the mass matrix at q and the vector
    field at `y` (q from `y`): one program per joint class."""
    q = y[0]
    energy = jax.vmap(lambda u_: mech.kinetic_energy(q, u_, t))(us)
    return energy, mech.dynamics(q, y[1], t)[0], mech.vector_field(t, y, None)


def test_mass_scaling_adds_inertia_only_to_relative_motion():
    # Closed forms of `MassScaledPlanetaryJoint`'s added inertia (every family), through the
    # whole mechanism's mass matrix and kinetic energy: (1) rigid rolling at the servo's rate
    # carries none (the kinetic energy of the steady state equals the full planetary joint's);
    # (2) a unit speed of one coordinate against the rigid train (sun or carrier translation at
    # 1 m/s; a planet or the sun spinning at 1 rad/s with the carrier still) adds (s-1)/2 times
    # the scaled bodies' own mass or inertia (the motor's included for the sun, the planets' for
    # the carrier) to the full joint's kinetic energy, and s/2 times it where only those bodies
    # move (the carrier's translation also moves everything the output carries); (3) s = 1
    # gives the planetary joint's vector field to rounding; (4) bad input is refused.
    from tolerax.mechanism.stage_joints import SCALED_FAMILIES

    s = 37.0
    full = tx.antenna("dual", fidelity="planetary")
    scaled = tx.Mechanism(
        *(
            tx.MassScaledPlanetaryJoint(j.stage, j.drive, j.motor_inertia, j.drag_torque, mass_scaling=s, families=SCALED_FAMILIES)
            for j in (full.azimuth, full.pitch)
        ),
        base=full.base,
    )
    q, u, v = scaled.initial_state("steady")
    t = jnp.asarray(0.0)
    assert float(jnp.abs(u).max()) > 0.0
    joint, lay = scaled.azimuth, scaled.layout
    stage, jl = joint.stage, joint.stage.layout
    cases = (
        (jl.sun_xy.start, stage.sun_mass),
        (jl.carrier_xy.start, stage.carrier_mass + stage.n_planets * stage.planet_mass),  # planets ride along
        (jl.planet_xy.start, stage.planet_mass),
        (jl.planet_theta.start, stage.planet_inertia),
        (jl.sun_theta, stage.sun_inertia + joint.motor_inertia),
    )
    # The speeds: the steady state's, a unit speed of each coordinate above, and the steady
    # state's with the azimuth sun moving sideways at 1 mm/s (for the vector fields).
    y = (q, u.at[lay.azimuth_u.start + jl.sun_xy.start].add(1e-3), v)
    us = jnp.stack([u] + [jnp.zeros(lay.size_u).at[lay.azimuth_u.start + index].set(1.0) for index, _ in cases] + [y[1]])
    energy_s, mass, _ = _mass_terms(scaled, t, y, us)
    energy_f, _, want = _mass_terms(full, t, y, us)
    np.testing.assert_allclose(float(energy_s[0]), float(energy_f[0]), rtol=1e-14)
    for k, (index, inertia) in enumerate(cases, start=1):
        du = us[k]
        own = float(energy_f[k])
        want_k = own + 0.5 * (s - 1.0) * float(inertia)
        np.testing.assert_allclose(float(energy_s[k]), want_k, rtol=1e-12)
        np.testing.assert_allclose(0.5 * float(du @ mass @ du), want_k, rtol=1e-12)
        if index != jl.carrier_xy.start:
            np.testing.assert_allclose(own, 0.5 * float(inertia), rtol=1e-12)
    unscaled = eqx.tree_at(lambda m: (m.azimuth.mass_scaling, m.pitch.mass_scaling), scaled, (jnp.asarray(1.0), jnp.asarray(1.0)))
    got = _mass_terms(unscaled, t, y, us)[2]  # the scaled joint's program: the scaling is a value
    for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * float(jnp.abs(b).max(initial=0.0)))
    for bad in (0.5, float("nan")):
        with pytest.raises(ValueError, match="mass_scaling"):
            tx.MassScaledPlanetaryJoint(mass_scaling=bad)
    with pytest.raises(ValueError, match="families"):
        tx.MassScaledPlanetaryJoint(families=("ring_translation",))


def _joints_for_the_pattern():
    from _kane_reference import spring_ring_stage

    stages = {
        "clearances": tx.default_stage(),
        "rigid supports": tx.default_stage(sun_support="rigid", carrier_support="rigid", planet_support="rigid"),
        "springs": tx.default_stage(sun_support="spring", carrier_support="spring", planet_support="spring"),
        "spring ring": spring_ring_stage(),
    }
    joints = {f"planetary, {name}": tx.PlanetaryJoint(stage) for name, stage in stages.items()}
    joints["mass-scaled"] = tx.MassScaledPlanetaryJoint()
    joints["lumped"] = tx.LumpedJoint()
    joints["lumped, rigid output bearing"] = tx.LumpedJoint(stages["rigid supports"])
    joints["ideal, torque drive"] = tx.IdealJoint(drive=tx.TorqueDrive(1.0))
    joints["ideal, servo"] = tx.IdealJoint()
    joints["custom (the default: every coordinate)"] = TorsionSpringJoint()
    return joints


@pytest.mark.parametrize("name", list(_joints_for_the_pattern()))
def test_body_coordinates_are_what_moves_each_body(name):
    # Independent: forward-mode derivatives of the joint's planar poses at a random state. The
    # mechanism's block solve needs every coordinate that moves a body in its declared set (a
    # missing one would drop mass-matrix terms); a declared coordinate that moves nothing only
    # wastes work, so the fidelities' declarations must be exact (the default, every
    # coordinate for every body, is a superset by construction).
    joint = _joints_for_the_pattern()[name]
    size = joint.layout.size
    qj = jax.random.uniform(jax.random.key(3), (size,), minval=-1.0, maxval=1.0) * jnp.where(
        jnp.asarray([n.startswith("theta") for n in joint.layout.names], bool), 3.0, 1e-4
    ) if size else jnp.zeros(0)

    def poses(q):
        centres, angles, out_c, out_a = joint.planar(q, jnp.asarray(0.37))
        return jnp.concatenate([centres, out_c[None]]), jnp.concatenate([angles, jnp.reshape(out_a, (1,))])

    jc, ja = (np.asarray(x) for x in jax.jacfwd(poses)(qj))
    declared = joint.body_coordinates()
    assert len(declared) == jc.shape[0] == int(joint.body_inertia()[0].shape[0]) + 1
    for b, cols in enumerate(declared):
        moves = set(np.flatnonzero((np.abs(jc[b]).max(axis=0) > 0) | (np.abs(ja[b]) > 0)).tolist())
        assert moves <= set(cols), (b, sorted(moves), cols)
        if not name.startswith("custom"):
            assert moves == set(cols), (b, sorted(moves), cols)


def test_block_solve_is_used_where_speeds_are_a_body_s_own():
    # The full stage eliminates each sun's and planet's spin and translations (3 each); the
    # lumped joint the sun's angle; a joint with added inertia (mass scaling) is solved whole.
    blocks = tx.antenna("dual", fidelity="planetary").kane_blocks()
    assert blocks is not None and blocks.own.shape == (8, 3) and blocks.shared.size == 12
    assert tx.antenna("dual", fidelity="lumped").kane_blocks().own.shape == (2, 1)
    assert tx.antenna("dual", fidelity="planetary-scaled").kane_blocks() is None
    assert tx.Mechanism(mass_solve="whole").kane_blocks() is None
    with pytest.raises(ValueError, match="mass_solve='dense' is unknown"):
        tx.Mechanism(mass_solve="dense")
