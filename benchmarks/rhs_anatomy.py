"""Where one right-hand-side evaluation of the dual-axis antenna spends its time, per fidelity,
and what the cheaper formulation of Kane's equations buys over a short planetary run.

    python benchmarks/rhs_anatomy.py [--fidelities ideal lumped planetary] [--calls 300] [--horizon 0.5]
        [--batches 1 4 16 64]

Writes `benchmarks/results/rhs_anatomy.md`. Each piece is timed *inside* one compiled program
(a `lax.scan` of `--calls` evaluations at slightly perturbed states, so nothing is hoisted), which
removes Python dispatch: the numbers are the compiled cost, what diffrax pays per evaluation.

Pieces: the whole vector field, today's (`Mechanism.vector_field`: body Jacobians and
accelerations by propagating frames down the chain, `Mechanism.kinematics`; Cholesky solve) and
the reference formulation in the same run (`_vector_field_by_autodiff`: `jacfwd` of the twists
over all speeds, `jvp` over $(q, t)$, LU solve); their parts; the joints' forces and impact-rate
rates; poses; twists. Then the planetary dual-axis antenna from a steady start over `--horizon`
seconds with both formulations (wall time after compilation, steps): the per-step saving.

Pieces are compiled with the XLA options `tolerax.simulate` uses for a single solve on a CPU
(`tolerax._solve.CPU_COMPILER_OPTIONS`: no YNNPACK fusions), and the whole vector field once more
with XLA's defaults. For planetary joints, the joints' forces also with the stages' deflection rates and force
projection by a `jvp` + `vjp` pair (before commit 2e0792c; today: the deflections' Jacobian by
forward mode and two products).

`--batches`: the whole vector field `vmap`ped over that many states at once (what a Monte Carlo
chunk pays per evaluation), per fidelity: microseconds per batched call and per state. If the
cost were the dispatch of XLA's ~220 small kernels, the per-state cost would fall about as 1/B;
it falls much less when the kernels' own work (arithmetic, and copies into padded and
concatenated arrays) dominates.
"""

import argparse
import functools
import os
import time

import equinox as eqx
import jax
import jax.numpy as jnp

import tolerax
from tolerax import _mechanism, _planetary
from tolerax._joint import _AbstractStageJoint
from tolerax._solve import CPU_COMPILER_OPTIONS

import _results

# What `tolerax.simulate` compiles a single solve with on a CPU (Monte Carlo's vmapped programs
# keep XLA's defaults, and so does `--batches` here).
CPU_OPTIONS = CPU_COMPILER_OPTIONS if jax.default_backend() == "cpu" else None


def timed(fn, mech, args, n, options=CPU_OPTIONS):
    """Compiled microseconds per call of `fn(mech, *args)`, best of 3 loops of `n` calls, compiled
    with XLA `options` (default: those `tolerax.simulate` compiles with on a CPU)."""

    @functools.partial(eqx.filter_jit, compiler_options=options)
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


def _forces_by_jvp_vjp(m, q, u, v, t):
    """`Mechanism.joint_forces` with the stages' forces projected by a `jvp` and a `vjp`
    (`_planetary.stage_forces(..., projection="jvp-vjp")`, the formulation before 2e0792c)."""

    def one(joint, qj, uj, vj):
        f = _planetary.stage_forces(joint.stage, qj, uj, vj, projection="jvp-vjp")
        return f.generalised + joint.drive_forces(qj, uj, t), f.contact

    return m.each_joint(one, ("q", q), ("u", u), ("v", v))


def _cholesky(mass, force):
    return jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(mass), force)


def _impact_rate_rates(m, q, u, ud, v):
    return [j.impact_rate_rates(q[sq], u[su], ud[su], v[sv]) for j, sq, su, sv in m.joints()]


