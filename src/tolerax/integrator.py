"""The run settings as one value: `Integrator` (the solver, the step-size controller and the
steps' limits) taken by `simulate`, held by `PointingObjective` and named by a scene file's
`[run]`; its presets by name (`ACCURATE`, `FAST_STAGE`, `NAMED_INTEGRATORS`) and `refined` (a
preset refined by settings given one by one). `tolerax.solve` runs it; every name here is
importable from there too.
"""

from typing import ClassVar
import diffrax
import equinox as eqx
import numpy as np
from .srk53 import SRK53

DTMIN = 1e-13  # s: a step below this is a step-size collapse (see `solve`)
# The step-size controller's coefficients: name -> (valid, the rule in words). `solve` and the
# scene files' `[run]` check (which names the key and line) both read it.
PID_RULES = {"pcoeff": (lambda x: x >= 0, ">= 0"), "icoeff": (lambda x: x > 0, "> 0")}
# The default (pcoeff, icoeff): diffrax's I-controller. A PI controller (0.3, 0.3) rejects fewer
# steps at the same rtol, so a single run at rtol 1e-6 costs a little less; it gains nothing at
# tight tolerances or on rattling Monte Carlo units (as many attempted steps), and in a developed
# rattle its pointing error lies farther from a tight solve. It is an option, not the default:
# with it the same solve compiled in two programs (a vmapped batch, a gradient) differs by ~1e-8
# instead of rounding (tests/test_reliability.py).
DEFAULT_PID = (0.0, 1.0)
# The explicit Runge-Kutta solvers a run may name (scene files' `[run] solver`, `simulate(solver=
# "Bosh3")`). Tsit5 is the default (`DEFAULT_SOLVER`). On the full planetary stage the explicit
# step is held by the stability of lightly damped mesh modes, not by accuracy, so a method with a
# larger stability region per evaluation pays there. Bosh3 (3rd order, 3 evaluations a step) at
# rtol 1e-4 to 1e-5 with the PI controller is cheaper than Tsit5 at rtol 1e-6, its pointing RMS
# and peak errors against a tight solve near Tsit5's, its jitter (the rattle's most chaotic
# output) farther off on the worst units. SRK53 (3rd order, 5 evaluations, its stability region
# fitted to the full stage's damped mesh modes) at rtol 1e-3 with pcoeff = icoeff = 0.2 is the
# cheapest of them on the full planetary antenna in developed rattle, its pointing and jitter
# errors against a tight solve of the default's size; on scenes whose fast modes are undamped it
# is slower than Bosh3 (`SRK53`). `benchmarks/rattle_window.py` and
# `benchmarks/monte_carlo_solvers.py` measure them (benchmarks/README.md lists the runs).
DEFAULT_SOLVER = "Tsit5"


SOLVERS = {"Tsit5": diffrax.Tsit5, "Bosh3": diffrax.Bosh3, "SRK53": SRK53, "Dopri5": diffrax.Dopri5, "Dopri8": diffrax.Dopri8}


def solver_named(solver) -> diffrax.AbstractSolver:
    """`solver` as a diffrax solver: a name in `SOLVERS`, a diffrax solver (returned as it is),
    or `None` (`DEFAULT_SOLVER`). `ValueError` for an unknown name, `TypeError` for anything else."""
    if solver is None:
        return SOLVERS[DEFAULT_SOLVER]()
    if isinstance(solver, str):
        if solver not in SOLVERS:
            raise ValueError(f"solver {solver!r} is unknown; use one of {sorted(SOLVERS)} (or pass a diffrax solver).")
        return SOLVERS[solver]()
    if not isinstance(solver, diffrax.AbstractSolver):
        raise TypeError(f"solver must be a name in {sorted(SOLVERS)} or a diffrax solver (e.g. diffrax.Tsit5()), "
                        f"got {type(solver).__name__}.")
    return solver


def run_settings_error(*, rtol, atol, dt0, dtmax, dtmin, pcoeff, icoeff) -> str | None:
    """What is wrong with these step-control settings, in words (`None`: nothing): the one check
    `solve` and `Integrator` both make."""
    for name, value in (("rtol", rtol), ("atol", atol), ("dt0", dt0), ("dtmax", dtmax), ("dtmin", dtmin)):
        try:
            ok = bool(np.isfinite(value) and value > 0)
        except TypeError:  # not a number at all
            ok = False
        if not ok:
            return f"{name} must be a positive finite number, got {value!r}."
    for (name, (ok, rule)), value in zip(PID_RULES.items(), (pcoeff, icoeff)):
        if not (isinstance(value, (int, float, np.floating, np.integer)) and np.isfinite(value) and ok(value)):
            return (f"{name} must be a finite Python number {rule} (a static setting, like the solver), got {value!r}; "
                    "the default (pcoeff, icoeff) = (0, 1) is an I-controller, (0.3, 0.3) a PI controller.")
    if not dtmin < dt0 <= dtmax:
        return f"Steps must satisfy dtmin < dt0 <= dtmax, got dtmin={dtmin!r}, dt0={dt0!r}, dtmax={dtmax!r}."
    return None


