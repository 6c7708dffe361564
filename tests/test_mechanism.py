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


@pytest.mark.parametrize(
    "fidelity, duration",
    [("ideal", 1.0), ("lumped", 0.1), ("planetary", 0.01), ("planetary-scaled", 0.01)],
)
def test_free_base_conserves_momentum(fidelity, duration):
    # Dual-axis servo drive at 30 deg/s from rest (planetary: 100 um clearances rattle): every
    # force is internal, so linear and angular momentum must stay at their initial value. For
    # the mass-scaled joint this checks that its added inertia acts only on relative motion:
    # the momentum is the physical bodies' alone.
    mech = tx.antenna("dual", fidelity=fidelity, rate=math.radians(30.0))
    res = tx.simulate(mech, duration, n_save=21, rtol=1e-10, atol=1e-12)
    lin_scale, ang_scale = _momentum_scale(mech, res)
    assert lin_scale > 1e-3 and ang_scale > 1e-3  # the bodies really move
    lin = np.asarray(res.momentum)
    ang = np.asarray(res.angular_momentum)
    assert np.abs(lin - lin[0]).max() / lin_scale < 1e-9
    assert np.abs(ang - ang[0]).max() / ang_scale < 1e-9


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


@pytest.mark.parametrize("fidelity, duration", [("lumped", 0.02), ("planetary", 0.004), ("planetary-scaled", 0.004)])
def test_energy_conserved_without_damping(fidelity, duration):
    # Damping off (meshes, contacts: restitution 1), drives and drag off, free base. The joints
    # are kicked so that the 2 um clearances close within the run; the drift of kinetic plus
    # elastic energy must follow the integrator tolerance (rtol 1e-10). The lumped joint gets
    # rigid planet pins: its pin play is a smoothed dead zone, whose softplus ramp has no
    # closed-form potential (the planetary stage's pin contacts do, through the contact law).
    # The mass-scaled joint's kinetic energy includes its added inertia.
    stage = _conservative_stage(2e-6, "clearance" if fidelity.startswith("planetary") else "rigid")
    joint = lambda: tx.FIDELITIES[fidelity](stage, tx.TorqueDrive(0.0), drag_torque=0.0)  # noqa: E731
    mech = tx.Mechanism(joint(), joint(), base="free")
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
    y0 = (q, u, mech.initial_impact_rates(q, u))
    res = tx.simulate(mech, duration, n_save=41, rtol=1e-10, atol=1e-13, y0=y0)
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
    res = tx.simulate(mech, 1.0, n_save=11, rtol=1e-11, atol=1e-13)
    j = _azimuth_inertia(mech)
    w = 2 * math.pi
    ts = np.asarray(res.ts)
    expected = 1.5 / (j * w**2) * (1 - np.cos(w * ts))
    np.testing.assert_allclose(np.asarray(res.joint_angle[:, 0]), expected, rtol=1e-8, atol=1e-14)