PIECES = {
    "vector field (all)": lambda m, t, q, u, v, ud, mass, f: m.vector_field(t, (q, u, v), None),
    "vector field (all), XLA's default CPU options": lambda m, t, q, u, v, ud, mass, f: m.vector_field(t, (q, u, v), None),
    "vector field, reference (jacfwd Kane, LU)": lambda m, t, q, u, v, ud, mass, f: _mechanism._vector_field_by_autodiff(m, t, (q, u, v)),
    "dynamics: M and b (frames)": lambda m, t, q, u, v, ud, mass, f: m.dynamics(q, u, t),
    "  kinematics: frames down the chain": lambda m, t, q, u, v, ud, mass, f: m.kinematics(q, u, t),
    "dynamics, reference: M and b": lambda m, t, q, u, v, ud, mass, f: _mechanism._kane_by_autodiff(m, q, u, t),
    "  M: jacfwd of twists over u": lambda m, t, q, u, v, ud, mass, f: jax.jacfwd(lambda w: m.twists(q, w, t))(u),
    "  b: jvp of twists over (q, t)": lambda m, t, q, u, v, ud, mass, f: jax.jvp(
        lambda a, b: m.twists(a, u, b), (q, t), (m.qdot(q, u), jnp.ones_like(t))
    ),
    "joint forces (both joints)": lambda m, t, q, u, v, ud, mass, f: m.joint_forces(q, u, v, t),
    "joint forces, stages projected by jvp + vjp (before 2e0792c)": lambda m, t, q, u, v, ud, mass, f: _forces_by_jvp_vjp(m, q, u, v, t),
    "impact-rate rates (both joints)": lambda m, t, q, u, v, ud, mass, f: _impact_rate_rates(m, q, u, ud, v),
    "poses": lambda m, t, q, u, v, ud, mass, f: m.poses(q, t),
    "twists": lambda m, t, q, u, v, ud, mass, f: m.twists(q, u, t),
    "solve M x = f: Cholesky": lambda m, t, q, u, v, ud, mass, f: _cholesky(mass, f),
    "solve M x = f: LU (reference)": lambda m, t, q, u, v, ud, mass, f: jnp.linalg.solve(mass, f),
}


def pieces(mech, n, only):
    q, u, v = mech.initial_state("steady")
    t = jnp.asarray(0.01)
    mass, bias = mech.dynamics(q, u, t)
    _, ud, _ = mech.vector_field(t, (q, u, v), None)
    args = (t, q, u, v, ud, mass, -bias)
    stages = all(isinstance(j, _AbstractStageJoint) for j in (mech.azimuth, mech.pitch))
    out = {}
    for k, fn in PIECES.items():
        if only and k not in only:
            continue
        if "jvp + vjp" in k:
            out[k] = timed(fn, mech, args, n) if stages else float("nan")  # stage joints only
        elif "default CPU options" in k:
            out[k] = timed(fn, mech, args, n, options=None)
        else:
            out[k] = timed(fn, mech, args, n)
    return out


