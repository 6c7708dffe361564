"""Numerical stability on hard cases (issue 5).

For every case: the solver succeeds or returns an explicit failure result (never NaN presented as
numbers); when it succeeds, the outputs and the gradient of an output-error objective with
respect to the five clearances and backlashes are finite (forward mode, along a direction with
every component nonzero: `_directional`); invariants are checked where they
apply (symmetry, momentum; energy without damping is `test_planetary.py::
test_stage_energy_conserved_without_damping`, with contacts).

Each hard case is a *value* of one scene structure, the default stage on its bench saved at
`N_SAVE` times, so that one compiled forward program (the one `test_bench.py` and
`test_validation.py` run too: the run's compilation cache serves it) and one compiled derivative
serve them all: stiffness, smoothing width, clearances, restitution, damping, speed and a
reversing drive are numbers in that structure, not new programs. Every run starts from the
steady-rolling state (meshes closed, bearings centred) with every journal thrown at its bearing,
so the joint rattles from the start: a journal thrown at 0.2 m/s crosses a 100 µm clearance and
hits in 0.5 ms, so 2 ms hold the first impacts (the step-size collapse onto the contact, a
peak force of ~13 kN) and the rattle after them; a longer run repeats the same impacts, at
2.2-2.6x the steps for 5 ms. The full-size variants (the antenna mechanism at planetary fidelity, the
Adams law's own programs, 600 s) are `slow`.
"""

import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax import contact as C, mesh as _mesh, planetary as P

DURATION = 2e-3  # s: long enough for every journal to cross its clearance and hit (module docstring)
N_SAVE = 51  # the bench's save grid in this file, test_bench.py and test_validation.py: one program
NOMINAL = np.array([100e-6, 100e-6, 100e-6, 100e-6, 100e-6])  # design vector, tx.design_names(bench) order


KICK = 0.2  # m/s: initial speed of every bearing journal, so that impacts come within 0.5 ms


def _bench_case(rate_deg=0.98, kick=KICK, planets_only=False, start_rate_deg=None, **stage):
    """The bench with `stage` overrides, and a start in steady rolling with every journal thrown
    at its bearing (`kick`, m/s; sun and carrier along x and y, planets tangentially, the way
    their drive flanks open: radially they are held by the ring mesh within ~10 µm). The start
    rolls at `start_rate_deg` (deg/s) where given, else at the commanded `rate_deg`."""
    bench = tx.TestBench(tx.default_stage(**stage), servo=tx.SpeedServo(math.radians(rate_deg)))
    start = bench if start_rate_deg is None else tx.TestBench(bench.stage, servo=tx.SpeedServo(math.radians(start_rate_deg)))
    q, qd, _ = start.initial_state("steady")
    lay = bench.stage.layout
    if not planets_only:
        qd = qd.at[lay.sun_xy].set(jnp.array([kick, 0.0])).at[lay.carrier_xy].set(jnp.array([0.0, kick]))
    qd = qd.at[lay.planet_xy].set(jnp.tile(jnp.array([0.0, kick]), bench.stage.n_planets))
    return bench, (q, qd, P.initial_impact_rates(bench.stage, q, qd))


def _objective(bench, p, y0, adjoint=None):
    """Mean square transmission error plus output angle error (rad^2) over the run."""
    res = tx.simulate(tx.with_design(bench, p), DURATION, n_save=N_SAVE, y0=y0, throw=False, adjoint=adjoint)
    return jnp.mean(res.transmission_error**2) + jnp.mean(res.output_angle_error**2)


# The derivative along one direction with every component nonzero, by forward mode (the design
# optimiser's default gradient): finite exactly where every feature's partial derivative is (a
# NaN or an infinity in any one reaches it). One tangent through the solve compiles in ~11 s
# where reverse mode's checkpointed adjoint took ~36 s (measured alone); reverse mode through
# the adaptive solve is checked on the lumped scan (test_gradients.py), and on these cases by
# `test_bench_hard_case_reverse_mode` (slow: reverse mode's own NaN traps).
_DIRECTION = jnp.asarray([0.9, -0.6, 0.7, 1.1, -0.8])
_grad = eqx.filter_jit(jax.grad(_objective, argnums=1))  # reverse mode: the slow variant
_directional = eqx.filter_jit(
    lambda bench, p, y0: jax.jvp(lambda u: _objective(bench, u, y0, diffrax.ForwardMode()), (p,), (_DIRECTION,))[1])


