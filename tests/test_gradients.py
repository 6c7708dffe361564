"""Pointing-error gradients against central finite differences in float64 at several design
points, on a lumped-joint scene (the scan) and a planetary-joint scene (the bench), including
points where a contact has only just started to carry load; and the batching identities
vmap-of-grad == grad-of-vmap == per-point grad (issue 12).

How the points near contact onset are found. In a run with the clearance (or backlash) opened
so wide that the contact never closes, record the displacement that the contact would see: the
output bearing's journal eccentricity $|e(t)|$, or the lumped mesh's deflection $g(t)$ against
the back flank's gap. Setting the clearance to that displacement at a time $t_{on}$ makes the
contact close at $t_{on}$ and carry load from then on (the motion before $t_{on}$ does not see
the clearance at all). Choosing $t_{on}$ just before the end of the horizon puts the design
just on the contact side of onset: its derivative is non-zero but comes from the last few
milliseconds, where the smoothed contact switches on.

Accuracy budget. The relative tolerance 1e-4 is met only if central differences are better than
that: the solver is tightened (rtol 1e-10, atol 1e-13 in SI units, against clearances of tens of
um) and the step h is far below the smoothing width w (1 um) that sets the scale of the
objective's curvature near a contact, yet large enough that solver noise / h stays small. Each
check computes the differences at two steps and asserts that they agree to 1e-5, which bounds
the differences' own truncation and noise, before comparing them with the gradient.

On the planetary bench, where every contact carries load, the curvature is larger: a central
difference's truncation error $h^2 f'''/6$ is ~(h/w)^2 relative: 2e-5 at h = 10 nm and 9e-5 at
20 nm at 5 um everywhere, falling fourfold per halving of h (measured; the same with the
solver's steps frozen, so it is truncation, not the adaptive steps' noise), and larger where a
contact only grazes. Those checks extrapolate (Richardson: the $h^2$ term cancels in
$(4 D(h/2) - D(h))/3$) from three steps and require the two extrapolations to agree.
"""


import dataclasses

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax.mechanism.outputs import pointing_metrics


# Two tiers. The default run checks each property once, cheaply: a forward-mode directional
# derivative (one tangent through the solve) against central differences along the same
# direction, at a point of contact onset, on the lumped scan and on the planetary bench; and
# the batching identities on the bench over a short horizon. The `slow` tests enlarge them: the
# full gradient (every feature, reverse mode on the scan) at every design point, each a program
# that compiles for minutes on CI's 2 cores (one point took 500 s wall there).

WIDTH = 1e-6  # m: the optimiser's continuation width at which pointing gradients are meaningful
RTOL, ATOL = 1e-10, 1e-13
STEPS = (2e-8, 1e-8)  # m: two central-difference steps, both << WIDTH
FD_SPREAD = 1e-5  # the two steps agree to this: the differences resolve the derivative
# m: three steps, two Richardson extrapolations (planetary). At the "mixed" point a contact only
# grazes (penetration << w) and the curvature scale is smaller still: there the extrapolations
# from 20, 10, 5 nm disagree by 8e-4, those from 5, 2.5, 1.25 nm by 3e-5 (AD-FD 2e-6; measured
# alike with the solver's steps frozen, so not step noise).
RICHARDSON_STEPS = (5e-9, 2.5e-9, 1.25e-9)
RICHARDSON_SPREAD = 1e-4  # the two extrapolations agree to this
AD_VS_FD = 1e-4  # the requirement where the objective is smooth
OPEN = 1e-3  # m: a clearance or backlash so wide that its contact never closes in the horizon


def _central(f, p, h):
    return np.array([(float(f(p.at[k].add(h))) - float(f(p.at[k].add(-h)))) / (2 * h) for k in range(p.shape[0])])


def _check_against_differences(f, grad, p):
    """AD against central differences at `p`; returns (ad, fd) for further checks."""
    ad = np.asarray(grad(p))
    fd_coarse, fd = (_central(f, p, h) for h in STEPS)
    scale = np.linalg.norm(fd)
    spread = np.linalg.norm(fd_coarse - fd) / scale
    error = np.linalg.norm(ad - fd) / scale
    print(f"\n  p = {np.asarray(p) * 1e6} um\n  AD = {ad * 1e-6}\n  FD = {fd * 1e-6} (per um)\n  spread {spread:.1e}, AD-FD {error:.1e}")
    assert spread < FD_SPREAD
    assert error < AD_VS_FD
    return ad, fd


