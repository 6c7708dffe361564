"""The vector field traced once per solve: what `tolerax`'s nested jitted calls (`solve._vector_field`,
`Mechanism.accelerations`, the bench's `accelerations`) change in tracing, compiling and running
a program, and in its numbers.

    taskset -c 0 python benchmarks/trace_once.py [--rounds 2] [--results DIR]

diffrax traces a solve's step three or four times (its term check, its loop body's shape once or
twice, the loop itself) and `observe` computes the accelerations again at the saves; as nested
jitted calls, JAX keeps their trace for the next trace with the same structure and shapes. Each
workload runs in a fresh process with the compilation cache off, once as `tolerax` is ("nested")
and once with the three calls replaced by the plain functions they wrap ("plain", patched in the
child), interleaved over `--rounds` rounds; the fastest of each is kept. Workloads: the RMS
pointing error of the planetary azimuth scan (20 ms from rest, the life tests' start-up), its
forward-mode directional derivative (`diffrax.ForwardMode`), the reverse-mode gradient of the
lumped scan's over 0.3 s, and the planetary bench's start-up (8 ms). `trace+lower`: `.lower()`;
`compile`: `.compile()`; `run`: the compiled program's call. The figures are the ratios nested /
plain in the same run, and each workload's largest relative difference in its numbers.
"""

import os

import harness

CHILD = r"""
import json, sys, time
import diffrax, equinox as eqx, jax, jax.numpy as jnp
import tolerax as tx
work, mode = sys.argv[1], sys.argv[2]
if mode == "plain":
    import tolerax.solve as S, tolerax.mechanism.mechanism as M, tolerax.mechanism.bench as B
    S._vector_field = lambda scene, t, y, args: scene.vector_field(t, y, args)
    M._accelerations = lambda m, *a: m._accelerations(*a)
    B._accelerations = lambda b, *a: b._accelerations(*a)
if work in ("planetary-value", "planetary-jvp"):
    scene = tx.scan("azimuth", fidelity=("planetary", "ideal"))
    adjoint = diffrax.ForwardMode() if work == "planetary-jvp" else diffrax.RecursiveCheckpointAdjoint()
    p = tx.PointingObjective(scene, duration=0.02, settle=0.0, start="rest", n_save=41, rtol=1e-8, atol=1e-11, adjoint=adjoint)
    x, d = jnp.full(5, 5e-6), jnp.ones(5) / jnp.sqrt(5.0)
    if work == "planetary-value":
        f, args = eqx.filter_jit(lambda p, v: p(v, 1e-6)["pointing_rms"]), (p, x)
    else:
        f, args = eqx.filter_jit(lambda p, v, d: jax.jvp(lambda u: p(u, 1e-6)["pointing_rms"], (v,), (d,))), (p, x, d)
elif work == "lumped-grad":
    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    p = tx.PointingObjective(scene, duration=0.3, settle=0.0, start="steady", n_save=31)
    f, args = eqx.filter_jit(lambda p, v: jax.value_and_grad(lambda u: p(u, 1e-6)["pointing_rms"])(v)), (p, tx.design_of(scene))
elif work == "bench":
    bench = tx.TestBench()
    f, args = eqx.filter_jit(lambda b: tx.simulate(b, 0.008, n_save=41, throw=False).output_angle_error), (bench,)
out = {}
t = time.perf_counter(); low = f.lower(*args); out["trace+lower"] = time.perf_counter() - t
t = time.perf_counter(); c = low.compile(); out["compile"] = time.perf_counter() - t
t = time.perf_counter(); v = jax.block_until_ready(c(*args)); out["run"] = time.perf_counter() - t
out["numbers"] = [float(e) for e in jnp.ravel(jnp.concatenate([jnp.ravel(a) for a in jax.tree.leaves(v)]))]
print("RESULT " + json.dumps(out))
"""

WORKLOADS = ("planetary-value", "planetary-jvp", "lumped-grad", "bench")
MODES = ("nested", "plain")
PARTS = ("trace+lower", "compile", "run")


def child(work: str, mode: str) -> dict:
    return harness.child_result(CHILD, [work, mode], dict(os.environ, TOLERAX_CACHE="off"))


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--rounds", type=int, default=2, help="interleaved rounds (the fastest of each kept)")
    parser.add_argument("--workloads", nargs="+", default=list(WORKLOADS), choices=WORKLOADS)
    args = harness.parse_args(parser)
    best = harness.interleaved_best(args.rounds, args.workloads, MODES, child, PARTS)
    rows = []
    for work in args.workloads:
        a, b = best[(work, "nested")], best[(work, "plain")]
        diff = max(abs(x - y) / max(abs(y), 1e-300) for x, y in zip(a["numbers"], b["numbers"], strict=True))
        cells = [f"{a[k]:.2f} / {b[k]:.2f} ({a[k] / b[k]:.2f})" for k in PARTS]
        rows.append((work, *cells, f"{diff:.1e}"))
    harness.write_table(
        "trace_once", "The vector field traced once per solve: nested jitted calls against plain ones", harness.command(args),
        ["workload", "trace+lower, nested / plain (s) (ratio)", "compile (s)", "run (s)", "largest relative difference"], rows,
        about="Fresh process per workload and mode, compilation cache off; the fastest of "
              f"{args.rounds} interleaved rounds.",
    )


if __name__ == "__main__":
    main()
