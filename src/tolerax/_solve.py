"""One diffrax call shared by every scene (bench, mechanism), and its failure report.

A scene provides `vector_field(t, y, args)` and `observe(t, y)` (the forces and other
instantaneous quantities at a saved state); `solve` integrates it and evaluates `observe` at the
save times, in one compiled program per scene *structure* (values are passed as arrays).
"""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


class SimulationError(RuntimeError):
    """The integrator did not reach the final time."""


@eqx.filter_jit
def _solve(scene, y0, t1, ts, solver, rtol, atol, dt0, dtmax, max_steps, progress):
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(scene.vector_field),
        solver,
        t0=0.0,
        t1=t1,
        dt0=dt0,
        y0=y0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax),
        max_steps=max_steps,
        throw=False,
        progress_meter=diffrax.TextProgressMeter() if progress else diffrax.NoProgressMeter(),
    )
    observed = jax.vmap(scene.observe)(sol.ts, sol.ys)
    return sol, observed


def solve(scene, y0, duration, n_save, solver, rtol, atol, dt0, dtmax, max_steps, progress):
    """Integrate `scene` over `[0, duration]`, saving at `n_save` equally spaced times.

    Returns the diffrax `Solution` (with `throw=False`: check `sol.result`) and `observe` at
    the saved states. Numbers become float64 arrays so that changing them does not recompile.
    """
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive finite time in seconds, got {duration!r}.")
    if int(n_save) < 2:
        raise ValueError(f"n_save must be at least 2 (the start and the end), got {n_save!r}.")
    for name, value in (("rtol", rtol), ("atol", atol), ("dt0", dt0), ("dtmax", dtmax)):
        if not (np.isfinite(value) and value > 0):
            raise ValueError(f"{name} must be a positive finite number, got {value!r}.")
    f64 = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
    ts = jnp.linspace(0.0, duration, int(n_save))
    return _solve(
        scene, y0, f64(duration), ts, solver, f64(rtol), f64(atol), f64(dt0), f64(dtmax),
        int(max_steps), bool(progress),
    )


def raise_on_failure(sol, duration: float, what: str) -> None:
    """Raise `SimulationError` with the result code, the time reached and what to try."""
    if sol.result == diffrax.RESULTS.successful:
        return
    ys0 = jax.tree.leaves(sol.ys)[0]
    finite = np.all(np.isfinite(np.asarray(ys0).reshape(ys0.shape[0], -1)), axis=1)
    reached = float(np.asarray(sol.ts)[finite][-1]) if finite.any() else 0.0
    steps = int(sol.stats["num_accepted_steps"])
    raise SimulationError(
        f"The {what} simulation failed ({sol.result}) after {steps} steps; the last saved time "
        f"reached is {reached:.6g} s of {duration:.6g} s. Try a larger `max_steps`, looser "
        f"`rtol`/`atol`, or a larger `smoothing_width`; pass `throw=False` to inspect the result."
    )
