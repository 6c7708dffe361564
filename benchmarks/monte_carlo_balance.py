"""How much a vmapped Monte Carlo chunk waits for its slowest unit, and whether ordering the units
by their cost would help (issue 32, item 5).

    python benchmarks/monte_carlo_balance.py [--scenes scan-azimuth scan-azimuth-fast scan-azimuth-planetary]
        [--units 64 32 16] [--chunks 4 8 16 32] [--results DIR]

For each built-in scene (its `[run]` settings and `[tolerances]`), `--units` units drawn with key 0
are solved one at a time (one compiled program, `PointingObjective.run`), recording each unit's
wall time and its attempted steps (accepted + rejected). A vmapped chunk of `c` units runs its
batched while-loop until its slowest member is done, every iteration costing the same whatever
number of members are still stepping, so its efficiency is

    sum of the members' steps / (c * the largest member's steps),

which the script reports with the units in sample order (what `tolerax.monte_carlo` does: chunk k
holds samples k*c .. k*c + c - 1) and sorted by their steps (the best any ordering by predicted
cost could do). It also fits the steps linearly on the features (R^2 over the units) to say
whether a cost could be predicted from a unit's draws before solving it.

Between chunks, the `processes` and `dask` backends hand the next chunk to whichever worker is
free (a queue), so workers do not wait for each other except on the last chunks.
"""

import time

import diffrax
import equinox as eqx
import jax
import numpy as np

import tolerax

import harness

jax.config.update("jax_enable_x64", True)


@eqx.filter_jit
def _solve(pointing, values):
    res = pointing.run(values)
    return res.num_steps + res.num_rejected, res.result == diffrax.RESULTS.successful


def measure(name: str, n: int, chunks) -> tuple[tuple, list[str]]:
    scene_file = tolerax.load_scene(name)
    pointing = scene_file.objective()
    tolerances = scene_file.tolerances(pointing.scene)
    values = np.asarray(tolerax.sample(tolerances, jax.random.key(0), n))
    compile_s, _ = harness.wall(lambda: jax.block_until_ready(_solve(pointing, values[0])))
    walls, steps, ok = [], [], []
    for x in values:
        start = time.perf_counter()
        s, good = jax.block_until_ready(_solve(pointing, x))
        walls.append(time.perf_counter() - start)
        steps.append(int(s))
        ok.append(bool(good))
    walls, steps = np.asarray(walls), np.asarray(steps)
    efficiency = []
    for c in chunks:
        m = n // c * c
        if m < c:
            efficiency.append("—")
            continue
        in_order = steps[:m].reshape(-1, c)
        ordered = np.sort(steps[:m]).reshape(-1, c)
        e = in_order.sum() / (in_order.max(axis=1).sum() * c)
        e_sorted = ordered.sum() / (ordered.max(axis=1).sum() * c)
        efficiency.append(f"{e:.3f} / {e_sorted:.3f}")
    design = np.c_[np.ones(n), values]
    coef, *_ = np.linalg.lstsq(design, steps, rcond=None)
    r2 = 1.0 - np.sum((steps - design @ coef) ** 2) / np.sum((steps - steps.mean()) ** 2)
    row = (
        f"`{name}`", str(n), f"{sum(ok)}/{n}", f"{compile_s:.1f}",
        f"{walls.min():.3f} / {np.median(walls):.3f} / {walls.max():.3f}",
        f"{steps.min()} / {int(np.median(steps))} / {steps.max()}", f"{np.std(steps) / np.mean(steps):.3f}",
        f"{np.corrcoef(walls, steps)[0, 1]:.2f}", f"{r2:.2f}" + (" (fewer units than 3x features)" if n < 3 * design.shape[1] else ""),
        *efficiency,
    )
    print(row, flush=True)
    return row


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scenes", nargs="+", default=["scan-azimuth", "scan-azimuth-fast", "scan-azimuth-planetary"])
    parser.add_argument("--units", type=int, nargs="+", default=[64, 32, 16], help="units per scene, in the order of --scenes")
    parser.add_argument("--chunks", type=int, nargs="+", default=[4, 8, 16, 32])
    args = harness.parse_args(parser)
    if len(args.units) != len(args.scenes):
        parser.error("give one --units count per scene")
    load = harness.load()
    rows = [measure(name, n, args.chunks) for name, n in zip(args.scenes, args.units)]
    harness.write_table(
        "monte_carlo_balance", "Unit-to-unit solver cost and the vmapped chunk's wait for its slowest unit", harness.command(args),
        ["scene", "units", "succeeded", "compile (s)", "wall per unit, min / median / max (s)", "attempted steps, min / median / max",
         "steps, std / mean", "corr(wall, steps)", "R² of steps on the features"]
        + [f"chunk {c}: efficiency in sample order / sorted" for c in args.chunks],
        rows,
        about=f"Each unit solved alone (one program per scene), key 0, the scene's [run] settings and [tolerances]. Load average "
              f"before: {load}; after: {harness.load()}.",
    )


if __name__ == "__main__":
    main()
