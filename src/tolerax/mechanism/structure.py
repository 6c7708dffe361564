"""The antenna's structure data: the chain's offsets (`Geometry`, m) and the rigid bodies'
masses and principal inertias (`Inertias`: the reference paper's Table 1), for
`tolerax.mechanism.mechanism.Mechanism`.

**Bodies.** The base (the spacecraft, 1500 kg); per joint the sun (plus the motor rotor), the
carrier and the planets as thin discs (transverse inertia half the polar one); link 1, link 2 and
the reflector with the paper's Table 1 data. The ring and the gear housing are part of the body
that carries the joint (base or link 1).

**Default geometry** (all offsets are parameters of `Geometry`; base frame B at the spacecraft's
centre of mass, zero joint angles)::

                        z_B (azimuth axis)
                         ^
                         |   pitch joint P at 0.6 m up link 1; pitch axis = x_B (at zero azimuth)
           reflector  R  +--[P]=====  link 2: a 0.6 m shaft along the pitch axis, centred on P
   boresight y_B <---o---|
       (0.25 m in front  |  link 1: 0.6 m boom along z, centre 0.3 m above A
        of the pitch     |
        axis)           [A]  azimuth joint, 1.5 m above the base centre (top face)
                  +------+------+
                  |  spacecraft |  1500 kg, (2100, 1700, 2400) kg m²
                  +-------------+

Azimuth axis: $z_B$. Pitch axis: the $x$ axis of link 1 (perpendicular to and intersecting the
azimuth axis). Boresight: the reflector's $y$ axis (its largest inertia), horizontal along $y_B$
at zero angles; pitch tilts it in elevation, azimuth turns it about $z_B$. Table 1's "azimuth
joint" and "pitch joint" bodies (3.77 kg, small inertia about their own $z$) are the joints'
rotating output members: link 1 with its $z$ along the azimuth axis, link 2 with its $z$ along
the pitch axis. These inertias fit 0.6 m rods ($\\sqrt{12\\cdot0.11545/3.77}$ = 0.61 m).
"""

import dataclasses

import equinox as eqx
from jaxtyping import Array, Float

from .. import _validate as V


def _set_checked(module, values: dict, shape_of, unit_of):
    """Set real numbers of the expected shape as float arrays (ranges: `__check_init__`)."""
    owner = type(module).__name__
    for name, value in values.items():
        setattr(module, name, V.real(owner, name, value, unit_of(name), shape_of(name)))


class Geometry(eqx.Module):
    """Offsets of the chain (m); see the drawing in the module docstring.

    - `azimuth_position`: azimuth joint centre in the base frame.
    - `link1_centre`: link 1's centre of mass in the azimuth output frame.
    - `pitch_position`: pitch joint centre in the azimuth output frame.
    - `link2_centre`: link 2's centre of mass in the pitch output frame.
    - `reflector_centre`: reflector's centre of mass in the pitch output frame (along the
      boresight $y$).
    """

    azimuth_position: Float[Array, "3"]
    link1_centre: Float[Array, "3"]
    pitch_position: Float[Array, "3"]
    link2_centre: Float[Array, "3"]
    reflector_centre: Float[Array, "3"]

    def __init__(
        self,
        azimuth_position=(0.0, 0.0, 1.5),
        link1_centre=(0.0, 0.0, 0.3),
        pitch_position=(0.0, 0.0, 0.6),
        link2_centre=(0.0, 0.0, 0.0),
        reflector_centre=(0.0, 0.25, 0.0),
    ):
        values = dict(
            azimuth_position=azimuth_position,
            link1_centre=link1_centre,
            pitch_position=pitch_position,
            link2_centre=link2_centre,
            reflector_centre=reflector_centre,
        )
        _set_checked(self, values, lambda name: (3,), lambda name: "m")

    def __check_init__(self):
        V.check(self, **{f.name: V.FINITE("m") for f in dataclasses.fields(self)})


class Inertias(eqx.Module):
    """Masses (kg) and principal inertias (kg m², about each body's own axes) of the paper's
    Table 1. Link 1 = the paper's "azimuth joint", link 2 = its "pitch joint"."""

    base_mass: Float[Array, ""]
    base_inertia: Float[Array, "3"]
    link1_mass: Float[Array, ""]
    link1_inertia: Float[Array, "3"]
    link2_mass: Float[Array, ""]
    link2_inertia: Float[Array, "3"]
    reflector_mass: Float[Array, ""]
    reflector_inertia: Float[Array, "3"]

    def __init__(
        self,
        base_mass=1500.0,
        base_inertia=(2100.0, 1700.0, 2400.0),
        link1_mass=3.77,
        link1_inertia=(0.11545, 0.11545, 0.004712),
        link2_mass=3.77,
        link2_inertia=(0.11545, 0.11545, 0.004712),
        reflector_mass=8.005,
        reflector_inertia=(0.68297, 1.05956, 0.68297),
    ):
        values = dict(
            base_mass=base_mass,
            base_inertia=base_inertia,
            link1_mass=link1_mass,
            link1_inertia=link1_inertia,
            link2_mass=link2_mass,
            link2_inertia=link2_inertia,
            reflector_mass=reflector_mass,
            reflector_inertia=reflector_inertia,
        )
        is_mass = lambda name: name.endswith("mass")  # noqa: E731
        _set_checked(self, values, lambda n: () if is_mass(n) else (3,), lambda n: "kg" if is_mass(n) else "kg m^2")

    def __check_init__(self):
        V.check(self, **{f.name: V.POSITIVE("kg" if f.name.endswith("mass") else "kg m^2") for f in dataclasses.fields(self)})


@dataclasses.dataclass(frozen=True)
class MechanismLayout:
    """Index map of the mechanism's coordinates `q` and speeds `u` (static)."""

    base_q: int  # 7 (position, unit quaternion) for a free base, else 0
    base_u: int  # 6 (velocity in the world frame, angular velocity in the base frame) or 0
    azimuth_q: slice
    pitch_q: slice
    azimuth_u: slice
    pitch_u: slice
    azimuth_v: slice  # impact-rate states
    pitch_v: slice
    size_q: int
    size_u: int
    size_v: int
