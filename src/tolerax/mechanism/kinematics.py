"""Frame propagation for Kane's equations (`Mechanism.kinematics`): each body's world pose, its
twist Jacobians and its acceleration at $\\dot u = 0$, carried down the chain base -> rigid
offsets -> each joint's planar motion in its housing."""

from typing import TYPE_CHECKING, NamedTuple

import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array

from ..physics.rigid import rz, small_matmul
from .joints import AbstractJoint

if TYPE_CHECKING:
    from .mechanism import Mechanism


class Frames(NamedTuple):
    """Kinematics of a stack of bodies (leading axis), world frame.

    Twists are affine in the speeds, $v = J_v u + \\ldots$, $\\omega = J_\\omega u + \\ldots$
    (the rest from prescribed motion), so each body carries its Jacobians and, at the actual
    state, its twist and its acceleration at $\\dot u = 0$ (velocity products and prescribed
    accelerations): exactly the terms of Kane's equations.
    """

    pos: Array  # (nb, 3) centre, m
    rot: Array  # (nb, 3, 3) body-to-world rotation
    jv: Array  # (nb, 3, n_u) d v / d u
    jw: Array  # (nb, 3, n_u) d omega / d u
    v: Array  # (nb, 3) velocity, m/s
    w: Array  # (nb, 3) angular velocity, rad/s
    a: Array  # (nb, 3) acceleration at u' = 0, m/s^2
    alpha: Array  # (nb, 3) angular acceleration at u' = 0, rad/s^2


def take(frames: Frames, index) -> Frames:
    return jax.tree.map(lambda x: x[index], frames)


def base_frame(mech: "Mechanism", q, u, columns=None) -> Frames:
    """The base: velocity in the world frame and angular velocity in the base frame are its
    speeds, so its Jacobians are constant blocks and its accelerations at $\\dot u = 0$ vanish
    ($\\tfrac{d}{dt}(R\\omega_B) = \\omega\\times\\omega = 0$). `columns` (static, or `None`:
    every speed in order): the speeds its Jacobians' columns stand for (n: none, zero)."""
    n = mech.layout.size_u
    pos, rot = mech.base_pose(q)
    jv, jw = jnp.zeros((3, n)), jnp.zeros((3, n))
    if mech.base == "free":
        jv = jv.at[:, :3].set(jnp.eye(3))
        jw = jw.at[:, 3:6].set(rot)
    zero = jnp.zeros(3)
    v, w = jv @ u, jw @ u
    if columns is not None:
        jv, jw = (jnp.concatenate([x, jnp.zeros((3, 1))], axis=1)[:, np.asarray(columns)] for x in (jv, jw))
    return Frames(pos[None], rot[None], jv[None], jw[None], v[None], w[None], zero[None], zero[None])


def offset(frame: Frames, offset, turn=None) -> Frames:
    """Frames rigidly attached to `frame` at `offset` (its axes, m), turned by the constant
    rotation `turn`: $v' = v + \\omega\\times\\rho$, $a' = a + \\alpha\\times\\rho +
    \\omega\\times(\\omega\\times\\rho)$ with $\\rho = R\\,$`offset`."""
    rho = small_matmul(frame.rot, offset)
    rot = frame.rot if turn is None else small_matmul(frame.rot, turn)
    w = frame.w
    return Frames(
        frame.pos + rho,
        rot,
        frame.jv + jnp.cross(frame.jw, rho[:, :, None], axisa=1, axisb=1, axisc=1),
        frame.jw,
        frame.v + jnp.cross(w, rho),
        w,
        frame.a + jnp.cross(frame.alpha, rho) + jnp.cross(w, jnp.cross(w, rho)),
        frame.alpha,
    )


