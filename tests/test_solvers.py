"""The one design loop (`tolerax.design.loop.solve_design`) runs any solver: a new one is one
class. Here a projected Adam on a quadratic penalty, written with optax in a few lines, against
the closed-form optimum of a linear stack-up and against the built-in sequential solver on the
same problem through the same loop."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import optax
import pytest
import scipy.optimize

from tolerax.design.cost import ReciprocalPower
from tolerax.design.loop import AbstractDesignSolver, ConstrainedDesign, make_result, solve_design
from tolerax.design.sequential import SequentialSolver
from tolerax.design.types import Design, Features

UM = 1e-6
A, W, V = np.array([1.0, 2.0, 0.5]), np.array([1.0, 3.0, 2.0]), np.array([0.5, 0.0, 1.5])
FEATURES = Features(["a", "b", "c"], [12.0, 80.0, 20.0])
LOWER, UPPER = Design(jnp.full(3, 5 * UM), jnp.full(3, 1 * UM)), Design(jnp.full(3, 40 * UM), jnp.full(3, 50 * UM))


def _stack(x, draws, width):
    """A linear stack-up (arcsec): lower limits and bands both open the lost motion."""
    return (jnp.dot(W, x.nominal + x.band) + jnp.dot(V, x.band)) / UM


PROBLEM = ConstrainedDesign(_stack, FEATURES, 60.0, 0.01, LOWER, UPPER, ReciprocalPower(scale=A, reference_band=1.0, floor=1e-15))


def _closed_form():
    """Lower limits at their minimum (free of cost); bands from a_i / b_i^2 = lambda d_i, lambda
    from the budget (brentq)."""
    d, fixed = W + V, np.sum(W) * 5.0

    def bands(lam):
        return np.clip(np.sqrt(A / (lam * d / UM)), 1 * UM, 50 * UM)

    lam = scipy.optimize.brentq(lambda lam: fixed + np.dot(d, bands(lam)) / UM - 60.0, 1e-6, 1e12, xtol=1e-14, rtol=1e-14)
    return bands(lam), float(np.sum(A / bands(lam)))


class PenaltyAdam(AbstractDesignSolver):
    """A new solver in one class: `inner` steps of optax's Adam per step on the cost plus a
    quadratic penalty on the constraints' excess, in box coordinates, projected onto the box."""

    learning_rate: float = 0.01
    penalty: float = 1e4
    inner: int = 500

    def init(self, problem, x0):
        lo, span = jax.tree.map(jnp.asarray, problem.lower), jax.tree.map(lambda a, b: b - a, problem.lower, problem.upper)
        to_x = lambda z: jax.tree.map(lambda l_, s, zz: l_ + s * zz, lo, span, z)  # noqa: E731
        z = jax.tree.map(lambda x, l_, s: (x - l_) / s, x0, lo, span)
        c0 = problem.cost_model.total(x0.band, problem.features.size_mm)

        def loss(z):
            x = to_x(z)
            excess = jnp.maximum(jnp.atleast_1d(problem.objective(x, problem.draws, problem.width)) / problem.requirements - 1, 0)
            return problem.cost_model.total(x.band, problem.features.size_mm) / c0 + self.penalty * jnp.sum(excess**2)

        optimiser = optax.adam(self.learning_rate)

        def adam_step(_, carry):
            z, state = carry
            updates, state = optimiser.update(jax.grad(loss)(z), state, z)
            z = optax.apply_updates(z, updates)
            return optax.projections.projection_box(z, jax.tree.map(jnp.zeros_like, z), jax.tree.map(jnp.ones_like, z)), state

        # The `inner` steps in one compiled loop (not `inner` Python calls of eager optax updates).
        inner = jax.jit(lambda z, state: jax.lax.fori_loop(0, self.inner, adam_step, (z, state)))
        return dict(z=z, state=optimiser.init(z), to_x=to_x, inner=inner, rows=[])

    def step(self, problem, s):
        s["z"], s["state"] = s["inner"](s["z"], s["state"])
        x = s["to_x"](s["z"])
        f = float(problem.objective(x, problem.draws, problem.width))
        s["rows"].append((float(problem.cost_model.total(x.band, problem.features.size_mm)), f, f - 60.0, 0.0, self.penalty, 0.0,
                          len(s["rows"]) + 1))
        return s

    def terminate(self, problem, s):
        return len(s["rows"]) >= 2 and abs(s["rows"][-1][0] - s["rows"][-2][0]) <= 1e-4 * s["rows"][-1][0]

    def last(self, problem, s):
        return s["to_x"](s["z"]), s["rows"][-1][0], s["rows"][-1][1], len(s["rows"])

    def postprocess(self, problem, s):
        x = s["to_x"](s["z"])
        f, g = jax.value_and_grad(lambda x_: problem.objective(x_, problem.draws, problem.width))(x)
        return make_result(problem, x, f, g, 0.0, converged=self.terminate(problem, s), iteration=len(s["rows"]) - 1, rows=s["rows"])