def _assert_finite_run(res):
    """Success with finite outputs, or an explicit failure code: never NaN as numbers."""
    if not res.success:
        assert res.result != diffrax.RESULTS.successful and res.failures()
        return False
    for name in ("output_angle", "transmission_error", "contact_force", "sun_mesh_force", "ring_mesh_force"):
        assert np.all(np.isfinite(np.asarray(getattr(res, name)))), name
    assert float(res.t_reached) == pytest.approx(res.duration)
    return True


def _assert_finite_gradient(bench, y0):
    g = _directional(bench, tx.design_of(bench), y0)
    assert np.isfinite(float(g)), g


BENCH_CASES = {
    "nominal (eps = 1e-9 m)": dict(),
    "exact limit eps = 0": dict(smoothing_width=0.0),
    "zero clearance and backlash": dict(sun_clearance=0.0, carrier_clearance=0.0, planet_clearance=0.0, backlash=0.0),
    # Thrown at 1 m/s, so that the journals fly across their 1 mm and hit within 2 ms.
    "1 mm clearances (free rattling)": dict(sun_clearance=1e-3, carrier_clearance=1e-3, planet_clearance=1e-3, kick=1.0),
    "restitution 0.1": dict(restitution=0.1),
    "restitution 1.0": dict(restitution=1.0),
    "no damping": dict(restitution=1.0, mesh_damping_ratio=0.0, bearing_damping=0.0),
    "high speed 30 deg/s": dict(rate_deg=30.0),
    # The stiffest material the stage accepts: the bearings' Bai-Zhao force L pi E*/2
    # d^1.5 / sqrt(2 c) is ~5e11 N/m^1.5 (steel's ~1e11; the paper's Adams law 1e7) and the
    # meshes 5x stiffer, their modes sqrt(5)x faster: stiffer, shorter impacts.
    "stiff contacts and meshes (Young 1e12 Pa)": dict(young=1e12),
}


@pytest.mark.parametrize("case", list(BENCH_CASES))
def test_bench_hard_case(case):
    bench, y0 = _bench_case(**BENCH_CASES[case])
    res = tx.simulate(bench, DURATION, n_save=N_SAVE, y0=y0, throw=False)
    assert _assert_finite_run(res), res.report()
    assert np.asarray(res.contact_force).max() > 0.0 or case == "zero clearance and backlash"
    _assert_finite_gradient(bench, y0)


@pytest.mark.slow
@pytest.mark.parametrize("case", ["nominal (eps = 1e-9 m)", "exact limit eps = 0", "zero clearance and backlash",
                                  "1 mm clearances (free rattling)"])
def test_bench_hard_case_reverse_mode(case):
    """Reverse mode's own NaN traps (a zero cotangent times an infinite local derivative in a
    branch `where` did not take, which forward mode never forms): the gradient by `jax.grad`
    through diffrax's checkpointed adjoint, finite on the hard cases where contacts sit at their
    limits. Enlarges `test_bench_hard_case` (forward mode, every case): its program compiles in
    ~36 s alone against forward mode's ~11 s, which the default tier could no longer afford."""
    bench, y0 = _bench_case(**BENCH_CASES[case])
    g = _grad(bench, tx.design_of(bench), y0)
    assert np.all(np.isfinite(np.asarray(g))), g


@pytest.mark.slow
def test_contact_stiffness_1e11():
    """The Adams law at 1e11 N/m^1.5 (10^4 times the paper's 1e7) on the bench: a stiffer,
    shorter impact, with the law's own compiled forward and gradient programs (~60 s to build).
    Enlarges `test_bench_hard_case[stiff contacts and meshes (Young 1e12 Pa)]` (the same
    property at 5x that stiffness on the default law, in the shared programs) and
    `test_contact.py::test_adams_matches_exact_at_1e11` (the Adams law at 1e11 on one impact)."""
    bench, y0 = _bench_case(contact_law=C.AdamsImpact(stiffness=1e11))
    res = tx.simulate(bench, DURATION, n_save=N_SAVE, y0=y0, throw=False)
    assert _assert_finite_run(res), res.report()
    assert np.asarray(res.contact_force).max() > 0.0
    _assert_finite_gradient(bench, y0)


