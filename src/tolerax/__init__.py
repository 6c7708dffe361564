"""tolerax: differentiable simulation of planetary-gear pointing mechanisms with clearances.

The public API is what this module exports. Low-level kernels stay under their modules:
`tolerax.smooth` (smoothing primitives), `tolerax.contact` (contact kinematics and forces),
`tolerax.mesh` (mesh stiffness and dynamic backlash), `tolerax.planetary` (stage physics:
deflections, forces, mass matrix).

Names are imported on first use (PEP 562): `import tolerax` sets float64 and XLA's compile
flag and loads nothing else (not even JAX), so that a command line's argument errors and
`--help` answer before the simulator's modules and JAX are imported.
"""

import importlib as _importlib

from ._xla import enable_x64 as _enable_x64, prefer_fast_compiles as _prefer_fast_compiles

# SI units with 10 µm clearances next to 1e8 N/m stiffnesses: float64 is the default.
_enable_x64()
_prefer_fast_compiles()  # XLA's faster-compiling CPU code generator, before JAX starts its backend

__version__ = "0.1.0"

# Where each public name lives (module under `tolerax`: names). One table: `__getattr__` imports
# from it, `__all__` lists it.
_FACE = {
    "cache": ("enable_compilation_cache",),
    "physics.contact": ("AbstractContactLaw", "AdamsImpact", "BaiZhao", "Flores", "HertzLN", "JournalBearing"),
    "physics.stage": ("Mesh", "PlanetaryStage", "Support"),
    "physics.gears": ("default_stage",),
    "physics.planetary": ("AddedInertia",),
    "physics.modes": ("Modes", "natural_frequencies"),
    "mechanism.drives": ("AbstractServo", "ProfileServo", "ScanServo", "SpeedServo", "TorqueDrive"),
    "mechanism": ("FIDELITIES",),
    "mechanism.joints": ("AbstractJoint", "IdealJoint", "LumpedJoint", "LumpedMesh", "lumped_mesh"),
    "mechanism.stage_joints": ("MassScaledPlanetaryJoint", "PlanetaryJoint"),
    "solve": ("Integrator", "SimulationError", "SolverReport"),
    "mechanism.scene": ("AbstractScene", "simulate"),
    "mechanism.bench": ("BenchResult", "TestBench"),
    "mechanism.mechanism": ("Mechanism",),
    "mechanism.structure": ("Geometry", "Inertias"),
    "mechanism.outputs": ("ARCSEC", "MechanismResult", "vibration_amplitude"),
    "mechanism.scenes": ("antenna", "scan"),
    "io.scenefile": ("SceneFile", "SceneFileError", "SceneFileNote", "builtin_scenes", "load_scene", "parse_scene", "save_scene"),
    "design.features": ("design_names", "design_of", "lost_motion_weights", "tolerances_of", "with_design"),
    "design.objectives": ("AbstractMetric", "AbstractObjective", "PointingObjective"),
    "design.propose": ("DesignReport", "propose_design"),
    "design.spec": ("AbstractConstraintModel", "Auto", "MeanPlusKStd", "Secants", "Surface", "Tangents", "ToleranceProblem", "Yield", "Zones"),
    "design.solvers": ("AbstractDesignMethod", "AugmentedLagrangian", "SLSQP", "Sequential"),
    "design.report": ("RequirementOutcome",),
    "design.outcome": ("DesignStatus",),
    "design.requirements": ("Requirement",),
    "design.reliability": ("LinearisedYield",),
    "design.check": ("Check", "YieldCheck", "yield_check"),
    "design.sequential": ("sequential_design",),
    "uncertainty.sampling": ("Tolerances", "apply_draws", "sample", "unit_draws"),
    "uncertainty.montecarlo": ("monte_carlo",),
    "uncertainty.results": ("MonteCarloResult", "wilson_interval"),
    "uncertainty.sensitivity": ("SobolResult", "sobol_indices"),
    "design.cost": ("AbstractCostModel", "Exponential", "GradeTable", "IsoGrade", "ReciprocalPower", "grade_of", "it_tolerance"),
    "design.optimise": ("Design", "Features", "OptimisationResult", "optimise_design", "realise", "robust"),
    "identification.recording": ("Recording", "RecordingError", "read_recording"),
    "identification.identify": ("Identification", "identify", "synthetic_recording"),
    "identification.parameters": ("parameter_names",),
    "identification.testdesign": ("TestDesign", "design_test"),
}
_KERNELS = ("smooth", "contact", "mesh", "planetary")  # modules of `tolerax.physics`, on the face as modules
_WHERE = {name: module for module, names in _FACE.items() for name in names}

# The face: every public name and the four kernel modules the docstring names (what
# `from tolerax import *` gives; tests/test_validation.py checks it against what the README and
# docs/ call). Subpackages (`tolerax.design`, ...) stay importable by their paths but are not the face.
__all__ = sorted([*_WHERE, *_KERNELS])


# Former public names, still served for one release with a DeprecationWarning saying what replaces them.
_DEPRECATED = {"JitterRequirement": ("design.report", "a jitter requirement's outcome is report.outcomes[k], a "
                                                      "RequirementOutcome, as every requirement's")}


def __getattr__(name: str):
    if name in _DEPRECATED:
        import warnings

        module, instead = _DEPRECATED[name]
        warnings.warn(f"tolerax.{name} is deprecated and goes in the next release: {instead}.", DeprecationWarning, stacklevel=2)
        return getattr(_importlib.import_module(f".{module}", __name__), name)
    if name in _WHERE:
        value = getattr(_importlib.import_module(f".{_WHERE[name]}", __name__), name)
    elif name in _KERNELS:
        value = _importlib.import_module(f".physics.{name}", __name__)
    else:
        try:  # a subpackage or module by its path (`tolerax.design`, `tolerax.io.scenefile`)
            value = _importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as error:
            if error.name != f"{__name__}.{name}":
                raise
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    globals()[name] = value  # once: later lookups do not come here
    return value


def __dir__():
    return sorted({*globals(), *__all__})
