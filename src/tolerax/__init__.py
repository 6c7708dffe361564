"""tolerax: differentiable simulation of planetary-gear pointing mechanisms with clearances."""

import jax as _jax

# SI units with 10 µm clearances next to 1e8 N/m stiffnesses: float64 is the default.
_jax.config.update("jax_enable_x64", True)

from . import _smooth as smooth
from ._contact import (
    AbstractContactLaw as AbstractContactLaw,
    AdamsImpact as AdamsImpact,
    BaiZhao as BaiZhao,
    ContactState as ContactState,
    Flores as Flores,
    HertzLN as HertzLN,
    JournalBearing as JournalBearing,
    composite_modulus as composite_modulus,
    contact_kinematics as contact_kinematics,
    effective_impact_rate as effective_impact_rate,
    impact_rate_derivative as impact_rate_derivative,
    normal_force as normal_force,
    rate_derivative as rate_derivative,
)

from ._mesh import dynamic_backlash as dynamic_backlash, mesh_stiffness as mesh_stiffness
from ._planetary import (
    AddedInertia as AddedInertia,
    Mesh as Mesh,
    Modes as Modes,
    PlanetaryStage as PlanetaryStage,
    Support as Support,
    default_stage as default_stage,
    natural_frequencies as natural_frequencies,
)
from ._solve import SimulationError as SimulationError
from ._bench import (
    BenchResult as BenchResult,
    SpeedServo as SpeedServo,
    TestBench as TestBench,
    simulate_bench as simulate_bench,
)

from ._mechanism import (
    Geometry as Geometry,
    Inertias as Inertias,
    Joint as Joint,
    LumpedMesh as LumpedMesh,
    Mechanism as Mechanism,
    MechanismResult as MechanismResult,
    TorqueDrive as TorqueDrive,
    antenna as antenna,
    lumped_mesh as lumped_mesh,
    simulate as simulate,
    vibration_amplitude as vibration_amplitude,
)

__version__ = "0.1.0"
