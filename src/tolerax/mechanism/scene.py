"""A scene is anything `simulate` can run: the joint on its test bench, the antenna mechanism.

A scene provides its initial state (`start="rest"`; `"steady"`: already turning at the
commanded rate in rigid kinematics; `"loaded"`, mechanisms only: the loaded steady state), its
equations of motion (`vector_field`), what is observed at a saved state (`observe`), and how
the saved series become its result type. `simulate` is the one entry point; `tolerax.solve.solve` the
one diffrax call.
"""

import abc
import inspect
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax

from .. import _validate as V
from ..solve import DEFAULT_PID, DTMIN, Integrator, SolverReport, raise_on_failure, solve, solver_named

STARTS = ("rest", "steady", "loaded")


class AbstractScene(eqx.Module):
    """What `simulate` needs of a scene. `_what` names it in failure messages."""

    _what = "simulation"

    @abc.abstractmethod
    def initial_state(self, start: str = "rest") -> tuple:
        """The state at t = 0 for `start` (one of `STARTS`)."""

    @abc.abstractmethod
    def vector_field(self, t, y, args):
        """$\\dot y = f(t, y)$."""

    @abc.abstractmethod
    def observe(self, t, y):
        """Instantaneous outputs at a saved state (a pytree of arrays)."""

    @abc.abstractmethod
    def result(self, sol: diffrax.Solution, observed, duration: float) -> SolverReport:
        """The scene's result (built with `SolverReport.from_solution`) from the solution of
        `tolerax.solve.solve` and the observations at its save times."""

    def check_runnable(self) -> None:
        """Raise a `ValueError` saying what to change if this scene has nothing to integrate."""

    def named_stages(self) -> tuple[tuple[str, Callable, tuple[str, ...]], ...]:
        """The scene's gear stages, once for everything that reads them by name (design
        features, smoothing widths, cost sizes, reports): `(name, stage_of, features)` per stage,
        where `name` is the joint's name (`""` for a scene with one stage), `stage_of(scene)`
        returns the `PlanetaryStage` (a path `eqx.tree_at` can follow) and `features` are the
        design features (`DESIGN_FEATURES` names) that the joint's fidelity reads. Default: none."""
        return ()


