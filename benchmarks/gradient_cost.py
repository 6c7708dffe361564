"""Cost and accuracy of the gradient of a pointing-type objective with respect to every clearance
and backlash of a joint: reverse mode through diffrax against central finite differences.

    python benchmarks/gradient_cost.py [--duration 0.3] [--rtol 1e-8]

Scene: the default joint on its test bench from rest (the servo start-up closes the backlash and
the planets land on their pins at about 0.24 s), so the objective sees impacts. Objective: RMS
output angle error (arcsec) over the run. Design parameters (m): sun, carrier and planet-pin
radial clearances, sun- and ring-mesh backlash (all planets alike).

Writes `benchmarks/results/gradient_cost.md`: wall time of one forward solve, of one reverse-mode
gradient (diffrax's default `RecursiveCheckpointAdjoint`) and of central differences (2 solves
per parameter), all after compilation, best of 3; and the gradient from each method with their
relative difference.
"""

import argparse
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

import tolerax
from tolerax import _bench

from _design import NAMES, rms_output_error



def objective_factory(bench, duration, rtol):
    return lambda p: rms_output_error(bench, p, duration, rtol)[0]


def best_of(fn, *args, repeats=3):
    jax.block_until_ready(fn(*args))
    best = float("inf")
    for _ in range(repeats):
        start = time.perf_counter()
        out = jax.block_until_ready(fn(*args))
        best = min(best, time.perf_counter() - start)
    return best, out


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=0.3)
    parser.add_argument("--rtol", type=float, default=1e-8)
    args = parser.parse_args()
    bench = _bench.TestBench()
    p0 = jnp.array([100e-6, 100e-6, 100e-6, 100e-6, 100e-6])
    objective = objective_factory(bench, args.duration, args.rtol)
    forward = jax.jit(objective)
    gradient = jax.jit(jax.grad(objective))

    start = time.perf_counter()
    jax.block_until_ready(forward(p0))
    compile_forward = time.perf_counter() - start
    start = time.perf_counter()
    jax.block_until_ready(gradient(p0))
    compile_gradient = time.perf_counter() - start

    t_forward, value = best_of(forward, p0)
    t_gradient, grad = best_of(gradient, p0)
    h = 1e-3 * p0  # 0.1 um: small against the gaps, large against the solver's error
    fd = []
    start = time.perf_counter()
    for k in range(p0.size):
        e = jnp.zeros_like(p0).at[k].set(h[k])
        fd.append((float(forward(p0 + e)) - float(forward(p0 - e))) / (2 * h[k]))
    t_fd = time.perf_counter() - start
    fd = np.array(fd)
    grad = np.asarray(grad)
    scale = np.maximum(np.abs(fd), 1e-12 * max(np.abs(fd).max(), 1e-300))
    rel = np.where((grad == 0) & (fd == 0), 0.0, np.abs(grad - fd) / scale)

    lines = [
        "# Gradient cost and accuracy (bench, every clearance and backlash)",
        "",
        f"`python benchmarks/gradient_cost.py --duration {args.duration} --rtol {args.rtol}` (tolerax {tolerax.__version__}, "
        f"{jax.devices()[0].platform}). Objective: RMS output angle error over {args.duration} s from rest = {float(value):.3f} arcsec; "
        f"Tsit5, rtol {args.rtol:g}.",
        "",
        "| | wall (s) | x forward |",
        "|---|---|---|",
        f"| forward solve | {t_forward:.3f} | 1 |",
        f"| reverse-mode gradient (5 parameters) | {t_gradient:.3f} | {t_gradient / t_forward:.1f} |",
        f"| central differences (10 solves) | {t_fd:.3f} | {t_fd / t_forward:.1f} |",
        "",
        f"Compilation: forward {compile_forward:.1f} s, gradient {compile_gradient:.1f} s (first call, including one run).",
        "",
        "| parameter | d(RMS)/dp, reverse mode (arcsec/um) | central difference, h = 0.1 um | relative difference |",
        "|---|---|---|---|",
    ]
    for name, g, f, r in zip(NAMES, grad, fd, rel):
        lines.append(f"| {name} | {g * 1e-6:.6g} | {f * 1e-6:.6g} | {r:.1e} |")
    out = pathlib.Path(__file__).parent / "results" / "gradient_cost.md"
    out.write_text("\n".join(lines) + "\n")
    print(out.read_text())


if __name__ == "__main__":
    main()
