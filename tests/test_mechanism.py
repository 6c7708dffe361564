"""The dual-axis mechanism: invariants of the free-floating base, energy, ideal kinematics
against closed forms, and the lumped joint against the stage it is derived from."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax import contact as C, planetary as P
from tolerax.physics import modes as _modes
from tolerax.physics.rigid import small_einsum, small_matmul, world_inertia


def _momentum_scale(mech, res):
    """Largest sum over bodies of |m v| and |p x m v| + |I w| during the run: the size of the
    momenta that must cancel, against which drift is measured."""
    q, u, _ = res.states
    masses, principal = mech.body_inertia()

    def sizes(q_, u_, t_):
        pos, rot = mech.poses(q_, t_)
        v, w = mech.twists(q_, u_, t_)
        lin = masses[:, None] * v
        inertia = world_inertia(rot, principal)
        ang = jnp.cross(pos, lin) + jnp.einsum("bij,bj->bi", inertia, w)
        return jnp.sum(jnp.linalg.norm(lin, axis=1)), jnp.sum(jnp.linalg.norm(ang, axis=1))

    lin, ang = jax.vmap(sizes)(q, u, res.ts)
    return float(lin.max()), float(ang.max())


def _conservative_stage(clearance, planet_support="clearance"):
    return tx.default_stage(
        mesh="linear",
        planet_support=planet_support,
        mesh_damping_ratio=0.0,
        contact_law=C.Flores(1.0),  # restitution 1: no contact damping; Hertz potential
        sun_clearance=clearance,
        carrier_clearance=clearance,
        planet_clearance=clearance,
    )


def _free_mechanism(fidelity, rate=math.radians(30.0), gains=(0.2, 2.0), drag_torque=0.05):
    """Both joints of `fidelity` on a free base, on the conservative stage (linear meshes, no
    damping, restitution-1 Hertz contacts in 2 um clearances; the lumped joint on rigid planet
    pins: its pin play is a smoothed dead zone, whose softplus ramp has no closed-form
    potential), servo-driven at `rate` with `gains` (k_p, k_i) against `drag_torque`. Every
    number is a value, so every call for one fidelity is one structure: the vector-field tests
    below share one compiled program per fidelity. With zero gains and no drag nothing acts but
    the conservative stage: T + V is conserved (a prescribed ideal joint is not: its servo
    moves it whatever the load)."""
    stage = _conservative_stage(2e-6, "clearance" if fidelity.startswith("planetary") else "rigid")
    joint = lambda: tx.FIDELITIES[fidelity](stage, tx.SpeedServo(rate, *gains), drag_torque=drag_torque)  # noqa: E731
    return tx.Mechanism(joint(), joint(), base="free")


def _mixed_fixed_mechanism():
    """A fixed base under unlike joints (each evaluated on its own, not as a batch of two): the
    azimuth joint a full stage whose sun is rigid (its block in the block solve its spin alone:
    width 1), whose planets float on their pins (spin and translation: width 3) and whose ring
    sits on springs (a body of its own, width 3); the pitch joint lumped. The blocks' padding,
    their unequal widths and the fixed base meet the LU solve of the whole M."""
    from _kane_reference import spring_ring_stage

    return tx.Mechanism(tx.PlanetaryJoint(spring_ring_stage(sun_support="rigid")), tx.LumpedJoint(), base="fixed")


def _kane_mechanism(fidelity, base):
    if base == "free":
        return _free_mechanism(fidelity)
    if fidelity == "ideal":
        # Ideal joints with a torque drive on a fixed base: the chain with one coordinate per joint.
        return tx.antenna("dual", fidelity="ideal", base="fixed", drive="torque")
    return _mixed_fixed_mechanism()


@eqx.filter_jit
def _at_state(mech, t, y):
    """At one state, what the vector-field tests below check: the tested formulation
    (`dynamics`, `vector_field`: frames propagated by hand, block solve), the reference
    (`_kane_reference`: autodiff of the poses, LU solve), and along the tested vector field, by
    autodiff of the poses, each body's momentum rates and the rates of kinetic and potential
    energy (`None` for joints whose smoothed forces have no potential). One program per
    mechanism structure, shared by the tests of this module."""
    from _kane_reference import kane_by_autodiff, momentum_rates, vector_field_by_autodiff

    q, u, v = y
    field = mech.vector_field(t, y, None)
    qd, ud, _ = field
    kinetic = jax.jvp(mech.kinetic_energy, (q, u, t), (qd, ud, jnp.ones_like(t)))[1]
    try:
        potential = jax.jvp(mech.potential_energy, (q,), (qd,))
    except ValueError:  # raised while tracing: no closed-form potential
        potential = None
    return dict(
        new=(mech.dynamics(q, u, t), field),
        ref=(kane_by_autodiff(mech, q, u, t), vector_field_by_autodiff(mech, t, y)),
        momentum=momentum_rates(mech, q, u, ud, t),
        kinetic_rate=kinetic,
        potential=potential,
    )


KANE_CASES = [("free", "ideal"), ("free", "lumped"), ("free", "planetary"), ("free", "planetary-scaled"), ("fixed", "ideal"),
              ("fixed", "mixed")]


@pytest.mark.parametrize("base, fidelity", KANE_CASES)
def test_kane_by_frames_equals_autodiff_reference(fidelity, base):
    # Independent: `kane_by_autodiff` differentiates the poses (jacfwd over all speeds, jvp over
    # q and t); `Mechanism.dynamics` propagates Jacobians and accelerations down the chain by
    # hand. Equal to rounding (1e-12 of each quantity's scale) at random states, the whole
    # vector field included (block solve against LU on the same equations), and at the steady
    # start (meshes engaged, everything turning at its rate). Every fidelity on the free base
    # (the mass-scaled joint's added inertia included); on the fixed base ideal joints with a
    # torque drive (one coordinate per joint) and unlike joints with blocks of unequal width
    # (`_mixed_fixed_mechanism`).
    mech = _kane_mechanism(fidelity, base)
    # At the steady start the accelerations are ~1e-10 of the random states' (no contact
    # pressed), while M (a 2400 kg m^2 base beside gears of 1e-6 kg m^2) is as ill-conditioned:
    # the two solves' rounding is then a larger part of them (measured 1.2e-12 lumped), 1e-10.
    states = [(t, _random_state(mech, jax.random.key(k)), 1e-12) for k, t in enumerate((0.0, 0.37, 1.91))]
    states.append((0.0, mech.initial_state("steady"), 1e-10))
    for t, y, tol in states:
        out = _at_state(mech, jnp.asarray(t), y)
        (mass, bias), (_, ud, _) = out["ref"]
        # (A torque-driven joint has no steady speed: its steady start is rest.)
        if tol == 1e-12 or float(jnp.abs(y[1]).max()) > 0.0:
            assert float(jnp.abs(mass).max()) > 0.0 and float(jnp.abs(bias).max()) > 0.0
            assert float(jnp.abs(ud).max()) > 0.0
        for a, b in zip(jax.tree.leaves(out["new"]), jax.tree.leaves(out["ref"])):
            # Scale 0 (impact rates of contacts out of touch): exactly equal.
            scale = float(jnp.abs(b).max(initial=0.0))
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=tol * scale)


def test_block_solve_with_blocks_of_unequal_width_equals_reference():
    # The block solve pads each eliminated body's own speeds to one width: in
    # `_mixed_fixed_mechanism` the azimuth sun's block is its spin alone (width 1), its planets'
    # spin and translation (width 3), the ring on springs a body of its own; the pitch joint
    # lumped (its sun's angle). The padding's unit diagonal and the unequal blocks meet the LU
    # solve of the whole M (`test_kane_by_frames_equals_autodiff_reference[fixed-mixed]`
    # compares the rest of the equations at more states, with the same compiled program).
    mech = _mixed_fixed_mechanism()
    blocks = mech.kane_blocks()
    assert (blocks.own == mech.layout.size_u).any()  # padded
    assert {int(np.sum(row < mech.layout.size_u)) for row in blocks.own} == {1, 3}  # unequal widths
    lay = mech.azimuth.stage.layout
    assert lay.ring_xy is not None and lay.sun_xy is None  # the ring a body, the sun rigid
    for k, t in enumerate((0.0, 0.37)):
        out = _at_state(mech, jnp.asarray(t), _random_state(mech, jax.random.key(10 + k)))
        for a, b in zip(jax.tree.leaves(out["new"][1]), jax.tree.leaves(out["ref"][1])):
            scale = float(jnp.abs(b).max(initial=0.0))
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * scale)


@pytest.mark.parametrize("fidelity", ["ideal", "lumped", "planetary", "planetary-scaled"])
def test_free_base_conserves_momentum(fidelity):
    # Servo drive at 30 deg/s against the output drag, free base: every force is internal (servo
    # and drag between housing and motor or output, meshes and contacts between gears), so the
    # rates of the bodies' linear and angular momentum, by autodiff of the poses along the
    # tested vector field, sum to zero at any state: to rounding (1e-12) of the largest body's
    # terms, at random states with every contact closed. For the mass-scaled joint this checks
    # that its added inertia acts only on relative motion: the momentum is the physical bodies'
    # alone. (The same over a run: `test_conservative_planetary_run_keeps_energy_and_momentum`,
    # and per fidelity in the slow `test_free_base_conserves_momentum_over_a_run`.)
    mech = _free_mechanism(fidelity)
    for k, t in enumerate((0.0, 0.37, 1.91)):
        lin, ang = _at_state(mech, jnp.asarray(t), _random_state(mech, jax.random.key(20 + k)))["momentum"]
        for rates in (lin, ang):
            scale = float(jnp.max(jnp.linalg.norm(rates, axis=1)))
            assert scale > 1.0  # the bodies are pushed hard (N, N m)
            assert float(jnp.linalg.norm(jnp.sum(rates, axis=0))) < 1e-12 * scale


@pytest.mark.parametrize("fidelity", ["lumped", "planetary", "planetary-scaled"])
def test_energy_conserved_without_damping(fidelity):
    # Damping off (meshes, contacts: restitution 1), drives and drag off, free base: the rate of
    # kinetic energy (autodiff of `kinetic_energy` along the tested vector field, the mass-scaled
    # joint's added inertia included) is minus the rate of elastic energy (`potential_energy`)
    # at any state: to rounding (1e-10 of either; measured <= 7e-13) at random states near
    # rigid rolling (`_rolling_state`: the 2 um clearances partly closed, meshes deflected by
    # up to a um, so that the elastic power does not drown the inertial terms), everything
    # moving. This checks the velocity terms against the kinetic energy and the forces against
    # the potential. (The same over a run:
    # `test_conservative_planetary_run_keeps_energy_and_momentum`, and per fidelity in the slow
    # `test_energy_conserved_over_a_run`.)
    mech = _free_mechanism(fidelity, gains=(0.0, 0.0), drag_torque=0.0)
    for k, t in enumerate((0.0, 0.37, 1.91)):
        out = _at_state(mech, jnp.asarray(t), _rolling_state(mech, jax.random.key(30 + k)))
        potential, potential_rate = (float(x) for x in out["potential"])
        kinetic_rate = float(out["kinetic_rate"])
        assert potential > 0.0 and abs(kinetic_rate) > 0.0  # contacts and meshes loaded, energy exchanged
        assert abs(kinetic_rate + potential_rate) < 1e-10 * abs(potential_rate)


def test_conservative_planetary_run_keeps_energy_and_momentum():
    # The run behind the two tests above, on the full stage: damping, drives and drag off, free
    # base; the joints are kicked so that the 2 um clearances close within the run. The drift of
    # kinetic plus elastic energy and of the momenta must follow the integrator tolerance
    # (rtol 1e-10) through the impacts: energy to 1e-7 of the kick's, momenta to 1e-9 of the
    # largest sum of the bodies' momenta (`_momentum_scale`).
    mech = _free_mechanism("planetary", gains=(0.0, 0.0), drag_torque=0.0)
    res = tx.simulate(mech, 0.004, n_save=41, y0=_kicked_state(mech), integrator=tx.Integrator(rtol=1e-10, atol=1e-13))
    pot = jax.vmap(mech.potential_energy)(res.states[0])
    total = np.asarray(res.kinetic_energy + pot)
    kick_energy = float(res.kinetic_energy[0])
    assert float(pot.max()) > 1e-3 * kick_energy  # the contacts and meshes were loaded
    assert np.abs(total - total[0]).max() / kick_energy < 1e-7
    lin_scale, ang_scale = _momentum_scale(mech, res)
    assert lin_scale > 1e-3 and ang_scale > 1e-3  # the bodies really move
    for series, scale in ((res.momentum, lin_scale), (res.angular_momentum, ang_scale)):
        drift = np.asarray(series) - np.asarray(series[0])
        assert np.abs(drift).max() / scale < 1e-9


def _kicked_state(mech):
    """Each joint's sun at 0.5 rad/s and its output bearing at random speeds of 2 mm/s."""
    lay = mech.layout
    q, u, _ = mech.initial_state()
    kick = np.zeros(lay.size_u)
    rng = np.random.default_rng(0)
    for joint_, sl in ((mech.azimuth, lay.azimuth_u), (mech.pitch, lay.pitch_u)):
        jl = joint_.layout
        part = np.zeros(jl.size)
        part[jl.sun] = 0.5  # rad/s on the sun
        part[jl.carrier_xy] = rng.normal(size=2) * 2e-3  # m/s on the output bearing
        kick[sl] = part
    u = jnp.asarray(kick)
    return q, u, mech.initial_impact_rates(q, u)


