"""The joint on its test bench: fixed housing, a speed-servoed motor on the sun, a load on the
carrier. The smallest scene that exercises every term of the planetary stage.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array, Float
from ..physics import gears as _gears
from ..physics import planetary as _planetary
from .. import _validate as V
from .drives import AbstractServo, SpeedServo, drag
from ..physics.planetary import AddedInertia
from .scene import AbstractScene
from ..solve import ACCURATE, SolverReport
from ..physics.stage import DESIGN_FEATURES, PlanetaryStage


class TestBench(AbstractScene):
    """A stage on a bench.

    - `stage`: the `PlanetaryStage`.
    - `servo`: the servo on the sun (`SpeedServo`, or `ScanServo` for a back-and-forth scan).
    - `motor_inertia`: rotor inertia on the sun shaft (kg m²).
    - `load_inertia`, `load_mass`: body rigidly on the carrier (kg m², kg); defaults are the
      reference paper's antenna reflector (Table 1: 8.005 kg, 1.05956 kg m² about its largest axis).
    - `load_torque`: constant torque resisting the carrier's motion (N m), e.g. harness drag;
      smoothed through zero speed as $T\\tanh(\\dot\\theta_c/\\omega_0)$, $\\omega_0$ = 1e-3 rad/s.

    Run it with `simulate(bench, duration, start=...)`.
    """

    __test__ = False  # not a pytest class

    stage: PlanetaryStage
    servo: SpeedServo
    motor_inertia: Float[Array, ""]
    load_inertia: Float[Array, ""]
    load_mass: Float[Array, ""]
    load_torque: Float[Array, ""]
    _what = "bench"

    def __init__(
        self,
        stage=None,
        servo=None,
        motor_inertia=2e-4,
        load_inertia=1.05956,
        load_mass=8.005,
        load_torque=0.05,
    ):
        self.load_torque = V.real("TestBench", "load_torque", load_torque, "N m")
        self.stage = _gears.default_stage() if stage is None else stage
        self.servo = SpeedServo() if servo is None else servo
        self.motor_inertia = V.real("TestBench", "motor_inertia", motor_inertia, "kg m^2")
        self.load_inertia = V.real("TestBench", "load_inertia", load_inertia, "kg m^2")
        self.load_mass = V.real("TestBench", "load_mass", load_mass, "kg")

    def __check_init__(self):
        if not isinstance(self.stage, PlanetaryStage):
            raise TypeError(f"TestBench.stage must be a PlanetaryStage, got {type(self.stage).__name__}.")
        if not isinstance(self.servo, AbstractServo):
            raise TypeError(f"TestBench.servo must be a servo (SpeedServo, ScanServo, ProfileServo), got {type(self.servo).__name__}.")
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

    def automatic_integrator(self):
        # A bench run checks the stage's physics (transmission error, impacts, restitution,
        # frequencies) to the integrator's accuracy: ACCURATE, not FAST_STAGE.
        return ACCURATE, "a bench run checks the stage's physics: accuracy asked"

    def named_stages(self):
        return (("", lambda x: x.stage, DESIGN_FEATURES),)

    def initial_state(self, start: str = "rest"):
        """Every component centred, meshes at $g = 0$; at rest (`start="rest"`) or in rigid
        kinematics at the commanded speed (`"steady"`)."""
        if start == "loaded":
            raise ValueError(
                "start='loaded' is built for mechanisms (tolerax.antenna scenes); the test bench "
                "has 'rest' and 'steady'."
            )
        stage = self.stage
        lay = stage.layout
        omega_c = self.servo.rate(0.0) * (1.0 if start == "steady" else 0.0)
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
        """$\\ddot q$ and the `StageForces` at one instant (one jitted call, traced once for the
        vector field and `observe`: `Mechanism.accelerations`)."""
        return _accelerations(self, t, q, qd, v)

    def _accelerations(self, t, q, qd, v):
        stage = self.stage
        lay = stage.layout
        forces = _planetary.stage_forces(stage, q, qd, v)
        drive = self.servo.torque(stage.ratio, t, q[lay.sun_theta], qd[lay.sun_theta])
        load = drag(self.load_torque, qd[lay.carrier_theta])
        rhs = forces.generalised.at[lay.sun_theta].add(drive).at[lay.carrier_theta].add(-load)
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

    def result(self, sol, observed, duration):
        q, qd, v = sol.ys
        lay = self.stage.layout
        theta_c = q[:, lay.carrier_theta]
        return BenchResult.from_solution(
            sol,
            duration,
            ts=sol.ts,
            output_angle=theta_c,
            output_angle_error=theta_c - self.servo.angle(sol.ts),
            transmission_error=theta_c - q[:, lay.sun_theta] / self.stage.ratio,
            contact_force=observed.contact,
            sun_mesh_force=observed.sun_mesh,
            ring_mesh_force=observed.ring_mesh,
            states=sol.ys,
            contact_names=self.stage.contact_names,
        )


class BenchResult(SolverReport):
    """Time series of a bench run (SI units; angles in rad).

    - `ts`: save times (s).
    - `output_angle`: carrier angle $\\theta_c$; `output_angle_error`: $\\theta_c - \\theta^*(t)$,
      the servo's commanded angle ($\\Omega t$ for a `SpeedServo`).
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


@eqx.filter_jit
def _accelerations(bench, t, q, qd, v):
    return bench._accelerations(t, q, qd, v)
