"""Linearisation of a planetary stage: tangent stiffness and undamped natural frequencies
(checked against Lin & Parker's 1999 example in the tests)."""

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array
from .planetary import AddedInertia, mass_matrix, stage_forces
from .stage import PlanetaryStage

class Modes(eqx.Module):
    """Undamped natural frequencies (Hz, ascending) and mass-normalised mode shapes (columns),
    with the coordinate names of the rows."""

    frequencies: Array
    shapes: Array
    names: tuple[str, ...] = eqx.field(static=True)


def stiffness_matrix(stage: PlanetaryStage, q: Array) -> Array:
    """Tangent stiffness $K = -\\partial Q/\\partial q$ at rest ($\\dot q = 0$), N/m-type units."""
    n_contacts = len(stage.contact_names)
    rates = jnp.full((n_contacts,), 1.0)

    def force(q_):
        return stage_forces(stage, q_, jnp.zeros_like(q_), rates).generalised

    return -jax.jacfwd(force)(q)


def natural_frequencies(
    stage: PlanetaryStage, q: Array | None = None, added: AddedInertia = AddedInertia()
) -> Modes:
    """Linearise about the operating point `q` (default: nominal, all coordinates 0) and solve
    $K\\phi = \\omega^2 M\\phi$. Damping and gyroscopic terms are left out (undamped modes of the
    Lin–Parker model at zero carrier speed). A clearance support contributes its tangent contact
    stiffness at `q` (none if the clearance is open there: close it via `q` or use `"spring"`).
    """
    lay = stage.layout
    if q is None:
        q = jnp.zeros(lay.size)
    m = mass_matrix(stage, q, added)
    k = stiffness_matrix(stage, q)
    k = 0.5 * (k + k.T)
    l_inv = jnp.linalg.inv(jnp.linalg.cholesky(m))
    lam, vec = jnp.linalg.eigh(l_inv @ k @ l_inv.T)
    freqs = jnp.sqrt(jnp.clip(lam, 0.0, None)) / (2.0 * jnp.pi)
    return Modes(frequencies=freqs, shapes=l_inv.T @ vec, names=lay.names)