def test_a_new_solver_is_one_class_run_by_the_same_loop():
    bands, cost = _closed_form()
    x0 = Design(jnp.full(3, 30 * UM), jnp.full(3, 10 * UM))
    adam = solve_design(PROBLEM, PenaltyAdam(), x0, max_steps=40)
    sequential = solve_design(PROBLEM, SequentialSolver(trust_region=1.0), x0, max_steps=10)
    # The sequential solver: exact on a linear stack-up.
    assert bool(sequential.converged) and float(sequential.cost) == pytest.approx(cost, rel=1e-8)
    np.testing.assert_allclose(sequential.x.band, bands, rtol=1e-8)
    # The penalty method sits just outside the constraint, by about cost / (2 penalty x lambda R):
    # within 0.5 % of the optimum's cost and 1 % of its bands here.
    assert bool(adam.converged)
    assert float(adam.cost) == pytest.approx(cost, rel=5e-3) and float(adam.objective[0]) == pytest.approx(60.0, rel=5e-3)
    np.testing.assert_allclose(adam.x.band, bands, rtol=1e-2)
    np.testing.assert_allclose(adam.x.nominal, 5 * UM, rtol=1e-6)


def test_the_loop_calls_back_and_refuses_a_bad_problem():
    seen = []
    x0 = Design(jnp.full(3, 30 * UM), jnp.full(3, 10 * UM))
    solve_design(PROBLEM, SequentialSolver(trust_region=1.0), x0, max_steps=10, callback=lambda *a: seen.append(a))
    assert [s[0] for s in seen] == list(range(1, len(seen) + 1)) and seen[0][3] == pytest.approx(float(_stack(x0, None, None)))
    with pytest.raises(ValueError, match="requirements > 0"):
        dataclasses.replace(PROBLEM, requirements=-1.0)
    with pytest.raises(ValueError, match="tol must be in"):
        dataclasses.replace(PROBLEM, tol=(0.01, 0.01))
    with pytest.raises(ValueError, match="max_steps"):
        solve_design(PROBLEM, SequentialSolver(), x0, max_steps=-1)
    # No step (what `propose_design` reports where the tightest designs miss the requirement):
    # the start, evaluated, is the result and its history's one row; the callback sees it once.
    seen.clear()
    start = solve_design(PROBLEM, SequentialSolver(), x0, max_steps=0, callback=lambda *a: seen.append(a))
    np.testing.assert_array_equal(np.asarray(start.x.band), np.asarray(x0.band))
    assert float(start.objective[0]) == pytest.approx(float(_stack(x0, None, None)), rel=1e-12)
    assert len(np.asarray(start.history.cost)) == 1 and int(start.history.steps[-1]) == 1 and len(seen) == 1
    assert not bool(start.converged)
