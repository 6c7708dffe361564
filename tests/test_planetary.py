"""The planetary stage against independent references: Lin & Parker (1999), kinematics, energy."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax import planetary as P


def lin_parker_stage(n_planets=3):
    """The example system of Lin & Parker (1999), J. Vib. Acoust. 121:316-321, Table 1.

    Masses (kg), I/r^2 (kg), diameters (mm), all bearings 1e8 N/m, ring torsion 1e9 N/m on u,
    sun and carrier free to rotate, meshes 5e8 N/m, pressure angle 24.6 deg. Transcribed from
    the test suite of gfsReboucas/Drivetrain (Lin_Parker_99.m, test_01), which cites the paper's
    Table 1; the planet bearing carries no torque.
    """
    r = dict(s=77.4e-3 / 2, r=275e-3 / 2, c=176.8e-3 / 2, p=100.3e-3 / 2)
    m = dict(s=0.4, r=2.35, c=5.43, p=0.66)
    i_over_r2 = dict(s=0.39, r=3.0, c=6.29, p=0.61)
    f = lambda x: jnp.asarray(x, float)  # noqa: E731
    alpha = math.radians(24.6)
    return tx.PlanetaryStage(
        n_planets=n_planets,
        # The paper gives no tooth counts (linear meshes use them only for phases); these match
        # its radii, 25 : 32 : 89 (module 3.4 mm), so the planets' tip circles are realistic for
        # the construction check that the planets fit on the carrier.
        sun_teeth=25,
        planet_teeth=32,
        ring_teeth=89,
        sun_mass=f(m["s"]),
        carrier_mass=f(m["c"]),
        planet_mass=f(m["p"]),
        ring_mass=f(m["r"]),
        sun_inertia=f(i_over_r2["s"] * r["s"] ** 2),
        carrier_inertia=f(i_over_r2["c"] * r["c"] ** 2),
        planet_inertia=f(i_over_r2["p"] * r["p"] ** 2),
        ring_inertia=f(i_over_r2["r"] * r["r"] ** 2),
        sun_base_radius=f(r["s"]),
        planet_base_radius=f(r["p"]),
        ring_base_radius=f(r["r"]),
        carrier_radius=f(r["c"]),
        sun_pressure_angle=f(alpha),
        ring_pressure_angle=f(alpha),
        planet_angles=f(2 * np.pi * np.arange(n_planets) / n_planets),
        sun_support=tx.Support("spring", 1e8),
        carrier_support=tx.Support("spring", 1e8),
        planet_support=tx.Support("spring", 1e8),
        ring_support=tx.Support("spring", 1e8),
        sun_torsion=None,
        carrier_torsion=None,
        ring_torsion=f(1e9),
        sun_mesh=tx.Mesh("linear", 5e8, n_planets=n_planets),
        ring_mesh=tx.Mesh("linear", 5e8, n_planets=n_planets),
        contact_law=None,
        smoothing_width=f(0.0),
        impact_rate_floor=f(1e-3),
        impact_memory_time=f(1e-5),
    )


# Lin & Parker (1999) Table 2, N = 3 (Hz): rotational modes and degenerate translational pairs.
LIN_PARKER_N3 = sorted(
    [0.0, 1475.7, 1930.3, 2658.3, 7462.8, 11775.3]
    + 2 * [743.2, 1102.4, 1896.0, 2276.4, 6986.3, 9647.9]
)


# The modes in one compiled program per stage structure (op by op, 4-5x the time).
_natural_frequencies = eqx.filter_jit(tx.natural_frequencies)


def test_lin_parker_natural_frequencies():
    modes = _natural_frequencies(lin_parker_stage(3))
    computed = np.asarray(modes.frequencies)
    assert computed.shape == (18,)
    # The rigid-body rotation (sun and carrier free) is the 0 Hz mode.
    assert computed[0] < 1e-3
    rel = np.abs(computed[1:] - LIN_PARKER_N3[1:]) / np.asarray(LIN_PARKER_N3[1:])
    # 0.1 % is the bar; the table prints 5 significant digits (rounding <= 0.007 %).
    assert rel.max() < 1e-3, rel


def test_rigid_mode_has_the_kinematic_ratio():
    """The null mode of the linearised default joint turns sun:carrier as 1 + z_r/z_s."""
    stage = tx.default_stage(
        mesh="linear", sun_support="rigid", carrier_support="rigid", planet_support="rigid"
    )
    modes = _natural_frequencies(stage)
    shape = np.asarray(modes.shapes[:, 0])
    assert float(modes.frequencies[0]) < 1e-3
    ratio = shape[0] / shape[1]
    assert abs(ratio - (1 + 80 / 20)) < 1e-9 * 5


def test_simulated_speed_ratio_rigid_supports_zero_backlash():
    """Servo-driven from rest with rigid supports and linear (zero-backlash) meshes, the settled
    speed ratio is 1 + z_r/z_s; the mesh deflection is then constant, so speeds see no offset."""
    stage = tx.default_stage(
        mesh="linear", sun_support="rigid", carrier_support="rigid", planet_support="rigid"
    )
    bench = tx.TestBench(stage, load_torque=0.0)
    res = tx.simulate(bench, 0.02, start="steady", n_save=3, integrator=tx.Integrator(rtol=1e-10, atol=1e-13))
    q, qd, _ = res.states
    lay = stage.layout
    ratio = qd[-1, lay.sun_theta] / qd[-1, lay.carrier_theta]
    assert abs(float(ratio) - 5.0) < 1e-9 * 5.0


def _conservative_stage():
    """Damping off, restitution 1 (no hysteresis), linear meshes, Hertz contact at the planet
    pins (2 um clearance) and springs elsewhere."""
    from tolerax import Flores

    return tx.default_stage(
        mesh="linear",
        mesh_damping_ratio=0.0,
        sun_support="spring",
        carrier_support="spring",
        planet_support="clearance",
        planet_clearance=2e-6,
        contact_law=Flores(1.0),
        smoothing_width=1e-9,
    )


def _conservative_bench():
    """The conservative stage on its bench, no drive (zero servo gains) and no load torque."""
    return tx.TestBench(_conservative_stage(), servo=tx.SpeedServo(math.radians(30.0), 0.0, 0.0), load_torque=0.0)


@eqx.filter_jit
def _energy_rates(bench, t, y):
    """The rates of kinetic and elastic energy along the bench's vector field (autodiff of
    `kinetic_energy` and `potential_energy`), and the elastic energy."""
    stage = bench.stage
    q, qd, _ = y
    _, qdd, _ = bench.vector_field(t, y, None)
    kinetic = jax.jvp(lambda q_, qd_: P.kinetic_energy(stage, q_, qd_, bench.added), (q, qd), (qd, qdd))[1]
    potential, potential_rate = jax.jvp(lambda q_: P.potential_energy(stage, q_), (q,), (qd,))
    return kinetic, potential, potential_rate


def test_stage_energy_conserved_without_damping():
    """Damping off, restitution 1 (no hysteresis), linear meshes, Hertz contact at the planet
    pins and springs elsewhere, no drive: along the bench's vector field the rate of kinetic
    energy is minus the rate of elastic energy, to rounding (1e-10) of either, at random states
    near rigid rolling: the angles the rigid train's at a random carrier angle plus 1e-5 rad
    (meshes deflected by fractions of a um, as in a run: angles anywhere would deflect them by
    cm and drown the inertial terms), translations to 6 um (the 2 um pin clearances partly
    closed), speeds the rigid train's at a random rate plus 1e-2 rad/s and 1 mm/s. This checks
    the Coriolis/centripetal terms against the kinetic energy and the smoothed contact force
    being the exact gradient of its potential. (Over a run through impacts: the slow
    `test_stage_energy_conserved_over_a_run`.)"""
    bench = _conservative_bench()
    lay = bench.stage.layout
    angle = jnp.asarray([n.startswith("theta") for n in lay.names])
    rolling = bench.initial_state("steady")[1] / bench.initial_state("steady")[1][lay.carrier_theta]  # per radian of the carrier
    for k in range(3):
        ka, kb, kc, kd = jax.random.split(jax.random.key(40 + k), 4)
        noise = jnp.where(angle, 1e-5, 2e-6) * jax.random.uniform(kb, (lay.size,), minval=-3.0, maxval=3.0)
        q = rolling * jax.random.uniform(ka, minval=-np.pi, maxval=np.pi) + noise
        qd = rolling * jax.random.normal(kc) + jnp.where(angle, 1e-2, 1e-3) * jax.random.normal(kd, (lay.size,))
        y = (q, qd, P.initial_impact_rates(bench.stage, q, qd))
        kinetic, potential, potential_rate = (float(x) for x in _energy_rates(bench, jnp.asarray(0.1 * k), y))
        assert potential > 0.0 and abs(kinetic) > 0.0  # loaded, exchanging energy
        assert abs(kinetic + potential_rate) < 1e-10 * abs(potential_rate), (kinetic, potential_rate)


@pytest.mark.slow
def test_stage_energy_conserved_over_a_run():
    """Enlarges `test_stage_energy_conserved_without_damping` (the vector field at random states)
    to a run: T + V is constant to the integrator's tolerance, through impacts."""
    bench = _conservative_bench()
    stage = bench.stage
    q0, qd_rigid, v0 = bench.initial_state("steady")
    lay = stage.layout
    # Throw each planet radially and tangentially at its pin: impacts within the run.
    kick = jnp.tile(jnp.array([0.01, -0.005]), stage.n_planets)
    qd0 = qd_rigid.at[lay.planet_xy].set(kick)
    v0 = P.initial_impact_rates(stage, q0, qd0)
    res = tx.simulate(bench, 0.004, n_save=101, y0=(q0, qd0, v0), integrator=tx.Integrator(rtol=1e-11, atol=1e-14, dtmax=1e-5))
    q, qd, _ = res.states

    def energy(q_, qd_):
        return P.kinetic_energy(stage, q_, qd_, bench.added) + P.potential_energy(stage, q_)

    e = np.asarray(jax.vmap(energy)(q, qd))
    assert np.asarray(res.contact_force).max() > 1.0  # the planets did hit their pins
    # Measure the drift against the energy of the kick (what the contacts exchange), not the
    # total, which the rotating load dominates (0.14 J against 1e-5 J of the kick alone).
    kick_energy = 0.5 * float(stage.planet_mass) * float(jnp.sum(kick**2))
    drift = np.abs(e - e[0]).max() / kick_energy
    # Measured 1e-9 at rtol 1e-11 and 1e-6 at rtol 1e-8 (the drift follows the tolerance, as
    # a conservative model's must); 1e-7 leaves margin for other platforms' rounding.
    assert drift < 1e-7, drift


