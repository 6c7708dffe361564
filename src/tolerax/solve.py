"""The one diffrax call shared by every scene (bench, mechanism), and its failure report.

A scene provides `vector_field(t, y, args)` and `observe(t, y)` (the forces and other
instantaneous quantities at a saved state); `solve` integrates it and evaluates `observe` at the
save times, in one compiled program per scene *structure* (values are passed as arrays). Users
call `tolerax.simulate`, which builds the scene's result with `SolverReport.from_solution`.
"""

import contextlib
import functools
import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array
from . import _validate
from .cache import exported_jit
from .srk53 import SRK53  # noqa: F401  (tolerax.solve.SRK53: a public path)

# The run settings' value and its presets live in `tolerax.integrator`; importable from here (public paths).
from .integrator import (  # noqa: F401
    ACCURATE, DEFAULT_PID, DEFAULT_SOLVER, DTMIN, FAST_STAGE, NAMED_INTEGRATORS, PID_RULES, SOLVERS, Integrator,
    named_integrator, refined, run_settings_error, solver_named)


class SimulationError(RuntimeError):
    """The integrator did not reach the final time."""


def _all_finite(tree):
    return jnp.all(jnp.stack([jnp.all(jnp.isfinite(x)) for x in jax.tree.leaves(tree)]))


class _NanSafe(diffrax.AbstractAdaptiveStepSizeController):
    """Wraps a `diffrax.PIDController` so that a non-finite error estimate (the right-hand side
    returned NaN or inf) counts as an infinitely large error: the step is rejected and shrunk 5x,
    so a run that can only produce NaN ends with `dt_min_reached` after ~30 rejections. (diffrax's
    own controller turns a NaN error into a NaN step size, which neither shrinks below `dtmin`
    nor stops: the run spins until `max_steps`, and under `vmap` holds the whole batch there.)
    Finite errors are handled exactly as by the wrapped controller."""

    controller: diffrax.PIDController

    @property
    def rtol(self):
        return self.controller.rtol

    @property
    def atol(self):
        return self.controller.atol

    @property
    def norm(self):
        return self.controller.norm

    def wrap(self, direction):
        return _NanSafe(self.controller.wrap(direction))

    def init(self, terms, t0, t1, y0, dt0, args, func, error_order):
        return self.controller.init(terms, t0, t1, y0, dt0, args, func, error_order)

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        bad = ~(_all_finite(y_error) & _all_finite(y0))
        y_error = jax.tree.map(lambda e: jnp.where(bad, jnp.inf, e), y_error)
        y0 = jax.tree.map(lambda y: jnp.where(jnp.isfinite(y), y, 0.0), y0)
        return self.controller.adapt_step_size(t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state)


# XLA's CPU compiler hands some products and reductions to YNNPACK ("ynn fusions"); for one
# state's right-hand side of these scenes (36 x 36 mass matrices, many kernels of a few
# microseconds) that costs more than it saves: a single solve is faster without them, with the
# same steps and results; vmapped over many states they pay, so Monte Carlo's batched programs
# keep the default. Eigen's products on one thread: split over the CPU's threads, the right-hand
# side's 12 x 84 x 12 and smaller products pay the hand-over more than they save.
CPU_COMPILER_OPTIONS = {"xla_cpu_experimental_ynn_fusion_type": "", "xla_cpu_multi_thread_eigen": False}


@contextlib.contextmanager
def _checks_without_host_callbacks():
    """diffrax checks its arguments at run time (save times increasing and within [t0, t1], the
    sign of dt0) with equinox's `error_if`, which by default raises through a host callback;
    JAX never writes a program with host callbacks to its persistent compilation cache, so the
    solve, the one program that takes seconds to compile, was compiled anew in every process.
    `simulate` validates those inputs in Python before the solve, so inside it the checks are
    traced in equinox's `"nan"` mode (a failing check returns NaN, which the solve reports as a
    failure, not numbers). Equinox reads the mode at trace time from `equinox._errors`; where
    that is not there (another equinox), nothing changes."""
    errors = getattr(eqx, "_errors", None)
    if getattr(errors, "EQX_ON_ERROR", None) != "raise":
        yield
        return
    errors.EQX_ON_ERROR = "nan"
    try:
        yield
    finally:
        errors.EQX_ON_ERROR = "raise"


