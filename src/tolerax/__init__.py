"""tolerax: differentiable simulation of planetary-gear pointing mechanisms with clearances.

The public API is what this module exports. Low-level kernels stay under their modules:
`tolerax.smooth` (smoothing primitives), `tolerax.contact` (contact kinematics and forces),
`tolerax.mesh` (mesh stiffness and dynamic backlash), `tolerax.planetary` (stage physics:
deflections, forces, mass matrix).
"""

import types as _types

import jax as _jax

# SI units with 10 µm clearances next to 1e8 N/m stiffnesses: float64 is the default.
_jax.config.update("jax_enable_x64", True)

from .cache import enable_compilation_cache as enable_compilation_cache
from .physics import contact as contact, mesh as mesh, planetary as planetary, smooth as smooth
from .physics.contact import (
    AbstractContactLaw as AbstractContactLaw,
    AdamsImpact as AdamsImpact,
    BaiZhao as BaiZhao,
    Flores as Flores,
    HertzLN as HertzLN,
    JournalBearing as JournalBearing,
)
from .physics.stage import Mesh as Mesh, PlanetaryStage as PlanetaryStage, Support as Support
from .physics.gears import default_stage as default_stage
from .physics.planetary import AddedInertia as AddedInertia
from .physics.modes import Modes as Modes, natural_frequencies as natural_frequencies
from .mechanism.drives import (
    AbstractServo as AbstractServo,
    ProfileServo as ProfileServo,
    ScanServo as ScanServo,
    SpeedServo as SpeedServo,
    TorqueDrive as TorqueDrive,
)
from .mechanism import FIDELITIES as FIDELITIES
from .mechanism.joints import (
    AbstractJoint as AbstractJoint,
    IdealJoint as IdealJoint,
    LumpedJoint as LumpedJoint,
    LumpedMesh as LumpedMesh,
    lumped_mesh as lumped_mesh,
)
from .mechanism.stage_joints import (
    MassScaledPlanetaryJoint as MassScaledPlanetaryJoint,
    PlanetaryJoint as PlanetaryJoint,
)
from .solve import SimulationError as SimulationError, SolverReport as SolverReport
from .mechanism.scene import AbstractScene as AbstractScene, simulate as simulate
from .mechanism.bench import BenchResult as BenchResult, TestBench as TestBench
from .mechanism.mechanism import Mechanism as Mechanism
from .mechanism.structure import Geometry as Geometry, Inertias as Inertias
from .mechanism.outputs import ARCSEC as ARCSEC, MechanismResult as MechanismResult, vibration_amplitude as vibration_amplitude
from .mechanism.scenes import antenna as antenna, scan as scan
from .io.scenefile import (
    SceneFile as SceneFile,
    SceneFileError as SceneFileError,
    SceneFileNote as SceneFileNote,
    builtin_scenes as builtin_scenes,
    load_scene as load_scene,
    parse_scene as parse_scene,
    save_scene as save_scene,
)
from .design.features import (
    design_names as design_names,
    design_of as design_of,
    lost_motion_weights as lost_motion_weights,
    tolerances_of as tolerances_of,
    with_design as with_design,
)
from .design.objectives import (
    AbstractMetric as AbstractMetric,
    AbstractObjective as AbstractObjective,
    PointingObjective as PointingObjective,
)
from .design.propose import DesignReport as DesignReport, JitterRequirement as JitterRequirement, propose_design as propose_design
from .design.report import RequirementOutcome as RequirementOutcome
from .design.requirements import Requirement as Requirement
from .design.reliability import LinearisedYield as LinearisedYield, YieldCheck as YieldCheck, yield_check as yield_check
from .design.sequential import sequential_design as sequential_design
from .uncertainty.sampling import Tolerances as Tolerances, apply_draws as apply_draws, sample as sample, unit_draws as unit_draws
from .uncertainty.montecarlo import monte_carlo as monte_carlo
from .uncertainty.results import MonteCarloResult as MonteCarloResult, wilson_interval as wilson_interval
from .uncertainty.sensitivity import SobolResult as SobolResult, sobol_indices as sobol_indices
from .design.cost import (
    AbstractCostModel as AbstractCostModel,
    Exponential as Exponential,
    GradeTable as GradeTable,
    IsoGrade as IsoGrade,
    ReciprocalPower as ReciprocalPower,
    grade_of as grade_of,
    it_tolerance as it_tolerance,
)
from .design.optimise import (
    Design as Design,
    Features as Features,
    OptimisationResult as OptimisationResult,
    optimise_design as optimise_design,
    realise as realise,
    robust as robust,
)

__version__ = "0.1.0"

# The face: every public name above and the four kernel modules the docstring names (what
# `from tolerax import *` gives; tests/test_validation.py checks it against what the README and
# docs/ call). Subpackages bound here by their imports (`tolerax.design`, ...) stay importable by
# their paths but are not the face.
__all__ = sorted(name for name, value in dict(globals()).items() if not name.startswith("_")
                 and (not isinstance(value, _types.ModuleType) or name in ("smooth", "contact", "mesh", "planetary")))
