"""The joint on its test bench: fixed housing, a speed-servoed motor on the sun, a load on the
carrier. The smallest scene that exercises every term of the planetary stage.
"""

import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float

from . import _planetary, _validate as V
from ._planetary import AddedInertia, PlanetaryStage
from ._solve import DTMIN, SimulationError, SolverReport, raise_on_failure, solve  # noqa: F401 (SimulationError: re-exported)


class SpeedServo(eqx.Module):
    """PI speed servo on the motor (sun) shaft, tracking a commanded *output* rate.

    Torque on the sun: $T = k_p(i\\Omega - \\dot\\theta_s) + k_i(i\\Omega t - \\theta_s)$ with
    $i = 1 + z_r/z_s$ and $\\Omega$ the commanded carrier rate.

    - `output_rate`: $\\Omega$ (rad/s); the paper's 0.49, 0.98, 1.96 °/s.
    - `proportional`: $k_p$ (N m s/rad); `integral`: $k_i$ (N m/rad).
    """

    output_rate: Float[Array, ""]
    proportional: Float[Array, ""]
    integral: Float[Array, ""]

    def __init__(self, output_rate=math.radians(0.98), proportional=0.2, integral=2.0):
        self.output_rate = V.real("SpeedServo", "output_rate", output_rate, "rad/s")
        self.proportional = V.real("SpeedServo", "proportional", proportional, "N m s/rad")
        self.integral = V.real("SpeedServo", "integral", integral, "N m/rad")

    def __check_init__(self):
        V.check(
            self,
            output_rate=V.FINITE("rad/s"),
            proportional=V.NONNEGATIVE("N m s/rad"),
            integral=V.NONNEGATIVE("N m/rad"),
        )

    def torque(self, ratio: float, t, theta_s, omega_s):
        return self.proportional * (ratio * self.output_rate - omega_s) + self.integral * (
            ratio * self.output_rate * t - theta_s
        )


class TestBench(eqx.Module):
    """A stage on a bench.

    - `stage`: the `PlanetaryStage`.
    - `servo`: the `SpeedServo` on the sun.
    - `motor_inertia`: rotor inertia on the sun shaft (kg m²).
    - `load_inertia`, `load_mass`: body rigidly on the carrier (kg m², kg); defaults are the
      reference paper's antenna reflector (Table 1: 8.005 kg, 1.05956 kg m² about its largest axis).
    - `load_torque`: constant torque resisting the carrier's motion (N m), e.g. harness drag;
      smoothed through zero speed as $T\\tanh(\\dot\\theta_c/\\omega_0)$, $\\omega_0$ = 1e-3 rad/s.
    - `start`: `"rest"` (everything at rest: the servo's start-up closes the backlash, so the
      run has impacts) or `"steady"` (rigid kinematics at the commanded speed). Static.
    """

    __test__ = False  # not a pytest class

    stage: PlanetaryStage
    servo: SpeedServo
    motor_inertia: Float[Array, ""]
    load_inertia: Float[Array, ""]
    load_mass: Float[Array, ""]
    load_torque: Float[Array, ""]
    start: str = eqx.field(static=True)

    def __init__(
        self,
        stage=None,
        servo=None,
        motor_inertia=2e-4,
        load_inertia=1.05956,
        load_mass=8.005,
        load_torque=0.05,
        start="rest",
    ):
        if start not in ("rest", "steady"):
            raise ValueError(f"start={start!r} is unknown; use 'rest' or 'steady'.")
        self.start = start
        self.load_torque = V.real("TestBench", "load_torque", load_torque, "N m")
        self.stage = _planetary.default_stage() if stage is None else stage
        self.servo = SpeedServo() if servo is None else servo
        self.motor_inertia = V.real("TestBench", "motor_inertia", motor_inertia, "kg m^2")
        self.load_inertia = V.real("TestBench", "load_inertia", load_inertia, "kg m^2")
        self.load_mass = V.real("TestBench", "load_mass", load_mass, "kg")

    def __check_init__(self):
        if not isinstance(self.stage, PlanetaryStage):
            raise TypeError(f"TestBench.stage must be a PlanetaryStage, got {type(self.stage).__name__}.")
        if not isinstance(self.servo, SpeedServo):
            raise TypeError(f"TestBench.servo must be a SpeedServo, got {type(self.servo).__name__}.")
        V.check(
            self,
            load_torque=V.NONNEGATIVE("N m"),
            motor_inertia=V.NONNEGATIVE("kg m^2"),
            load_inertia=V.NONNEGATIVE("kg m^2"),
            load_mass=V.NONNEGATIVE("kg"),
        )

    @property
    def added(self) -> AddedInertia:
        return AddedInertia(self.motor_inertia, self.load_inertia, self.load_mass)

    def initial_state(self):
        """Every component centred, meshes at $g = 0$; at rest or in rigid kinematics at the
        commanded speed (`start`)."""
        stage = self.stage
        lay = stage.layout
        omega_c = self.servo.output_rate * (1.0 if self.start == "steady" else 0.0)
        omega_s = stage.ratio * omega_c
        # Planet spin from the sun mesh rolling without deflection.
        omega_p = (
            stage.carrier_radius * jnp.cos(stage.sun_pressure_angle) * omega_c
            - stage.sun_base_radius * omega_s
        ) / stage.planet_base_radius
        q = jnp.zeros(lay.size)
        qd = q.at[lay.sun_theta].set(omega_s).at[lay.carrier_theta].set(omega_c)
        qd = qd.at[lay.planet_theta].set(omega_p)
        v = _planetary.initial_impact_rates(stage, q, qd)
        return q, qd, v

    def accelerations(self, t, q, qd, v):
        """$\\ddot q$ and the `StageForces` at one instant."""
        stage = self.stage
        lay = stage.layout
        forces = _planetary.stage_forces(stage, q, qd, v)
        drive = self.servo.torque(stage.ratio, t, q[lay.sun_theta], qd[lay.sun_theta])
        drag = self.load_torque * jnp.tanh(qd[lay.carrier_theta] / 1e-3)
        rhs = forces.generalised.at[lay.sun_theta].add(drive).at[lay.carrier_theta].add(-drag)
        rhs = rhs - _planetary.velocity_forces(stage, q, qd, self.added)
        qdd = jnp.linalg.solve(_planetary.mass_matrix(stage, q, self.added), rhs)
        return qdd, forces

    def observe(self, t, y):
        """The `StageForces` at a saved state."""
        q, qd, v = y
        return self.accelerations(t, q, qd, v)[1]

    def vector_field(self, t, y, args):
        q, qd, v = y
        with jax.named_scope("bench_dynamics"):
            qdd, _ = self.accelerations(t, q, qd, v)
        with jax.named_scope("impact_memory"):
            vd = _planetary.impact_rate_rates(self.stage, q, qd, qdd, v)
        return qd, qdd, vd


