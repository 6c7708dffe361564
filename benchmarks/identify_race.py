"""`identify`'s search (a Sobol screen, Levenberg-Marquardt from its best points, a line screen
where the fit misses) raced against SciPy's differential evolution, the off-the-shelf global
search, on the same batched least-squares cost at equal wall time, over several recordings.

    taskset -c 0 python benchmarks/identify_race.py [--n 5] [--dual] [--out benchmarks/results/identify_race.md]

The unit: the lumped azimuth scan (`tx.scan("azimuth", fidelity=("lumped", "ideal"))`; `--dual`:
the lumped dual scan recorded by both encoders), 0.35 s from a steady start with a reversal, 141
saves, a 20-bit encoder with 2 µrad of noise. Identified: the driven joints' ring backlash and
drag torque. Each recording's unit draws its own truth, log-uniform within a factor 1.6 of the
scene's values (100 µm; 0.05 N m), from the recording's seed, so the scene's values are never the
answer. Per recording, both searches from nothing but the scene and the recording, compiled
first (one warm-up recording of each, not counted):

- `identify(scene, recording, parameters)` with every default: its wall time W and the cost
  $\\lVert r\\rVert^2$ (µrad²) at its estimate;
- `scipy.optimize.differential_evolution` over the same box `identify`'s screen covers (a factor
  `search` = 2 either side of the scene's values, in the logarithm of each parameter), its
  defaults (popsize 15, best1bin, Latin hypercube start) but `vectorized=True` (each generation
  one batched run of the same compiled residual `identify` screens with) and `polish=False`,
  stopped at the first generation that ends after W: the best cost it has found by then.

Reported: both costs against the noise's expected $N\\sigma^2$, each estimate's error against the
truth in `identify`'s standard errors, `identify`'s status of each parameter (`Identification.status`:
an estimate far from the truth is honest only where the status says its interval is not a
two-sided one), DE's generations and evaluations, and the wall times.

`--along SEED`: instead of the race, recording SEED's cost along each backlash through
`identify`'s estimate (the other parameters held there) and through the truth, and identify's
table: where the cost is flat the recording does not bound the backlash on that side.
"""

import argparse
import math
import os
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np
from scipy.optimize import differential_evolution

import tolerax as tx
from tolerax.identification.fit import _costs
from tolerax.identification.identify import _problem, own_width
from tolerax.identification.parameters import parameter_values

SPREAD = 1.6  # each unit's truth within this factor of the scene's values (log-uniform)
SEARCH = 2.0  # identify's default screen box: a factor either side


def recording(scene, names, axes, seed):
    rng = np.random.default_rng([2026, seed])
    base = np.asarray(parameter_values(scene, names))
    truth = base * SPREAD ** rng.uniform(-1.0, 1.0, len(names))
    rec = tx.synthetic_recording(scene, dict(zip(names, truth)), duration=0.35, n_save=141, noise=2e-6,
                                 quantum=2 * math.pi / 2**20, key=jax.random.key(5000 + seed), axes=axes)
    return truth, rec


def race_de(scene, rec, names, budget, seed):
    """Differential evolution on `identify`'s own cost until `budget` seconds: `(cost, x, generations, evaluations, wall)`."""
    fit, x0, scale, *_ = _problem(scene, rec, tuple(names), 0.0, None, None, "steady", "auto", {})
    width = own_width(scene)
    logs = np.log(x0)
    bounds = [(v - math.log(SEARCH), v + math.log(SEARCH)) for v in logs]
    evaluations, generations = [0], [0]

    def cost(z):  # z: (p, S) log-parameters, one column per member
        points = np.exp(np.asarray(z).T)
        evaluations[0] += len(points)
        c = np.asarray(_costs(fit, jnp.asarray(points), width))
        return np.where(np.isfinite(c), c, 1e30)

    start = time.perf_counter()

    def stop(intermediate_result=None):
        generations[0] += 1
        return time.perf_counter() - start >= budget

    out = differential_evolution(cost, bounds, vectorized=True, updating="deferred", polish=False, seed=seed, callback=stop,
                                 maxiter=100000, tol=0.0, atol=0.0)
    wall = time.perf_counter() - start
    return float(out.fun), np.exp(out.x) * scale, generations[0], evaluations[0], wall


