"""The mechanism: joints at each fidelity, their drives, the dual-axis antenna, the test bench,
the scene builders and the outputs a pointing study reads."""

from .joints import AbstractJoint, IdealJoint, LumpedJoint
from .stage_joints import MassScaledPlanetaryJoint, PlanetaryJoint

# The `antenna(fidelity=...)` / scene-file shorthand: name -> joint class. A new fidelity is a
# new final subclass of `AbstractJoint` (docs/architecture.md), registered here for the shorthand.
FIDELITIES: dict[str, type[AbstractJoint]] = {
    "ideal": IdealJoint,
    "lumped": LumpedJoint,
    "planetary": PlanetaryJoint,
    "planetary-scaled": MassScaledPlanetaryJoint,
}
