"""A scene is anything `simulate` can run: the joint on its test bench, the antenna mechanism.

A scene provides its initial state (`start="rest"`; `"steady"`: already turning at the
commanded rate in rigid kinematics; `"loaded"`, mechanisms only: the loaded steady state), its
equations of motion (`vector_field`), what is observed at a saved state (`observe`), and how
the saved series become its result type. `simulate` is the one entry point; `tolerax.solve.solve` the
one diffrax call.
"""

import abc
import dataclasses
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax

from .. import _validate as V
from ..solve import ACCURATE, Integrator, SimulationError, SolverReport, named_integrator, raise_on_failure, solve, solver_named

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

    def automatic_integrator(self) -> tuple[Integrator, str]:
        """The integrator this scene gets when its run asks for none, and why in words (a
        result's `integrated_with`). Default: `ACCURATE` (Tsit5 at rtol 1e-6); a scene whose
        outputs a faster integrator reads as closely (measured, `benchmarks/auto_integrator.py`)
        returns that one."""
        return ACCURATE, "no full planetary stage: accuracy, not the stage's contact modes, sets the step"

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
    rtol: float | None = None,
    atol: float | None = None,
    dt0: float | None = None,
    dtmax: float | None = None,
    dtmin: float | None = None,
    max_steps: int | None = None,
    fixed_step: float | None = None,
    throw: bool = True,
    progress: bool = False,
    adjoint: diffrax.AbstractAdjoint | None = None,
    pcoeff: float | None = None,
    icoeff: float | None = None,
    integrator: Integrator | str = "auto",
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
    - **How it is integrated** (default: chosen from the scene, `integrator="auto"`,
      `scene.automatic_integrator()`; every scene measured gets `tolerax.solve.ACCURATE`,
      Tsit5 at rtol 1e-6, atol 1e-9, the I-controller). The result's `integrated_with` (and
      `report()`) says which and why: for a scene with a full planetary joint, that
      `tolerax.solve.FAST_STAGE` (SRK53 at rtol 1e-4, the (0.2, 0.2) controller) runs it faster
      but reads its outputs less closely (`benchmarks/auto_integrator.py`). A
      choice of one's own overrides it: `integrator=tolerax.Integrator(...)` (or
      `tolerax.solve.FAST_STAGE`), every setting as one value, or the settings one by one, each
      replacing `ACCURATE`'s:
    - `solver`: a diffrax solver, or the name of one in `tolerax.solve.SOLVERS` (`"Tsit5"`,
      `"Bosh3"`, `"SRK53"`, `"Dopri5"`, `"Dopri8"`); implicit solvers are compared in
      `benchmarks/work_precision.py`.
    - `rtol`, `atol`: PID step-size controller tolerances (atol in the state's SI units: m, rad,
      m/s, rad/s; 1e-9 resolves nanometres against 100 µm clearances).
    - `dt0`, `dtmax` (s): first and largest step; `dtmin` (s): a step the error control wants
      below it ends the run with `RESULTS.dt_min_reached` (a step-size collapse).
    - `max_steps`: step budget.
    - `pcoeff`, `icoeff`: the step-size controller's proportional and integral coefficients
      (`diffrax.PIDController`; (0, 1) is diffrax's I-controller, `tolerax.solve.DEFAULT_PID`).
      Python numbers: changing them recompiles (like `solver`); ignored with `fixed_step`.
    - `fixed_step` (s): constant steps instead of the adaptive controller (the paper's multibody
      setting is 1e-4 s; an explicit solver is unstable there, see `benchmarks/`).
    - `integrator`: `"auto"` (the default), a name in `tolerax.solve.NAMED_INTEGRATORS`
      (`"accurate"`, `"fast-stage"`: that preset, the settings given one by one refining it),
      or a `tolerax.Integrator` (what a `PointingObjective` holds and a scene file's `[run]`
      names), not beside the settings one by one.
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
    chosen, why = choose_integrator(scene, integrator, dict(solver=solver, rtol=rtol, atol=atol, dt0=dt0, dtmax=dtmax,
                                                            dtmin=dtmin, max_steps=max_steps, fixed_step=fixed_step,
                                                            pcoeff=pcoeff, icoeff=icoeff))
    settings = chosen.options() if isinstance(chosen, Integrator) else chosen
    settings["solver"] = solver_named(settings["solver"])
    sol, observed = solve(scene, y0, duration, n_save=n_save, progress=progress, adjoint=adjoint, **settings)
    result = dataclasses.replace(scene.result(sol, observed, duration), integrated_with=why)
    if throw:
        try:
            raise_on_failure(sol, duration, scene._what)
        except SimulationError as err:
            raise SimulationError(f"{err} It was integrated with {why}.") from None
    return result


def choose_integrator(scene: AbstractScene, integrator: "Integrator | str", given: dict) -> tuple:
    """`(settings, why)` for a run of `scene`: `integrator` (a `tolerax.Integrator`, or `"auto"`:
    `scene.automatic_integrator()`) unless settings are `given` one by one (name -> value,
    `None` for not given), which then replace `ACCURATE`'s. `settings` is an `Integrator`, or
    a dict of `simulate`'s keywords where the solver is a diffrax solver object rather than a
    name; `why` says which and why in words (a result's `integrated_with`)."""
    given = {k: v for k, v in given.items() if v is not None}
    if isinstance(integrator, str) and integrator != "auto":
        named = named_integrator(integrator, "simulate")  # a preset by name: the settings given refine it
        if "solver" in given and not isinstance(given["solver"], str):
            raise ValueError(f"simulate: integrator={integrator!r} takes its solver by name, not a diffrax solver object.")
        chosen = named.replace(**given) if given else named
        return chosen, chosen.said()
    if isinstance(integrator, Integrator):
        if given:
            raise ValueError(f"simulate: give {', '.join(sorted(given))} in the integrator (Integrator.replace(...)), not beside it.")
        return integrator, integrator.said()
    if integrator != "auto":
        raise TypeError(f"integrator must be 'auto', a name in tolerax.solve.NAMED_INTEGRATORS or a tolerax.Integrator, got "
                        f"{integrator!r}.")
    if not given:
        chosen, reason = scene.automatic_integrator()
        return chosen, chosen.said(reason)
    solver_named(given.get("solver"))  # an unknown name or a wrong type refused in simulate's words
    if "solver" in given and not isinstance(given["solver"], str):  # a diffrax solver object
        return ACCURATE.options() | given, f"{type(given['solver']).__name__} with the settings given"
    chosen = ACCURATE.replace(**given)
    return chosen, chosen.said()