class BenchResult(SolverReport):
    """Time series of a bench run (SI units; angles in rad).

    - `ts`: save times (s).
    - `output_angle`: carrier angle $\\theta_c$; `output_angle_error`: $\\theta_c - \\Omega t$.
    - `transmission_error`: $\\theta_c - \\theta_s/i$ (rad), $i = 1 + z_r/z_s$.
    - `contact_force`: normal force of each clearance contact (N), columns `contact_names`.
    - `sun_mesh_force`, `ring_mesh_force`: tooth force per planet (N), + drive flank, − back flank.
    - solver report (`SolverReport`): `result`, `t_reached`, `num_steps`, `num_rejected`,
      `duration`; `success`, `failures()`, `report()` (per sample for a batch).
    """

    _what = "bench"

    ts: Array
    output_angle: Array
    output_angle_error: Array
    transmission_error: Array
    contact_force: Array
    sun_mesh_force: Array
    ring_mesh_force: Array
    states: tuple
    contact_names: tuple[str, ...] = eqx.field(static=True)


def simulate_bench(
    bench: TestBench | None = None,
    duration: float = 2.0,
    *,
    n_save: int = 2001,
    solver: diffrax.AbstractSolver | None = None,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    dt0: float = 1e-6,
    dtmax: float = 1e-3,
    max_steps: int = 2_000_000,
    throw: bool = True,
    y0: tuple | None = None,
    progress: bool = False,
    fixed_step: float | None = None,
    dtmin: float = DTMIN,
) -> BenchResult:
    """Run the bench from `bench.initial_state()` (at rest or in steady rolling, per `start`).

    **Arguments:**

    - `bench`: the `TestBench` (default: the default joint at 0.98 °/s, 100 µm clearances).
    - `duration`: simulated time (s).
    - `n_save`: number of equally spaced save times.
    - `solver`: a diffrax solver (default `Tsit5`, explicit: its step is held near its
      stability limit by the ~18 kHz sun-translation/mesh mode, see
      `benchmarks/bench_profile.py`; implicit solvers are not yet compared).
    - `rtol`, `atol`: PID step-size controller tolerances (atol in the state's SI units: m, rad,
      m/s, rad/s; 1e-9 resolves nanometres against 100 µm clearances).
    - `dt0`, `dtmax`: first and largest step (s); `dtmin` (s): a step the error control wants
      below it ends the run with `RESULTS.dt_min_reached` (a step-size collapse).
    - `max_steps`: step budget.
    - `throw`: raise `SimulationError` on failure; otherwise return with `result` set.
    - `y0`: initial `(q, qd, impact_rates)` (default `bench.initial_state()`).
    - `progress`: print diffrax's text progress meter (static: compiles a separate program).
    - `fixed_step`: constant step (s) instead of the adaptive controller (the paper's multibody
      setting is 1e-4 s; an explicit solver is unstable there, see `benchmarks/`).
    """
    bench = TestBench() if bench is None else bench
    solver = diffrax.Tsit5() if solver is None else solver
    if not isinstance(bench, TestBench):
        raise TypeError(f"bench must be a TestBench, got {type(bench).__name__}.")
    if y0 is None:
        y0 = bench.initial_state()
    else:
        V.state_like(y0, bench.initial_state())
    sol, forces = solve(
        bench, y0, duration, n_save, solver, rtol, atol, dt0, dtmax, max_steps, progress, fixed_step, dtmin
    )
    q, qd, v = sol.ys
    lay = bench.stage.layout
    omega = bench.servo.output_rate
    theta_c = q[:, lay.carrier_theta]
    result = BenchResult(
        ts=sol.ts,
        output_angle=theta_c,
        output_angle_error=theta_c - omega * sol.ts,
        transmission_error=theta_c - q[:, lay.sun_theta] / bench.stage.ratio,
        contact_force=forces.contact,
        sun_mesh_force=forces.sun_mesh,
        ring_mesh_force=forces.ring_mesh,
        states=(q, qd, v),
        result=sol.result,
        t_reached=sol.stats["t_reached"],
        num_steps=sol.stats["num_accepted_steps"],
        num_rejected=sol.stats["num_rejected_steps"],
        duration=float(duration),
        contact_names=bench.stage.contact_names,
    )
    if throw:
        raise_on_failure(sol, duration, "bench")
    return result
