"""The bench's design vector and its pointing objective, shared by the gradient and Monte Carlo
benchmarks."""

import math

import diffrax
import equinox as eqx
import jax.numpy as jnp

from tolerax import _solve

ARCSEC = 180 / math.pi * 3600

NAMES = ("sun clearance", "carrier clearance", "planet clearance", "sun backlash", "ring backlash")


def with_design(bench, p):
    """`bench` with its stage's clearances and backlash set from `p` (m), in `NAMES` order
    (all planets alike). Traceable: `p` may be a tracer (grad, vmap)."""
    stage = bench.stage
    n = stage.n_planets
    stage = eqx.tree_at(
        lambda s: (
            s.sun_support.bearing.clearance,
            s.carrier_support.bearing.clearance,
            s.planet_support.bearing.clearance,
            s.sun_mesh.backlash,
            s.ring_mesh.backlash,
        ),
        stage,
        (
            p[0],
            p[1],
            jnp.broadcast_to(p[2], jnp.shape(stage.planet_support.bearing.clearance)),
            p[3] * jnp.ones(n),
            p[4] * jnp.ones(n),
        ),
    )
    return eqx.tree_at(lambda b: b.stage, bench, stage)


def rms_output_error(bench, p, duration, rtol):
    """Run `bench` with design `p` from its initial state (Tsit5, atol = 1e-3 rtol, 101 saves).
    Returns the RMS output angle error (arcsec), whether the solve succeeded, and its step count."""
    scene = with_design(bench, p)
    sol, _ = _solve.solve(scene, scene.initial_state(), duration, 101, diffrax.Tsit5(), rtol, 1e-3 * rtol, 1e-6, 1e-3, 400_000, False)
    lay = bench.stage.layout
    err = (sol.ys[0][:, lay.carrier_theta] - bench.servo.output_rate * sol.ts) * ARCSEC
    ok = sol.result == diffrax.RESULTS.successful
    return jnp.sqrt(jnp.mean(err**2)), ok, sol.stats["num_steps"]
