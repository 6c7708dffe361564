"""Rigid-body helpers: rotation matrices, the vee map, world inertia, planar-to-world poses."""

import jax.numpy as jnp
import numpy as np

# Fixed orientation of the pitch joint's housing in link 1 (structure, not a parameter): the
# housing's z axis (the joint axis) along link 1's x axis.
PITCH_HOUSING = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def small_matmul(a, b):
    """`a @ b` for small operands (rotations, offsets: a few dozen products) as a sum of products
    over the contracted axis, batch axes broadcast as `@` does; `b` may be a vector. XLA:CPU
    runs every dot as a library call of its own, a kernel with its own overhead that nothing
    fuses into, while a sum of products fuses with the elementwise work beside it, so the
    frames' rotations are written this way. For products of a few hundred terms
    and more keep `@`: a fused sum recomputes its operands per output element."""
    a, b = jnp.asarray(a), jnp.asarray(b)
    if b.ndim == 1:
        return jnp.sum(a * b, axis=-1)
    return jnp.sum(a[..., :, :, None] * b[..., None, :, :], axis=-2)


def small_einsum(subscripts: str, *operands):
    """`jnp.einsum(subscripts, *operands)` for small operands as one broadcast product summed
    over the contracted indices (explicit `->` form only, no repeated index within an operand).
    The same reason as `small_matmul`: XLA:CPU runs a contraction as a library call of its own,
    and a *batched* one (`"bkn,bkm->bnm"`) as one call per batch entry, each costing more than
    its few dozen products; the sum fuses with its neighbours. Use it where the broadcast
    product is small (a few thousand terms)."""
    inputs, output = subscripts.replace(" ", "").split("->")
    inputs = inputs.split(",")
    letters = list(dict.fromkeys("".join(inputs)))
    product = None
    for names, x in zip(inputs, operands, strict=True):
        x = jnp.asarray(x)
        if len(set(names)) != len(names) or x.ndim != len(names):
            raise ValueError(f"small_einsum: operand subscripts {names!r} do not fit an operand of shape {x.shape}")
        present = [c for c in letters if c in names]
        x = jnp.transpose(x, [names.index(c) for c in present])
        x = x.reshape([x.shape[present.index(c)] if c in names else 1 for c in letters])
        product = x if product is None else product * x
    total = jnp.sum(product, axis=tuple(i for i, c in enumerate(letters) if c not in output))
    kept = [c for c in letters if c in output]
    return jnp.transpose(total, [kept.index(c) for c in output])


def rot2(angle):
    """Planar rotation matrix (2, 2) of `angle` (rad)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    return jnp.array([[c, -s], [s, c]])


def rz(angle):
    """Rotation about $z$ by `angle` (rad), (..., 3, 3) for an angle of shape (...)."""
    c, s = jnp.cos(angle), jnp.sin(angle)
    zero, one = jnp.zeros_like(c), jnp.ones_like(c)
    return jnp.stack(
        [jnp.stack([c, -s, zero], -1), jnp.stack([s, c, zero], -1), jnp.stack([zero, zero, one], -1)], -2
    )


def quat_matrix(quat):
    """Rotation matrix of a quaternion $(w, x, y, z)$ (normalised here, so drift in its norm
    never distorts a pose)."""
    w, x, y, z = quat / jnp.sqrt(jnp.sum(quat**2))
    return jnp.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
            [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
            [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
        ]
    )


def quat_rate(quat, omega_body):
    """$\\dot q = \\tfrac12 q\\otimes(0, \\omega_B)$ for body-frame angular velocity (rad/s)."""
    w, x, y, z = quat
    wx, wy, wz = omega_body
    return 0.5 * jnp.stack(
        [-x * wx - y * wy - z * wz, w * wx + y * wz - z * wy, w * wy + z * wx - x * wz, w * wz + x * wy - y * wx]
    )


def vee(w):
    """Vector of the skew part of `w` (..., 3, 3)."""
    return 0.5 * jnp.stack(
        [w[..., 2, 1] - w[..., 1, 2], w[..., 0, 2] - w[..., 2, 0], w[..., 1, 0] - w[..., 0, 1]], -1
    )


def world_inertia(rot, principal):
    """$R\\,\\mathrm{diag}(I)R^T$ per body (nb, 3, 3) from rotations (nb, 3, 3) and principal
    inertias (nb, 3), kg m²."""
    return jnp.einsum("bij,bj,bkj->bik", rot, principal, rot)


def planar_to_world(p_h, r_h, centres, angles):
    """World positions (nb, 3) and rotations (nb, 3, 3) of bodies given in a housing's plane
    (centres (nb, 2), m; angles (nb,), rad) whose frame is at `p_h` with rotation `r_h`."""
    pos = p_h + jnp.concatenate([centres, jnp.zeros((centres.shape[0], 1))], axis=1) @ r_h.T
    return pos, r_h @ rz(angles)
