"""`start="loaded"`: the mechanism's loaded steady state against its closed form, a run from it
against a run from the unloaded `"steady"` start, and a run from rest settling to the closed
form's servo lag."""

import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax.mechanism.drives import drag


def _servo_lag(joint):
    """Output lag (rad) the servo's angle gain needs to carry the drag: T / (i^2 k_i)."""
    torque = float(drag(joint.drag_torque, joint.drive.rate(0.0)))
    return torque / (float(joint.stage.ratio) ** 2 * float(joint.drive.integral))


@pytest.mark.parametrize(
    "mode, sign, tol",
    [("azimuth", 1.0, 2e-8), ("azimuth", -1.0, 2e-8), ("dual", 1.0, 5e-7)],
)
def test_lumped_loaded_state_is_the_closed_form(mode, sign, tol):
    # Lumped joints: output lag = servo part T/(i^2 k_i) (1 mrad) + the loaded flank's gap on
    # the lever (forwards the pin play drive_gap, 4 mrad at 100 um pins; backwards back_gap,
    # play plus backlash) + the mesh windup F/K (1e-7 rad). Single axis the polish may only add
    # what the closed form leaves out: the smoothed flank's force at the 1 nm smoothing width
    # (1e-8 rad on the 0.1 m lever; measured 1.7e-11 on the free base as on a fixed one).
    # Backwards the drag and every gap change side. Dual axis the joints load each other: the
    # closed form leaves out the inertial torques of one axis turning the other (measured: the
    # sun 1.3e-7 rad off, against < 2e-8 single-axis). All on the free base: one structure (the
    # single-axis antenna holds its pitch joint by its servo), one compiled polish for the three
    # and for the runs below.
    mech = tx.antenna(mode, fidelity="lumped", rate=sign * math.radians(0.98))
    q, u, _ = mech.initial_state("loaded")
    for joint, sq, _, _ in mech.joints():
        if float(joint.drive.rate(0.0)) == 0.0:
            # A held joint carries no drag (tanh(0) = 0); whatever small inertial load the other
            # axis puts on it moves its output across its play (measured: to -4.0 mrad of the
            # 4 mrad play; none of it is in the closed form, so only the bound is tested).
            assert abs(float(q[sq][joint.layout.carrier])) <= float(joint.mesh.lost_motion) + tol
            continue
        lm = joint.mesh
        torque = float(drag(joint.drag_torque, joint.drive.rate(0.0)))
        gap = float(lm.drive_gap) if sign > 0 else -float(lm.back_gap)
        flank = (gap + torque / float(lm.lever) / float(lm.stiffness)) / float(lm.lever)
        expected = -(_servo_lag(joint) + flank)
        assert float(q[sq][joint.layout.carrier]) == pytest.approx(expected, abs=tol)
        assert float(q[sq][joint.layout.sun]) == pytest.approx(-torque / (float(joint.stage.ratio) * float(joint.drive.integral)), abs=tol)
    np.testing.assert_array_equal(np.asarray(u), np.asarray(mech.initial_state("steady")[1]))


def test_lumped_loaded_state_derivative_is_the_closed_forms():
    """The loaded start differentiated (forward mode through the polish: optimistix's implicit
    function theorem on `_loaded_equations_once`, whose own rule carries the tangents of the
    mechanism's values): the sun's and the output's loaded angles per N m of drag torque against
    the closed form's, -d/(i k_i) and -d (1/(i^2 k_i) + 1/(r^2 K)), d the drag law's torque per N m
    at the rate (linear in the torque). The closed form leaves out the smoothed flank's force
    (1e-8 rad of the 4 mrad angle: 2.5e-6 of it), so 1e-5 relative; the polish converges to its
    rounding (the same program as the closed-form test above, differentiated)."""
    import equinox as eqx

    mech = tx.antenna("azimuth", fidelity="lumped", rate=math.radians(0.98))
    joint = mech.azimuth
    sq = next(sq for j, sq, _, _ in mech.joints() if j is joint)
    lay = joint.layout

    def angles(torque):
        q, _, _ = eqx.tree_at(lambda m: m.azimuth.drag_torque, mech, torque).initial_state("loaded")
        return jnp.stack([q[sq][lay.sun], q[sq][lay.carrier]])

    torque = jnp.asarray(joint.drag_torque, dtype=float)
    # One compiled program for the tangent (eagerly, each jitted piece of the polish is traced and
    # compiled for its jvp on its own: 37 s against 31 s alone on one core).
    _, slope = jax.jit(lambda t: jax.jvp(angles, (t,), (jnp.ones_like(t),)))(torque)
    per_nm = float(drag(1.0, joint.drive.rate(0.0)))
    ratio, integral, lm = float(joint.stage.ratio), float(joint.drive.integral), joint.mesh
    expected = [-per_nm / (ratio * integral), -per_nm * (1.0 / (ratio**2 * integral) + 1.0 / (float(lm.lever) ** 2 * float(lm.stiffness)))]
    np.testing.assert_allclose(np.asarray(slope), expected, rtol=1e-5)


# Saves of the lumped runs below: one compiled solve for the three (only y0 and the duration,
# values, differ).
N_SAVE = 401


def test_lumped_run_from_loaded_state_is_quiet():
    # From "steady" (servo at zero lag) the output's speed swings by ~10 mrad/s within 0.3 s as
    # the servo builds its lag against the drag (benchmarks/results/archive/loaded_start.md); from
    # "loaded" the mechanism is already in equilibrium: speed error (X, Z) below 2 urad/s
    # (measured 0.5), pointing error constant. Same compiled program (only y0 differs).
    mech = tx.antenna("dual", fidelity="lumped")
    loaded = tx.simulate(mech, 0.3, n_save=N_SAVE, start="loaded")
    steady = tx.simulate(mech, 0.3, n_save=N_SAVE, start="steady")
    quiet = np.abs(np.asarray(loaded.tracking_speed_error)[:, [0, 2]]).max()
    swing = np.abs(np.asarray(steady.tracking_speed_error)[:, [0, 2]]).max()
    assert quiet < 2e-6
    assert swing > 5e-3
    pe = np.asarray(loaded.pointing_error)
    assert np.ptp(pe) < 1e-3 * pe.mean()