@eqx.filter_jit
def _forces_and_potential_gradient(stage, q):
    zero = jnp.zeros(stage.layout.size)
    forces = P.stage_forces(stage, q, zero, jnp.zeros(len(stage.contact_names)))
    return forces, -jax.grad(lambda q_: P.potential_energy(stage, q_))(q)


def test_generalised_forces_are_minus_the_potential_gradient():
    """`stage_forces` projects the forces through the deflections' Jacobian (forward mode,
    `D^T F`); independently, for a conservative stage at rest (no damping, restitution 1, planets
    pressed into their pins) the generalised forces are $-\\partial V/\\partial q$ of
    `potential_energy` (reverse mode through a different function). Random states with the
    carrier turned (the deflections' nonlinear part)."""

    stage = _conservative_stage()
    lay = stage.layout
    for k in range(3):
        q = 3e-6 * jax.random.normal(jax.random.key(k), (lay.size,))
        q = q.at[lay.carrier_theta].set(0.7 * k + 0.3).at[lay.sun_theta].add(0.2 * k)
        f, want = _forces_and_potential_gradient(stage, q)
        assert float(jnp.abs(f.contact).max()) > 0.0  # some planet is in contact
        scale = float(jnp.abs(want).max())
        assert scale > 0.0
        np.testing.assert_allclose(np.asarray(f.generalised), np.asarray(want), rtol=0, atol=1e-10 * scale)