def _check_against_extrapolated_differences(f, grad, p):
    """AD against Richardson-extrapolated central differences at `p` (module docstring);
    returns (ad, fd)."""
    ad = np.asarray(grad(p))
    d = [_central(f, p, h) for h in RICHARDSON_STEPS]  # each step half the one before
    coarse, fd = ((4 * fine - wide) / 3 for wide, fine in zip(d, d[1:]))
    scale = np.linalg.norm(fd)
    spread = np.linalg.norm(coarse - fd) / scale
    error = np.linalg.norm(ad - fd) / scale
    plain = [np.linalg.norm(ad - x) / scale for x in d]
    print(f"\n  p = {np.asarray(p) * 1e6} um\n  AD = {ad * 1e-6}\n  FD = {fd * 1e-6} (per um, extrapolated)"
          f"\n  plain differences at {RICHARDSON_STEPS} m: AD-FD {', '.join(f'{e:.1e}' for e in plain)}"
          f"\n  extrapolations' spread {spread:.1e}, AD-FD {error:.1e}")
    assert spread < RICHARDSON_SPREAD
    assert error < AD_VS_FD
    return ad, fd


# -- lumped joint: the azimuth scan ---------------------------------------------------------------

LUMPED_HORIZON = 0.3  # s: one reversal (0.25 s); before the output bearing's second impact (~0.4 s)


class _Lumped:
    """The scan scene at lumped fidelity with its compiled objective, gradient and probe."""

    def __init__(self):
        self.scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
        self.pointing = tx.PointingObjective(
            self.scene, duration=LUMPED_HORIZON, settle=0.0, start="steady", n_save=61,
            integrator=tx.Integrator(rtol=RTOL, atol=ATOL, max_steps=400_000),
        )
        rms = lambda p: self.pointing(p, WIDTH)["pointing_rms"]  # noqa: E731
        self.grad = eqx.filter_jit(jax.grad(rms))
        joint = self.scene.azimuth
        lever, ratio, lay = tx.lumped_mesh(joint.stage, joint.motor_inertia).lever, joint.stage.ratio, joint.layout
        sq = self.scene.layout.azimuth_q

        @eqx.filter_jit
        def observe(p):
            # The objective (the objective's own metric of the same run: `pointing_rms` over every
            # save, settle 0) and, from that run (one compiled program for both), the displacements
            # the two contacts see: the output bearing's eccentricity (m) and the lumped mesh
            # deflection g (m; the back flank closes at g = -back_gap).
            run = self.pointing.run(p, WIDTH)
            q = run.states[0][:, sq]
            return (pointing_metrics(run, run.ts >= 0.0)["pointing_rms"], jnp.hypot(q[:, lay.carrier_xy][:, 0], q[:, lay.carrier_xy][:, 1]),
                    lever * (q[:, lay.sun] / ratio - q[:, lay.carrier]))

        self.f = lambda p: observe(p)[0]
        self.probe = lambda p: observe(p)[1:]
        self.ts = np.linspace(0.0, LUMPED_HORIZON, 61)
        self.kappa = float(jnp.cos(joint.stage.sun_pressure_angle) + jnp.cos(joint.stage.ring_pressure_angle))

    def bearing_onset(self, t_on, pin, backlash):
        """Output-bearing clearance (m) at which the journal first touches at `t_on` (s): its
        eccentricity at `t_on` in a run with the bearing open."""
        ecc, _ = self.probe(jnp.array([OPEN, pin, backlash, backlash]))
        return float(np.interp(t_on, self.ts, np.asarray(ecc)))

    def back_flank_onset(self, t_on, bearing, pin):
        """Per-mesh backlash (m, sun and ring alike) at which the back flank first closes at
        `t_on` (s): the lumped mesh's back gap $b_s + b_r + \\kappa c_p$ equals $-g(t_{on})$ in
        a run with the backlash open."""
        _, g = self.probe(jnp.array([bearing, pin, OPEN, OPEN]))
        back_gap = -float(np.interp(t_on, self.ts, np.asarray(g)))
        backlash = 0.5 * (back_gap - self.kappa * pin)
        assert backlash > 0, "the chosen onset time leaves no room for backlash"
        return backlash


@pytest.fixture(scope="module")
def lumped():
    return _Lumped()