def planar_motion(joint: AbstractJoint, qj, uj, t):
    """The joint's bodies (`planar`: gears, then its output) in its housing plane: centres $c$
    (nb, 2) and angles $\\theta$ (nb,), their Jacobians over $q_j$, rates, and accelerations at
    $\\ddot q_j = 0$ (forward-mode autodiff of `planar`: cheap, its inputs are the joint's own
    few coordinates)."""

    def planar(qj_, t_):
        centres, angles, out_c, out_a = joint.planar(qj_, t_)
        return jnp.concatenate([centres, out_c[None]]), jnp.concatenate([angles, out_a[None]])

    def rates(qj_, t_):
        return jax.jvp(planar, (qj_, t_), (uj, jnp.ones_like(t_)))

    t = jnp.asarray(t, dtype=float)
    ((c, theta), (cd, thetad)), (_, (cdd, thetadd)) = jax.jvp(rates, (qj, t), (uj, jnp.ones_like(t)))
    jc, jtheta = jax.jacfwd(planar)(qj, t)  # (nb, 2, nj), (nb, nj)
    return c, theta, jc, jtheta, cd, thetad, cdd, thetadd


def planar_frames(housing: Frames, motion, cols: slice, n: int, index=None) -> Frames:
    """The bodies of one joint (`planar_motion`) in the housing frame `housing` (one frame),
    with the joint's speeds at columns `cols` of the `n` speeds. With `index` (static, (nb, C))
    the Jacobians have C columns instead: column c of body b is the joint's coordinate
    `index[b, c]` (the joint's size: no coordinate, a zero column), and the housing's Jacobians
    stand for the same speeds column by column.

    A body at housing-plane centre $c(q_j, t)$ and angle $\\theta(q_j, t)$ has
    $\\rho = R_h c$, $\\omega = \\omega_h + \\dot\\theta R_h e_z$,
    $v = v_h + \\omega_h\\times\\rho + R_h\\dot c$,
    $\\dot\\omega = \\alpha_h + \\dot\\theta\\,\\omega_h\\times R_he_z + \\ddot\\theta R_he_z$ and
    $a = a_h + \\alpha_h\\times\\rho + \\omega_h\\times(\\omega_h\\times\\rho) + 2\\omega_h\\times R_h\\dot c + R_h\\ddot c$.
    """
    c, theta, jc, jtheta, cd, thetad, cdd, thetadd = motion
    nb = c.shape[0]
    r_h = housing.rot[0]
    plane, axis = r_h[:, :2], r_h[:, 2]
    rho = small_matmul(c, plane.T)
    rho_dot = small_matmul(cd, plane.T)  # R_h c'
    w_h, alpha_h = housing.w[0], housing.alpha[0]
    if index is None:
        jw_own = jnp.zeros((nb, 3, n)).at[:, :, cols].set(axis[None, :, None] * jtheta[:, None, :])
        jv_own = jnp.zeros((nb, 3, n)).at[:, :, cols].set(jnp.einsum("ik,bkn->bin", plane, jc))
    else:
        index = np.asarray(index)
        jc = jnp.take_along_axis(jnp.concatenate([jc, jnp.zeros((nb, 2, 1))], axis=2), index[:, None, :], axis=2)
        jtheta = jnp.take_along_axis(jnp.concatenate([jtheta, jnp.zeros((nb, 1))], axis=1), index, axis=1)
        jw_own = axis[None, :, None] * jtheta[:, None, :]
        jv_own = jnp.einsum("ik,bkn->bin", plane, jc)
    jw = housing.jw + jw_own
    jv = housing.jv + jnp.cross(housing.jw, rho[:, :, None], axisa=1, axisb=1, axisc=1) + jv_own
    w = w_h + thetad[:, None] * axis
    v = housing.v + jnp.cross(w_h, rho) + rho_dot
    alpha = alpha_h + thetad[:, None] * jnp.cross(w_h, axis) + thetadd[:, None] * axis
    a = (
        housing.a
        + jnp.cross(alpha_h, rho)
        + jnp.cross(w_h, jnp.cross(w_h, rho))
        + 2.0 * jnp.cross(w_h, rho_dot)
        + small_matmul(cdd, plane.T)
    )
    return Frames(housing.pos + rho, r_h @ rz(theta), jv, jw, v, w, a, alpha)
