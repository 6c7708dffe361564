"""Construction of a planetary stage from gear data: the default joint of docs/model.md §4."""

import math

import equinox as eqx
import numpy as np

from . import contact as _contact
from .. import _validate as V
from .stage import MESH_KINDS, SUPPORT_KINDS, Mesh, PlanetaryStage, Support, as_float

STEEL = dict(young=206e9, poisson=0.3, density=7850.0)


_GEAR_RULES = dict(
    module=V.Rule("m: ISO 54 modules run from 0.05 to 50 mm", low=5e-5, high=0.05),  # a plausible gear, not 1e9 m
    pressure_angle=V.PRESSURE_ANGLE,
    face_width=V.POSITIVE("m"),
    carrier_radius=V.Rule("m", low=0.0, low_open=True, optional=True),
    # Plausible gear materials, polymers to tungsten alloys: outside, a slip of unit (g/cm^3, GPa).
    density=V.Rule("kg/m^3: gear materials run from about 900 (polymers) to 19300 (tungsten)", low=500.0, high=25000.0),
    young=V.Rule("Pa: gear materials run from about 1 GPa (polymers) to 700 GPa (carbides)", low=5e8, high=1e12),
    poisson=V.Rule("-", low=-1.0, high=0.5, low_open=True, high_open=True),
    mesh_stiffness=V.POSITIVE("N/m"),
    contact_ratio=V.CONTACT_RATIO,
    mesh_damping_ratio=V.NONNEGATIVE("-"),
    sun_mesh_stiffness=V.Rule("N/m", low=0.0, low_open=True, optional=True),
    ring_mesh_stiffness=V.Rule("N/m", low=0.0, low_open=True, optional=True),
    sun_mesh_damping_ratio=V.Rule("-", low=0.0, optional=True),
    ring_mesh_damping_ratio=V.Rule("-", low=0.0, optional=True),
    backlash=V.NONNEGATIVE("m"),
    profile_error=V.FINITE("m"),
    sun_clearance=V.NONNEGATIVE("m"),
    carrier_clearance=V.NONNEGATIVE("m"),
    planet_clearance=V.NONNEGATIVE("m"),
    sun_journal_radius=V.POSITIVE("m"),
    carrier_journal_radius=V.POSITIVE("m"),
    planet_journal_radius=V.POSITIVE("m"),
    bearing_length=V.POSITIVE("m"),
    bearing_stiffness=V.NONNEGATIVE("N/m"),
    bearing_damping=V.NONNEGATIVE("N s/m"),
    restitution=V.RESTITUTION,
    smoothing_width=V.NONNEGATIVE("m"),
    impact_rate_floor=V.POSITIVE("m/s"),
    impact_memory_time=V.POSITIVE("s"),
)


def _check_gear_data(args: dict) -> None:
    """`default_stage`'s arguments, named as the caller wrote them."""
    for name in ("sun_teeth", "planet_teeth", "ring_teeth", "n_planets"):
        V.positive_integer(f"default_stage({name}=...)", args[name])
    if not isinstance(args["distinct_planets"], bool):
        raise TypeError(f"default_stage(distinct_planets=...) must be True or False, got {args['distinct_planets']!r}.")
    if args["planet_spacing"] not in ("equal", "assembled"):
        raise ValueError(f"planet_spacing={args['planet_spacing']!r} is unknown; use 'equal' or 'assembled'.")
    for name in ("mesh", "sun_support", "carrier_support", "planet_support"):
        allowed = MESH_KINDS if name == "mesh" else SUPPORT_KINDS
        if args[name] not in allowed:
            raise ValueError(f"default_stage({name}={args[name]!r}) is unknown; use one of {allowed}.")
    holder = type("default_stage", (), {})()
    for name, rule in _GEAR_RULES.items():
        value = args[name]
        if value is not None:
            value = V.real("default_stage", name, value, rule.unit, shape=None)
        setattr(holder, name, value)
    V.check(holder, **_GEAR_RULES)
    for part in ("sun", "carrier", "planet"):
        c, r = np.asarray(args[f"{part}_clearance"]), np.asarray(args[f"{part}_journal_radius"])
        if not np.all(c < r):
            raise ValueError(
                f"default_stage({part}_clearance={args[part + '_clearance']!r}) must be smaller than "
                f"{part}_journal_radius={args[part + '_journal_radius']!r} (m): clearances are µm, journals mm."
            )
    backlash, module = np.asarray(args["backlash"], dtype=float), float(args["module"])
    if not np.all(backlash < module):
        raise ValueError(f"default_stage(backlash={args['backlash']!r}) must be below the module ({module!r} m): a backlash of a "
                         "whole module leaves the teeth barely in mesh (gear standards' backlash is a few % of the module, "
                         "DIN 3967); lengths are in m.")