def _lumped_point(lumped, name):
    t_late = LUMPED_HORIZON - 0.02  # the contact carries load for the last 20 ms
    if name == "both at onset":
        pin = 50e-6
        backlash = lumped.back_flank_onset(t_late, OPEN, pin)
        return jnp.array([lumped.bearing_onset(t_late, pin, OPEN), pin, backlash, backlash])
    if name == "bearing at onset":
        pin, backlash = 40e-6, 30e-6  # back flank closes at ~0.24 s
        return jnp.array([lumped.bearing_onset(t_late, pin, backlash), pin, backlash, backlash])
    if name == "back flank at onset":
        bearing, pin = 80e-6, 50e-6  # the journal first hits the bearing at ~0.17 s
        backlash = lumped.back_flank_onset(t_late, bearing, pin)
        return jnp.array([bearing, pin, backlash, backlash])
    return {
        "both in contact": jnp.array([60e-6, 30e-6, 20e-6, 40e-6]),
        "baseline bearing, tight meshes": jnp.array([100e-6, 40e-6, 10e-6, 25e-6]),
    }[name]


LUMPED_DEFAULT = ["both at onset"]
LUMPED_SLOW = ["bearing at onset", "back flank at onset", "both in contact", "baseline bearing, tight meshes"]


def _directional(f, jvp, p, d, steps):
    """`(jvp, central differences along d at each of steps)`: the derivative of `f` at `p` along
    the direction `d` by the tangent, and by differences."""
    tangent = float(jvp(p, d))
    return tangent, [(float(f(p + h * d)) - float(f(p - h * d))) / (2 * h) for h in steps]


def test_lumped_scan_directional_derivative_at_contact_onset(lumped):
    """At the point where both the output bearing and the back flank first close 20 ms before
    the end of the horizon ("both at onset", module docstring): the forward-mode derivative of
    the scan's RMS pointing error along a random direction of the four features against central
    differences along it at 20 and 10 nm (which agree to `FD_SPREAD`), to `AD_VS_FD`; the
    reverse-mode gradient (`jax.grad` through diffrax's checkpointed adjoint) along the same
    direction equals the tangent to 1e-10 (the same derivative of the same discrete solve by
    another route: they differ by rounding pulled back and pushed forward through the steps,
    measured 2e-14 here); sun and ring backlash enter the lumped mesh only through their sum, so
    their reverse-mode derivatives are equal. The same point, every feature, against
    differences: `test_lumped_scan_gradients_against_finite_differences` (slow)."""
    p = _lumped_point(lumped, "both at onset")
    d = jnp.asarray(np.random.default_rng(3).normal(size=4))
    d = d / jnp.linalg.norm(d)
    forward = dataclasses.replace(lumped.pointing, adjoint=diffrax.ForwardMode())
    jvp = eqx.filter_jit(lambda p_, d_: jax.jvp(lambda u: forward(u, WIDTH)["pointing_rms"], (p_,), (d_,))[1])
    tangent, (coarse, fine) = _directional(lumped.f, jvp, p, d, STEPS)
    reverse = np.asarray(lumped.grad(p))
    print(f"\n  jvp {tangent:.6e}, reverse - jvp {(reverse @ np.asarray(d) - tangent) / tangent:.1e} (relative), differences "
          f"{coarse:.6e} {fine:.6e}")
    assert abs(coarse - fine) < FD_SPREAD * abs(fine)
    assert abs(tangent - fine) < AD_VS_FD * abs(fine)
    assert abs(reverse @ np.asarray(d) - tangent) < 1e-10 * abs(tangent)
    assert reverse[2] == pytest.approx(reverse[3], rel=1e-9)


@pytest.mark.slow
@pytest.mark.parametrize("name", LUMPED_DEFAULT + LUMPED_SLOW)
def test_lumped_scan_gradients_against_finite_differences(lumped, name):
    """Reverse-mode gradient of the RMS pointing error over 0.3 s of the scan against central
    differences, at a design point (see the module docstring for the onset points). Enlarges
    `test_lumped_scan_directional_derivative_at_contact_onset` (every feature, reverse mode,
    five points) and tests/test_design.py::test_scan_gradients_against_finite_differences (the
    solver tightened to 1e-10: the tolerance 1e-4 instead of 2e-3)."""
    p = _lumped_point(lumped, name)
    ad, fd = _check_against_differences(lumped.f, lumped.grad, p)
    # Every derivative is non-trivial at these points: both contacts carry load within the
    # horizon, so each of the four features moves the pointing error.
    assert np.all(np.abs(fd) > 1e-3 * np.linalg.norm(fd))
    # Sun and ring backlash enter the lumped mesh only through their sum.
    assert ad[2] == pytest.approx(ad[3], rel=1e-9)


