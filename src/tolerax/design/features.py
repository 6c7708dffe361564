"""The tolerance design of a scene: its clearances and backlash as one vector, by name.

A *feature* is a clearance or backlash that a scene models: each stage contributes its
clearance supports (`sun_clearance`, `carrier_clearance`, `planet_clearance`, m) and the
backlash of its nonlinear mesh families (`sun_backlash`, `ring_backlash`, m), all planets alike
unless the stage has `distinct_planets` (then `planet_clearance[i]`, `sun_backlash[i]`,
`ring_backlash[i]` per planet `i`).
A joint lists the features its fidelity reads (`AbstractJoint.design_features`): an ideal joint
none, a lumped joint its output bearing, pin play and the two backlashes, a planetary joint all.
Features a scene does not model are absent, never present with zero effect. In a mechanism the
names are prefixed by the joint's name (`AbstractScene.named_stages`), e.g. `azimuth.planet_clearance`.

`design_of(scene)` reads the vector, `with_design(scene, values)` writes it back (traceable:
`values` may be a tracer under `grad`/`vmap`), `design_names(scene)` names its entries, and
`tolerances_of(scene, band)` makes the `Tolerances` a Monte Carlo run draws from.
"""

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float
from collections.abc import Callable

from ..mechanism.outputs import ARCSEC
from ..mechanism.scene import AbstractScene
from ..physics.stage import PlanetaryStage
from ..uncertainty.sampling import Tolerances

# feature -> (does the stage model it?, where its value lives in the stage)
STAGE_FEATURES = {
    "sun_clearance": (lambda s: s.sun_support.kind == "clearance", lambda s: s.sun_support.bearing.clearance),
    "carrier_clearance": (lambda s: s.carrier_support.kind == "clearance", lambda s: s.carrier_support.bearing.clearance),
    "planet_clearance": (lambda s: s.planet_support.kind == "clearance", lambda s: s.planet_support.bearing.clearance),
    "sun_backlash": (lambda s: s.sun_mesh.kind == "nonlinear", lambda s: s.sun_mesh.backlash),
    "ring_backlash": (lambda s: s.ring_mesh.kind == "nonlinear", lambda s: s.ring_mesh.backlash),
}


# Features of which each planet has its own (with `PlanetaryStage.distinct_planets`).
PER_PLANET = ("planet_clearance", "sun_backlash", "ring_backlash")


def _fields(scene) -> list[tuple[str, str, PlanetaryStage, Callable, int | None]]:
    """`(name, feature, stage, field, planet)` per design feature: `field(scene)` is the stage's
    array that holds it, `planet` the planet's index where each planet is a feature of its own
    (`distinct_planets`: named `"joint.feature[i]"`), else `None`."""
    if not isinstance(scene, AbstractScene) or not scene.named_stages():
        raise TypeError(f"A design needs a scene with gear stages (a TestBench or a Mechanism), got {type(scene).__name__}.")
    out = []
    for joint, stage_of, reads in scene.named_stages():
        stage = stage_of(scene)
        for feature in reads:
            present, where = STAGE_FEATURES[feature]
            if present(stage):
                name = f"{joint}.{feature}" if joint else feature
                field = lambda x, s=stage_of, w=where: w(s(x))  # noqa: E731
                if stage.distinct_planets and feature in PER_PLANET:
                    out += [(f"{name}[{i}]", feature, stage, field, i) for i in range(stage.n_planets)]
                else:
                    out.append((name, feature, stage, field, None))
    return out


def feature_entries(scene) -> list[tuple[str, str, PlanetaryStage, Callable]]:
    """`(name, feature, stage, get)` for each design feature of the scene (`named_stages`):
    `name` is `"joint.feature"` (`feature` for a scene with one stage; `"joint.feature[i]"` for
    planet `i` of a stage with `distinct_planets`), `get(scene)` the value (m)."""
    out = []
    for name, feature, stage, field, planet in _fields(scene):
        if planet is None:
            out.append((name, feature, stage, field))
        else:
            out.append((name, feature, stage, lambda x, f=field, i=planet, n=stage.n_planets: jnp.broadcast_to(f(x), (n,))[i]))
    return out


