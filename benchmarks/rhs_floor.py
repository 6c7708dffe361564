"""The floor of one vector-field evaluation of the full planetary dual antenna: what XLA's
compiled program counts (flops, bytes, instructions, fusions), what one evaluation costs, and
how far that is from what this core can do (issue 41, step 1).

    python benchmarks/rhs_floor.py [--calls 300] [--batches 1 8 64] [--rounds 20] [--against REV ...] [--results DIR]

Scene: `tolerax.antenna("dual", fidelity="planetary")` (free base, 100 um clearances and
backlash, 83 states), at the state reached 0.3 s after a steady start (the rattle under way).
Each piece is compiled alone with the XLA options `tolerax.simulate` uses on a CPU and:

- **counted** from the compiled program: `cost_analysis()`'s flops, transcendentals and bytes
  accessed (XLA's own count of what it executes, padding and zeros included), the number of
  HLO instructions in the optimised module, and of fusions (each a kernel launched);
- **timed** inside one compiled program (a `lax.scan` of `--calls` evaluations at slightly
  perturbed states, so nothing is hoisted and Python never dispatches): microseconds per call,
  the best of `--rounds` rounds in which every piece's program runs once in turn (interleaved:
  on a noisy machine a slow spell falls on all pieces alike).

Pieces: the whole vector field (`Mechanism.vector_field`) as it is (the equations of motion
solved by blocks, `Mechanism.kane_blocks`; the planetary joints' deflection Jacobian in closed
form; Eigen's products on one thread, `CPU_COMPILER_OPTIONS`), as it was before the closed form
(the Jacobian by forward mode, `harness.with_forward_jacobian`, compiled with Eigen's products
over the CPU's threads, `harness.EIGEN_THREADS`), as it is but with Eigen's threads (the option's
part alone), and as it was before the blocks (`mass_solve="whole"`: the whole mass matrix formed
and factorised, the same equations; Eigen threaded), the accelerations by blocks
(Kane's terms over the frames and the block solve), the whole mass matrix and bias terms
(`Mechanism.dynamics`), the joints' forces (`Mechanism.joint_forces`: meshes, bearing contacts,
servos), the Cholesky solve of the whole M x = f, the impact-rate rates. The whole vector field
is also `vmap`ped over `--batches` states (what a Monte Carlo chunk pays per state), the three ways.
`--against REV`: the whole vector field as it was at each git revision REV too (the scene built
by that version of tolerax, `harness.tolerax_at`), alone and vmapped, timed in the same rounds.

**The core's ceiling**, measured in the same run: a float64 matrix product (512 x 512, the
machine's best flop rate on one core) and 500 elementwise passes over 32 k doubles (256 kB:
the bandwidth of the caches an evaluation's data lives in, read + write; memory's over 64 MB
is given too). A piece's floor is max(flops / peak, bytes / bandwidth); its time over
that floor is how much it pays beyond its arithmetic and traffic: launches of small kernels,
loops, copies the count does not see.
"""

import functools
import re
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.solve import CPU_COMPILER_OPTIONS

import harness


def loop_program(fn, n, options=None):
    """`n` calls of `fn(*args)` inside one compiled program (a scan at perturbed arguments),
    compiled with `CPU_COMPILER_OPTIONS` updated by `options`."""

    @functools.partial(eqx.filter_jit, compiler_options={**CPU_COMPILER_OPTIONS, **(options or {})})
    def loop(args):
        def body(c, k):
            a = jax.tree.map(lambda x: x + 1e-12 * k * c if eqx.is_inexact_array(x) else x, args)
            out = fn(*a)
            return c + 1e-30 * sum(jnp.sum(leaf) for leaf in jax.tree.leaves(out)), None

        return jax.lax.scan(body, jnp.asarray(0.0), jnp.arange(n, dtype=float))[0]

    return loop


def interleaved_us(programs, rounds):
    """Microseconds per call of each `(loop, args, n)` of `programs` (a dict of `loop_program`s):
    each run once (compiling), then `rounds` rounds in which every one runs once in turn; the
    best round of each. Interleaved, a noisy machine's slow spells fall on all pieces alike."""
    for loop, args, _ in programs.values():
        jax.block_until_ready(loop(args))
    best = {name: float("inf") for name in programs}
    for _ in range(rounds):
        for name, (loop, args, n) in programs.items():
            start = time.perf_counter()
            jax.block_until_ready(loop(args))
            best[name] = min(best[name], (time.perf_counter() - start) / n * 1e6)
    return best


