"""The data of a 2K-H planetary stage (docs/model.md §4): supports, mesh families, the stage itself,
its checks, and the index map of its coordinates. The physics is in `tolerax.physics.planetary`, the
linearisation in `tolerax.physics.modes`, construction from gear data in `tolerax.physics.gears`.

Structure (static: decides which coordinates and terms exist): tooth and planet counts, each
support's kind, each mesh family's kind and whether its backlash is dynamic. Values (arrays:
may be differentiated, sampled, vmapped): masses, radii, stiffnesses, clearances, backlash.
"""

import dataclasses
import math
from collections.abc import Iterator

import equinox as eqx
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float
from . import contact as _contact
from .. import _validate as V

# The clearances and backlash a stage can model (m), in the order a design lists them: the
# sun, carrier (output) and planet-pin bearing clearances and the sun and ring mesh backlash.
DESIGN_FEATURES = ("sun_clearance", "carrier_clearance", "planet_clearance", "sun_backlash", "ring_backlash")

SUPPORT_KINDS = ("rigid", "spring", "clearance")
MESH_KINDS = ("linear", "nonlinear")


def as_float(x):
    return jnp.asarray(x, dtype=float)


class Support(eqx.Module):
    """How a component's centre is held in its bearing.

    - `kind`: `"rigid"` (no translation coordinates), `"spring"` (linear bearing, the
      Lin–Parker model) or `"clearance"` (radial clearance with a contact law). Static.
    - `stiffness`: bearing stiffness $k$ (N/m), used by `"spring"`.
    - `damping`: bearing damping (N s/m), used by `"spring"`.
    - `bearing`: the `JournalBearing` (journal radius, clearance, length, $E^*$), used by
      `"clearance"`; its fields may have shape `(n_planets,)` for the planet pins.
    """

    kind: str = eqx.field(static=True)
    stiffness: Float[Array, ""]
    damping: Float[Array, ""]
    bearing: _contact.JournalBearing | None

    def __init__(self, kind="rigid", stiffness=0.0, damping=0.0, bearing=None):
        self.kind = kind
        self.stiffness = V.real("Support", "stiffness", stiffness, "N/m")
        self.damping = V.real("Support", "damping", damping, "N s/m")
        self.bearing = bearing

    def __check_init__(self):
        if self.kind not in SUPPORT_KINDS:
            raise ValueError(f"Support kind {self.kind!r} is unknown; use one of {SUPPORT_KINDS}.")
        if self.kind == "clearance" and self.bearing is None:
            raise ValueError("A 'clearance' support needs a JournalBearing (`bearing=`).")
        if self.bearing is not None and not isinstance(self.bearing, _contact.JournalBearing):
            raise TypeError(f"Support.bearing must be a JournalBearing, got {type(self.bearing).__name__}.")
        V.check(self, stiffness=V.NONNEGATIVE("N/m"), damping=V.NONNEGATIVE("N s/m"))

    @property
    def translates(self) -> bool:
        return self.kind != "rigid"


