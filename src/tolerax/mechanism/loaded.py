"""The loaded steady state of a mechanism (`Mechanism.loaded_state`): the joint coordinates at
which the joints, turning at their steady speeds, are in equilibrium, by Levenberg-Marquardt
(`optimistix`) from each joint's closed form.
"""

import equinox as eqx
import jax.numpy as jnp
import optimistix as optx

from .. import _validate as V
from .._linearise import jacobian_once
from .drives import SpeedServo


def loaded_state(mech, q, u, max_steps: int = 200):
    """`Mechanism.loaded_state` (its docstring): the coordinates `q` with the joint part solved."""
    lay = mech.layout
    for name, joint in (("azimuth", mech.azimuth), ("pitch", mech.pitch)):
        if joint.layout.size == 0:
            continue  # prescribed (an ideal joint following its servo)
        if not isinstance(joint.drive, SpeedServo):
            raise ValueError(
                f"start='loaded' needs constant-rate servos; the {name} joint's drive is a "
                f"{type(joint.drive).__name__}, whose load changes with time. Use start='steady'."
            )
        if not V.is_traced(joint.drive.integral) and float(joint.drive.integral) <= 0.0:
            raise ValueError(
                f"start='loaded' needs a servo with an integral (angle) gain > 0 to hold the load; "
                f"the {name} joint's SpeedServo has integral={float(joint.drive.integral)!r}. Use start='steady'."
            )
    guess = q
    for joint, sq, _, _ in mech.joints():
        guess = guess.at[sq].set(joint.loaded_coordinates())
    steady_norm, x, norm = _polish_loaded(mech, q, u, guess[lay.base_q :], max_steps)
    if not V.is_traced(norm) and not float(norm) <= 1e-2 * float(steady_norm):
        raise ValueError(
            f"The loaded steady state was not found: the equilibrium residual is {float(norm):.3g} "
            f"against {float(steady_norm):.3g} at start='steady' (Levenberg-Marquardt, {max_steps} "
            "steps). Use start='steady' (and a longer settle), or raise max_steps."
        )
    return q.at[lay.base_q :].set(x)


def _loaded_residual(mech, q, u, x):
    """$\\sqrt{M_{kk}}\\,\\dot u_k$ over the joint speeds at joint coordinates `x` (base as in `q`)."""
    lay = mech.layout
    qx = q.at[lay.base_q :].set(x)
    ud, _, mass = mech._accelerations_and_mass(0.0, qx, u, mech.initial_impact_rates(qx, u))
    return (jnp.sqrt(jnp.diag(mass)) * ud)[lay.base_u :]


LOADED_ANCHOR = 1.0  # sqrt(kg)/s^2: weight of (x - x0) beside the residual (see `Mechanism.loaded_state`)


def _loaded_equations(x, mech, q, u, x0):
    """What Levenberg-Marquardt zeroes in the least-squares sense: the residual and the anchor."""
    return jnp.concatenate([_loaded_residual(mech, q, u, x), LOADED_ANCHOR * (x - x0)])


# Levenberg-Marquardt's linearisation is the Jacobian of one forward-mode pass (`jacobian_once`):
# no reverse-mode program of the accelerations for its transpose (the compile times of both:
# benchmarks/loaded_state_compile.py).
_loaded_equations_once = jacobian_once(_loaded_equations)


@eqx.filter_jit
def _polish_loaded(mech, q, u, x0, max_steps: int):
    """Levenberg-Marquardt from `x0`; returns (residual norm at `"steady"`, solution, its norm)."""
    lay = mech.layout
    fn = lambda x, _: _loaded_equations_once(x, mech, q, u, x0)  # noqa: E731
    solver = optx.LevenbergMarquardt(rtol=1e-12, atol=1e-14)
    sol = optx.least_squares(fn, solver, x0, max_steps=max_steps, throw=False)
    residual = lambda x: _loaded_residual(mech, q, u, x)  # noqa: E731
    return jnp.linalg.norm(residual(q[lay.base_q :])), sol.value, jnp.linalg.norm(residual(sol.value))
