"""Monte Carlo throughput: samples per second against batch size, `jax.vmap` over manufacturing
draws of every clearance and backlash of the bench joint.

    python benchmarks/monte_carlo_throughput.py [--duration 0.3] [--batches 1 2 4 8 16]

Each sample: clearances and backlash drawn uniformly in 10-100 um, the joint started from rest
(impacts from about 0.24 s), Tsit5 at rtol 1e-6; output: RMS output angle error. For each batch
size the same draws are solved twice: one `vmap`ped solve, and one at a time by the compiled
single-sample function (the serial baseline), so the ratio isolates what batching buys. A vmapped
adaptive solve steps all samples together until the slowest finishes, so the batch pays for its
hardest member. Wall time after compilation, best of 2. Writes
`benchmarks/results/monte_carlo_throughput.md`.
"""

import argparse
import time

import jax
import jax.numpy as jnp
import numpy as np

import tolerax

import _results
from _design import rms_output_error


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=0.3)
    parser.add_argument("--batches", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    args = parser.parse_args()
    bench = tolerax.TestBench()
    n_features = len(tolerax.design_names(bench))

    def sample(p):
        return rms_output_error(bench, p, args.duration, 1e-6)

    batched = jax.jit(jax.vmap(sample))
    single = jax.jit(sample)
    jax.block_until_ready(single(jnp.full(n_features, 50e-6)))
    rng = np.random.default_rng(0)
    rows = []
    for n in args.batches:
        p = jnp.asarray(rng.uniform(10e-6, 100e-6, size=(n, n_features)))
        start = time.perf_counter()
        jax.block_until_ready(batched(p))
        first = time.perf_counter() - start
        best = float("inf")
        for _ in range(2):
            start = time.perf_counter()
            rms, ok, steps = jax.block_until_ready(batched(p))
            best = min(best, time.perf_counter() - start)
        serial = float("inf")
        for _ in range(2):
            start = time.perf_counter()
            for k in range(n):
                jax.block_until_ready(single(p[k]))
            serial = min(serial, time.perf_counter() - start)
        rows.append(dict(n=n, wall=best, serial=serial, compile=first - best, rate=n / best, ok=int(np.sum(ok)), steps=np.asarray(steps)))
        print(rows[-1], flush=True)
    _results.write_table(
        "monte_carlo_throughput",
        "Monte Carlo throughput (bench, vmap over clearance and backlash draws)",
        _results.command(args),
        [
            "batch", "vmapped wall (s)", "samples/s", "same draws one at a time (s)", "vmap speed-up", "compile (s)",
            "succeeded", "steps per sample, min / max",
        ],
        [
            (
                str(r["n"]), f"{r['wall']:.2f}", f"{r['rate']:.2f}", f"{r['serial']:.2f}", f"{r['serial'] / r['wall']:.2f}",
                f"{r['compile']:.1f}", f"{r['ok']}/{r['n']}", f"{r['steps'].min()} / {r['steps'].max()}",
            )
            for r in rows
        ],
        about=f"{args.duration} s from rest per sample.",
    )


if __name__ == "__main__":
    main()