@eqx.filter_jit
def _vector_field(scene, t, y, args):
    """`scene.vector_field` as one jitted call: diffrax traces a solve's step three or four times
    (its term check, the shape of its loop's body, the loop itself), and the trace of a nested jit
    is kept by JAX for the next trace with the same structure and shapes, so the vector field (most
    of a step's tracing) is traced once or twice instead; its lowering is emitted once. The results
    are those of the plain call (`benchmarks/trace_once.py` compares the two)."""
    return scene.vector_field(t, y, args)


def _solve(scene, y0, t1, ts, solver, rtol, atol, dt0, dtmin, dtmax, max_steps, progress, fixed, adjoint, pid):
    with _checks_without_host_callbacks():
        return _solve_traced(scene, y0, t1, ts, solver, rtol, atol, dt0, dtmin, dtmax, max_steps, progress, fixed, adjoint, pid)


def _solve_traced(scene, y0, t1, ts, solver, rtol, atol, dt0, dtmin, dtmax, max_steps, progress, fixed, adjoint, pid):
    if fixed:
        controller = diffrax.ConstantStepSize()
    else:
        # force_dtmin=False: a step the error control wants below dtmin ends the solve with
        # RESULTS.dt_min_reached (a step-size collapse) instead of being silently accepted.
        # `pid` = (pcoeff, icoeff), Python floats: static (default `DEFAULT_PID`, diffrax's I-controller (0, 1)).
        pcoeff, icoeff = pid
        controller = _NanSafe(
            diffrax.PIDController(
                rtol=rtol, atol=atol, pcoeff=pcoeff, icoeff=icoeff, dtmin=dtmin, dtmax=dtmax, force_dtmin=False
            )
        )
    saveat = diffrax.SaveAt(subs=(diffrax.SubSaveAt(ts=ts), diffrax.SubSaveAt(t1=True)))
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(functools.partial(_vector_field, scene)),
        solver,
        t0=0.0,
        t1=t1,
        dt0=dt0,
        y0=y0,
        saveat=saveat,
        stepsize_controller=controller,
        max_steps=max_steps,
        adjoint=adjoint,
        throw=False,
        progress_meter=diffrax.TextProgressMeter() if progress else diffrax.NoProgressMeter(),
    )
    (ts_saved, t_last), (ys, y_last) = sol.ts, sol.ys
    # A fixed step beyond the stability limit, or an unstable model, can run to t1 "successfully"
    # with NaN or inf states: report that as a failure, never as numbers.
    finite = _all_finite(ys) & _all_finite(y_last)
    silent = (sol.result == diffrax.RESULTS.successful) & ~finite
    result = diffrax.RESULTS.where(silent, diffrax.RESULTS.nonfinite, sol.result)
    # The time reached: where the solver stopped, or, if the state went non-finite, the last save
    # time at which it was still finite.
    rows = jnp.stack([jnp.all(jnp.isfinite(x.reshape(x.shape[0], -1)), axis=1) for x in jax.tree.leaves(ys)])
    good = jnp.all(rows, axis=0) & jnp.isfinite(ts_saved)
    last_good = jnp.max(jnp.where(good, ts_saved, 0.0))
    t_reached = jnp.where(_all_finite(y_last), t_last[0], last_good)
    stats = dict(sol.stats, t_reached=t_reached)
    sol = eqx.tree_at(lambda s: (s.ts, s.ys, s.result, s.stats), sol, (ts_saved, ys, result, stats))
    observed = jax.vmap(scene.observe)(sol.ts, sol.ys)
    return sol, observed


_solve_jit = eqx.filter_jit(_solve)
# The top-level solve (concrete inputs): its traced program is kept between processes with the
# compilation cache (`tolerax.cache.exported_jit`); under a caller's transformation, `_solve_jit`.
_solve_cpu = exported_jit(_solve, compiler_options=CPU_COMPILER_OPTIONS)