class Integrator(eqx.Module):
    """How a scene is integrated, as one value: the explicit Runge-Kutta method, the adaptive
    step-size controller's tolerances and coefficients, and the steps' limits. `simulate(...,
    integrator=...)` takes it, `PointingObjective` holds it, a scene file's `[run]` table names
    its fields (`solver`, `rtol`, `atol`, `pcoeff`, `icoeff`, `dt0`, `dtmax`, `dtmin`,
    `max_steps`, `fixed_step`).

    - `solver`: the name of an explicit method in `SOLVERS` (default `"Tsit5"`), or a diffrax
      solver object (an implicit one such as `diffrax.Kvaerno5()`: its root finder takes the
      controller's tolerances). A scene file names it by name only.
    - `rtol`, `atol`: the PID controller's relative and absolute tolerances (atol in the
      state's SI units: m, rad, m/s, rad/s).
    - `pcoeff`, `icoeff`: the controller's proportional and integral coefficients (default
      (0, 1): diffrax's I-controller).
    - `dt0`, `dtmax` (s): first and largest step; `dtmin` (s): a step the error control wants
      below it ends the run (a step-size collapse); `max_steps`: the step budget.
    - `fixed_step` (s, optional): constant steps instead of the controller.

    Every field is static (a Python value): two integrators compile two programs.
    `replace(**changes)` gives another.
    """

    solver: str | diffrax.AbstractSolver = eqx.field(static=True, default=DEFAULT_SOLVER)
    rtol: float = eqx.field(static=True, default=1e-6)
    atol: float = eqx.field(static=True, default=1e-9)
    pcoeff: float = eqx.field(static=True, default=DEFAULT_PID[0])
    icoeff: float = eqx.field(static=True, default=DEFAULT_PID[1])
    dt0: float = eqx.field(static=True, default=1e-6)
    dtmax: float = eqx.field(static=True, default=1e-3)
    dtmin: float = eqx.field(static=True, default=DTMIN)
    max_steps: int = eqx.field(static=True, default=4_000_000)
    fixed_step: float | None = eqx.field(static=True, default=None)

    FIELDS: ClassVar[tuple[str, ...]] = ("solver", "rtol", "atol", "pcoeff", "icoeff", "dt0", "dtmax", "dtmin", "max_steps",
                                         "fixed_step")

    def __check_init__(self):
        if isinstance(self.solver, str) and self.solver not in SOLVERS:
            raise ValueError(f"Integrator: solver {self.solver!r} is unknown; use one of {sorted(SOLVERS)} (by name) or a "
                             "diffrax solver (e.g. diffrax.Kvaerno5()).")
        if not isinstance(self.solver, (str, diffrax.AbstractSolver)):
            raise TypeError(f"Integrator: solver must be a name in {sorted(SOLVERS)} or a diffrax solver (e.g. "
                            f"diffrax.Tsit5()), got {type(self.solver).__name__}.")
        wrong = run_settings_error(rtol=self.rtol, atol=self.atol, dt0=self.dt0, dtmax=self.dtmax, dtmin=self.dtmin,
                                   pcoeff=self.pcoeff, icoeff=self.icoeff)
        if wrong is not None:
            raise ValueError(f"Integrator: {wrong}")
        if not (isinstance(self.max_steps, int) and self.max_steps > 0):
            raise ValueError(f"Integrator: max_steps must be a positive integer, got {self.max_steps!r}.")
        if self.fixed_step is not None and not self.fixed_step > 0:
            raise ValueError(f"Integrator: fixed_step must be > 0 (s) or None, got {self.fixed_step!r}.")

    def options(self) -> dict:
        """These settings as `simulate`'s keywords."""
        return {name: getattr(self, name) for name in self.FIELDS}

    def replace(self, **changes) -> "Integrator":
        """This integrator with `changes` (field name -> value)."""
        unknown = sorted(set(changes) - set(self.FIELDS))
        if unknown:
            raise TypeError(f"Integrator: unknown setting(s) {', '.join(unknown)}; its settings: {', '.join(self.FIELDS)}.")
        return Integrator(**(self.options() | changes))

    def describe(self) -> str:
        """These settings in a few words (what a result's `integrated_with` starts with)."""
        solver = self.solver if isinstance(self.solver, str) else type(self.solver).__name__
        if self.fixed_step is not None:
            return f"{solver}, fixed steps of {self.fixed_step:g} s"
        control = "I-controller" if (self.pcoeff, self.icoeff) == DEFAULT_PID else f"PI controller ({self.pcoeff:g}, {self.icoeff:g})"
        return f"{solver}, rtol {self.rtol:g}, atol {self.atol:g}, {control}"

    def said(self, reason: str | None = None) -> str:
        """These settings and why, in words (a result's and an objective's `integrated_with`):
        `reason` for an automatic choice (`AbstractScene.automatic_integrator`), else asked for."""
        return f"{self.describe()}: " + ("as asked" if reason is None else f"chosen automatically, {reason}")


