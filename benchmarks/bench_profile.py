"""Cost anatomy of the bench scene, and where its fastest eigenvalues come from.

Run:  python benchmarks/bench_profile.py [--duration 1.0]
Writes benchmarks/results/bench_profile.md. Timings are wall-clock on whatever machine runs it
(2-core CPU in the project's numbers); ratios within one run are the meaningful figures.
"""

import argparse
import math
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

from tolerax import _bench, _planetary as P


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=1.0)
    args = parser.parse_args()
    bench = _bench.TestBench()
    lines = ["# Bench scene profile", "", f"Default joint, 100 um clearances/backlash, 0.98 deg/s, start from rest, {args.duration} s simulated.", ""]

    t = time.perf_counter()
    res = _bench.simulate_bench(bench, args.duration, n_save=11)
    first = time.perf_counter() - t
    t = time.perf_counter()
    res = _bench.simulate_bench(bench, args.duration, n_save=11)
    run = time.perf_counter() - t
    steps, rejected = int(res.num_steps), int(res.num_rejected)
    lines += [
        "| quantity | value |",
        "|---|---|",
        f"| compile + first run (s) | {first:.1f} |",
        f"| run after compile (s) | {run:.2f} |",
        f"| compile time, approx. (s) | {first - run:.1f} |",
        f"| wall time per simulated second (s) | {run / args.duration:.2f} |",
        f"| accepted / rejected steps | {steps} / {rejected} |",
        f"| mean accepted step (s) | {args.duration / steps:.3g} |",
    ]

    # One right-hand-side evaluation, in a jitted loop (no per-call dispatch).
    y = jax.tree.map(lambda a: a[-1], res.states)
    f = lambda y_: bench.vector_field(0.0, y_, None)  # noqa: E731

    @jax.jit
    def many(y_):
        def body(i, acc):
            out = f(jax.tree.map(lambda a: a + 1e-30 * i, y_))
            return acc + out[1][0]
        return jax.lax.fori_loop(0, 1000, body, 0.0)

    many(y).block_until_ready()
    t = time.perf_counter()
    many(y).block_until_ready()
    rhs = (time.perf_counter() - t) / 1000
    per_step = run / (steps + rejected)
    lines += [
        f"| one RHS evaluation (us) | {rhs * 1e6:.1f} |",
        f"| cost per step, accepted or rejected (us) | {per_step * 1e6:.1f} |",
        f"| per-step cost / (6 RHS evaluations of Tsit5 with FSAL) | {per_step / (6 * rhs):.2f} |",
        "",
    ]

    # Where the fastest eigenvalues come from: the full Jacobian of the vector field at the end
    # of the run (planets seated on their pins), and the undamped modes of the tangent stiffness.
    flat, unravel = jax.flatten_util.ravel_pytree(y)
    jac = jax.jacfwd(lambda z: jax.flatten_util.ravel_pytree(f(unravel(z)))[0])(flat)
    eig, vec = np.linalg.eig(np.asarray(jac))
    stage = bench.stage
    names = list(stage.layout.names)
    n = len(names)
    state_names = [f"{x}" for x in names] + [f"d/dt {x}" for x in names] + [f"impact_rate {c}" for c in stage.contact_names]
    order = np.argsort(-np.abs(eig))
    lines += ["## Fastest eigenvalues of the full Jacobian (at t = end of run)", "", "| |lambda| (1/s) | Re | Im/(2 pi) Hz | dominant states |", "|---|---|---|---|"]
    shown = 0
    seen = set()
    for k in order:
        key = (round(abs(eig[k]), 3), round(abs(eig[k].imag), 3))
        if key in seen:
            continue
        seen.add(key)
        v = np.abs(vec[:, k])
        top = np.argsort(-v)[:3]
        lines.append(f"| {abs(eig[k]):.3g} | {eig[k].real:.3g} | {abs(eig[k].imag) / (2 * math.pi):.4g} | {', '.join(state_names[i] for i in top)} |")
        shown += 1
        if shown >= 8:
            break
    q, qd, v = y
    m = P.mass_matrix(stage, q, bench.added)
    k = P.stiffness_matrix(stage, q)
    k = 0.5 * (k + k.T)
    l_inv = np.linalg.inv(np.linalg.cholesky(np.asarray(m)))
    lam, phi = np.linalg.eigh(l_inv @ np.asarray(k) @ l_inv.T)
    shapes = l_inv.T @ phi
    lines += ["", "## Highest undamped modes of the tangent stiffness (same state)", "", "| f (Hz) | kinetic-energy share (top 3 coordinates) |", "|---|---|"]
    for j in np.argsort(-lam)[:4]:
        s = shapes[:, j]
        share = s * (np.asarray(m) @ s)
        top = np.argsort(-share)[:3]
        lines.append(f"| {math.sqrt(max(lam[j], 0)) / (2 * math.pi):.1f} | {', '.join(f'{names[i]} {share[i]:.2f}' for i in top)} |")
    lines += ["", f"Tsit5's stability interval on the negative real axis is about 3.5/|lambda|: {3.5 / abs(eig[order[0]]):.3g} s for the fastest eigenvalue."]
    text = "\n".join(lines) + "\n"
    out = pathlib.Path(__file__).parent / "results" / "bench_profile.md"
    out.write_text(text)
    print(text)


if __name__ == "__main__":
    main()
