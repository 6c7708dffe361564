"""An additive split of the mechanism's vector field for IMEX methods (benchmarks only).

`internal_field(mech)(t, y, args)` is $f_I$: the joints' internal forces (meshes, supports,
clearance contacts: each joint's `forces` less its `drive_forces`) through the true mass matrix,
with the joint coordinates' kinematics, $f_I = (\\dot q_j = u_j;\\ \\dot u = M(q)^{-1}[0;
Q_{int}];\\ \\dot v = 0)$; `external_field(mech)` is $f_E = f - f_I$ (servo, drag, velocity terms,
the base's kinematics, the impact-rate states). Their sum is `Mechanism.vector_field`.
"""

import jax
import jax.numpy as jnp


def internal_field(mech):
    lay = mech.layout

    def f_imp(t, y, args):
        q, u, v = y
        mass, _ = mech.dynamics(q, u, t)
        # Both joints in one batch where they are twins, as `Mechanism.joint_forces` does.
        internal = mech.each_joint(
            lambda joint, qj, uj, vj: joint.forces(qj, uj, vj, t)[0] - joint.drive_forces(qj, uj, t), ("q", q), ("u", u), ("v", v)
        )
        ud = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(mass), jnp.concatenate([jnp.zeros(lay.base_u), *internal]))
        qd = jnp.zeros_like(q).at[lay.base_q:].set(u[lay.base_u:])  # joint coordinates: q_j and u_j coincide
        return qd, ud, jnp.zeros_like(v)

    return f_imp


def external_field(mech):
    f_imp = internal_field(mech)

    def f_exp(t, y, args):
        return jax.tree.map(lambda a, b: a - b, mech.vector_field(t, y, args), f_imp(t, y, args))

    return f_exp