@pytest.mark.slow
@pytest.mark.parametrize(
    "fidelity, duration",
    [("ideal", 1.0), ("lumped", 0.1), ("planetary", 0.01), ("planetary-scaled", 0.01)],
)
def test_free_base_conserves_momentum_over_a_run(fidelity, duration):
    """Enlarges `test_free_base_conserves_momentum` (the vector field at random states) to whole
    runs of each fidelity. Dual-axis servo drive at 30 deg/s from rest (planetary: 100 um
    clearances rattle): every force is internal, so linear and angular momentum must stay at
    their initial value."""
    mech = tx.antenna("dual", fidelity=fidelity, rate=math.radians(30.0))
    res = tx.simulate(mech, duration, n_save=21, integrator=tx.Integrator(rtol=1e-10, atol=1e-12))
    lin_scale, ang_scale = _momentum_scale(mech, res)
    assert lin_scale > 1e-3 and ang_scale > 1e-3  # the bodies really move
    lin = np.asarray(res.momentum)
    ang = np.asarray(res.angular_momentum)
    assert np.abs(lin - lin[0]).max() / lin_scale < 1e-9
    assert np.abs(ang - ang[0]).max() / ang_scale < 1e-9


@pytest.mark.slow
@pytest.mark.parametrize("fidelity, duration", [("lumped", 0.02), ("planetary", 0.004), ("planetary-scaled", 0.004)])
def test_energy_conserved_over_a_run(fidelity, duration):
    """Enlarges `test_energy_conserved_without_damping` (the vector field at random states) to
    whole runs of each fidelity (the default tier runs the planetary one:
    `test_conservative_planetary_run_keeps_energy_and_momentum`). Damping, drives and drag off,
    free base, joints kicked so that the 2 um clearances close: the drift of kinetic plus elastic
    energy must follow the integrator tolerance (rtol 1e-10)."""
    mech = _free_mechanism(fidelity, gains=(0.0, 0.0), drag_torque=0.0)
    res = tx.simulate(mech, duration, n_save=41, y0=_kicked_state(mech), integrator=tx.Integrator(rtol=1e-10, atol=1e-13))
    pot = jax.vmap(mech.potential_energy)(res.states[0])
    total = np.asarray(res.kinetic_energy + pot)
    kick_energy = float(res.kinetic_energy[0])
    assert float(pot.max()) > 1e-3 * kick_energy  # the contacts and meshes were loaded
    assert np.abs(total - total[0]).max() / kick_energy < 1e-7


