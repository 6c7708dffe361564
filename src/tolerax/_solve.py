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
def _solve(scene, y0, t1, ts, solver, rtol, atol, dt0, dtmax, max_steps, progress, fixed=False):
    if fixed:
        controller = diffrax.ConstantStepSize()
    else:
        controller = diffrax.PIDController(rtol=rtol, atol=atol, dtmax=dtmax)
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(scene.vector_field),
        solver,
        t0=0.0,
        t1=t1,
        dt0=dt0,
        y0=y0,
        saveat=diffrax.SaveAt(ts=ts),
        stepsize_controller=controller,
        max_steps=max_steps,
        throw=False,
        progress_meter=diffrax.TextProgressMeter() if progress else diffrax.NoProgressMeter(),
    )
    # A fixed step beyond the stability limit, or an unstable model, can run to t1 "successfully"
    # with NaN or inf states: report that as a failure, never as numbers.
    finite = jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in jax.tree.leaves(sol.ys)]))
    silent = (sol.result == diffrax.RESULTS.successful) & ~finite
    sol = eqx.tree_at(lambda s: s.result, sol, diffrax.RESULTS.where(silent, diffrax.RESULTS.nonfinite, sol.result))
    observed = jax.vmap(scene.observe)(sol.ts, sol.ys)
    return sol, observed


def solve(scene, y0, duration, n_save, solver, rtol, atol, dt0, dtmax, max_steps, progress, fixed_step=None):
    """Integrate `scene` over `[0, duration]`, saving at `n_save` equally spaced times.

    Adaptive steps (`diffrax.PIDController` with `rtol`, `atol`, first step `dt0`, largest
    `dtmax`), or, with `fixed_step` (s), constant steps of that size (the paper's multibody setting
    is 1e-4 s); an implicit solver whose root finder takes its tolerances from the step-size
    controller then gets `diffrax.VeryChord(rtol, atol)` instead.

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
    fixed = fixed_step is not None
    if fixed:
        if not (np.isfinite(fixed_step) and 0 < fixed_step <= duration):
            raise ValueError(f"fixed_step must be a positive time no longer than the duration, got {fixed_step!r}.")
        needed = int(np.ceil(duration / fixed_step))
        if needed > int(max_steps):
            raise ValueError(
                f"fixed_step={fixed_step!r} needs {needed} steps for {duration!r} s, more than "
                f"max_steps={max_steps}; raise max_steps or take a larger step."
            )
        dt0 = fixed_step
        if isinstance(solver, diffrax.AbstractImplicitSolver) and not isinstance(
            getattr(solver.root_finder, "rtol", None), (int, float)
        ):
            solver = eqx.tree_at(lambda s_: s_.root_finder, solver, diffrax.VeryChord(rtol=rtol, atol=atol))
    f64 = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
    ts = jnp.linspace(0.0, duration, int(n_save))
    return _solve(
        scene, y0, f64(duration), ts, solver, f64(rtol), f64(atol), f64(dt0), f64(dtmax),
        int(max_steps), bool(progress), fixed,
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
        f"`rtol`/`atol`, or a larger `smoothing_width`; with a fixed step, a smaller step or "
        f"adaptive steps; pass `throw=False` to inspect the result."
    )
