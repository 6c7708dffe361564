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
import time

import jax
import numpy as np

import tolerax

import _results
from _design import rms_output_error


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
    bench = tolerax.TestBench()
    p0 = tolerax.design_of(bench)  # 100 um each
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
        e = np.zeros(p0.size)
        e[k] = h[k]
        fd.append((float(forward(p0 + e)) - float(forward(p0 - e))) / (2 * h[k]))
    t_fd = time.perf_counter() - start
    fd = np.array(fd)
    grad = np.asarray(grad)
    scale = np.maximum(np.abs(fd), 1e-12 * max(np.abs(fd).max(), 1e-300))
    rel = np.where((grad == 0) & (fd == 0), 0.0, np.abs(grad - fd) / scale)

    n = p0.size
    _results.write_table(
        "gradient_cost",
        "Gradient cost and accuracy (bench, every clearance and backlash)",
        _results.command(args),
        ["", "wall (s)", "x forward"],
        [
            ("forward solve", f"{t_forward:.3f}", "1"),
            (f"reverse-mode gradient ({n} parameters)", f"{t_gradient:.3f}", f"{t_gradient / t_forward:.1f}"),
            (f"central differences ({2 * n} solves)", f"{t_fd:.3f}", f"{t_fd / t_forward:.1f}"),
        ],
        about=f"Objective: RMS output angle error over {args.duration} s from rest = {float(value):.3f} arcsec; "
        f"Tsit5, rtol {args.rtol:g}.",
        notes=[f"Compilation: forward {compile_forward:.1f} s, gradient {compile_gradient:.1f} s (first call, including one run)."],
        sections=[
            _results.Section(
                None,
                ["parameter", "d(RMS)/dp, reverse mode (arcsec/um)", "central difference, h = 0.1 um", "relative difference"],
                [
                    (name.replace("_", " "), f"{g * 1e-6:.6g}", f"{f * 1e-6:.6g}", f"{r:.1e}")
                    for name, g, f, r in zip(tolerax.design_names(bench), grad, fd, rel)
                ],
            )
        ],
    )


if __name__ == "__main__":
    main()