def test_reversing_drive_crosses_the_backlash():
    """The drive reverses: the bench rolls steadily at +90 deg/s and the servo commands -90 deg/s
    (no kick). The motor turns back and its sun crosses the backlash onto the back flanks (sun
    mesh force < 0: `BenchResult`'s sign convention; first saved at 1.48 ms), within the run:
    the hardness of the paper's reversing torque (`test_reversing_torque_drive`, slow, runs that
    on the antenna mechanism at planetary fidelity over 30 ms). Finite run and finite gradient
    through it."""
    bench, y0 = _bench_case(rate_deg=-90.0, start_rate_deg=90.0, kick=0.0)
    res = tx.simulate(bench, DURATION, n_save=N_SAVE, y0=y0, throw=False)
    assert _assert_finite_run(res), res.report()
    sun_rate = np.asarray(res.states[1])[:, bench.stage.layout.sun_theta]
    assert sun_rate[0] > 0.0 and sun_rate[-1] < 0.0  # the motor turned back
    mesh = np.asarray(res.sun_mesh_force)
    assert mesh[0].min() >= 0.0 and mesh.min() < -10.0, mesh.min()  # from the drive flanks to the back flanks
    _assert_finite_gradient(bench, y0)


def test_grazing_contact():
    # Planet 0 starts exactly on its pin's clearance circle (penetration 0) moving along it
    # (penetration rate 0): the contact switch, the impact-rate state and its floor all sit at
    # their edge at t = 0.
    bench, (q, qd, v) = _bench_case(kick=0.0)
    lay = bench.stage.layout
    c = float(bench.stage.planet_support.bearing.clearance)
    q = q.at[lay.planet_xy.start].set(c)
    qd = qd.at[lay.planet_xy.start + 1].set(1e-3)
    v = P.initial_impact_rates(bench.stage, q, qd)
    y0 = (q, qd, v)
    res = tx.simulate(bench, DURATION, n_save=N_SAVE, y0=y0, throw=False)
    assert _assert_finite_run(res), res.report()
    _assert_finite_gradient(bench, y0)


def test_all_planets_engage_at_once():
    # Equally spaced planets, sun and carrier centred, every mesh closed at t = 0: by symmetry the
    # three planets carry the same loads and hit their pins at the same instant. Symmetry is an
    # invariant of the exact solution; numerically it holds to rounding until the rattle (a
    # chaotic system) amplifies it, so it is checked over the first 2 ms (the run's whole
    # horizon: its N_SAVE saves then come every 40 us).
    # Constant mesh stiffness (contact ratio 1): with 1.6 the planets' mesh phases z_s psi_n
    # differ (20/3 of a tooth apart), planet 0 sits at a stiffness peak and the others do not, and
    # the loads are rightly unequal.
    bench, y0 = _bench_case(planets_only=True, contact_ratio=1.0)
    res = tx.simulate(bench, DURATION, n_save=N_SAVE, y0=y0, throw=False)
    assert _assert_finite_run(res), res.report()
    names = res.contact_names
    pins = np.asarray(res.contact_force)[:, [names.index(f"planet{k}") for k in range(3)]]
    assert pins.max() > 1.0  # the planets hit their pins within 2 ms
    np.testing.assert_allclose(pins, pins[:, :1].repeat(3, axis=1), rtol=1e-6, atol=1e-6)
    mesh = np.asarray(res.sun_mesh_force)
    np.testing.assert_allclose(mesh, mesh[:, :1].repeat(3, axis=1), rtol=1e-6, atol=1e-6)
    # The sun's net bearing force cancels: it stays on its centre, so it never touches.
    assert np.asarray(res.contact_force)[:, names.index("sun")].max() == 0.0