def solve(
    scene,
    y0,
    duration,
    *,
    n_save: int,
    integrator: Integrator = ACCURATE,
    progress: bool = False,
    adjoint: diffrax.AbstractAdjoint | None = None,
):
    """Integrate `scene` over `[0, duration]`, saving at `n_save` equally spaced times, as
    `integrator` says (a `tolerax.Integrator`: solver, step-size controller, steps' limits).

    Adaptive steps (`diffrax.PIDController` with the integrator's `rtol`, `atol`, first step
    `dt0`, largest `dtmax`, coefficients `pcoeff`, `icoeff`; a step the error control wants below
    `dtmin` (s) stops the solve with `RESULTS.dt_min_reached`: a journal crossing the 1 nm
    smoothing zone at 0.2 m/s needs steps of order 5 ns, 5e4 times the default), or, with its
    `fixed_step` (s), constant steps of that size (the paper's multibody setting is 1e-4 s); an
    implicit solver whose root finder takes its tolerances from the step-size controller then
    gets `diffrax.VeryChord(rtol, atol)` instead.

    `adjoint` (default `diffrax.RecursiveCheckpointAdjoint()`): how derivatives pass through the
    solve; `diffrax.ForwardMode()` for forward-mode (`jax.jvp`, `jax.jacfwd`) derivatives.

    The scene's values and `y0` are checked first (`_validate.check_tree`: values set with
    `eqx.tree_at` bypass the constructors' checks).

    Returns the diffrax `Solution` (with `throw=False`: check `sol.result`; `sol.stats["t_reached"]`
    is the time the solver reached) and `observe` at the saved states. Numbers become float64
    arrays so that changing them does not recompile.
    """
    if not isinstance(integrator, Integrator):
        raise TypeError(f"integrator must be a tolerax.Integrator, got {type(integrator).__name__}.")
    solver = solver_named(integrator.solver)
    rtol, atol, dt0, dtmax, dtmin = integrator.rtol, integrator.atol, integrator.dt0, integrator.dtmax, integrator.dtmin
    max_steps, fixed_step = integrator.max_steps, integrator.fixed_step
    if not (np.isfinite(duration) and duration > 0):
        raise ValueError(f"duration must be a positive finite time in seconds, got {duration!r}.")
    if int(n_save) < 2:
        raise ValueError(f"n_save must be at least 2 (the start and the end), got {n_save!r}.")
    _validate.check_tree(scene)
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
    # Compiler options are allowed on a top-level jit only: inside a caller's jit (the ops here
    # are then staged, tracers), or with traced inputs (vmap, grad), the plain jit.
    traced = any(isinstance(x, jax.core.Tracer) for x in jax.tree.leaves((scene, y0, ts)))
    run = _solve_cpu if jax.default_backend() == "cpu" and not traced else _solve_jit
    return run(
        scene, y0, f64(duration), ts, solver, f64(rtol), f64(atol), f64(dt0), f64(dtmin), f64(dtmax),
        int(max_steps), bool(progress), fixed, diffrax.RecursiveCheckpointAdjoint() if adjoint is None else adjoint,
        (0.0, 1.0) if fixed else (float(integrator.pcoeff), float(integrator.icoeff)),  # no controller with a fixed step
    )


_ADVICE = {
    "max_steps_reached": "the step budget ran out: raise `max_steps`, loosen `rtol`/`atol`, or widen "
    "`smoothing_width` (a rattling joint takes many small steps)",
    "dt_min_reached": "the step size collapsed below `dtmin`: the right-hand side is (nearly) "
    "discontinuous or unstable there (an exact contact law with `smoothing_width=0`, an extreme "
    "stiffness); widen `smoothing_width` or check the inputs",
    "nonfinite": "the state became NaN or inf: with a fixed step, the step is beyond the stability "
    "limit (take a smaller step, or adaptive steps); otherwise the model is unstable for these inputs",
    "nonlinear_divergence": "the implicit solver's Newton iteration diverged: take smaller steps or an "
    "explicit solver (Tsit5)",
    "nonlinear_max_steps_reached": "the implicit solver's Newton iteration did not converge: take smaller "
    "steps or an explicit solver (Tsit5)",
}
_NAMES = {int(item._value): name for name, item in diffrax.RESULTS._name_to_item.items()}