def _entries(scene):
    return [(name, get) for name, _, _, get in feature_entries(scene)]


def design_names(scene) -> tuple[str, ...]:
    """Names of the scene's design features, in the order of `design_of`."""
    return tuple(name for name, _ in _entries(scene))


def design_of(scene) -> Float[Array, " n_features"]:
    """The scene's clearances and backlash (m), in `design_names` order (the first planet's value
    for per-planet fields, unless the stage has `distinct_planets`: then one entry per planet;
    `with_design` sets all planets alike otherwise)."""
    return jnp.stack([jnp.ravel(get(scene))[0] for _, get in _entries(scene)])


def with_design(scene, values: Float[Array, " n_features"]):
    """`scene` with its clearances and backlash set from `values` (m, `design_names` order; all
    planets alike). Traceable. Values set this way bypass the constructors' checks; `simulate`
    checks concrete values again before running."""
    entries = _entries(scene)
    if jnp.shape(values) != (len(entries),):
        raise ValueError(
            f"with_design: values must have shape ({len(entries)},) for the features "
            f"{[n for n, _ in entries]}, got shape {jnp.shape(values)}."
        )
    # One leaf per stage field; a field whose planets are features of their own gets one value each.
    leaves: dict[str, list] = {}  # by "joint.feature" (two joints may hold one stage object)
    for k, (name, _, stage, field, planet) in enumerate(_fields(scene)):
        leaves.setdefault(name.split("[")[0], [field, stage.n_planets, []])[2].append((k, planet))
    getters = [field for field, _, _ in leaves.values()]
    new = []
    for (field, n, items), old in zip(leaves.values(), [get(scene) for get in getters]):
        if items[0][1] is None:
            new.append(jnp.broadcast_to(values[items[0][0]], jnp.shape(old)).astype(float))
        else:
            new.append(jnp.stack([values[k] for k, _ in sorted(items, key=lambda item: item[1])]).astype(float))
    return eqx.tree_at(lambda x: tuple(get(x) for get in getters), scene, tuple(new))


def tolerances_of(scene, band=10e-6, distribution: str = "uniform") -> Tolerances:
    """`Tolerances` around the scene's current design: nominal `design_of(scene)`, half-width
    `band` (m, a scalar or one per feature), drawn `distribution`-ly, floored at 0."""
    nominal = design_of(scene)
    return Tolerances(design_names(scene), nominal, jnp.broadcast_to(jnp.asarray(band, dtype=float), nominal.shape), distribution)


def lost_motion_weights(scene):
    """The geometric stack-up's weights (arcsec/m): the one-sided lost motion at each joint's
    output per metre of each design feature, with the sun held, from the stage's geometry alone
    (`LumpedMesh`): a backlash (sun or ring mesh) moves the output by $1/r$, a planet-pin
    clearance $c_p$ by $(\\cos\\alpha_s + \\cos\\alpha_r)/r$ (the carrier floats by that on the pin's
    loaded side), the bearings that carry the output (sun, carrier) 0; $r = i\\,r_{bs}$ the lever of
    the output rotation on the sun's base circle. What an engineer reads off the drawings; a
    simulation's sensitivities (`propose_design`'s report, `DesignReport.split`) say where the
    dynamics weigh otherwise.
    With `distinct_planets`, each planet's feature weighs $1/N$ of that: the stack-up of the
    planets' mean play (the first planet to take the load sets the lost motion, which a linear
    stack-up cannot say in advance)."""
    weights = []
    for _, feature, stage, _, planet in _fields(scene):
        lever = float(stage.ratio * stage.sun_base_radius)
        if feature.endswith("_backlash"):
            w = 1.0
        elif feature == "planet_clearance":
            w = float(jnp.cos(stage.sun_pressure_angle) + jnp.cos(stage.ring_pressure_angle))
        else:
            w = 0.0
        if planet is not None:  # one planet's share of the stack-up of the planets' mean play
            w /= stage.n_planets
        weights.append(w / lever / ARCSEC)
    return jnp.asarray(weights)
