"""SciPy's SLSQP as the independent reference of the constrained design tests (shared by
`test_optimise.py` and `test_requirements.py`)."""

import jax
import jax.numpy as jnp
import numpy as np
import scipy.optimize

from tolerax.design.types import Design

UM = 1e-6


def slsqp_reference(constraints, requirements, draws, model, size_mm):
    """SLSQP on $\\min C(b)$ s.t. `constraints(x, draws, 0)[j] <= requirements[j]` for each j, over
    three lower limits in [20, 40] um and three bands in [1, 15] um, from 30 um / 8 um, with the
    cost's and the constraints' exact gradients (jax): `(scipy result in um, margins)`, each
    margin `p -> requirements[j] - constraint j` at a point `p` in um."""
    R = np.asarray(requirements, dtype=float)
    unpack = lambda p: Design(p[:3] * UM, p[3:] * UM)  # noqa: E731
    as_numpy = lambda f: lambda p: np.asarray(f(jnp.asarray(p)))  # noqa: E731
    cost = jax.jit(lambda p: model.total(p[3:] * UM, size_mm))
    margins = [jax.jit(lambda p, j=j: R[j] - constraints(unpack(p), draws, 0.0)[j]) for j in range(R.shape[0])]
    reference = scipy.optimize.minimize(
        as_numpy(cost), np.r_[np.full(3, 30.0), np.full(3, 8.0)], jac=as_numpy(jax.jit(jax.grad(cost))), method="SLSQP",
        bounds=[(20.0, 40.0)] * 3 + [(1.0, 15.0)] * 3,
        constraints=[{"type": "ineq", "fun": as_numpy(g), "jac": as_numpy(jax.jit(jax.grad(g)))} for g in margins],
        options={"ftol": 1e-12, "maxiter": 500},
    )
    return reference, margins
