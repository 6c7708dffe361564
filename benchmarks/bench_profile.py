"""Cost anatomy of the bench scene, and where its fastest eigenvalues come from.

Run:  python benchmarks/bench_profile.py [--duration 1.0]
Writes benchmarks/results/bench_profile.md. Timings are wall-clock on whatever machine runs it
(2-core CPU in the project's numbers); ratios within one run are the meaningful figures.
"""

import argparse
import math
import time

import jax
import numpy as np
from jax.flatten_util import ravel_pytree

import tolerax

import _results


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=1.0)
    args = parser.parse_args()
    bench = tolerax.TestBench()

    def run():
        # n_save and the step budget of the old `simulate_bench` call, from rest.
        return tolerax.simulate(bench, args.duration, n_save=11, max_steps=2_000_000)

    t = time.perf_counter()
    res = run()
    first = time.perf_counter() - t
    t = time.perf_counter()
    res = run()
    elapsed = time.perf_counter() - t
    steps, rejected = int(res.num_steps), int(res.num_rejected)
    rows = [
        ("compile + first run (s)", f"{first:.1f}"),
        ("run after compile (s)", f"{elapsed:.2f}"),
        ("compile time, approx. (s)", f"{first - elapsed:.1f}"),
        ("wall time per simulated second (s)", f"{elapsed / args.duration:.2f}"),
        ("accepted / rejected steps", f"{steps} / {rejected}"),
        ("mean accepted step (s)", f"{args.duration / steps:.3g}"),
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
    per_step = elapsed / (steps + rejected)
    rows += [
        ("one RHS evaluation (us)", f"{rhs * 1e6:.1f}"),
        ("cost per step, accepted or rejected (us)", f"{per_step * 1e6:.1f}"),
        ("per-step cost / (6 RHS evaluations of Tsit5 with FSAL)", f"{per_step / (6 * rhs):.2f}"),
    ]

    # Where the fastest eigenvalues come from: the full Jacobian of the vector field at the end
    # of the run (planets seated on their pins), and the undamped modes of the tangent stiffness.
    flat, unravel = ravel_pytree(y)
    jac = jax.jacfwd(lambda z: ravel_pytree(f(unravel(z)))[0])(flat)
    eig, vec = np.linalg.eig(np.asarray(jac))
    stage = bench.stage
    names = list(stage.layout.names)
    state_names = [f"{x}" for x in names] + [f"d/dt {x}" for x in names] + [f"impact_rate {c}" for c in stage.contact_names]
    order = np.argsort(-np.abs(eig))
    fastest = []
    seen = set()
    for k in order:
        key = (round(abs(eig[k]), 3), round(abs(eig[k].imag), 3))
        if key in seen:
            continue
        seen.add(key)
        top = np.argsort(-np.abs(vec[:, k]))[:3]
        fastest.append(
            (f"{abs(eig[k]):.3g}", f"{eig[k].real:.3g}", f"{abs(eig[k].imag) / (2 * math.pi):.4g}", ", ".join(state_names[i] for i in top))
        )
        if len(fastest) >= 8:
            break
    q = y[0]
    modes = tolerax.natural_frequencies(stage, q, bench.added)  # K phi = omega^2 M phi at this state
    m = np.asarray(tolerax.planetary.mass_matrix(stage, q, bench.added))
    highest = []
    for j in np.argsort(-np.asarray(modes.frequencies))[:4]:
        s = np.asarray(modes.shapes[:, j])
        share = s * (m @ s)
        top = np.argsort(-share)[:3]
        highest.append((f"{float(modes.frequencies[j]):.1f}", ", ".join(f"{names[i]} {share[i]:.2f}" for i in top)))
    _results.write_table(
        "bench_profile",
        "Bench scene profile",
        _results.command(args),
        ["quantity", "value"],
        rows,
        about=f"Default joint, 100 um clearances/backlash, 0.98 deg/s, start from rest, {args.duration} s simulated.",
        sections=[
            _results.Section(
                "Fastest eigenvalues of the full Jacobian (at t = end of run)",
                ["|lambda| (1/s)", "Re", "Im/(2 pi) Hz", "dominant states"],
                fastest,
            ),
            _results.Section(
                "Highest undamped modes of the tangent stiffness (same state)",
                ["f (Hz)", "kinetic-energy share (top 3 coordinates)"],
                highest,
                notes=[
                    "Tsit5's stability interval on the negative real axis is about 3.5/|lambda|: "
                    f"{3.5 / abs(eig[order[0]]):.3g} s for the fastest eigenvalue."
                ],
            ),
        ],
    )


if __name__ == "__main__":
    main()