class Mesh(eqx.Module):
    """One family of meshes (all sun–planet, or all ring–planet meshes) of a stage.

    - `kind`: `"linear"` (constant stiffness $k_m$, no backlash) or `"nonlinear"` (dead zone,
      time-varying stiffness, profile error). Static.
    - `dynamic_backlash`: recompute the backlash from the displaced centres. Static.
    - `stiffness`: mean mesh stiffness $k_m$ (N/m).
    - `contact_ratio`: $\\varepsilon_c$ (time-varying stiffness amplitude $\\varepsilon_c - 1$).
    - `damping_ratio`: $\\xi$.
    - `backlash`: $b_0$ per planet (m), shape `(n_planets,)`.
    - `profile_error`: amplitude $E_e$ (m); `profile_phase`: $\\varphi_e$ (rad).
    - `stiffness_phase`: offset of each planet's mesh phase (rad), shape `(n_planets,)`.
    """

    kind: str = eqx.field(static=True)
    dynamic_backlash: bool = eqx.field(static=True)
    stiffness: Float[Array, ""]
    contact_ratio: Float[Array, ""]
    damping_ratio: Float[Array, ""]
    backlash: Float[Array, " n_planets"]
    profile_error: Float[Array, ""]
    profile_phase: Float[Array, ""]
    stiffness_phase: Float[Array, " n_planets"]

    def __init__(
        self,
        kind="nonlinear",
        stiffness=1e8,
        contact_ratio=1.6,
        damping_ratio=0.06,
        backlash=100e-6,
        profile_error=0.0,
        profile_phase=0.0,
        stiffness_phase=0.0,
        dynamic_backlash=True,
        n_planets=3,
    ):
        V.positive_integer("Mesh.n_planets", n_planets)
        self.kind = kind
        self.dynamic_backlash = bool(dynamic_backlash)
        self.stiffness = V.real("Mesh", "stiffness", stiffness, "N/m")
        self.contact_ratio = V.real("Mesh", "contact_ratio", contact_ratio, "-")
        self.damping_ratio = V.real("Mesh", "damping_ratio", damping_ratio, "-")
        per_planet = (int(n_planets),)
        self.backlash = jnp.broadcast_to(V.real("Mesh", "backlash", backlash, "m", per_planet, True), per_planet)
        self.profile_error = V.real("Mesh", "profile_error", profile_error, "m")
        self.profile_phase = V.real("Mesh", "profile_phase", profile_phase, "rad")
        phase = V.real("Mesh", "stiffness_phase", stiffness_phase, "rad", per_planet, True)
        self.stiffness_phase = jnp.broadcast_to(phase, per_planet)

    def __check_init__(self):
        if self.kind not in MESH_KINDS:
            raise ValueError(f"Mesh kind {self.kind!r} is unknown; use one of {MESH_KINDS}.")
        V.check(
            self,
            stiffness=V.POSITIVE("N/m"),
            contact_ratio=V.CONTACT_RATIO,
            damping_ratio=V.NONNEGATIVE("-"),
            backlash=V.NONNEGATIVE("m"),
            profile_error=V.FINITE("m"),
            profile_phase=V.FINITE("rad"),
            stiffness_phase=V.FINITE("rad"),
        )


class PlanetaryStage(eqx.Module):
    """A 2K-H planetary stage: structure (static) and values (arrays). See the module docstring.

    Masses (kg), inertias (kg m²), base radii and carrier radius (m), pressure angles (rad),
    torsional support stiffnesses on $u = r\\theta$ (N/m; `None` = free rotation), supports and
    meshes as `Support` / `Mesh`. The ring is `"rigid"` (fixed to the housing) or `"spring"`.
    Numerical options: `smoothing_width` $\\varepsilon$ (m) of every dead zone, ramp and switch;
    `impact_rate_floor` (m/s) and `impact_memory_time` (s) of the contacts' impact-rate states.
    `distinct_planets` (static): the tolerance design treats each planet's pin clearance and
    mesh backlash as a feature of its own (`tolerax.design.features`); the dynamics read
    per-planet values either way. Build a stage from gear data with `default_stage`.
    """

    n_planets: int = eqx.field(static=True)
    sun_teeth: int = eqx.field(static=True)
    planet_teeth: int = eqx.field(static=True)
    ring_teeth: int = eqx.field(static=True)
    sun_mass: Float[Array, ""]
    carrier_mass: Float[Array, ""]
    planet_mass: Float[Array, ""]
    ring_mass: Float[Array, ""]
    sun_inertia: Float[Array, ""]
    carrier_inertia: Float[Array, ""]
    planet_inertia: Float[Array, ""]
    ring_inertia: Float[Array, ""]
    sun_base_radius: Float[Array, ""]
    planet_base_radius: Float[Array, ""]
    ring_base_radius: Float[Array, ""]
    carrier_radius: Float[Array, ""]
    sun_pressure_angle: Float[Array, ""]
    ring_pressure_angle: Float[Array, ""]
    planet_angles: Float[Array, " n_planets"]
    sun_support: Support
    carrier_support: Support
    planet_support: Support
    ring_support: Support
    sun_torsion: Float[Array, ""] | None
    carrier_torsion: Float[Array, ""] | None
    ring_torsion: Float[Array, ""] | None
    sun_mesh: Mesh
    ring_mesh: Mesh
    contact_law: _contact.AbstractContactLaw | None  # None only for a stage without clearances
    smoothing_width: Float[Array, ""]
    impact_rate_floor: Float[Array, ""]
    impact_memory_time: Float[Array, ""]
    distinct_planets: bool = eqx.field(static=True, default=False)

    def __check_init__(self):
        _check_stage(self)
        if self.ring_support.kind == "clearance":
            raise ValueError("The ring support must be 'rigid' or 'spring' (no ring clearance).")
        if self.contact_names and self.contact_law is None:
            raise ValueError("A stage with a 'clearance' support needs a `contact_law`.")
        if self.ring_support.kind == "spring" and self.ring_torsion is None:
            raise ValueError("A spring-mounted ring needs `ring_torsion` (N/m on u = r theta).")

    # ----------------------------------------------------------------------------------------
    # Coordinates

    @property
    def layout(self) -> "Layout":
        return Layout.of(self)

    @property
    def ratio(self) -> float:
        """Rigid transmission ratio sun/carrier with the ring fixed, $1 + z_r/z_s$."""
        return 1.0 + self.ring_teeth / self.sun_teeth

    def supports(self) -> Iterator[tuple[str, "Support"]]:
        """`(component, support)` for the sun, carrier, ring and planet pins, in this order: the
        order of translation coordinates, deflections and clearance contacts everywhere."""
        yield "sun", self.sun_support
        yield "carrier", self.carrier_support
        yield "ring", self.ring_support
        yield "planet", self.planet_support

    def torsions(self) -> Iterator[tuple[str, Array | None]]:
        """`(component, torsional stiffness or None)` for the sun, carrier and ring (N/m on $u = r\\theta$)."""
        yield "sun", self.sun_torsion
        yield "carrier", self.carrier_torsion
        yield "ring", self.ring_torsion

    @property
    def contact_names(self) -> tuple[str, ...]:
        """The clearance contacts this stage has, in the order of the impact-rate states."""
        names = []
        for name, support in self.supports():
            if support.kind == "clearance":
                names += [f"planet{n}" for n in range(self.n_planets)] if name == "planet" else [name]
        return tuple(names)