def test_lumped_mesh_is_the_stage_condensed():
    # Independent: the stage's own tangent stiffness (autodiff of its mesh forces), rigid
    # supports and linear meshes, planets condensed out; torsion on delta = theta_s/i - theta_c.
    stage = tx.default_stage(mesh="linear", sun_support="rigid", carrier_support="rigid", planet_support="rigid")
    k = np.asarray(_modes.stiffness_matrix(stage, jnp.zeros(stage.layout.size)))
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
    # deflection functions. Planet 0 pressed against its pin at the tangential offset eta = +-c_p;
    # the carrier angle where both of its drive (back) deflections vanish together (the planet
    # spin solved out) is the drive (back) flank onset; deflections are affine in q.
    b, c_p = 60e-6, 30e-6
    stage = tx.default_stage(backlash=b, planet_clearance=c_p)
    lay = stage.layout

    def onset(eta, flank):
        def residual(x):  # x = (theta_c, theta_p0)
            q = jnp.zeros(lay.size).at[lay.carrier_theta].set(x[0]).at[lay.planet_theta.start].set(x[1])
            q = q.at[lay.planet_xy.start + 1].set(eta)
            d = P.deflections(stage, q)
            return jnp.stack([d[f"sun_{flank}"][0], d[f"ring_{flank}"][0]])

        a = np.asarray(jax.jacfwd(residual)(jnp.zeros(2)))
        return np.linalg.solve(a, -np.asarray(residual(jnp.zeros(2))))[0]

    # The pin lets the planet float tangentially: the drive flank engages (carrier lagging, at
    # theta_c < 0) with the planet at eta = +c_p, the back flank (theta_c > 0) at eta = -c_p.
    lost = onset(-c_p, "back") - onset(c_p, "drive")
    nl = tx.lumped_mesh(stage, 2e-4)
    assert lost > 0
    np.testing.assert_allclose(float(nl.lost_motion), lost, rtol=1e-10)
    # ...and the lumped joint's tooth torque switches on exactly there (exact dead zone, eps = 0).
    sharp = eqx.tree_at(lambda s_: s_.smoothing_width, stage, jnp.asarray(0.0))
    mech = tx.Mechanism(tx.LumpedJoint(sharp, tx.TorqueDrive(0.0), drag_torque=0.0), base="fixed")
    jl, sq = mech.azimuth.layout, mech.layout.azimuth_q

    def carrier_torque(theta_c):
        q = mech.initial_state()[0].at[sq.start + jl.carrier].set(theta_c)
        (qa, _), _ = mech.joint_forces(q, jnp.zeros(mech.layout.size_u), jnp.zeros(mech.layout.size_v), 0.0)
        return float(qa[jl.carrier])

    drive, back = onset(c_p, "drive"), onset(-c_p, "back")
    nudge = 1e-3 * lost
    assert carrier_torque(drive + nudge) == 0.0 and carrier_torque(back - nudge) == 0.0
    assert carrier_torque(drive - nudge) > 0.0 > carrier_torque(back + nudge)
    # Without pin play, the lost motion is the backlash alone, (b_s + b_r) / r.
    rigid = tx.lumped_mesh(tx.default_stage(backlash=b, planet_support="rigid"), 2e-4)
    np.testing.assert_allclose(float(rigid.lost_motion * rigid.lever), 2 * b, rtol=1e-12)
    assert float(rigid.drive_gap) == 0.0


def test_lumped_joint_servo_lag_matches_closed_form():
    # Fixed base, azimuth at 0.98 deg/s on lumped joints, started at rest. The PI servo acts as
    # a PD on the motor angle, so the steady lag under the drag torque T is T / (i^2 k_i) at the
    # output (the mesh windup, T / K, is 1e-7 rad), plus the drive-side lost motion the output
    # trails the motor by: the planet-pin play, drive_gap / lever (4e-3 rad at 100 um pins). The
    # loop (w_n = 5.3 rad/s, zeta = 0.27) settles in ~2 s; the output bearing keeps rattling in
    # its clearance and stirs the lag by about +-6 % of the servo part, so the lag is averaged
    # over 2-4 s (3 %).
    mech = tx.antenna("azimuth", fidelity="lumped", base="fixed")
    res = tx.simulate(mech, 4.0, n_save=401)
    joint = mech.azimuth
    lm = tx.lumped_mesh(joint.stage, joint.motor_inertia)
    servo = float(joint.drag_torque / (joint.stage.ratio**2 * joint.drive.integral))
    expected = servo + float(lm.drive_gap / lm.lever)
    lag = np.asarray(res.commanded_angle[200:, 0] - res.joint_angle[200:, 0])
    assert float(lag.mean()) == pytest.approx(expected, abs=0.03 * servo)
    q, u, _ = res.states
    rate = float(u[-1, mech.layout.azimuth_u][1])
    assert rate == pytest.approx(math.radians(0.98), rel=0.02)


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