def along(scene, names, axes, seed) -> int:
    """Recording `seed`'s cost (µrad²) along each backlash, 60 µm to 250 µm, through identify's
    estimate and through the truth (the other parameters held at each), and identify's table."""
    truth, rec = recording(scene, names, axes, seed)
    got = tx.identify(scene, rec, names)
    fit, _, scale, *_ = _problem(scene, rec, tuple(names), 0.0, None, None, "steady", "auto", {})
    grid = np.arange(60e-6, 251e-6, 5e-6)
    print(f"recording {seed}: truth {', '.join(f'{v:.4g}' for v in truth)}; N sigma^2 {got.n * (rec.noise / 1e-6) ** 2:.1f}")
    for j, name in enumerate(names):
        if not name.endswith("ring_backlash"):
            continue
        for label, at in (("identify's estimate", np.asarray(got.estimate)), ("the truth", truth)):
            points = np.repeat(at[None], grid.size, axis=0)
            points[:, j] = grid
            costs = np.asarray(_costs(fit, jnp.asarray(points / scale), own_width(scene)))
            print(f"{name} through {label}: " + " ".join(f"{1e6 * g:.0f}:{c:.1f}" for g, c in zip(grid, costs)))
    print(got.table())
    return 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=5, help="recordings (default 5)")
    parser.add_argument("--dual", action="store_true", help="the lumped dual scan, both joints' parameters")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    parser.add_argument("--along", type=int, default=None, metavar="SEED",
                        help="recording SEED's cost along each backlash through identify's estimate and the truth, no race")
    args = parser.parse_args(argv)
    if args.dual:
        scene, axes = tx.scan("dual", fidelity="lumped"), ("azimuth", "pitch")
    else:
        scene, axes = tx.scan("azimuth", fidelity=("lumped", "ideal")), ("azimuth",)
    names = [f"{a}.{p}" for a in axes for p in ("ring_backlash", "drag_torque")]
    if args.along is not None:
        return along(scene, names, axes, args.along)
    # Warm-up: both searches' programs compiled on a recording not counted.
    _, warm = recording(scene, names, axes, 999)
    tx.identify(scene, warm, names)
    race_de(scene, warm, names, 1.0, 0)
    rows, wins = [], []
    for seed in range(args.n):
        truth, rec = recording(scene, names, axes, seed)
        start = time.perf_counter()
        got = tx.identify(scene, rec, names)
        w_id = time.perf_counter() - start
        de_cost, de_x, gens, evals, w_de = race_de(scene, rec, names, w_id, seed)
        expected = got.n * (rec.noise / 1e-6) ** 2  # N sigma^2, µrad^2: the cost at the truth, on average
        se = np.asarray(got.standard_error)
        id_err = (np.asarray(got.estimate) - truth) / se
        de_err = (de_x - truth) / se
        wins.append(got.cost <= de_cost)
        rows.append(f"| {seed} | {', '.join(f'{v:.4g}' for v in truth)} | {got.cost:.1f} | {de_cost:.1f} | {expected:.1f} | "
                    f"{np.max(np.abs(id_err)):.2f} | {np.max(np.abs(de_err)):.3g} | {', '.join(got.status())} | "
                    f"{got.screened} + {got.line_screened} | "
                    f"{gens} / {evals} | {w_id:.1f} | {w_de:.1f} |")
        print(rows[-1], flush=True)
    what = "the lumped dual scan, both encoders" if args.dual else "the lumped azimuth scan"
    text = "\n".join([
        "# Identification: identify's search against differential evolution at equal wall time", "",
        f"`python benchmarks/identify_race.py --n {args.n}{' --dual' if args.dual else ''}`; {os.cpu_count()} cores; "
        f"load average {os.getloadavg()[0]:.2f} at the end; {time.strftime('%Y-%m-%d')}.", "",
        f"{what}; identified: {', '.join(names)} (SI: m, N m), each unit's truth log-uniform within x{SPREAD:g} of the "
        f"scene's values; 20-bit encoder, 2 µrad noise. Both searches compiled first. DE: SciPy's defaults, vectorized, no "
        f"polish, the box identify's screen covers (x{SEARCH:g} either side), stopped at the first generation ending after "
        "identify's wall time.", "",
        f"**identify's cost at or below DE's on {sum(wins)} of {len(wins)} recordings.**", "",
        "| recording | truth | identify's cost (µrad²) | DE's best cost (µrad²) | N sigma² (µrad²) | identify: max error (its SEs) "
        "| DE: max error (identify's SEs) | identify's status | identify: screened + line points "
        "| DE: generations / evaluations | identify wall (s) | DE wall (s) |",
        "|---|---|---:|---:|---:|---:|---:|---|---|---|---:|---:|", *rows])
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