@eqx.filter_jit
def _three_projections(stage, q, qd, v):
    return tuple(P.stage_forces(stage, q, qd, v, projection=p) for p in ("closed-form", "jvp-vjp", "forward"))


def test_force_projections_agree():
    """The three formulations of `stage_forces` (the deflections' Jacobian in closed form, the
    default; by forward-mode autodiff; a jvp and a vjp) give the same forces to rounding, on the
    default nonlinear stage (backlash, dynamic backlash, profile error, every bearing in
    clearance) at random states with impacts."""
    stage = tx.default_stage(profile_error=5e-6)
    lay = stage.layout
    for k in range(3):
        kq, ku, kv = jax.random.split(jax.random.key(k), 3)
        q = 1.2e-4 * jax.random.normal(kq, (lay.size,))  # past the 100 um clearances
        q = q.at[lay.carrier_theta].set(0.9 * k + 0.1).at[lay.sun_theta].add(4.0 * k)
        qd = jax.random.normal(ku, (lay.size,))
        v = 0.1 * jax.random.normal(kv, (len(stage.contact_names),))
        a, b, c = _three_projections(stage, q, qd, v)
        assert float(jnp.abs(b.contact).max()) > 0.0 and float(jnp.abs(b.sun_mesh).max()) > 0.0
        for x, y, z in zip(jax.tree.leaves(a), jax.tree.leaves(b), jax.tree.leaves(c)):
            scale = float(jnp.abs(y).max(initial=0.0))
            np.testing.assert_allclose(np.asarray(x), np.asarray(y), rtol=0, atol=1e-12 * scale)
            np.testing.assert_allclose(np.asarray(z), np.asarray(y), rtol=0, atol=1e-12 * scale)
    with pytest.raises(ValueError, match="projection='adjoint' is unknown"):
        P.stage_forces(stage, q, qd, v, projection="adjoint")