@eqx.filter_jit
def _field_and_derivative(bench, y, tangent):
    """The bench's right-hand side at one state and its derivative along `tangent`: one compiled
    program (smaller than the Jacobian's)."""
    return jax.jvp(lambda y_: bench.vector_field(0.0, y_, None), (y,), (tangent,))


_backlash_and_slope = jax.jit(jax.value_and_grad(_mesh.dynamic_backlash), static_argnums=4)


def test_dynamic_backlash_at_the_arccos_edge():
    # Centres approaching by A0 (1 - cos a0) = 1.5 mm put arccos at the edge of its domain. A
    # planet pushed radially inwards by 1.4, 1.5 and 1.6 mm (the last beyond the edge, where the
    # argument is clipped): the right-hand side and its Jacobian stay finite, the backlash
    # gradient too. The Jacobian J is checked through its product with a dense random direction
    # t (no zero component): J t sums every column with a nonzero finite weight, so it is
    # non-finite wherever an entry of J is (NaN stays NaN, inf + finite is inf, inf - inf NaN).
    bench, (q, qd, v) = _bench_case(planet_clearance=1e-3)
    lay = bench.stage.layout
    rng = np.random.default_rng(0)
    tangent = jax.tree.map(lambda x: jnp.asarray(rng.uniform(0.5, 1.5, x.shape) * rng.choice([-1.0, 1.0], x.shape)), (q, qd, v))
    for push in (-1.4e-3, -1.5e-3, -1.6e-3, 1.6e-3):
        qp = q.at[lay.planet_xy.start].set(push)
        out, derivative = _field_and_derivative(bench, (qp, qd, v), tangent)
        for leaf in jax.tree.leaves((out, derivative)):
            assert np.all(np.isfinite(np.asarray(leaf))), push
    a0 = 25e-3
    cos0 = math.cos(math.radians(20.0))
    for a in (a0 * cos0 * (1 + 1e-13), a0 * cos0, a0 * cos0 * (1 - 1e-3)):
        for internal in (False, True):
            b, db = _backlash_and_slope(a, a0, math.radians(20.0), 1e-4, internal)
            assert np.isfinite(float(b)) and np.isfinite(float(db))


# --------------------------------------------------------------------------------------------
# The antenna mechanism


@pytest.mark.slow
def test_reversing_torque_drive():
    """The paper's Table 2 profile on the antenna mechanism: enlarges
    `test_reversing_drive_crosses_the_backlash` (the reversal on the bench, 2 ms, in the shared
    programs) to the planetary azimuth joint of the antenna over 30 ms, with the lumped
    joint's gradient; its own programs take ~45 s to build."""
    # 1.5 N m cos(2 pi t) on the azimuth output, shifted in phase so that it reverses at t = 5 ms:
    # the teeth cross the backlash to their back flanks. Planetary azimuth joint, ideal pitch,
    # fixed base.
    mech = tx.antenna("azimuth", fidelity=("planetary", "ideal"), drive="torque", base="fixed")
    mech = eqx.tree_at(lambda m: m.azimuth.drive.phase, mech, jnp.asarray(math.pi / 2 - 2 * math.pi * 5e-3))
    res = tx.simulate(mech, 0.03, n_save=61, throw=False)
    assert res.success, res.report()
    for leaf in (res.joint_angle, res.pointing_error, res.azimuth_contact):
        assert np.all(np.isfinite(np.asarray(leaf)))
    angle = np.asarray(res.joint_angle)[:, 0]
    rate = np.gradient(angle, np.asarray(res.ts))
    assert rate[np.asarray(res.ts) > 0.02].max() < 0.0  # the output turned back
    # Gradient of the mean square pointing error w.r.t. the azimuth stage's design, lumped
    # fidelity (the planetary reverse-mode program takes minutes to compile on 2 cores).
    lumped = tx.antenna("azimuth", fidelity=("lumped", "ideal"), drive="torque", base="fixed")
    lumped = eqx.tree_at(lambda m: m.azimuth.drive.phase, lumped, jnp.asarray(math.pi / 2 - 2 * math.pi * 5e-3))

    def objective(p):
        # The lumped azimuth joint's features: output bearing, pin play, sun and ring backlash.
        r = tx.simulate(tx.with_design(lumped, p), 0.03, n_save=61, throw=False)
        return jnp.mean(r.pointing_error**2)

    g = jax.jit(jax.grad(objective))(jnp.asarray(NOMINAL[1:]))
    assert np.all(np.isfinite(np.asarray(g))), g


