"""tolerax: differentiable simulation of planetary-gear pointing mechanisms with clearances.

The public API is what this module exports. Low-level kernels stay under their modules:
`tolerax.smooth` (smoothing primitives), `tolerax.contact` (contact kinematics and forces),
`tolerax.mesh` (mesh stiffness and dynamic backlash), `tolerax.planetary` (stage physics:
deflections, forces, mass matrix).
"""

import jax as _jax

# SI units with 10 µm clearances next to 1e8 N/m stiffnesses: float64 is the default.
_jax.config.update("jax_enable_x64", True)

from . import _contact as contact, _mesh as mesh, _planetary as planetary, _smooth as smooth
from ._contact import (
    AbstractContactLaw as AbstractContactLaw,
    AdamsImpact as AdamsImpact,
    BaiZhao as BaiZhao,
    Flores as Flores,
    HertzLN as HertzLN,
    JournalBearing as JournalBearing,
)
from ._stage import Mesh as Mesh, PlanetaryStage as PlanetaryStage, Support as Support
from ._gears import default_stage as default_stage
from ._planetary import AddedInertia as AddedInertia
from ._modes import Modes as Modes, natural_frequencies as natural_frequencies
from ._drives import (
    AbstractServo as AbstractServo,
    ScanServo as ScanServo,
    SpeedServo as SpeedServo,
    TorqueDrive as TorqueDrive,
)
from ._joint import (
    FIDELITIES as FIDELITIES,
    AbstractJoint as AbstractJoint,
    IdealJoint as IdealJoint,
    LumpedJoint as LumpedJoint,
    LumpedMesh as LumpedMesh,
    PlanetaryJoint as PlanetaryJoint,
    lumped_mesh as lumped_mesh,
)
from ._solve import SimulationError as SimulationError, SolverReport as SolverReport
from ._scene import AbstractScene as AbstractScene, simulate as simulate
from ._bench import BenchResult as BenchResult, TestBench as TestBench
from ._mechanism import Geometry as Geometry, Inertias as Inertias, Mechanism as Mechanism
from ._outputs import ARCSEC as ARCSEC, MechanismResult as MechanismResult, vibration_amplitude as vibration_amplitude
from ._scenes import antenna as antenna, scan as scan
from ._design import design_names as design_names, design_of as design_of, with_design as with_design

__version__ = "0.1.0"
