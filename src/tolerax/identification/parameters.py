"""What `identify` can estimate: a scene's design features (clearances and backlash, m:
`tolerax.design.features`) and, beside them, named physical parameters of its modelled joints
that a test recording sees as well as the clearances: the output's drag (friction, N m), each
mesh family's mean stiffness (N/m) and damping ratio. Named `"joint.parameter"` as the features
are (`azimuth.drag_torque`, `azimuth.sun_mesh_stiffness`). A joint that models no clearance (an
ideal joint) has none: its parameters do not reach its output.

`parameter_names(scene)` lists them (the features first), `parameter_units` gives each one's SI
unit, `parameter_values(scene, names)` reads them and `with_parameters(scene, names, values)`
writes them back (traceable: `values` may be a tracer under `jacfwd`). Of the physical
parameters, a scene file holds the drag (its `drag_torque`, one for both joints: written where
one joint's drag acts, `Identification.scene_file`) and each joint's mesh families' stiffness
and damping (its stage table's `sun_mesh_stiffness`, ..., `default_stage`'s keys of the same
names).
"""

import difflib

import equinox as eqx
import jax.numpy as jnp

from ..design.features import design_names, design_of, with_design

# parameter -> (SI unit, where it lives given the scene and the joint's name)
PHYSICAL = {
    "drag_torque": ("N m", lambda scene, joint: getattr(scene, joint).drag_torque),
    "sun_mesh_stiffness": ("N/m", lambda scene, joint: getattr(scene, joint).stage.sun_mesh.stiffness),
    "ring_mesh_stiffness": ("N/m", lambda scene, joint: getattr(scene, joint).stage.ring_mesh.stiffness),
    "sun_mesh_damping_ratio": ("1", lambda scene, joint: getattr(scene, joint).stage.sun_mesh.damping_ratio),
    "ring_mesh_damping_ratio": ("1", lambda scene, joint: getattr(scene, joint).stage.ring_mesh.damping_ratio),
}
# Those a scene file's stage table holds, under the same names (`default_stage`'s keywords).
MESH_KEYS = tuple(name for name in PHYSICAL if name != "drag_torque")


def _physical(scene) -> dict:
    """`{name: (unit, get)}` of the physical parameters of the scene's modelled joints."""
    out = {}
    for joint, _, features in scene.named_stages():
        if not joint or not features or not hasattr(getattr(scene, joint, None), "drag_torque"):
            continue  # a bench's single stage, an ideal joint: no joint whose parameters reach the output
        for name, (unit, where) in PHYSICAL.items():
            out[f"{joint}.{name}"] = (unit, lambda x, j=joint, w=where: w(x, j))
    return out


def parameter_names(scene) -> tuple[str, ...]:
    """The names `identify` accepts for `scene`: its design features, then the physical ones."""
    return design_names(scene) + tuple(_physical(scene))


def parameter_units(scene, names) -> tuple[str, ...]:
    """Each parameter's SI unit: "m" for a feature, else `PHYSICAL`'s."""
    physical = _physical(scene)
    return tuple(physical[n][0] if n in physical else "m" for n in names)


def check_names(scene, names, what: str = "identify") -> tuple[str, ...]:
    """`names` as a tuple, refused (`ValueError`, naming the ones that exist) if any is unknown."""
    known = parameter_names(scene)
    names = known[: len(design_names(scene))] if names is None else tuple(names)
    unknown = [p for p in names if p not in known]
    if unknown or not names:
        near = [f"{p!r}: did you mean {m[0]!r}?" for p in unknown for m in [difflib.get_close_matches(p, known, n=1, cutoff=0.85)] if m]
        raise ValueError(f"{what}: {unknown or 'no parameters'} are not parameters of the scene" + (f" ({'; '.join(near)})" if near else "")
                         + "; its design features: "
                         f"{', '.join(design_names(scene))}; its physical parameters: {', '.join(_physical(scene)) or 'none'}.")
    if len(set(names)) != len(names):
        raise ValueError(f"{what}: a parameter is named twice in {list(names)}.")
    return names


def parameter_values(scene, names) -> jnp.ndarray:
    """The scene's values of `names` (SI units)."""
    features, physical = design_names(scene), _physical(scene)
    design = design_of(scene)
    return jnp.stack([design[features.index(n)] if n in features else jnp.asarray(physical[n][1](scene), dtype=float)
                      for n in names])


def with_parameters(scene, names, values):
    """`scene` with `names` set to `values` (SI units; traceable)."""
    features, physical = design_names(scene), _physical(scene)
    index = [k for k, n in enumerate(names) if n in features]
    if index:
        design = design_of(scene).at[jnp.asarray([features.index(names[k]) for k in index])].set(
            jnp.stack([values[k] for k in index]))
        scene = with_design(scene, design)
    for k, n in enumerate(names):
        if n not in features:
            scene = eqx.tree_at(physical[n][1], scene, jnp.asarray(values[k], dtype=float))
    return scene
