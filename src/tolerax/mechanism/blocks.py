"""The block solve of Kane's equations (`Mechanism.accelerations`): the speeds split into shared
ones and each body's own, $M\\dot u = f$ solved by eliminating every body's own speeds first
(small symmetric positive definite blocks), then the Schur complement over the shared ones.
"""

import collections
from typing import NamedTuple

import jax
import jax.numpy as jnp
import numpy as np

from ..physics.rigid import small_einsum


class KaneBlocks(NamedTuple):
    """Static index arrays of the block solve (`Mechanism.kane_blocks`)."""

    shared: np.ndarray  # (ns,) speeds solved from the Schur complement
    bodies: np.ndarray  # (nk,) bodies whose own speeds are eliminated first
    own: np.ndarray  # (nk, width) each such body's own speeds, padded with n (no speed)
    position: np.ndarray  # (n,) each speed's place in [shared, own.ravel()]
    columns: np.ndarray  # (nb, ns + width) the speeds of each body's Jacobian columns: shared, own (n: none)


def _small_spd_solve(a, b):
    """$a^{-1}b$ for a stack of small symmetric positive definite matrices `a` (..., k, k) and
    right-hand sides `b` (..., k, m): Cholesky unrolled over the few `k` (one body's own speeds)
    in elementwise operations, which fuse into a handful of kernels (a batched LAPACK call
    costs more than its arithmetic at these sizes). Above 6 (a joint whose bodies have many own
    coordinates) the unrolled program would grow as k^3: LAPACK's then."""
    k = a.shape[-1]
    if k > 6:
        return jax.vmap(lambda a_, b_: jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(a_), b_))(a, b)
    low = [[None] * k for _ in range(k)]
    for j in range(k):
        low[j][j] = jnp.sqrt(a[..., j, j] - sum(low[j][p] ** 2 for p in range(j)))
        for i in range(j + 1, k):
            low[i][j] = (a[..., i, j] - sum(low[i][p] * low[j][p] for p in range(j))) / low[j][j]
    y = []
    for i in range(k):
        y.append((b[..., i, :] - sum(low[i][p][..., None] * y[p] for p in range(i))) / low[i][i][..., None])
    x = [None] * k
    for i in reversed(range(k)):
        x[i] = (y[i] - sum(low[p][i][..., None] * x[p] for p in range(i + 1, k))) / low[i][i][..., None]
    return jnp.stack(x, axis=-2)


def partition(columns, n: int) -> "KaneBlocks | None":
    """The static partition of `n` speeds given each body's `columns` (the speeds its twist depends
    on, `Mechanism.body_columns`): a speed that one body alone uses is that body's own; `None`
    where no speed is any body's own (nothing to eliminate)."""
    uses = collections.Counter(c for cols in columns for c in cols)
    own = [tuple(c for c in cols if uses[c] == 1) for cols in columns]
    bodies = [b for b, cols in enumerate(own) if cols]
    if not bodies:
        return None
    width = max(len(own[b]) for b in bodies)
    shared = [c for c in range(n) if not any(c in cols for cols in own)]
    # Own speeds per body, padded to one width with index n (a column of zeros).
    padded = np.array([own[b] + (n,) * (width - len(own[b])) for b in bodies], dtype=int)
    order = np.concatenate([shared, padded.ravel()])
    position = np.zeros(n, dtype=int)
    position[order[order < n]] = np.flatnonzero(order < n)
    slots = np.full((len(columns), width), n)
    slots[bodies] = padded
    by_body = np.concatenate([np.broadcast_to(np.array(shared, dtype=int), (len(columns), len(shared))), slots], axis=1)
    return KaneBlocks(np.array(shared, dtype=int), np.array(bodies, dtype=int), padded, position, by_body)


def block_solve(blocks: KaneBlocks, jac, weights, g, force):
    """$\\dot u$ from $M\\dot u = Q - b$ by blocks: `jac` (nb, 6, C), `weights` (nb, 6) and `g`
    (nb, 6) the bodies' twist Jacobians in the blocks' columns (`blocks.columns`: the shared speeds,
    then each body's own), weights and inertial terms (`Mechanism._kane_terms`); `force` $Q$ (n,).

    With the speeds split into shared ones $s$ and each eliminated body's own $o_k$ (its
    Jacobian's only nonzero entries in those columns are its own rows), $M_{oo}$ is block
    diagonal, so $X_k = M_{o_ko_k}^{-1}[M_{o_ks}\\;f_{o_k}]$ body by body, the Schur
    complement $S = M_{ss} - \\sum_k M_{so_k}X_k$ gives $\\dot u_s$, and
    $\\dot u_{o_k} = M_{o_ko_k}^{-1}f_{o_k} - X_k\\dot u_s$. Cholesky elimination in another
    order: as stable as the whole factorisation (M is symmetric positive definite) and equal
    to it to rounding (the Kane tests compare it with an LU solve of the whole $M$)."""
    # The Jacobians straight in the blocks' columns: the shared speeds, then each body's own.
    ns = blocks.shared.size
    j_s, j_o = jac[:, :, :ns], jac[blocks.bodies, :, ns:]  # (nb, 6, ns), (nk, 6, width)
    w_o = weights[blocks.bodies]
    m_ss = jnp.einsum("bkn,bk,bkm->nm", j_s, weights, j_s)
    # The per-body (batched) contractions as fused sums (`small_einsum`: a batched dot is a
    # library call per body on XLA:CPU); the sums over all bodies stay dots.
    m_so = small_einsum("bkn,bk,bkm->bnm", j_s[blocks.bodies], w_o, j_o)
    # The padding's rows and columns are zero: a unit diagonal there (its force is zero too).
    m_oo = small_einsum("bkn,bk,bkm->bnm", j_o, w_o, j_o) + np.stack([np.diag(row == len(blocks.position)) for row in blocks.own])
    force = jnp.append(force, 0.0)
    f_s = force[blocks.shared] - jnp.einsum("bkn,bk->n", j_s, g)
    f_o = force[blocks.own] - small_einsum("bkn,bk->bn", j_o, g[blocks.bodies])
    x = _small_spd_solve(m_oo, jnp.concatenate([jnp.swapaxes(m_so, 1, 2), f_o[:, :, None]], axis=2))
    x_so, x_o = x[:, :, :-1], x[:, :, -1]
    schur = m_ss - small_einsum("bni,bim->nm", m_so, x_so)
    ud_s = jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(schur), f_s - jnp.einsum("bni,bi->n", m_so, x_o))
    ud_o = x_o - small_einsum("bin,n->bi", x_so, ud_s)
    return jnp.concatenate([ud_s, ud_o.ravel()])[blocks.position]