def _random_state(mech, key):
    """A state far from the steady one: every angle anywhere, translations of the order of the
    clearances (100 um), speeds of order 1 (rad/s, m/s on the base, mm/s on the gears), any base
    attitude, impact rates of order 1 mm/s."""
    lay = mech.layout
    kq, ku, kv, kb = jax.random.split(key, 4)
    q = jax.random.uniform(kq, (lay.size_q,), minval=-np.pi, maxval=np.pi)
    u = jax.random.normal(ku, (lay.size_u,))
    for joint, sq, su, _ in mech.joints():
        xy = np.ones(joint.layout.size, bool)
        xy[[i for i in (joint.layout.sun, joint.layout.carrier) if i is not None]] = False
        xy[[k for k, name in enumerate(joint.layout.names) if name.startswith("theta")]] = False
        q = q.at[sq].set(jnp.where(xy, 1e-4 * q[sq], q[sq]))
        u = u.at[su].set(jnp.where(xy, 1e-3 * u[su], u[su]))
    if mech.base == "free":
        q = q.at[:3].multiply(0.3).at[3:7].set(jax.random.normal(kb, (4,)))  # unnormalised: drift
    v = 1e-3 * jax.random.normal(kv, (lay.size_v,))
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


@pytest.mark.parametrize("fidelity", ["ideal", "lumped", "planetary"])
@pytest.mark.parametrize("base", ["free", "fixed"])
def test_kane_by_frames_equals_autodiff_reference(fidelity, base):
    # Independent: `kane_by_autodiff` differentiates the poses (jacfwd over all speeds, jvp over
    # q and t); `Mechanism.dynamics` propagates Jacobians and accelerations down the chain by
    # hand. Equal to rounding (1e-12 of each quantity's scale) at random states, the whole
    # vector field included (Cholesky against LU on the same equations). Ideal joints with a
    # torque drive on a fixed base give the chain with one coordinate per joint.
    drive = "torque" if (fidelity, base) == ("ideal", "fixed") else "speed"
    mech = tx.antenna("dual", fidelity=fidelity, base=base, drive=drive)
    from _kane_reference import kane_by_autodiff, vector_field_by_autodiff

    new = eqx.filter_jit(lambda m, t, y: (m.dynamics(y[0], y[1], t), m.vector_field(t, y, None)))
    ref = eqx.filter_jit(lambda m, t, y: (kane_by_autodiff(m, y[0], y[1], t), vector_field_by_autodiff(m, t, y)))
    for k, t in enumerate((0.0, 0.37, 1.91)):
        y = _random_state(mech, jax.random.key(k))
        got, want = new(mech, jnp.asarray(t), y), ref(mech, jnp.asarray(t), y)
        (mass, bias), (_, ud, _) = want
        assert float(jnp.abs(mass).max()) > 0.0 and float(jnp.abs(bias).max()) > 0.0
        assert float(jnp.abs(ud).max()) > 0.0
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
            # Scale 0 (impact rates of contacts out of touch): exactly equal.
            scale = float(jnp.abs(b).max(initial=0.0))
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * scale)


def test_kane_by_frames_trajectory_equals_reference():
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


def test_block_solve_with_blocks_of_unequal_width_equals_reference():
    # The block solve pads each eliminated body's own speeds to one width: here the azimuth
    # joint's sun is rigid (its spin alone: width 1) and its planets float on their pins (spin
    # and translation: width 3), the pitch joint a spring-mounted ring (a body of its own), so
    # the padding's unit diagonal and the unequal blocks meet the LU solve of the whole M.
    from _kane_reference import spring_ring_stage, vector_field_by_autodiff

    mech = tx.Mechanism(tx.PlanetaryJoint(tx.default_stage(sun_support="rigid")), tx.PlanetaryJoint(spring_ring_stage()))
    blocks = mech.kane_blocks()
    assert (blocks.own == mech.layout.size_u).any()  # padded
    new = eqx.filter_jit(lambda m, t, y: m.vector_field(t, y, None))
    ref = eqx.filter_jit(vector_field_by_autodiff)
    for k, t in enumerate((0.0, 0.37)):
        y = _random_state(mech, jax.random.key(10 + k))
        got, want = new(mech, jnp.asarray(t), y), ref(mech, jnp.asarray(t), y)
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
            scale = float(jnp.abs(b).max(initial=0.0))
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * scale)
