"""Where one right-hand-side evaluation of the dual-axis antenna spends its time, per fidelity.

    python benchmarks/rhs_anatomy.py [--fidelities ideal lumped planetary] [--calls 300]

Writes `benchmarks/results/rhs_anatomy.md`. Each piece is timed *inside* one compiled program
(a `lax.scan` of `--calls` evaluations at slightly perturbed states, so nothing is hoisted), which
removes Python dispatch: the numbers are the compiled cost, what diffrax pays per evaluation.
Pieces: the whole vector field; `Mechanism.dynamics` (mass matrix and velocity terms by Kane's
equations), split into the mass-matrix Jacobian (`jacfwd` of the twists over u) and the bias
(`jvp` of the twists over q and t); the joints' forces; poses; twists; the linear solve.
"""

import argparse
import time

import equinox as eqx
import jax
import jax.numpy as jnp

import tolerax

import _results


def timed(fn, mech, args, n):
    """Compiled microseconds per call of `fn(mech, *args)`, best of 3 loops of `n` calls."""

    @eqx.filter_jit
    def loop(mech, args):
        def body(c, k):
            a = jax.tree.map(lambda x: x + 1e-12 * k * c, args)
            out = fn(mech, *a)
            return c + 1e-30 * sum(jnp.sum(leaf) for leaf in jax.tree.leaves(out)), None

        return jax.lax.scan(body, jnp.asarray(0.0), jnp.arange(n, dtype=float))[0]

    jax.block_until_ready(loop(mech, args))
    best = float("inf")
    for _ in range(3):
        start = time.perf_counter()
        jax.block_until_ready(loop(mech, args))
        best = min(best, time.perf_counter() - start)
    return best / n * 1e6


def pieces(mech, n):
    q, u, v = mech.initial_state("steady")
    t = jnp.asarray(0.01)
    mass, bias = mech.dynamics(q, u, t)
    return {
        "vector field (all)": timed(lambda m, t_, q_, u_, v_: m.vector_field(t_, (q_, u_, v_), None), mech, (t, q, u, v), n),
        "dynamics: M and b": timed(lambda m, q_, u_, t_: m.dynamics(q_, u_, t_), mech, (q, u, t), n),
        "  M: jacfwd of twists over u": timed(lambda m, q_, u_, t_: jax.jacfwd(lambda w: m.twists(q_, w, t_))(u_), mech, (q, u, t), n),
        "  b: jvp of twists over (q, t)": timed(
            lambda m, q_, u_, t_: jax.jvp(lambda a, b: m.twists(a, u_, b), (q_, t_), (m.qdot(q_, u_), jnp.ones_like(t_))),
            mech, (q, u, t), n,
        ),
        "joint forces (both joints)": timed(lambda m, q_, u_, v_, t_: m.joint_forces(q_, u_, v_, t_), mech, (q, u, v, t), n),
        "poses": timed(lambda m, q_, t_: m.poses(q_, t_), mech, (q, t), n),
        "twists": timed(lambda m, q_, u_, t_: m.twists(q_, u_, t_), mech, (q, u, t), n),
        "linear solve M x = f": timed(lambda m, a, b: jnp.linalg.solve(a, b), mech, (mass, bias), n),
    }


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--fidelities", nargs="+", choices=list(tolerax.FIDELITIES), default=list(tolerax.FIDELITIES))
    parser.add_argument("--calls", type=int, default=300, help="evaluations per compiled loop")
    args = parser.parse_args()
    rows = {}
    sizes = {}
    for fid in args.fidelities:
        mech = tolerax.antenna("dual", fidelity=fid)
        rows[fid] = pieces(mech, args.calls)
        sizes[fid] = (mech.layout.size_u, mech.layout.size_v)
        print(fid, {k: round(x, 1) for k, x in rows[fid].items()}, flush=True)
    fids = list(rows)
    _results.write_table(
        "rhs_anatomy",
        "One right-hand-side evaluation, dual-axis antenna: where the time goes",
        _results.command(args),
        ["piece"] + [f"{f} (u: {sizes[f][0]}, contacts: {sizes[f][1]})" for f in fids],
        [[key] + [f"{rows[f][key]:.1f}" for f in fids] for key in rows[fids[0]]],
        about=f"Compiled microseconds per call ({args.calls} calls inside one program, best of 3).",
    )


if __name__ == "__main__":
    main()