def counts(fn, args, options=None):
    """XLA's counts of one call of `fn(*args)`, compiled alone."""
    compiled = jax.jit(fn, compiler_options={**CPU_COMPILER_OPTIONS, **(options or {})}).lower(*args).compile()
    cost = compiled.cost_analysis()
    cost = cost[0] if isinstance(cost, (list, tuple)) else cost
    text = compiled.as_text()
    instructions = len(re.findall(r"^\s+(?:ROOT )?%?[\w.\-]+ = ", text, flags=re.M))
    fusions = len(re.findall(r"^\s+(?:ROOT )?%?[\w.\-]+ = \S+ fusion\(", text, flags=re.M))
    return dict(flops=float(cost.get("flops", 0.0)), transcendentals=float(cost.get("transcendentals", 0.0)),
                bytes=float(cost.get("bytes accessed", 0.0)), instructions=instructions, fusions=fusions)


def ceiling():
    """(flop/s of a 512^2 float64 matrix product, bytes/s of an elementwise pass over 8 M
    doubles (memory), bytes/s of 500 elementwise passes over 32 k doubles (256 kB: the caches)),
    best of 5 each, on this process's core(s)."""
    a = jnp.asarray(np.random.default_rng(0).standard_normal((512, 512)))
    mm = jax.jit(lambda x: x @ x)
    x = jnp.asarray(np.random.default_rng(1).standard_normal(8 * 1024 * 1024))
    ew = jax.jit(lambda y: 1.000001 * y + 1e-9)
    small = jnp.asarray(np.random.default_rng(2).standard_normal(32 * 1024))
    passes = jax.jit(lambda y: jax.lax.fori_loop(0, 500, lambda i, z: 1.000001 * z + 1e-9, y))

    def best(f, arg):
        jax.block_until_ready(f(arg))
        times = []
        for _ in range(5):
            start = time.perf_counter()
            jax.block_until_ready(f(arg))
            times.append(time.perf_counter() - start)
        return min(times)

    return 2 * 512**3 / best(mm, a), 2 * 8 * x.size / best(ew, x), 500 * 2 * 8 * small.size / best(passes, small)


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--calls", type=int, default=300)
    parser.add_argument("--batches", type=int, nargs="+", default=[1, 8, 64])
    parser.add_argument("--rounds", type=int, default=20, help="interleaved timing rounds (the best of each piece)")
    parser.add_argument("--against", nargs="*", default=[], help="git revisions whose vector field is timed too")
    args = harness.parse_args(parser)
    start = time.perf_counter()
    mech = tx.antenna("dual", fidelity="planetary")
    whole = harness.with_mass_solve(mech, "whole")
    forward = harness.with_forward_jacobian(mech)
    threads = harness.EIGEN_THREADS
    res = tx.simulate(mech, 0.3, start="steady", n_save=2)
    q, u, v = (jnp.asarray(x[-1]) for x in res.states)
    t = jnp.asarray(0.3)
    mass, bias = mech.dynamics(q, u, t)
    (qa, _), (qp, _) = mech.joint_forces(q, u, v, t)
    force = jnp.concatenate([jnp.zeros(mech.layout.base_u), qa, qp]) - bias
    _, ud, _ = mech.vector_field(t, (q, u, v), None)
    n_states = q.size + u.size + v.size
    pieces = {
        "vector field (all), now": (lambda m, t_, q_, u_, v_: m.vector_field(t_, (q_, u_, v_), None), (mech, t, q, u, v)),
        "vector field (all), before the closed-form Jacobian (forward mode, Eigen threaded)": (
            lambda m, t_, q_, u_, v_: m.vector_field(t_, (q_, u_, v_), None), (forward, t, q, u, v), threads),
        "vector field (all), now but Eigen threaded": (lambda m, t_, q_, u_, v_: m.vector_field(t_, (q_, u_, v_), None),
                                                     (mech, t, q, u, v), threads),
        "vector field (all), whole M (before the blocks)": (lambda m, t_, q_, u_, v_: m.vector_field(t_, (q_, u_, v_), None),
                                                            (whole, t, q, u, v), threads),
        "accelerations by blocks: Kane's terms (frames) and the block solve": (lambda m, t_, q_, u_, f_: m._solve(q_, u_, t_, f_),
                                                                                (mech, t, q, u, force + bias)),
        "dynamics: whole M and b (Kane, frames)": (lambda m, t_, q_, u_: m.dynamics(q_, u_, t_), (mech, t, q, u)),
        "joint forces (meshes, contacts, servos)": (lambda m, t_, q_, u_, v_: m.joint_forces(q_, u_, v_, t_), (mech, t, q, u, v)),
        "joint forces, forward-mode Jacobian (before)": (lambda m, t_, q_, u_, v_: m.joint_forces(q_, u_, v_, t_), (forward, t, q, u, v)),
        "Cholesky solve of the whole M x = f": (lambda m_, f_: jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(m_), f_), (mass, force)),
        "impact-rate rates": (lambda m, q_, u_, ud_, v_: m.each_joint(lambda j, *x: j.impact_rate_rates(*x), ("q", q_), ("u", u_),
                                                                         ("u", ud_), ("v", v_)), (mech, q, u, ud, v)),
    }
    earlier = {rev: harness.tolerax_at(rev).antenna("dual", fidelity="planetary") for rev in args.against}
    for rev, scene in earlier.items():
        pieces[f"vector field (all), at {rev}"] = (lambda m, t_, q_, u_, v_: m.vector_field(t_, (q_, u_, v_), None), (scene, t, q, u, v))
    peak, memory, bandwidth = ceiling()
    print(f"ceiling: {peak / 1e9:.2f} GFLOP/s, {memory / 1e9:.2f} GB/s memory, {bandwidth / 1e9:.2f} GB/s caches", flush=True)
    rows, batch_rows, programs = [], [], {}
    for label, (fn, fargs, *options) in pieces.items():
        arrays, static = eqx.partition(fargs, eqx.is_array)
        c = counts(lambda a, f=fn, s=static: f(*eqx.combine(a, s)), (arrays,), *options)
        programs[label] = (loop_program(fn, args.calls, *options), fargs, args.calls)
        rows.append((label, c))
    for b in args.batches:
        states = jax.tree.map(lambda x: jnp.broadcast_to(x, (b, *x.shape)) * (1 + 1e-9 * jnp.arange(b).reshape(-1, *[1] * x.ndim)),
                              (q, u, v))
        fn = jax.vmap(lambda m, t_, y: m.vector_field(t_, y, None), in_axes=(None, None, 0))
        for solve, scene, options in (("now", mech, None), ("before the closed-form Jacobian (forward mode, Eigen threaded)", forward, threads),
                                      ("whole M (before the blocks, Eigen threaded)", whole, threads),
                                      *((f"at {rev}", scene, None) for rev, scene in earlier.items())):
            arrays, static = eqx.partition((scene, t, states), eqx.is_array)
            c = counts(lambda a, s=static: fn(*eqx.combine(a, s)), (arrays,), options)
            calls = max(10, args.calls // b)
            programs[(b, solve)] = (loop_program(fn, calls, options), (scene, t, states), calls)
            batch_rows.append(((b, solve), c))
    print(f"timing {len(programs)} programs over {args.rounds} interleaved rounds ...", flush=True)
    us = interleaved_us(programs, args.rounds)
    for k, (label, c) in enumerate(rows):
        floor_us = max(c["flops"] / peak, c["bytes"] / bandwidth) * 1e6
        rows[k] = (label, f"{c['flops']:.0f}", f"{c['transcendentals']:.0f}", f"{c['bytes'] / 1e3:.1f}", str(c["instructions"]),
                   str(c["fusions"]), f"{us[label]:.1f}", f"{floor_us:.2f}", f"{us[label] / floor_us:.0f}")
        print(rows[k], flush=True)
    for k, ((b, solve), c) in enumerate(batch_rows):
        floor_us = max(c["flops"] / peak, c["bytes"] / bandwidth) * 1e6
        t_us = us[(b, solve)]
        batch_rows[k] = (str(b), solve, f"{t_us:.1f}", f"{t_us / b:.2f}", f"{c['flops'] / b:.0f}", f"{c['bytes'] / b / 1e3:.1f}",
                         str(c["fusions"]), f"{floor_us / b:.3f}", f"{t_us / floor_us:.0f}")
        print(batch_rows[k], flush=True)
    harness.write_table(
        "rhs_floor", "One vector-field evaluation of the full planetary dual antenna: counted, timed, and its floor",
        harness.command(args),
        ["piece", "flops (XLA's count)", "transcendentals", "bytes accessed (kB)", "HLO instructions", "fusions (kernels)",
         "µs per call", "floor µs (flops or bytes at the core's ceiling)", "time / floor"],
        rows,
        about=(f"`tolerax.antenna('dual', fidelity='planetary')`, {n_states} states, at 0.3 s after a steady start; compiled with "
               f"`tolerax.solve.CPU_COMPILER_OPTIONS`; times inside one program of {args.calls} calls, the best of {args.rounds} rounds interleaved over all pieces. The core's "
               f"ceiling in this run: {peak / 1e9:.2f} GFLOP/s (float64 512^2 matrix product), {bandwidth / 1e9:.2f} GB/s "
               f"from the caches (500 elementwise passes over 256 kB; {memory / 1e9:.2f} GB/s from memory, over 64 MB: one "
               f"evaluation's data, {n_states} states and the scene's constants, stay in the caches). Total wall {time.perf_counter() - start:.0f} s, compilation included."),
        sections=[harness.Section(
            "The whole vector field vmapped over a batch of states",
            ["batch", "right-hand side", "µs per batched call", "µs per state", "flops per state", "kB accessed per state", "fusions (kernels)",
             "floor µs per state", "time / floor"], batch_rows)],
    )


if __name__ == "__main__":
    main()