def _check_stage(stage: PlanetaryStage) -> None:
    """Types, ranges and geometry of a stage (concrete values; traced ones are skipped)."""
    for name in ("n_planets", "sun_teeth", "planet_teeth", "ring_teeth"):
        V.positive_integer(f"PlanetaryStage.{name}", getattr(stage, name))
    if stage.ring_teeth != stage.sun_teeth + 2 * stage.planet_teeth:
        raise ValueError(
            f"Tooth counts do not assemble coaxially: ring_teeth={stage.ring_teeth} must equal "
            f"sun_teeth + 2*planet_teeth = {stage.sun_teeth + 2 * stage.planet_teeth}."
        )
    for name, cls in (
        ("sun_support", Support), ("carrier_support", Support), ("planet_support", Support),
        ("ring_support", Support), ("sun_mesh", Mesh), ("ring_mesh", Mesh),
    ):
        if not isinstance(getattr(stage, name), cls):
            raise TypeError(f"PlanetaryStage.{name} must be a {cls.__name__}, got {type(getattr(stage, name)).__name__}.")
    law = stage.contact_law
    if law is not None and not isinstance(law, _contact.AbstractContactLaw):
        raise TypeError(f"PlanetaryStage.contact_law must be a contact law (e.g. BaiZhao), got {type(law).__name__}.")
    n = stage.n_planets
    for name in ("sun_mesh", "ring_mesh"):
        for field in ("backlash", "stiffness_phase"):
            shape = jnp.shape(getattr(getattr(stage, name), field))
            if shape != (n,):
                raise ValueError(f"PlanetaryStage.{name}.{field} must have shape ({n},) (one per planet), got {shape}.")
    if jnp.shape(stage.planet_angles) != (n,):
        raise ValueError(f"PlanetaryStage.planet_angles must have shape ({n},) (rad), got {jnp.shape(stage.planet_angles)}.")
    bearing = stage.planet_support.bearing
    if bearing is not None:
        for field in ("journal_radius", "clearance", "length", "modulus"):
            shape = jnp.shape(getattr(bearing, field))
            if shape not in ((), (n,)):
                raise ValueError(
                    f"The planet pins' JournalBearing.{field} must be a scalar or shape ({n},), got {shape}."
                )
    for name, support in stage.supports():
        if name != "planet" and support.bearing is not None:
            shape = jnp.shape(support.bearing.clearance)
            if shape != ():
                raise ValueError(f"The {name} bearing's clearance must be a scalar (m), got shape {shape}.")
    mass, inertia, length = V.POSITIVE("kg"), V.POSITIVE("kg m^2"), V.POSITIVE("m")
    angle = V.PRESSURE_ANGLE
    V.check(
        stage,
        sun_mass=mass, carrier_mass=mass, planet_mass=mass, ring_mass=mass,
        sun_inertia=inertia, carrier_inertia=inertia, planet_inertia=inertia, ring_inertia=inertia,
        sun_base_radius=length, planet_base_radius=length, ring_base_radius=length, carrier_radius=length,
        sun_pressure_angle=angle, ring_pressure_angle=angle,
        planet_angles=V.FINITE("rad"),
        sun_torsion=V.Rule("N/m", low=0.0, low_open=True, optional=True),
        carrier_torsion=V.Rule("N/m", low=0.0, low_open=True, optional=True),
        ring_torsion=V.Rule("N/m", low=0.0, low_open=True, optional=True),
        smoothing_width=V.NONNEGATIVE("m"),
        impact_rate_floor=V.POSITIVE("m/s"),
        impact_memory_time=V.POSITIVE("s"),
    )
    if V.concrete(stage.planet_base_radius, stage.sun_pressure_angle, stage.carrier_radius, stage.planet_angles):
        # Neighbouring planets must not overlap: centre distance 2 r_c sin(dpsi/2) > tip diameter,
        # tip radius r_p (1 + 2/z_p) (addendum one module, m = 2 r_p / z_p).
        r_p = float(stage.planet_base_radius) / math.cos(float(stage.sun_pressure_angle))
        tip = r_p * (1.0 + 2.0 / stage.planet_teeth)
        psi = np.sort(np.mod(np.asarray(stage.planet_angles, dtype=float), 2 * math.pi))
        gaps = np.diff(np.append(psi, psi[0] + 2 * math.pi)) if n > 1 else np.array([2 * math.pi])
        distance = 2.0 * float(stage.carrier_radius) * math.sin(min(float(gaps.min()), 2 * math.pi) / 2.0)
        if n > 1 and not distance > 2.0 * tip:
            raise ValueError(
                f"The {n} planets do not fit: neighbouring planet centres are {distance * 1e3:.3g} mm apart "
                f"on the {float(stage.carrier_radius) * 1e3:.3g} mm carrier radius, less than a planet's tip "
                f"diameter {2 * tip * 1e3:.3g} mm. Use fewer or smaller planets, or spread planet_angles."
            )