def _long_horizon(duration):
    # Azimuth at 0.98 deg/s, lumped joint (100 um clearances), ideal pitch, free-floating base:
    # over the run the output turns by 0.98 duration degrees; momentum must not drift and the
    # output must keep tracking (no secular growth of the error).
    mech = tx.antenna("azimuth", fidelity=("lumped", "ideal"))
    res = tx.simulate(mech, duration, n_save=201, start="steady", throw=False, integrator=tx.Integrator(rtol=1e-8, atol=1e-11))
    assert res.success, res.report()
    lin = np.asarray(res.momentum)
    ang = np.asarray(res.angular_momentum)
    # Scales: the reflector moving at the commanded rate (linear: m v with v = 0.25 m Omega;
    # angular: I Omega), i.e. the momentum that the joint exchanges with the base.
    omega = math.radians(0.98)
    lin_scale = 8.005 * 0.25 * omega
    ang_scale = 1.05956 * omega
    assert np.abs(lin - lin[0]).max() / lin_scale < 1e-6
    assert np.abs(ang - ang[0]).max() / ang_scale < 1e-6
    err = np.asarray(res.joint_angle)[:, 0] - np.asarray(res.commanded_angle)[:, 0]
    assert np.all(np.isfinite(err))
    lm = float(tx.lumped_mesh(mech.azimuth.stage, mech.azimuth.motor_inertia).lost_motion)
    # The output stays within its lost motion plus the servo's elastic lag of the commanded angle.
    assert np.abs(err).max() < 2 * lm, (np.abs(err).max(), lm)
    return res


def test_long_horizon_lumped_short():
    """The default run's size of the 600 s case (`-m slow` runs the full horizon)."""
    _long_horizon(5.0)


@pytest.mark.slow
def test_long_horizon_lumped_600s():
    _long_horizon(600.0)


def test_batch_failures_are_per_sample():
    # Three runs in one vmap, the middle one with a NaN in its initial state (a stand-in for a
    # right-hand side that returns NaN). Each reports its own result code and time reached; the
    # NaN run must end quickly (dt_min_reached after a few dozen rejected steps), not hold the
    # batch until max_steps, and the good runs are unaffected by their neighbour.
    bench, y0 = _bench_case(kick=0.0)
    bad = (y0[0].at[0].set(jnp.nan), y0[1], y0[2])
    batch = jax.tree.map(lambda *xs: jnp.stack(xs), y0, bad, y0)

    def run(y):
        return tx.simulate(bench, 2e-3, n_save=N_SAVE, y0=y, throw=False)

    res = jax.vmap(run)(batch)
    assert res.success.tolist() == [True, False, True]
    assert int(res.num_steps[1]) == 0 and int(res.num_rejected[1]) < 100
    assert res.result._value.tolist()[1] == diffrax.RESULTS.dt_min_reached._value
    single = run(y0)
    # Batched and single runs round differently (vectorised kernels), and the step-size control
    # turns rounding into slightly different steps: they agree to the tolerance (atol 1e-9 rad).
    np.testing.assert_allclose(np.asarray(res.output_angle)[0], np.asarray(single.output_angle), rtol=0, atol=1e-8)
    np.testing.assert_allclose(np.asarray(res.output_angle)[0], np.asarray(res.output_angle)[2], rtol=1e-12)
    (line,) = res.failures()
    assert line.startswith("sample 1: ") and "dt_min_reached" in line and "t = 0 s" in line
    assert res.report().startswith("2 of 3 runs reached 0.002 s.")
    with pytest.raises(ValueError, match="throw=False"):
        jax.vmap(lambda y: tx.simulate(bench, 2e-3, n_save=N_SAVE, y0=y))(batch)
    # A concrete NaN state is refused before anything runs.
    with pytest.raises(ValueError, match=r"y0\[0\] contains NaN or inf"):
        run(bad)