def batched(mech, n, batch):
    """Microseconds per call of the vector field `vmap`ped over `batch` slightly different states."""
    q, u, v = mech.initial_state("steady")
    scale = 1.0 + 1e-6 * jnp.arange(batch, dtype=float)[:, None]
    args = (jnp.asarray(0.01), q[None] * scale, u[None] * scale, v[None] * scale)

    def fn(m, t, qb, ub, vb):
        return jax.vmap(lambda q_, u_, v_: m.vector_field(t, (q_, u_, v_), None))(qb, ub, vb)

    return timed(fn, mech, args, max(n // batch, 20), options=None)


def trajectory(horizon):
    """Wall time (s, after compilation) and steps of the planetary dual-axis antenna from a
    steady start, reference and today's formulation, same run."""
    mech = tolerax.antenna("dual", fidelity="planetary")
    out = {}
    for name, scene in (("reference (jacfwd Kane, LU)", _mechanism._KaneByAutodiff(mech)), ("today (frames, Cholesky)", mech)):
        run = lambda: tolerax.simulate(scene, horizon, start="steady", n_save=11)  # noqa: E731
        start = time.perf_counter()
        res = run()
        first = time.perf_counter() - start
        start = time.perf_counter()
        res = run()
        wall = time.perf_counter() - start
        out[name] = (first - wall, wall, int(res.num_steps), int(res.num_rejected), res)
        print(name, out[name][:4], os.getloadavg(), flush=True)
    return out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--fidelities", nargs="+", choices=list(tolerax.FIDELITIES), default=list(tolerax.FIDELITIES))
    parser.add_argument("--calls", type=int, default=300, help="evaluations per compiled loop")
    parser.add_argument("--horizon", type=float, default=0.5, help="simulated seconds of the planetary run (0: skip)")
    parser.add_argument("--pieces", nargs="*", default=[], help="time only these pieces (default: all)")
    parser.add_argument("--batches", nargs="*", type=int, default=[], help="also time the vector field vmapped over these batch sizes")
    args = parser.parse_args()
    rows, sizes, batch_us = {}, {}, {}
    load = [os.getloadavg()]
    for fid in args.fidelities:
        mech = tolerax.antenna("dual", fidelity=fid)
        rows[fid] = pieces(mech, args.calls, args.pieces)
        sizes[fid] = (mech.layout.size_u, mech.layout.size_v)
        print(fid, {k: round(x, 1) for k, x in rows[fid].items()}, flush=True)
        batch_us[fid] = {b: batched(mech, args.calls, b) for b in args.batches}
        if args.batches:
            print(fid, "batched", {b: round(x, 1) for b, x in batch_us[fid].items()}, flush=True)
    load.append(os.getloadavg())
    sections, notes = [], []
    if args.batches:
        sections.append(
            _results.Section(
                "The vector field over a batch of states (vmap): µs per batched call (µs per state)",
                ["batch"] + list(rows),
                [[str(b)] + [f"{batch_us[f][b]:.1f} ({batch_us[f][b] / b:.1f})" for f in rows] for b in args.batches],
            )
        )
    if args.horizon > 0:
        runs = trajectory(args.horizon)
        load.append(os.getloadavg())
        (_, _, _, _, ref), (_, _, _, _, new) = runs.values()
        diff = float(jnp.max(jnp.abs(new.pointing_error - ref.pointing_error)))
        sections.append(
            _results.Section(
                f"Planetary dual-axis antenna, {args.horizon} s from a steady start (Tsit5, rtol 1e-6)",
                ["formulation", "compile (s)", "wall (s)", "wall per simulated s", "accepted steps", "rejected", "µs per step"],
                [
                    [name, f"{c:.1f}", f"{w:.2f}", f"{w / args.horizon:.2f}", str(a), str(r), f"{w / (a + r) * 1e6:.0f}"]
                    for name, (c, w, a, r, _) in runs.items()
                ],
                [
                    f"Largest difference in pointing error between the two runs: {diff:.2e} rad, against a "
                    f"largest pointing error of {float(jnp.max(ref.pointing_error)):.2e} rad. The formulations "
                    "are equal to rounding (tests/test_mechanism.py: same steps and outputs to 1e-9 over 0.05 s); "
                    "over 0.5 s the bearing rattle amplifies rounding differences into different step sequences.",
                ],
            )
        )
    fids = list(rows)
    _results.write_table(
        "rhs_anatomy",
        "One right-hand-side evaluation, dual-axis antenna: where the time goes",
        _results.command(args),
        ["piece"] + [f"{f} (u: {sizes[f][0]}, contacts: {sizes[f][1]})" for f in fids],
        [[key] + ["—" if rows[f][key] != rows[f][key] else f"{rows[f][key]:.1f}" for f in fids] for key in rows[fids[0]]],
        about=f"Compiled microseconds per call ({args.calls} calls inside one program, best of 3). "
        f"Load average (1, 5, 15 min) at start, after the pieces, after the runs: {'; '.join(', '.join(f'{x:.2f}' for x in l) for l in load)}.",
        notes=notes,
        sections=sections,
    )


if __name__ == "__main__":
    main()