def _codes(result) -> np.ndarray:
    return np.atleast_1d(np.asarray(result._value))


def failure_lines(result, t_reached, num_steps, duration: float, what: str) -> list[str]:
    """One readable line per failed sample (none for successes): the result code, the time reached,
    the steps taken and what to try. Works for one run or a batch (`vmap`) of runs."""
    codes = _codes(result)
    t = np.broadcast_to(np.asarray(t_reached, dtype=float), codes.shape)
    n = np.broadcast_to(np.asarray(num_steps), codes.shape)
    lines = []
    for k, code in enumerate(codes):
        if code == 0:
            continue
        name = _NAMES.get(int(code), "unknown")
        advice = _ADVICE.get(name, diffrax.RESULTS._index_to_message[int(code)].split("\n")[0])
        sample = f"sample {k}: " if np.ndim(np.asarray(result._value)) > 0 else ""
        lines.append(
            f"{sample}the {what} simulation failed ({name}) at t = {t[k]:.6g} s of {duration:.6g} s, "
            f"after {int(n[k])} accepted steps: {advice}."
        )
    return lines


def raise_on_failure(sol, duration: float, what: str) -> None:
    """Raise `SimulationError` with the result code, the time reached and what to try."""
    if _validate.is_traced(sol.result._value):
        raise ValueError(
            f"throw=True cannot check a {what} simulation inside jit/vmap/grad; pass throw=False and "
            f"read the result's `success`, `t_reached` and `failures()` per sample."
        )
    lines = failure_lines(sol.result, sol.stats["t_reached"], sol.stats["num_accepted_steps"], duration, what)
    if lines:
        raise SimulationError("\n".join(lines) + " (Pass `throw=False` to inspect the result.)")


class SolverReport(eqx.Module):
    """What the solver did, for one run or per sample of a batch.

    - `result`: the diffrax result code (array of codes for a batch).
    - `t_reached`: time the solver reached (s); the duration if it succeeded; for a non-finite
      state, the last save time at which the state was still finite.
    - `num_steps`, `num_rejected`: accepted and rejected steps.
    - `duration`: the requested simulated time (s).
    """

    result: diffrax.RESULTS
    t_reached: Array
    num_steps: Array
    num_rejected: Array
    duration: float = eqx.field(static=True)
    # How the run was integrated and why, in words ("Tsit5, rtol 1e-06, ...: chosen
    # automatically, ..."; `simulate` sets it: `Integrator.said`).
    integrated_with: str = eqx.field(static=True, default="", kw_only=True)
    _what = "simulation"  # what the failure lines call the run (class attribute, not a field)

    @classmethod
    def from_solution(cls, sol: diffrax.Solution, duration: float, **fields):
        """Build `cls` (this report or a scene's result type, whose series are `fields`) from
        the diffrax `Solution` of `solve`: result code, time reached, accepted and rejected steps."""
        return cls(
            **fields,
            result=sol.result,
            t_reached=sol.stats["t_reached"],
            num_steps=sol.stats["num_accepted_steps"],
            num_rejected=sol.stats["num_rejected_steps"],
            duration=float(duration),
        )

    @property
    def success(self):
        """`True` if the run reached `duration`; for a batch, a boolean array per sample."""
        ok = _codes(self.result) == 0
        return bool(ok[0]) if np.ndim(np.asarray(self.result._value)) == 0 else ok

    def failures(self) -> list[str]:
        """A readable line per failed run (sample index, result code, time reached, what to try)."""
        return failure_lines(self.result, self.t_reached, self.num_steps, self.duration, self._what)

    def report(self) -> str:
        """A one-paragraph summary: successes, and every failure with its time reached."""
        ok = np.atleast_1d(self.success)
        head = f"{int(ok.sum())} of {ok.size} runs reached {self.duration:.6g} s."
        how = [f"Integrated with {self.integrated_with}."] if self.integrated_with else []
        return "\n".join([head, *how, *self.failures()])