def default_stage(
    *,
    module: float = 1e-3,
    sun_teeth: int = 20,
    planet_teeth: int = 30,
    ring_teeth: int = 80,
    n_planets: int = 3,
    pressure_angle: float = math.radians(20.0),
    face_width: float = 10e-3,
    carrier_radius: float | None = None,
    density: float = STEEL["density"],
    young: float = STEEL["young"],
    poisson: float = STEEL["poisson"],
    mesh_stiffness: float = 1e8,
    contact_ratio: float = 1.6,
    mesh_damping_ratio: float = 0.06,
    sun_mesh_stiffness: float | None = None,
    ring_mesh_stiffness: float | None = None,
    sun_mesh_damping_ratio: float | None = None,
    ring_mesh_damping_ratio: float | None = None,
    backlash: float = 100e-6,
    profile_error: float = 0.0,
    mesh: str = "nonlinear",
    dynamic_backlash: bool = True,
    sun_support: str = "clearance",
    carrier_support: str = "clearance",
    planet_support: str = "clearance",
    sun_clearance: float = 100e-6,
    carrier_clearance: float = 100e-6,
    planet_clearance: float = 100e-6,
    sun_journal_radius: float = 5e-3,
    carrier_journal_radius: float = 15e-3,
    planet_journal_radius: float = 4e-3,
    bearing_length: float = 8e-3,
    bearing_stiffness: float = 1e8,
    bearing_damping: float = 0.0,
    restitution: float = 0.9,
    contact_law: _contact.AbstractContactLaw | None = None,
    smoothing_width: float = 1e-9,
    impact_rate_floor: float = 1e-3,
    impact_memory_time: float = 1e-4,
    planet_spacing: str = "equal",
    distinct_planets: bool = False,
) -> PlanetaryStage:
    """The default joint of docs/model.md §4 (all values overridable; SI units).

    Module 1 mm, $z_s, z_p, z_r$ = 20, 30, 80 (ratio 5), $\\alpha_0$ = 20°, face width 10 mm,
    steel; solid-disc masses and inertias of the pitch circles; carrier a solid disc of radius
    $r_c$ = 25 mm (the centre distance); ring fixed. $k_m = 10^8$ N/m, $\\varepsilon_c$ = 1.6,
    $\\xi$ = 0.06, $c_e$ = 0.9 (Bai–Zhao law). Journals: sun 5 mm, carrier output 15 mm, planet pins
    4 mm radius, 8 mm long. Clearances and backlash 100 µm (the paper's cases). Support kinds
    `"rigid"`, `"spring"` (stiffness `bearing_stiffness`) or `"clearance"`.

    `impact_memory_time` $\\tau$ = 0.1 ms: after a contact separates, the offset between the
    impact-rate state and $\\dot\\delta$ decays as $e^{-t/\\tau}$ (1 % after 0.46 ms), which is short
    against a flight across a 10–100 µm clearance at the mm/s speeds of these joints. Its
    eigenvalue $-1/\\tau$ bounds an explicit solver's step (3.5e-4 s for Tsit5), so a much shorter
    memory would make it the step limit of the lumped joint.

    `planet_spacing`: `"equal"` puts the planets at $\\psi_n = 2\\pi n/N$ (docs/model.md and the paper),
    whatever the tooth counts; `"assembled"` also requires that real gears can be assembled that
    way, $(z_s + z_r)/N$ an integer, and raises otherwise. The paper's 20/30/80 with three planets
    is *not* assemblable equally spaced ((20 + 80)/3 is not an integer): the default keeps the
    paper's idealisation, in which each planet's mesh phases are $z_s\\psi_n$ and $-z_r\\psi_n$.

    `sun_mesh_stiffness`, `ring_mesh_stiffness` (N/m), `sun_mesh_damping_ratio`,
    `ring_mesh_damping_ratio`: one mesh family's own mean stiffness or damping ratio (default
    `None`: the shared `mesh_stiffness`, `mesh_damping_ratio`), e.g. a unit whose sun and ring
    meshes were identified apart (`tolerax.identify`).

    `distinct_planets`: design each planet's pin clearance and sun/ring backlash as features of
    their own (`azimuth.planet_clearance[0]`, ...; `tolerax.design.features`) instead of one
    value for all planets: for a tolerance design that sorts or matches planets. Design them at
    planetary fidelity: a lumped joint keeps only the tightest planet's lost motion.

    Every argument is checked before anything is built (`ValueError`/`TypeError` naming it).
    """
    _check_gear_data(locals())
    if planet_spacing == "assembled" and (sun_teeth + ring_teeth) % n_planets:
        raise ValueError(
            f"{n_planets} planets cannot be equally spaced with sun_teeth={sun_teeth}, "
            f"ring_teeth={ring_teeth}: (sun_teeth + ring_teeth) / n_planets = "
            f"{(sun_teeth + ring_teeth) / n_planets:.4g} must be an integer. Change the tooth counts "
            f"or use planet_spacing='equal' (the idealisation of docs/model.md)."
        )
    r_s, r_p, r_r = (module * z / 2 for z in (sun_teeth, planet_teeth, ring_teeth))
    if carrier_radius is None:
        carrier_radius = r_s + r_p
    cos_a = math.cos(pressure_angle)

    def disc(r):
        m = density * math.pi * r**2 * face_width
        return m, 0.5 * m * r**2

    m_s, i_s = disc(r_s)
    m_p, i_p = disc(r_p)
    m_c, i_c = disc(carrier_radius)
    r_out = r_r + 3 * module
    m_r = density * math.pi * (r_out**2 - r_r**2) * face_width
    i_r = 0.5 * m_r * (r_out**2 + r_r**2)
    e_star = _contact.composite_modulus(young, poisson, young, poisson)

    def support(kind, clearance, journal):
        bearing = _contact.JournalBearing(journal, clearance, bearing_length, e_star)
        return Support(kind, bearing_stiffness, bearing_damping, bearing if kind == "clearance" else None)

    def family(stiffness, damping_ratio):
        return Mesh(
            kind=mesh,
            stiffness=mesh_stiffness if stiffness is None else stiffness,
            contact_ratio=contact_ratio,
            damping_ratio=mesh_damping_ratio if damping_ratio is None else damping_ratio,
            backlash=backlash,
            profile_error=profile_error,
            dynamic_backlash=dynamic_backlash,
            n_planets=n_planets,
        )

    psi = 2 * np.pi * np.arange(n_planets) / n_planets
    sun_mesh = family(sun_mesh_stiffness, sun_mesh_damping_ratio)
    ring_mesh = family(ring_mesh_stiffness, ring_mesh_damping_ratio)
    # Each planet meets the sun and ring teeth at its own phase: z * psi_n.
    sun_mesh = eqx.tree_at(lambda m: m.stiffness_phase, sun_mesh, as_float(sun_teeth * psi))
    ring_mesh = eqx.tree_at(lambda m: m.stiffness_phase, ring_mesh, as_float(-ring_teeth * psi))
    return PlanetaryStage(
        n_planets=n_planets,
        sun_teeth=sun_teeth,
        planet_teeth=planet_teeth,
        ring_teeth=ring_teeth,
        sun_mass=as_float(m_s),
        carrier_mass=as_float(m_c),
        planet_mass=as_float(m_p),
        ring_mass=as_float(m_r),
        sun_inertia=as_float(i_s),
        carrier_inertia=as_float(i_c),
        planet_inertia=as_float(i_p),
        ring_inertia=as_float(i_r),
        sun_base_radius=as_float(r_s * cos_a),
        planet_base_radius=as_float(r_p * cos_a),
        ring_base_radius=as_float(r_r * cos_a),
        carrier_radius=as_float(carrier_radius),
        sun_pressure_angle=as_float(pressure_angle),
        ring_pressure_angle=as_float(pressure_angle),
        planet_angles=as_float(psi),
        sun_support=support(sun_support, sun_clearance, sun_journal_radius),
        carrier_support=support(carrier_support, carrier_clearance, carrier_journal_radius),
        planet_support=support(planet_support, planet_clearance, planet_journal_radius),
        ring_support=Support("rigid"),
        sun_torsion=None,
        carrier_torsion=None,
        ring_torsion=None,
        sun_mesh=sun_mesh,
        ring_mesh=ring_mesh,
        contact_law=_contact.BaiZhao(restitution) if contact_law is None else contact_law,
        smoothing_width=as_float(smoothing_width),
        impact_rate_floor=as_float(impact_rate_floor),
        impact_memory_time=as_float(impact_memory_time),
        distinct_planets=bool(distinct_planets),
    )