def test_ideal_joints_reproduce_commanded_kinematics():
    mech = tx.antenna("dual", fidelity="ideal", base="free")
    res = tx.simulate(mech, 2.0, n_save=41)
    assert float(np.max(res.pointing_error)) <= 1e-9
    assert float(np.abs(res.position_error).max()) <= 1e-12
    assert float(np.abs(res.tracking_speed_error).max()) <= 1e-12
    rate = math.radians(0.98)
    np.testing.assert_allclose(np.asarray(res.joint_angle), rate * np.asarray(res.ts)[:, None] * [1, 1], atol=1e-15)
    # ...while the floating base really does react (it rotates against the reflector).
    q = np.asarray(res.states[0])
    assert np.abs(q[-1, 4:7]).max() > 1e-6


def _azimuth_inertia(mech):
    """Inertia about the azimuth axis of everything it turns, at zero pitch, by hand."""
    st = mech.azimuth.stage
    i, n = st.ratio, st.n_planets
    motor = float(mech.azimuth.motor_inertia)
    spin = float(st.carrier_radius * jnp.cos(st.ring_pressure_angle) / st.planet_base_radius)
    rc = float(st.carrier_radius)
    az_gears = (float(st.sun_inertia) + motor) * i**2 + float(st.carrier_inertia)
    az_gears += n * (float(st.planet_mass) * rc**2 + float(st.planet_inertia) * spin**2)
    ps = mech.pitch.stage
    # Pitch gears: discs whose axis (x_B) is perpendicular to z_B -> transverse inertia I/2;
    # the planets sit at r_c (cos psi, sin psi) in the (-z_B, y_B) plane: distance r_c |sin psi|.
    pitch_gears = 0.5 * (float(ps.sun_inertia) + float(mech.pitch.motor_inertia) + float(ps.carrier_inertia))
    pitch_gears += ps.n_planets * 0.5 * float(ps.planet_inertia)
    pitch_gears += float(ps.planet_mass) * rc**2 * float(jnp.sum(jnp.sin(ps.planet_angles) ** 2))
    inert = mech.inertias
    links = float(inert.link1_inertia[2]) + float(inert.link2_inertia[0])
    d = float(mech.geometry.reflector_centre[1])
    reflector = float(inert.reflector_inertia[0]) + float(inert.reflector_mass) * d**2
    return az_gears + pitch_gears + links + reflector