@dataclasses.dataclass(frozen=True)
class Layout:
    """Index map of the generalised coordinates of a stage (pure Python, static)."""

    size: int
    sun_theta: int
    carrier_theta: int
    planet_theta: slice
    ring_theta: int | None
    sun_xy: slice | None
    carrier_xy: slice | None
    ring_xy: slice | None
    planet_xy: slice | None
    names: tuple[str, ...]

    @staticmethod
    def of(stage: PlanetaryStage) -> "Layout":
        n = stage.n_planets
        names = ["theta_s", "theta_c"] + [f"theta_p{k}" for k in range(n)]
        ring_theta = None
        if stage.ring_support.kind == "spring":
            ring_theta = len(names)
            names.append("theta_r")

        def block(flag, labels):
            if not flag:
                return None
            start = len(names)
            names.extend(labels)
            return slice(start, len(names))

        blocks = {}
        for name, support in stage.supports():
            if name == "planet":
                labels = [f"{a}_p{k}" for k in range(n) for a in ("zeta", "eta")]
            else:
                labels = [f"x_{name[0]}", f"y_{name[0]}"]
            blocks[name] = block(support.translates, labels)

        return Layout(
            size=len(names),
            sun_theta=0,
            carrier_theta=1,
            planet_theta=slice(2, 2 + n),
            ring_theta=ring_theta,
            sun_xy=blocks["sun"],
            carrier_xy=blocks["carrier"],
            ring_xy=blocks["ring"],
            planet_xy=blocks["planet"],
            names=tuple(names),
        )
