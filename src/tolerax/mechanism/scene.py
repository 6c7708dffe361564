"""A scene is anything `simulate` can run: the joint on its test bench, the antenna mechanism.

A scene provides its initial state (`start="rest"`; `"steady"`: already turning at the
commanded rate in rigid kinematics; `"loaded"`, mechanisms only: the loaded steady state), its
equations of motion (`vector_field`), what is observed at a saved state (`observe`), and how
the saved series become its result type. `simulate` is the one entry point; `tolerax.solve.solve` the
one diffrax call.
"""

import abc
import dataclasses
import warnings
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax

from .. import _validate as V
from ..solve import ACCURATE, Integrator, SimulationError, SolverReport, raise_on_failure, refined, solve

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

    def unit_chunk(self) -> int:
        """Units per vmapped batch (a Monte Carlo chunk) in which this scene's units run best on a
        CPU: what `monte_carlo`, `Check` and `Auto()`'s probe take where no chunk size is given. A
        batch steps until its slowest unit is done. A scene with a full planetary stage (a joint
        with `stiff_contact_modes`) rattles, its units' step counts differing widely: small
        batches (10) run faster there, larger ones (50) elsewhere, measured by
        `benchmarks/monte_carlo_chunks.py`."""
        joints = getattr(self, "named_joints", tuple)()
        return 10 if any(getattr(joint, "stiff_contact_modes", False) for _, joint in joints) else 50

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
    integrator: Integrator | str = "auto",
    throw: bool = True,
    progress: bool = False,
    adjoint: diffrax.AbstractAdjoint | None = None,
    **settings,
):
    """Run a scene (a `TestBench`, a `Mechanism`) for `duration` seconds.

    **Arguments:**

    - `scene`: what to run. Only its structure compiles (fidelities, supports, integrator,
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
    - `integrator`: how it is integrated, one value. `"auto"` (the default): chosen from the
      scene (`scene.automatic_integrator()`; every scene measured gets `tolerax.solve.ACCURATE`,
      Tsit5 at rtol 1e-6, atol 1e-9, the I-controller); a name in
      `tolerax.solve.NAMED_INTEGRATORS` (`"accurate"`, `"fast-stage"`: SRK53 at rtol 1e-4, the
      (0.2, 0.2) controller); or a `tolerax.Integrator` (solver, `rtol`, `atol`, `pcoeff`,
      `icoeff`, `dt0`, `dtmax`, `dtmin`, `max_steps`, `fixed_step`: its docstring), e.g.
      `tolerax.Integrator(rtol=1e-9, atol=1e-12)` or `tolerax.solve.ACCURATE.replace(
      max_steps=10**7)`. The result's `integrated_with` (and `report()`) says which and why.
    - `throw`: raise `SimulationError` on failure; otherwise return with `result` set (required
      under `jit`/`vmap`/`grad`).
    - `progress`: print diffrax's text progress meter (compiles a separate program).
    - `adjoint`: how derivatives pass through the solve (default: reverse mode with recursive
      checkpointing; `diffrax.ForwardMode()` for `jax.jvp`/`jax.jacfwd`).
    - `settings`: deprecated, for one release: the integrator's settings one by one
      (`solver=`, `rtol=`, ... as `tolerax.Integrator`'s fields), each replacing the named
      preset's (or `ACCURATE`'s); a `DeprecationWarning` names the `Integrator` to pass instead.

    **Returns:** the scene's result (`BenchResult`, `MechanismResult`), a `SolverReport`.
    """
    if not isinstance(scene, AbstractScene):
        raise TypeError(f"scene must be a TestBench or a Mechanism (see `antenna`), got {type(scene).__name__}.")
    if start not in STARTS:
        raise ValueError(f"start={start!r} is unknown; use one of {STARTS}.")
    chosen, why = choose_integrator(scene, integrator, settings)
    scene.check_runnable()
    if y0 is None:
        y0 = scene.initial_state(start)
    else:
        V.state_like(y0, jax.eval_shape(lambda: scene.initial_state(start)))  # shapes only: no steady-state solve
    sol, observed = solve(scene, y0, duration, n_save=n_save, integrator=chosen, progress=progress, adjoint=adjoint)
    result = dataclasses.replace(scene.result(sol, observed, duration), integrated_with=why)
    if throw:
        try:
            raise_on_failure(sol, duration, scene._what)
        except SimulationError as err:
            raise SimulationError(f"{err} It was integrated with {why}.") from None
    return result


def choose_integrator(scene: AbstractScene, integrator: "Integrator | str", given: dict | None = None) -> tuple:
    """`(integrator, why)` for a run of `scene`: `integrator` (a `tolerax.Integrator`, a name in
    `NAMED_INTEGRATORS`, or `"auto"`: `scene.automatic_integrator()`) and why in words (a
    result's `integrated_with`). `given`: deprecated settings one by one (`simulate`'s
    `**settings`, name -> value, `None` for not given), which refine the named preset (or
    `ACCURATE`'s, under `"auto"`) with a `DeprecationWarning` that names the value to pass."""
    given = {k: v for k, v in (given or {}).items() if v is not None}
    unknown = sorted(set(given) - set(Integrator.FIELDS))
    if unknown:
        raise TypeError(f"simulate() got unexpected keyword argument(s) {', '.join(unknown)}; the run's settings go in "
                        f"integrator=tolerax.Integrator(...) ({', '.join(Integrator.FIELDS)}).")
    if isinstance(integrator, Integrator) and given:
        raise ValueError(f"simulate: give {', '.join(sorted(given))} in the integrator (Integrator.replace(...)), not beside it.")
    chosen, written = refined(integrator, given, where="simulate")  # an unknown name or setting refused in simulate's words
    if chosen is None:
        chosen, reason = scene.automatic_integrator()
        return chosen, chosen.said(reason)
    if given:
        settings = ", ".join(f"{k}={v!r}" for k, v in given.items())
        warnings.warn(f"simulate({settings}) is deprecated: pass integrator={written} (one tolerax.Integrator holds every "
                      "run setting); the settings one by one go in the next release.", DeprecationWarning, stacklevel=3)
    return chosen, chosen.said()