def test_ideal_torque_drive_matches_closed_form():
    # Fixed base, pitch locked, azimuth driven by the paper's T = 1.5 cos(2 pi t) N m through a
    # rigid gear train, no drag: theta = T0 / (J w^2) (1 - cos w t) with J summed by hand.
    mech = tx.antenna("azimuth", fidelity="ideal", drive="torque", base="fixed", drag_torque=0.0)
    res = tx.simulate(mech, 1.0, n_save=11, integrator=tx.Integrator(rtol=1e-11, atol=1e-13))
    j = _azimuth_inertia(mech)
    w = 2 * math.pi
    ts = np.asarray(res.ts)
    expected = 1.5 / (j * w**2) * (1 - np.cos(w * ts))
    np.testing.assert_allclose(np.asarray(res.joint_angle[:, 0]), expected, rtol=1e-8, atol=1e-14)


@eqx.filter_jit
def _condensed_stiffness(stage):
    return _modes.stiffness_matrix(stage, jnp.zeros(stage.layout.size))


@eqx.filter_jit
def _flank_onsets(stage, eta):
    """Carrier angle at which the drive and the back flanks of planet 0 engage with the sun held
    and the planet at the tangential offset `eta` on its pin: where both of the flank's
    deflections (sun and ring mesh) vanish together, the planet spin solved out (deflections
    are affine in q: one Newton step from 0 is exact)."""
    lay = stage.layout

    def residual(x, flank):  # x = (theta_c, theta_p0)
        q = jnp.zeros(lay.size).at[lay.carrier_theta].set(x[0]).at[lay.planet_theta.start].set(x[1])
        q = q.at[lay.planet_xy.start + 1].set(eta)
        d = P.deflections(stage, q)
        return jnp.stack([d[f"sun_{flank}"][0], d[f"ring_{flank}"][0]])

    zero = jnp.zeros(2)
    return {flank: jnp.linalg.solve(jax.jacfwd(residual)(zero, flank), -residual(zero, flank))[0] for flank in ("drive", "back")}