@eqx.filter_jit
def _jacobians(stage, q):
    return P.deflections_and_jacobian(stage, q), jax.jacfwd(lambda q_: P.deflections(stage, q_))(q)


@pytest.mark.parametrize(
    "variant",
    ["default", "profile error", "rigid supports", "spring supports", "linear meshes", "static backlash", "spring ring",
     "four planets"],
)
def test_closed_form_jacobian_equals_autodiff(variant):
    """`deflections_and_jacobian`'s closed-form Jacobian equals the forward-mode Jacobian of the
    deflections it returns, for every kind of support and mesh (blocks of coordinates present or
    not, dynamic or fixed backlash, the ring on springs), at random large rotations and
    displacements past the clearances."""
    from _kane_reference import spring_ring_stage

    stage = {
        "default": lambda: tx.default_stage(),
        "profile error": lambda: tx.default_stage(profile_error=5e-6),
        "rigid supports": lambda: tx.default_stage(sun_support="rigid", carrier_support="rigid", planet_support="rigid"),
        "spring supports": lambda: tx.default_stage(sun_support="spring", carrier_support="spring", planet_support="spring"),
        "linear meshes": lambda: tx.default_stage(mesh="linear"),
        "static backlash": lambda: tx.default_stage(dynamic_backlash=False, profile_error=3e-6),
        "spring ring": spring_ring_stage,
        "four planets": lambda: tx.default_stage(n_planets=4, sun_support="spring", profile_error=2e-6),
    }[variant]()
    lay = stage.layout
    for k in range(3):
        q = 2e-4 * jax.random.normal(jax.random.key(10 + k), (lay.size,))
        q = q.at[lay.carrier_theta].set(1.7 * k - 0.6).at[lay.sun_theta].add(5.0 * k + 0.3)
        if lay.ring_theta is not None:
            q = q.at[lay.ring_theta].add(0.2 * k)
        (defl, jac), want = _jacobians(stage, q)
        assert sorted(jac) == sorted(want) == sorted(defl)
        for key in want:
            assert jac[key].shape == want[key].shape, key
            np.testing.assert_allclose(np.asarray(jac[key]), np.asarray(want[key]), rtol=0, atol=1e-13, err_msg=key)


