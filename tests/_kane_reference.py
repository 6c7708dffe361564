"""The reference formulation of `Mechanism.dynamics` for equivalence tests: body Jacobians by
`jacfwd` of the mechanism's twists, accelerations by a `jvp`. Independent of the hand-propagated
Jacobians in `tolerax.mechanism`."""

import jax
import jax.numpy as jnp

from tolerax import AbstractScene, Mechanism
from tolerax.physics.rigid import world_inertia


def kane_by_autodiff(mech: Mechanism, q, u, t):
    """The reference formulation of `Mechanism.dynamics` (kept for equivalence tests and
    benchmarks): body Jacobians by `jacfwd` of `twists` over all speeds, accelerations at
    $\\dot u = 0$ by a `jvp` of `twists` over $(q, t)$."""
    masses, principal = mech.body_inertia()
    _, rot = mech.poses(q, t)
    inertia = world_inertia(rot, principal)
    jac_v, jac_w = jax.jacfwd(lambda u_: mech.twists(q, u_, t))(u)
    (v, w), (a0, alpha0) = jax.jvp(
        lambda q_, t_: mech.twists(q_, u, t_), (q, t), (mech.qdot(q, u), jnp.ones_like(t))
    )
    mass = jnp.einsum("b,bin,bim->nm", masses, jac_v, jac_v) + jnp.einsum("bin,bij,bjm->nm", jac_w, inertia, jac_w)
    iw = jnp.einsum("bij,bj->bi", inertia, w)
    rot_term = jnp.einsum("bij,bj->bi", inertia, alpha0) + jnp.cross(w, iw)
    bias = jnp.einsum("b,bin,bi->n", masses, jac_v, a0) + jnp.einsum("bin,bi->n", jac_w, rot_term)
    return mech._with_added_inertia(mass), bias


def vector_field_by_autodiff(mech: Mechanism, t, y):
    """`Mechanism.vector_field` in the reference formulation (`kane_by_autodiff`, LU solve, one
    joint after the other)."""
    q, u, v = y
    lay = mech.layout
    mass, bias = kane_by_autodiff(mech, q, u, t)
    (qa, _), (qp, _) = [joint.forces(q[sq], u[su], v[sv], t) for joint, sq, su, sv in mech.joints()]
    ud = jnp.linalg.solve(mass, jnp.concatenate([jnp.zeros(lay.base_u), qa, qp]) - bias)
    vd = [joint.impact_rate_rates(q[sq], u[su], ud[su], v[sv]) for joint, sq, su, sv in mech.joints()]
    return mech.qdot(q, u), ud, jnp.concatenate(vd)


class KaneByAutodiff(AbstractScene):
    """A mechanism whose equations of motion are the reference formulation
    (`vector_field_by_autodiff`); everything else is the mechanism's. For equivalence tests and
    the before/after benchmark."""

    mechanism: Mechanism
    _what = "mechanism"

    def initial_state(self, start="rest"):
        return self.mechanism.initial_state(start)

    def vector_field(self, t, y, args):
        return vector_field_by_autodiff(self.mechanism, t, y)

    def observe(self, t, y):
        return self.mechanism.observe(t, y)

    def result(self, sol, observed, duration):
        return self.mechanism.result(sol, observed, duration)

    def check_runnable(self):
        self.mechanism.check_runnable()


def momentum_rates(mech: Mechanism, q, u, ud, t):
    """Each body's rate of change of linear momentum $m a$ (nb, 3) and of angular momentum about
    the world origin $p \\times m a + I\\alpha + \\omega \\times I\\omega$ (nb, 3) when the speeds
    change at `ud`: the accelerations by a `jvp` of `twists` over $(q, u, t)$ along
    $(\\dot q, \\dot u, 1)$, independent of the frames that `Mechanism.dynamics` propagates."""
    masses, principal = mech.body_inertia()
    pos, rot = mech.poses(q, t)
    inertia = world_inertia(rot, principal)
    (_, w), (a, alpha) = jax.jvp(lambda q_, u_, t_: mech.twists(q_, u_, t_), (q, u, t), (mech.qdot(q, u), ud, jnp.ones_like(t)))
    lin = masses[:, None] * a
    ang = jnp.cross(pos, lin) + jnp.einsum("bij,bj->bi", inertia, alpha) + jnp.cross(w, jnp.einsum("bij,bj->bi", inertia, w))
    return lin, ang


def spring_ring_stage(**options):
    """`tx.default_stage(**options)` with its ring on springs (radial and torsional, 1e8 N/m):
    the ring a moving body of its own, which `tx.default_stage` does not offer."""
    import equinox as eqx
    import jax.numpy as jnp
    import tolerax as tx
    from tolerax.physics.stage import Support

    return eqx.tree_at(
        lambda s: (s.ring_support, s.ring_torsion), tx.default_stage(**options), (Support("spring", 1e8), jnp.asarray(1e8)),
        is_leaf=lambda x: x is None,
    )


def twisted_scan_state(layout, ratio, key):
    """A random state of a one-axis scan whose azimuth stage turns as a rigid reduction up to a
    twist: output angle anywhere in [-3, 3] rad, motor at `ratio` times it plus up to 1 mrad of
    twist, speeds standard normal, no auxiliary states (test_joint.py, test_extending.py)."""
    kq, ku, kt = jax.random.split(key, 3)
    theta_c = jax.random.uniform(kt, minval=-3.0, maxval=3.0)
    twist = 1e-3 * jax.random.uniform(kq, (), minval=-1.0, maxval=1.0)
    q = jnp.zeros(layout.size_q).at[layout.azimuth_q].set(jnp.stack([ratio * (theta_c + twist), theta_c]))
    return q, jax.random.normal(ku, (layout.size_u,)), jnp.zeros(layout.size_v)