@eqx.filter_jit
def _carrier_torque(mech, theta_c):
    jl, sq = mech.azimuth.layout, mech.layout.azimuth_q
    q = mech.initial_state()[0].at[sq.start + jl.carrier].set(theta_c)
    (qa, _), _ = mech.joint_forces(q, jnp.zeros(mech.layout.size_u), jnp.zeros(mech.layout.size_v), 0.0)
    return qa[jl.carrier]


def test_lumped_mesh_is_the_stage_condensed():
    # Independent: the stage's own tangent stiffness (autodiff of its mesh forces), rigid
    # supports and linear meshes, planets condensed out; torsion on delta = theta_s/i - theta_c.
    stage = tx.default_stage(mesh="linear", sun_support="rigid", carrier_support="rigid", planet_support="rigid")
    k = np.asarray(_condensed_stiffness(stage))
    k = 0.5 * (k + k.T)
    keep, drop = [0, 1], list(range(2, 2 + stage.n_planets))
    kc = k[np.ix_(keep, keep)] - k[np.ix_(keep, drop)] @ np.linalg.solve(k[np.ix_(drop, drop)], k[np.ix_(drop, keep)])
    i = stage.ratio
    k_delta = np.array([i, 0.0]) @ kc @ np.array([i, 0.0])  # theta_s = i delta, theta_c = 0
    lm = tx.lumped_mesh(stage, 2e-4)
    np.testing.assert_allclose(float(lm.stiffness * lm.lever**2), k_delta, rtol=1e-10)
    # The rigid (null) mode of the condensed stage is the ratio i.
    assert abs(kc[0, 0] * i + kc[0, 1]) < 1e-8 * abs(kc[0, 0])
    # Backlash and pin play: the carrier's lost motion with the sun held, from the stage's own
    # deflection functions (`_flank_onsets`). The pin lets the planet float tangentially: the
    # drive flank engages (carrier lagging, at theta_c < 0) with the planet at eta = +c_p, the
    # back flank (theta_c > 0) at eta = -c_p.
    b, c_p = 60e-6, 30e-6
    stage = tx.default_stage(backlash=b, planet_clearance=c_p)
    drive, back = float(_flank_onsets(stage, c_p)["drive"]), float(_flank_onsets(stage, -c_p)["back"])
    lost = back - drive
    nl = tx.lumped_mesh(stage, 2e-4)
    assert lost > 0
    np.testing.assert_allclose(float(nl.lost_motion), lost, rtol=1e-10)
    # ...and the lumped joint's tooth torque switches on exactly there (exact dead zone, eps = 0).
    sharp = eqx.tree_at(lambda s_: s_.smoothing_width, stage, jnp.asarray(0.0))
    mech = tx.Mechanism(tx.LumpedJoint(sharp, tx.TorqueDrive(0.0), drag_torque=0.0), base="fixed")
    nudge = 1e-3 * lost
    torque = [float(_carrier_torque(mech, jnp.asarray(x))) for x in (drive + nudge, back - nudge, drive - nudge, back + nudge)]
    assert torque[0] == 0.0 and torque[1] == 0.0
    assert torque[2] > 0.0 > torque[3]
    # Without pin play, the lost motion is the backlash alone, (b_s + b_r) / r.
    rigid = tx.lumped_mesh(tx.default_stage(backlash=b, planet_support="rigid"), 2e-4)
    np.testing.assert_allclose(float(rigid.lost_motion * rigid.lever), 2 * b, rtol=1e-12)
    assert float(rigid.drive_gap) == 0.0


