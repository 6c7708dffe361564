"""The bench's pointing objective over its design vector (`tolerax.design_names`: every clearance
and backlash of the joint), shared by the gradient and Monte Carlo benchmarks."""

import diffrax
import jax.numpy as jnp

import tolerax


def rms_output_error(bench, p, duration, rtol):
    """Run `bench` with design `p` (m, `tolerax.design_names(bench)` order) from rest (Tsit5,
    atol = 1e-3 rtol, 101 saves, 400k-step budget). Returns the RMS output angle error (arcsec),
    whether the solve succeeded, and its accepted step count. Traceable (`jit`, `grad`, `vmap`)."""
    res = tolerax.simulate(
        tolerax.with_design(bench, p), duration, n_save=101, rtol=rtol, atol=1e-3 * rtol,
        max_steps=400_000, throw=False,
    )
    err = res.output_angle_error / tolerax.ARCSEC
    ok = res.result == diffrax.RESULTS.successful  # traceable; `res.success` is NumPy
    return jnp.sqrt(jnp.mean(err**2)), ok, res.num_steps