def simulate(
    scene: AbstractScene,
    duration: float,
    *,
    start: str = "rest",
    y0: tuple | None = None,
    n_save: int = 1001,
    solver: diffrax.AbstractSolver | str | None = None,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    dt0: float = 1e-6,
    dtmax: float = 1e-3,
    dtmin: float = DTMIN,
    max_steps: int = 4_000_000,
    fixed_step: float | None = None,
    throw: bool = True,
    progress: bool = False,
    adjoint: diffrax.AbstractAdjoint | None = None,
    pcoeff: float = DEFAULT_PID[0],
    icoeff: float = DEFAULT_PID[1],
    integrator: Integrator | None = None,
):
    """Run a scene (a `TestBench`, a `Mechanism`) for `duration` seconds.

    **Arguments:**

    - `scene`: what to run. Only its structure compiles (fidelities, supports, solver,
      `n_save`); changing values (clearances, stiffnesses, rates) reuses the compiled program.
    - `duration`: simulated time (s).
    - `start`: `"rest"` (everything at rest: a servo start-up closes the backlash, so the run
      has impacts), `"steady"` (each servo-driven joint already turning at its commanded rate
      in rigid kinematics, meshes at zero deflection, servo at zero lag: a start-up of ~2 s
      follows as the servo builds its lag against the drag) or, for a mechanism with
      constant-rate servos, `"loaded"` (the loaded steady state: `Mechanism.initial_state`).
      Ignored when `y0` is given.
    - `y0`: an explicit initial state, shaped like `scene.initial_state()`.
    - `n_save`: number of equally spaced save times.
    - `solver`: a diffrax solver, or the name of one in `tolerax.solve.SOLVERS` (`"Tsit5"`, the
      default; `"Bosh3"`, `"SRK53"`, `"Dopri5"`, `"Dopri8"`). For the full planetary stage in
      developed rattle, `"SRK53"` at rtol 1e-3 (atol 1e-6) with `pcoeff = icoeff = 0.2` is the
      cheapest setting, its errors against a tight solve of the default's size
      (`tolerax.solve.SRK53`); `"Bosh3"` at rtol 1e-4 (atol 1e-7) with `pcoeff = icoeff = 0.3`
      is also cheaper than Tsit5 at rtol 1e-6, its pointing RMS and peak errors near the
      default's, its jitter farther off on the worst rattling units (`tolerax.solve.SOLVERS`
      says why); implicit solvers are compared in `benchmarks/work_precision.py`.
    - `rtol`, `atol`: PID step-size controller tolerances (atol in the state's SI units: m, rad,
      m/s, rad/s; 1e-9 resolves nanometres against 100 µm clearances).
    - `dt0`, `dtmax` (s): first and largest step; `dtmin` (s): a step the error control wants
      below it ends the run with `RESULTS.dt_min_reached` (a step-size collapse).
    - `max_steps`: step budget.
    - `pcoeff`, `icoeff`: the step-size controller's proportional and integral coefficients
      (`diffrax.PIDController`). The default (0, 1) is diffrax's I-controller; a PI controller
      (0.3, 0.3) rejects fewer steps, so a single run at rtol 1e-6 costs a little less, but it
      gains nothing on rattling Monte Carlo units (`tolerax.solve.DEFAULT_PID` says why it is not
      the default). Python numbers: changing them recompiles (like `solver`); ignored
      with `fixed_step`.
    - `fixed_step` (s): constant steps instead of the adaptive controller (the paper's multibody
      setting is 1e-4 s; an explicit solver is unstable there, see `benchmarks/`).
    - `integrator` (optional): the run settings above (`solver` by name, `rtol`, `atol`, `dt0`,
      `dtmax`, `dtmin`, `max_steps`, `pcoeff`, `icoeff`, `fixed_step`) as one value,
      `tolerax.Integrator` (what a `PointingObjective` holds and a scene file's `[run]` names);
      those keywords are then left at their defaults.
    - `throw`: raise `SimulationError` on failure; otherwise return with `result` set (required
      under `jit`/`vmap`/`grad`).
    - `progress`: print diffrax's text progress meter (compiles a separate program).
    - `adjoint`: how derivatives pass through the solve (default: reverse mode with recursive
      checkpointing; `diffrax.ForwardMode()` for `jax.jvp`/`jax.jacfwd`).

    **Returns:** the scene's result (`BenchResult`, `MechanismResult`), a `SolverReport`.
    """
    if not isinstance(scene, AbstractScene):
        raise TypeError(f"scene must be a TestBench or a Mechanism (see `antenna`), got {type(scene).__name__}.")
    if start not in STARTS:
        raise ValueError(f"start={start!r} is unknown; use one of {STARTS}.")
    scene.check_runnable()
    if y0 is None:
        y0 = scene.initial_state(start)
    else:
        V.state_like(y0, jax.eval_shape(lambda: scene.initial_state(start)))  # shapes only: no steady-state solve
    settings = dict(solver=solver, rtol=rtol, atol=atol, dt0=dt0, dtmax=dtmax, dtmin=dtmin, max_steps=max_steps,
                    fixed_step=fixed_step, pcoeff=pcoeff, icoeff=icoeff)  # Integrator.FIELDS
    if integrator is not None:
        given = sorted(k for k, v in settings.items() if v is not _DEFAULTS[k] and v != _DEFAULTS[k])
        if given:
            raise ValueError(f"simulate: give {', '.join(given)} in the integrator (Integrator.replace(...)), not beside it.")
        settings = integrator.options()
    settings["solver"] = solver_named(settings["solver"])
    sol, observed = solve(scene, y0, duration, n_save=n_save, progress=progress, adjoint=adjoint, **settings)
    result = scene.result(sol, observed, duration)
    if throw:
        raise_on_failure(sol, duration, scene._what)
    return result


_DEFAULTS = {name: p.default for name, p in inspect.signature(simulate).parameters.items()}  # simulate's run settings' defaults