def test_bad_options_are_rejected():
    with pytest.raises(ValueError, match="fidelity"):
        tx.antenna("azimuth", fidelity="exact")
    with pytest.raises(ValueError, match="mode"):
        tx.antenna("roll")
    with pytest.raises(ValueError, match="drive"):
        tx.antenna("dual", drive="position")
    with pytest.raises(ValueError, match="base"):
        tx.Mechanism(base="floating")
    with pytest.raises(ValueError, match="reflector_centre"):
        tx.Geometry(reflector_centre=(0.0, float("nan"), 0.0))
    with pytest.raises(ValueError, match="reflector_mass"):
        tx.Inertias(reflector_mass=-8.0)
    with pytest.raises(TypeError, match="drive"):
        tx.PlanetaryJoint(drive=1.5)
    with pytest.raises(ValueError, match="nothing to integrate"):
        tx.simulate(tx.antenna("dual", fidelity="ideal", base="fixed"), 0.1)


def test_vibration_amplitude_recovers_a_sinusoid():
    ts = jnp.linspace(0.0, 2.0, 2001)[:-1]
    signal = 3e-6 * jnp.sin(2 * jnp.pi * 25.0 * ts) + 1e-3 * ts + 0.2  # drift is not vibration
    # rel 1e-3: the least-squares detrend also removes the sinusoid's small projection on a
    # straight line over the 2 s window (2.4e-4 of its amplitude here); the drift, 50x larger
    # than the sinusoid, is removed entirely.
    assert float(tx.vibration_amplitude(signal, ts)) == pytest.approx(3e-6, rel=1e-3)