# ACCURATE: what a run gets when it names no integrator (`AbstractScene.automatic_integrator`,
# the default of `simulate`, the command line, Monte Carlo and design): Tsit5 at rtol 1e-6, the
# I-controller. FAST_STAGE: SRK53 at rtol 1e-4 with the (0.2, 0.2) controller, for the full
# planetary stage, whose lightly damped mesh and bearing modes hold an explicit step at its
# stability limit, where SRK53's region reaches farthest (`SRK53`). It is faster there but was
# measured reading the outputs less closely than ACCURATE on most full-stage scenes, so the
# automatic choice stays ACCURATE and says so; a run names FAST_STAGE where its accuracy is
# enough. The measurements: `benchmarks/auto_integrator.py`, `benchmarks/monte_carlo_solvers.py`
# (benchmarks/README.md).
ACCURATE = Integrator()
FAST_STAGE = Integrator(solver="SRK53", rtol=1e-4, atol=1e-7, pcoeff=0.2, icoeff=0.2)
# The integrators a run names by name (`simulate(integrator="fast-stage")`, a scene file's
# `[run] integrator`, the command line's `--integrator`); "auto" is the scene's own choice.
NAMED_INTEGRATORS = {"accurate": ACCURATE, "fast-stage": FAST_STAGE}


def named_integrator(name: str, where: str = "integrator") -> "Integrator | None":
    """The integrator a run names: `NAMED_INTEGRATORS[name]`, or `None` for `"auto"` (the
    scene's automatic choice). An unknown name is refused with the names there are."""
    if name == "auto":
        return None
    if not isinstance(name, str) or name not in NAMED_INTEGRATORS:
        raise ValueError(f"{where}: {name!r} is not an integrator's name; use 'auto' (chosen from the scene), "
                         + ", ".join(repr(n) for n in NAMED_INTEGRATORS) + " or a tolerax.Integrator(...).")
    return NAMED_INTEGRATORS[name]


def refined(integrator, settings: dict | None = None, *, where: str = "integrator", budget: int | None = None) -> tuple:
    """The integrator a run names, refined by run settings given one by one, and how a user
    writes it: `(chosen, written)`.

    `integrator`: a `tolerax.Integrator`, a name in `NAMED_INTEGRATORS`, or `"auto"`;
    `settings`: `Integrator` fields -> values (`None`: not given), each replacing the
    integrator's own; under `"auto"` they refine `ACCURATE` (the automatic choice's default).
    `budget` (steps, optional): the step budget a preset or `ACCURATE` takes here (a design
    unit's, `PointingObjective`'s); an `Integrator` given keeps its own. `chosen` is `None` for
    `"auto"` with no settings (the scene's automatic choice, `AbstractScene.automatic_integrator`,
    left to the caller); `written` is the Python a caller passes instead of the settings one by
    one (`"tolerax.solve.ACCURATE.replace(rtol=1e-05)"`), for a deprecation's message. An unknown
    name or setting is refused in `where`'s words."""
    settings = {k: v for k, v in (settings or {}).items() if v is not None}
    if isinstance(integrator, Integrator):
        base, spelled = integrator, "integrator"
    elif isinstance(integrator, str):
        named = named_integrator(integrator, where)
        base = ACCURATE if named is None else named
        spelled = "tolerax.solve.ACCURATE" if named is None else f"tolerax.solve.NAMED_INTEGRATORS[{integrator!r}]"
        if named is None and not settings:
            return None, spelled
        if budget is not None:
            base, settings = base.replace(max_steps=budget), {"max_steps": budget} | settings
    else:
        raise TypeError(f"{where}: integrator must be 'auto', a name in tolerax.solve.NAMED_INTEGRATORS or a tolerax.Integrator, "
                        f"got {integrator!r}.")
    if not settings:
        return base, spelled
    try:
        chosen = base.replace(**settings)
    except (TypeError, ValueError) as err:
        raise type(err)(f"{where}: {str(err).removeprefix('Integrator: ')}") from None
    return chosen, f"{spelled}.replace({', '.join(f'{k}={v!r}' for k, v in settings.items())})"