@pytest.mark.slow
def test_lumped_vmap_of_grad_equals_grad_of_vmap(lumped):
    """Batching commutes with differentiation through the adaptive solve: each sample of a
    vmapped solve takes its own steps, so `vmap(grad f)`, `grad(sum(vmap f))` and the per-point
    gradients are the same numbers up to rounding. Enlarges
    `test_bench_vmap_of_jvp_equals_jvp_of_vmap` (reverse mode, the lumped scan over 0.3 s, three
    points)."""
    batch = jnp.stack([_lumped_point(lumped, name) for name in ("both in contact", "baseline bearing, tight meshes")])
    batch = jnp.concatenate([batch, batch[:1] * 1.3])
    rms = lambda p: lumped.pointing(p, WIDTH)["pointing_rms"]  # noqa: E731
    vmap_of_grad = np.asarray(eqx.filter_jit(jax.vmap(jax.grad(rms)))(batch))
    grad_of_vmap = np.asarray(eqx.filter_jit(jax.grad(lambda b: jnp.sum(jax.vmap(rms)(b))))(batch))
    per_point = np.stack([np.asarray(lumped.grad(p)) for p in batch])
    scale = np.linalg.norm(per_point, axis=1, keepdims=True)
    print(f"\n  vmap(grad) vs grad(vmap): {np.max(np.abs(vmap_of_grad - grad_of_vmap) / scale):.1e}; "
          f"vs per point: {np.max(np.abs(vmap_of_grad - per_point) / scale):.1e}")
    np.testing.assert_allclose(vmap_of_grad / scale, grad_of_vmap / scale, rtol=0, atol=1e-12)
    # Against the unbatched program: measured 1.1e-12 (batched and unbatched kernels round
    # differently, and ~3000 steps carry the last-bit differences); vmap(grad) and grad(vmap)
    # agreed exactly (0.0).
    np.testing.assert_allclose(vmap_of_grad / scale, per_point / scale, rtol=0, atol=1e-11)


# -- planetary joint: the bench ---------------------------------------------------------------------

BENCH_HORIZON = 0.02  # s from rest: the servo's start-up closes every play within ~5 ms


class _Bench:
    """The planetary stage on its bench, from rest (the start-up loads every contact), with the
    RMS output angle error (arcsec) as objective."""

    def __init__(self):
        bench = tx.TestBench()
        self.bench = eqx.tree_at(lambda b: b.stage.smoothing_width, bench, jnp.asarray(WIDTH))
        # Forward mode (the optimiser's default, `RobustPointing(adjoint=None)`): five
        # tangents through one solve, 4.8x a forward solve here against ~10x for reverse mode.
        self.grad = eqx.filter_jit(jax.jacfwd(lambda p: self.rms(p, diffrax.ForwardMode())))
        # One tangent (a direction `d` of the five features) through one solve.
        self.jvp = eqx.filter_jit(lambda p, d: jax.jvp(lambda u: self.rms(u, diffrax.ForwardMode()), (p,), (d,))[1])
        self.ts = np.linspace(0.0, BENCH_HORIZON, 41)
        lay = bench.stage.layout

        @eqx.filter_jit
        def observe(p):
            # The objective and, from the same run (one compiled program for both), the
            # eccentricities (m) of the sun and the carrier in their bearings.
            run = self.run(p)
            q = run.states[0]
            rms = jnp.sqrt(jnp.mean((run.output_angle_error / tx.ARCSEC) ** 2))
            return rms, jnp.linalg.norm(q[:, lay.sun_xy], axis=1), jnp.linalg.norm(q[:, lay.carrier_xy], axis=1)

        self.f = lambda p: observe(p)[0]
        self.probe = lambda p: observe(p)[1:]

    def run(self, p, adjoint=None):
        return tx.simulate(tx.with_design(self.bench, p), BENCH_HORIZON, n_save=41, throw=False, adjoint=adjoint,
                           integrator=tx.Integrator(rtol=RTOL, atol=ATOL, max_steps=400_000))

    def rms(self, p, adjoint=None):
        return jnp.sqrt(jnp.mean((self.run(p, adjoint).output_angle_error / tx.ARCSEC) ** 2))

    def onset(self, which, t_on, p):
        """Sun (`which=0`) or carrier (1) clearance (m) at which that member first touches its
        bearing at `t_on` (s): its eccentricity at `t_on` with the bearing open."""
        ecc = self.probe(p.at[which].set(OPEN))[which]
        return float(np.interp(t_on, self.ts, np.asarray(ecc)))


@pytest.fixture(scope="module")
def bench():
    return _Bench()


def _bench_point(bench, name):
    base = jnp.array([5e-6, 5e-6, 5e-6, 5e-6, 5e-6])
    t_late = 0.8 * BENCH_HORIZON
    if name == "sun bearing at onset":
        return base.at[0].set(bench.onset(0, t_late, base))
    if name == "carrier bearing at onset":
        return base.at[1].set(bench.onset(1, t_late, base))
    return {
        "5 um everywhere": base,
        "mixed": jnp.array([8e-6, 4e-6, 6e-6, 3e-6, 7e-6]),
        "loose pins": jnp.array([5e-6, 3e-6, 10e-6, 5e-6, 5e-6]),
    }[name]