def test_lumped_joint_servo_lag_matches_closed_form():
    # Free base, azimuth at 0.98 deg/s on lumped joints, started at rest: the run reaches the
    # loaded state's closed form by itself. The PI servo acts as a PD on the motor angle, so the
    # steady lag under the drag torque T is T / (i^2 k_i) at the output (the mesh windup, T / K,
    # is 1e-7 rad), plus the drive-side lost motion the output trails the motor by: the
    # planet-pin play, drive_gap / lever (4e-3 rad at 100 um pins). The loop (w_n = 5.3 rad/s,
    # zeta = 0.27) settles in ~2 s; the output bearing keeps rattling in its clearance and stirs
    # the lag by about +-7 % of the servo part, so the lag is averaged over 2-4 s (3 %; measured
    # 0.1 % on the free base, 0.7 % on a fixed one). The output's rate at the end: within 2 %
    # of the command (measured 1.0 %: the rattle, and the base turning back).
    mech = tx.antenna("azimuth", fidelity="lumped")
    res = tx.simulate(mech, 4.0, n_save=N_SAVE)
    joint = mech.azimuth
    lm = tx.lumped_mesh(joint.stage, joint.motor_inertia)
    servo = float(joint.drag_torque / (joint.stage.ratio**2 * joint.drive.integral))
    expected = servo + float(lm.drive_gap / lm.lever)
    lag = np.asarray(res.commanded_angle[200:, 0] - res.joint_angle[200:, 0])
    assert float(lag.mean()) == pytest.approx(expected, abs=0.03 * servo)
    q, u, _ = res.states
    rate = float(u[-1, mech.layout.azimuth_u][1])
    assert rate == pytest.approx(math.radians(0.98), rel=0.02)


@pytest.mark.parametrize("sign", [1.0, -1.0])
def test_planetary_loaded_state_is_the_closed_form(sign):
    # Full stages: forwards, each planet against its pin on the trailing side (eta = c) and
    # the carrier behind the sun's rigid position by c/r_c (4 mrad), plus the servo part; the
    # sun centred (equal load sharing). What the closed form leaves out is the pins' contact
    # compliance under ~1 N (the planets sink 35 nm into their pins: 35 nm / r_c = 1.4 urad)
    # and the meshes' windup (1e-7 rad): 5 urad covers both. Backwards, mirrored, with the
    # carrier further by the smallest total backlash over r_c (cos a_s + cos a_r).
    # The azimuth joint alone at full fidelity (the pitch ideal and held): the smallest scene
    # with a driven full stage (its loaded state's program compiles in ~37 s alone, the dual's
    # in ~45 s; both joints of the dual: test_planetary_dual_loaded_state_is_the_closed_form, slow).
    _check_planetary_loaded_state(tx.antenna("azimuth", fidelity=("planetary", "ideal"), rate=sign * math.radians(0.98)), sign)


@pytest.mark.slow
def test_planetary_dual_loaded_state_is_the_closed_form():
    """Both joints of the dual antenna at full fidelity, each driven: enlarges
    `test_planetary_loaded_state_is_the_closed_form` (the azimuth joint alone)."""
    _check_planetary_loaded_state(tx.antenna("dual", fidelity="planetary", rate=math.radians(0.98)), 1.0)


def _check_planetary_loaded_state(mech, sign):
    q, _, _ = mech.initial_state("loaded")
    for joint, sq, _, _ in mech.joints():
        if not isinstance(joint, tx.PlanetaryJoint):  # the ideal joint: no stage coordinates
            continue
        stage, lay = joint.stage, joint.stage.layout
        qj = np.asarray(q[sq])
        c = float(stage.planet_support.bearing.clearance)
        play = c / float(stage.carrier_radius)
        if sign < 0:
            kappa = math.cos(float(stage.sun_pressure_angle)) + math.cos(float(stage.ring_pressure_angle))
            total = float(jnp.min(jnp.broadcast_to(stage.sun_mesh.backlash + stage.ring_mesh.backlash, (stage.n_planets,))))
            play += total / (float(stage.carrier_radius) * kappa)
        assert qj[lay.carrier_theta] == pytest.approx(-sign * abs(_servo_lag(joint)) - sign * play, abs=5e-6)
        eta = qj[lay.planet_xy][1::2]
        np.testing.assert_allclose(eta, sign * c, atol=1e-7)
        assert np.abs(qj[lay.sun_xy]).max() < 1e-6  # of its 100 um clearance (measured 1.1e-7)


def test_loaded_start_needs_constant_rate_servos():
    with pytest.raises(ValueError, match="constant-rate"):
        tx.antenna("dual", fidelity="lumped", drive="scan").initial_state("loaded")
    with pytest.raises(ValueError, match="constant-rate"):
        tx.antenna("azimuth", fidelity="ideal", drive="torque").initial_state("loaded")
    with pytest.raises(ValueError, match="integral"):
        tx.antenna("azimuth", fidelity="lumped", servo_gains=(0.2, 0.0)).initial_state("loaded")
    with pytest.raises(ValueError, match="mechanisms"):
        tx.simulate(tx.TestBench(), 0.01, start="loaded")
    with pytest.raises(ValueError, match="unknown"):
        tx.simulate(tx.antenna("azimuth", fidelity="lumped"), 0.01, start="settled")
