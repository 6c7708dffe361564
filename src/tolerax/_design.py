"""The tolerance design vector of a stage: its clearances and backlash as one array."""

import equinox as eqx
import jax.numpy as jnp

NAMES = ("sun clearance", "carrier clearance", "planet clearance", "sun backlash", "ring backlash")


def with_design(bench, p):
    """`bench` (anything with a `.stage`) with its stage's clearances and backlash set from `p`
    (m), in `NAMES` order (all planets alike). Traceable: `p` may be a tracer (grad, vmap).
    Values set this way bypass the constructors' checks; `simulate`/`simulate_bench` check
    concrete values again before running."""
    stage = bench.stage
    n = stage.n_planets
    stage = eqx.tree_at(
        lambda s: (
            s.sun_support.bearing.clearance,
            s.carrier_support.bearing.clearance,
            s.planet_support.bearing.clearance,
            s.sun_mesh.backlash,
            s.ring_mesh.backlash,
        ),
        stage,
        (
            p[0],
            p[1],
            jnp.broadcast_to(p[2], jnp.shape(stage.planet_support.bearing.clearance)),
            p[3] * jnp.ones(n),
            p[4] * jnp.ones(n),
        ),
    )
    return eqx.tree_at(lambda b: b.stage, bench, stage)