def _random_state(mech, key, reach=1e-4):
    """A state far from the steady one: every angle anywhere, translations of the order of
    `reach` (default the default stage's 100 um clearances), speeds of order 1 (rad/s, m/s on
    the base, mm/s on the gears), any base attitude, impact rates of order 1 mm/s."""
    lay = mech.layout
    kq, ku, kv, kb = jax.random.split(key, 4)
    q = jax.random.uniform(kq, (lay.size_q,), minval=-np.pi, maxval=np.pi)
    u = jax.random.normal(ku, (lay.size_u,))
    for joint, sq, su, _ in mech.joints():
        xy = np.ones(joint.layout.size, bool)
        xy[[i for i in (joint.layout.sun, joint.layout.carrier) if i is not None]] = False
        xy[[k for k, name in enumerate(joint.layout.names) if name.startswith("theta")]] = False
        q = q.at[sq].set(jnp.where(xy, reach * q[sq], q[sq]))
        u = u.at[su].set(jnp.where(xy, 1e-3 * u[su], u[su]))
    if mech.base == "free":
        q = q.at[:3].multiply(0.3).at[3:7].set(jax.random.normal(kb, (4,)))  # unnormalised: drift
    v = 1e-3 * jax.random.normal(kv, (lay.size_v,))
    return q, u, v


def _rolling_state(mech, key, reach=2e-6):
    """A state near the gear trains' rigid rolling: as `_random_state` (translations of order
    `reach`), but each joint's angles those of its rigid train at a random output angle plus 1e-5
    rad, and its angular speeds the rigid train's at a random rate plus 1e-2 rad/s: the meshes
    deflected by fractions of a um, as in a run (angles anywhere would deflect them by cm); the
    base moving at 1e-2 of `_random_state`'s speeds (its large inertia at 1 rad/s would carry
    powers that cancel to rounding far above the joints' elastic power)."""
    q, u, v = _random_state(mech, key, reach)
    if mech.base == "free":
        u = u.at[: mech.layout.base_u].multiply(1e-2)
    for k, (joint, sq, su, _) in enumerate(mech.joints()):
        if joint.layout.size == 0:
            continue
        ka, kb, kc, kd = jax.random.split(jax.random.fold_in(key, 100 + k), 4)
        rolling = joint.steady_speeds() / joint.drive.rate(0.0)  # per radian of the output
        angle = jnp.asarray([name.startswith("theta") for name in joint.layout.names])
        n = joint.layout.size
        at = rolling * jax.random.uniform(ka, minval=-np.pi, maxval=np.pi) + 1e-5 * jax.random.normal(kb, (n,))
        rate = rolling * jax.random.normal(kc) + 1e-2 * jax.random.normal(kd, (n,))
        q = q.at[sq].set(jnp.where(angle, at, q[sq]))
        u = u.at[su].set(jnp.where(angle, rate, u[su]))
    return q, u, v