def test_dynamic_backlash_follows_planet_displacement():
    """In the stage, moving a planet radially outward by dz opens the sun mesh's back-flank gap
    and closes the ring mesh's one, by 2 dz sin(alpha) relative to the drive flank."""
    stage = tx.default_stage(sun_support="rigid", carrier_support="rigid")
    lay = stage.layout
    q = jnp.zeros(lay.size)
    dz = 1e-7
    q1 = q.at[lay.planet_xy.start].set(dz)
    d0, d1 = P.deflections(stage, q), P.deflections(stage, q1)
    b = lambda d, k: d[f"{k}_back"] - d[f"{k}_drive"]  # noqa: E731
    s = math.sin(math.radians(20.0))
    np.testing.assert_allclose(float(b(d1, "sun")[0] - b(d0, "sun")[0]), 2 * dz * s, rtol=1e-4)
    np.testing.assert_allclose(float(b(d1, "ring")[0] - b(d0, "ring")[0]), -2 * dz * s, rtol=1e-4)


@eqx.filter_jit
def _summary(stage, q, qd, v):
    """A contact-force summary of the stage at a state."""
    f = P.stage_forces(stage, q, qd, v)
    return jnp.sum(f.contact) + jnp.sum(f.sun_mesh**2)


_summary_gradient = eqx.filter_jit(eqx.filter_grad(_summary))


def test_no_retrace_and_finite_gradient_of_clearance():
    """Changing only values (clearances) must not retrace; the gradient of a contact-force
    summary with respect to every clearance and backlash is finite."""
    stage = tx.default_stage()
    bench = tx.TestBench(stage)
    y0 = bench.initial_state()

    @eqx.debug.assert_max_traces(max_traces=1)
    def rhs(b, y):
        return b.vector_field(0.0, y, None)

    rhs_jit = eqx.filter_jit(rhs)
    rhs_jit(bench, y0)
    bench2 = eqx.tree_at(lambda b: b.stage.planet_support.bearing.clearance, bench, jnp.asarray(50e-6, dtype=float))
    rhs_jit(bench2, y0)

    q, qd, v = y0
    q = q.at[stage.layout.planet_xy.start].set(100.5e-6)  # planet 0 pressed into its pin
    grads = _summary_gradient(stage, q, qd, v)  # with respect to every inexact array of the stage
    g_c = grads.planet_support.bearing.clearance
    g_b = grads.sun_mesh.backlash
    assert np.all(np.isfinite(np.asarray(g_c))) and float(g_c) != 0.0
    assert np.all(np.isfinite(np.asarray(g_b)))
    # AD against a central finite difference of the planet clearance.
    h = 1e-9

    def at(c):
        return _summary(eqx.tree_at(lambda s: s.planet_support.bearing.clearance, stage, jnp.asarray(c)), q, qd, v)

    fd = (at(100e-6 + h) - at(100e-6 - h)) / (2 * h)
    np.testing.assert_allclose(float(g_c), float(fd), rtol=1e-5)


def test_unknown_support_kind_is_rejected():
    with pytest.raises(ValueError, match=r"sun_support='loose'\) is unknown"):
        tx.default_stage(sun_support="loose")
    with pytest.raises(ValueError, match="do not assemble"):
        tx.default_stage(ring_teeth=81)
