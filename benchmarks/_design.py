"""The bench's design vector and its pointing objective, shared by the gradient and Monte Carlo
benchmarks."""

import math

import diffrax
import jax.numpy as jnp

from tolerax import _solve
from tolerax._design import NAMES, with_design  # noqa: F401 (NAMES: re-exported for gradient_cost)

ARCSEC = 180 / math.pi * 3600


def rms_output_error(bench, p, duration, rtol):
    """Run `bench` with design `p` from its initial state (Tsit5, atol = 1e-3 rtol, 101 saves).
    Returns the RMS output angle error (arcsec), whether the solve succeeded, and its step count."""
    scene = with_design(bench, p)
    sol, _ = _solve.solve(scene, scene.initial_state(), duration, 101, diffrax.Tsit5(), rtol, 1e-3 * rtol, 1e-6, 1e-3, 400_000, False)
    lay = bench.stage.layout
    err = (sol.ys[0][:, lay.carrier_theta] - bench.servo.output_rate * sol.ts) * ARCSEC
    ok = sol.result == diffrax.RESULTS.successful
    return jnp.sqrt(jnp.mean(err**2)), ok, sol.stats["num_steps"]
