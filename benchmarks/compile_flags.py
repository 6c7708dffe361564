"""XLA:CPU's code generators: what `tolerax`'s default `--xla_cpu_use_fusion_emitters=false`
(`tolerax.cache.prefer_fast_compiles`) changes in compile and running time, and in the results.

    taskset -c 0 python benchmarks/compile_flags.py [--rounds 2] [--results DIR]

Each workload runs in a fresh process with the compilation cache off, once with the flag tolerax
sets on import (the classic emitters) and once with `TOLERAX_XLA_FLAGS=off` (jaxlib's default,
the MLIR fusion emitters), interleaved over `--rounds` rounds; the fastest of each is kept.
Workloads: the value and gradient of the mean squared pointing error through a 20 ms solve of the
planetary dual antenna (`first`: trace, compile and one call; `run`: the fastest of three calls
of the compiled program), the same through a 0.5 s solve of the lumped one, a 32-unit Monte Carlo chunk of
`scan-azimuth` (`first`: the first chunk, `run`: a second one), and 40 eager operations of
distinct shapes (each a program of its own). The figures are the ratios classic / MLIR in the
same run, and each workload's largest relative difference in its numbers between the two.
"""

import os

import harness

CHILD = r"""
import json, sys, time
import jax, jax.numpy as jnp
import tolerax as tx
work = sys.argv[1]
out = {}
def timed(f, *a):
    t = time.perf_counter(); v = jax.block_until_ready(f(*a)); return time.perf_counter() - t, v
if work in ("planetary-grad", "lumped-grad"):
    fidelity, duration = ("planetary", 0.02) if work == "planetary-grad" else ("lumped", 0.5)
    scene = tx.scan("dual", fidelity=fidelity)
    def f(x):
        r = tx.simulate(tx.with_design(scene, x), duration, throw=False)
        return jnp.mean(r.pointing_error ** 2)
    g = jax.jit(jax.value_and_grad(f))
    x = tx.design_of(scene)
    out["first"], _ = timed(g, x)
    runs = [timed(g, x) for _ in range(3)]
    out["run"], (v, d) = min(r[0] for r in runs), runs[-1][1]
    out["numbers"] = [float(v)] + [float(e) for e in d]
elif work == "mc-chunk":
    p = tx.load_scene("scan-azimuth").objective()
    zones = tx.tolerances_of(p.scene, 1e-5)
    t = time.perf_counter(); r = tx.monte_carlo(p, zones, 32, jax.random.key(0), chunk_size=32, progress=False)
    out["first"] = time.perf_counter() - t
    t = time.perf_counter(); tx.monte_carlo(p, zones, 32, jax.random.key(1), chunk_size=32, progress=False)
    out["run"] = time.perf_counter() - t
    out["numbers"] = [float(e) for name in r.outputs for e in r.dataset[name].values]
elif work == "eager":
    jnp.ones(3).block_until_ready()
    t = time.perf_counter()
    values = [float(jnp.sum(jnp.sin(jnp.arange(n, dtype=float)) * 2.0)) for n in range(10, 50)]
    out["first"] = time.perf_counter() - t
    out["run"] = None
    out["numbers"] = values
print("RESULT " + json.dumps(out))
"""

WORKLOADS = ("planetary-grad", "lumped-grad", "mc-chunk", "eager")
CONFIGS = {"classic (tolerax default)": {}, "MLIR fusion emitters (jaxlib default)": {"TOLERAX_XLA_FLAGS": "off"}}


def child(work: str, extra: dict) -> dict:
    env = dict(os.environ, TOLERAX_CACHE="off", **extra)
    env.pop("XLA_FLAGS", None)
    return harness.child_result(CHILD, [work], env)


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--rounds", type=int, default=2, help="interleaved rounds (the fastest of each kept)")
    parser.add_argument("--workloads", nargs="+", default=list(WORKLOADS), choices=WORKLOADS)
    args = harness.parse_args(parser)
    best = harness.interleaved_best(args.rounds, args.workloads, list(CONFIGS), lambda work, name: child(work, CONFIGS[name]), ("first", "run"))
    classic, mlir = CONFIGS
    rows = []
    for work in args.workloads:
        a, b = best[(work, classic)], best[(work, mlir)]
        diff = max(abs(x - y) / max(abs(y), 1e-300) for x, y in zip(a["numbers"], b["numbers"], strict=True))
        run = (f"{a['run']:.3f}", f"{b['run']:.3f}", f"{a['run'] / b['run']:.2f}") if a["run"] is not None else ("-", "-", "-")
        rows.append((work, f"{a['first']:.2f}", f"{b['first']:.2f}", f"{a['first'] / b['first']:.2f}", *run, f"{diff:.1e}"))
    harness.write_table(
        "compile_flags", "XLA:CPU code generators: classic against MLIR fusion emitters", harness.command(args),
        ["workload", "first, classic (s)", "first, MLIR (s)", "first ratio", "run, classic (s)", "run, MLIR (s)", "run ratio",
         "largest relative difference"], rows,
        about="Fresh process per workload and configuration, compilation cache off; the fastest of "
              f"{args.rounds} interleaved rounds. `first`: trace, compile and the first call; `run`: the fastest of three calls of the compiled program (Monte Carlo: a second chunk).",
    )


if __name__ == "__main__":
    main()