def test_bench_directional_derivative_at_contact_onset(bench):
    """The planetary stage on its bench, at the point where the carrier first touches its
    bearing 4 ms before the end of the start-up: the forward-mode derivative of the RMS output
    angle error along a random direction of the five features against Richardson-extrapolated
    central differences along it (from 5, 2.5 and 1.25 nm; the two extrapolations agree to
    `RICHARDSON_SPREAD`), to `AD_VS_FD`. Every feature at five points:
    `test_bench_gradients_against_finite_differences` (slow)."""
    p = _bench_point(bench, "carrier bearing at onset")
    d = jnp.asarray(np.random.default_rng(4).normal(size=5))
    d = d / jnp.linalg.norm(d)
    tangent, plain = _directional(bench.f, bench.jvp, p, d, RICHARDSON_STEPS)
    coarse, fine = ((4 * b - a) / 3 for a, b in zip(plain, plain[1:]))
    print(f"\n  jvp {tangent:.6e}, differences {plain}, extrapolated {coarse:.6e} {fine:.6e}")
    assert abs(coarse - fine) < RICHARDSON_SPREAD * abs(fine)
    assert abs(tangent - fine) < AD_VS_FD * abs(fine)


def test_bench_vmap_of_jvp_equals_jvp_of_vmap(bench):
    """Batching commutes with differentiation through the adaptive solve, on the planetary bench's
    start-up: each sample of a vmapped solve takes its own steps, so the forward-mode
    derivatives of a batch of units (two design points, each along its own direction) through
    the vmapped solve (`jvp` of `vmap`) equal the per-point derivatives of
    `test_bench_directional_derivative_at_contact_onset`'s program to the solver's tolerance
    (batched and unbatched kernels round differently, and an adaptive solve can take another
    step sequence from a rounding-level difference: then the two differ by the integration
    error at rtol 1e-10, not by rounding). vmap(jvp) == jvp(vmap) and reverse mode on the lumped
    scan: `test_lumped_vmap_of_grad_equals_grad_of_vmap` (slow)."""
    batch = jnp.stack([_bench_point(bench, "mixed"), _bench_point(bench, "5 um everywhere")])
    directions = jnp.asarray(np.random.default_rng(5).normal(size=(2, 5)))
    directions = directions / jnp.linalg.norm(directions, axis=1, keepdims=True)
    forward = lambda p: bench.rms(p, diffrax.ForwardMode())  # noqa: E731
    # One batched program, the jvp of the vmapped solve (what a robust objective's forward-mode
    # gradient over units is), against the unbatched derivatives. The identity vmap(jvp) ==
    # jvp(vmap) itself (bitwise here when both were compiled: measured) needs a second ~25 s
    # program: checked in reverse mode by `test_lumped_vmap_of_grad_equals_grad_of_vmap` (slow).
    jvp_of_vmap = np.asarray(eqx.filter_jit(lambda b, d: jax.jvp(jax.vmap(forward), (b,), (d,))[1])(batch, directions))
    per_point = np.array([float(bench.jvp(p, d)) for p, d in zip(batch, directions)])
    print(f"\n  jvp(vmap) {jvp_of_vmap}, per point {per_point}")
    assert np.all(np.abs(per_point) > 0)
    np.testing.assert_allclose(jvp_of_vmap, per_point, rtol=1e-6)


@pytest.mark.slow
@pytest.mark.parametrize("name", ["5 um everywhere", "mixed", "loose pins", "sun bearing at onset", "carrier bearing at onset"])
def test_bench_gradients_against_finite_differences(bench, name):
    """Forward-mode gradient of the bench's RMS output angle error over its start-up (20 ms from
    rest: impacts close the backlash and push every member into its bearing) against
    extrapolated central differences, at a design point with all five clearances and backlashes
    of the planetary stage. Enlarges `test_bench_directional_derivative_at_contact_onset` (every
    feature, each on its own, at five points)."""
    p = _bench_point(bench, name)
    ad, fd = _check_against_extrapolated_differences(bench.f, bench.grad, p)
    # Every feature moves the objective and each derivative is right on its own, not only in
    # the norm: at the "mixed" point the sun barely touches its bearing and its derivative is
    # 5e-4 of the norm, yet AD and the differences agree on it to 3e-6 (all components: <= 6e-6
    # measured).
    np.testing.assert_array_less(np.abs(ad - fd), 1e-3 * np.abs(fd))