@pytest.mark.parametrize(
    "a_shape, b_shape",
    [((2, 2), (2,)), ((3, 2), (2, 2)), ((2, 2), (2, 15)), ((4, 3, 3), (3,)), ((4, 3, 3), (3, 3)), ((1, 3, 3), (5, 3, 3)), ((6, 2), (2, 3))],
)
def test_small_matmul_is_matmul(a_shape, b_shape):
    """The frames' rotations are written as sums of products (`small_matmul`, so that XLA fuses
    them); it must be `@` to rounding for every shape it is given, batch axes broadcast."""
    rng = np.random.default_rng(len(a_shape) * 10 + len(b_shape))
    a, b = rng.normal(size=a_shape), rng.normal(size=b_shape)
    out = small_matmul(jnp.asarray(a), jnp.asarray(b))
    assert out.shape == (a @ b).shape
    np.testing.assert_allclose(out, a @ b, rtol=1e-13, atol=1e-14)


@pytest.mark.parametrize(
    "subscripts, shapes",
    [
        ("bkn,bk,bkm->bnm", [(8, 6, 12), (8, 6), (8, 6, 3)]),  # the block solve's M_so
        ("bni,bim->nm", [(8, 12, 3), (8, 3, 12)]),  # its Schur complement's sum over bodies
        ("bin,n->bi", [(8, 3, 12), (12,)]),
        ("bji,bjn->bin", [(14, 3, 3), (14, 3, 15)]),  # the Kane terms' rotation into body axes
        ("ij,jk->ki", [(2, 3), (3, 4)]),  # an output in another order than the letters' first use
    ],
)
def test_small_einsum_is_einsum(subscripts, shapes):
    """The block solve's per-body contractions are fused sums (`small_einsum`); they must be
    `jnp.einsum` to rounding, and a malformed operand is refused."""
    rng = np.random.default_rng(len(subscripts))
    operands = [rng.normal(size=shape) for shape in shapes]
    np.testing.assert_allclose(small_einsum(subscripts, *operands), np.einsum(subscripts, *operands), rtol=1e-12, atol=1e-13)
    with pytest.raises(ValueError, match="do not fit"):
        small_einsum(subscripts, operands[0][..., None], *operands[1:])


@pytest.mark.slow
def test_kane_by_frames_trajectory_equals_reference():
    """Enlarges `test_kane_by_frames_equals_autodiff_reference[free-planetary]` (the vector field
    at random states and the steady start) to a run."""
    # 0.05 s of the planetary dual-axis antenna from a steady start (meshes engaged, bearings
    # free to rattle): the same accepted and rejected steps, the same outputs to 1e-9 of their
    # scale (rounding differences of the two formulations, grown by the adaptive solve).
    from _kane_reference import KaneByAutodiff

    mech = tx.antenna("dual", fidelity="planetary")
    new = tx.simulate(mech, 0.05, start="steady", n_save=11)
    ref = tx.simulate(KaneByAutodiff(mech), 0.05, start="steady", n_save=11)
    assert int(new.num_steps) == int(ref.num_steps) and int(new.num_rejected) == int(ref.num_rejected)
    for name in ("pointing_error", "joint_angle", "position_error", "tracking_speed_error", "runout", "azimuth_contact"):
        a, b = np.asarray(getattr(new, name)), np.asarray(getattr(ref, name))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max())
    for a, b in zip(new.states, ref.states):
        np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-9 * np.abs(np.asarray(b)).max())
