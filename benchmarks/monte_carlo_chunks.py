"""Units per second of a vmapped Monte Carlo chunk by its size: the default chunk a scene's units
run in (`AbstractScene.unit_chunk`, what `Check`, `Auto()`'s probe and `monte_carlo` take when
no `chunk_size` is given on a CPU).

    python benchmarks/monte_carlo_chunks.py [--scenes scan-azimuth-planetary scenes/issue60_drive.toml]
        [--n 100] [--seeds 0 1] [--chunks 10 16 50] [--results DIR]

For each scene (a built-in name or a scene file) and seed, `--n` units drawn from the scene's
`[tolerances]` (`tolerax.uncertainty.sampling.sample`) are evaluated in this process, one core,
as `monte_carlo`'s `"vmap"` backend does (`tolerax.uncertainty.backends.evaluate`, the last chunk
padded to the chunk's size), once per chunk size, each size's program compiled before it is
timed. A vmapped chunk steps until its slowest unit is done, so a larger chunk amortises the
per-kernel overhead over more units but waits longer for its slowest one; which wins depends on
how much the units' step counts differ (a rattling full stage: much).
"""

import time

import jax
import numpy as np

import tolerax as tx
from tolerax.uncertainty.backends import evaluate
from tolerax.uncertainty.sampling import sample

import harness


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scenes", nargs="+", default=["scan-azimuth-planetary", "scenes/issue60_drive.toml"])
    parser.add_argument("--n", type=int, default=100)
    parser.add_argument("--seeds", type=int, nargs="+", default=[0, 1])
    parser.add_argument("--chunks", type=int, nargs="+", default=[10, 16, 50])
    args = harness.parse_args(parser)
    start = time.perf_counter()
    rows = []
    for name in args.scenes:
        scene_file = tx.load_scene(name)
        pointing = scene_file.objective()
        tolerances = scene_file.tolerances(pointing.scene)
        for seed in args.seeds:
            values = np.asarray(sample(tolerances, jax.random.key(seed), args.n))
            walls = {}
            for chunk in args.chunks:
                evaluate(pointing, values[:chunk], chunk)  # compiles this size's program
                t0 = time.perf_counter()
                outs = [evaluate(pointing, values[i : i + chunk], chunk) for i in range(0, args.n, chunk)]
                walls[chunk] = time.perf_counter() - t0
                ok = int(sum(np.sum(o["success"]) for o in outs))
                print(f"{name} seed {seed} chunk {chunk}: {walls[chunk]:.1f} s ({ok}/{args.n} succeeded)", flush=True)
            best = min(walls.values())
            for chunk, wall in walls.items():
                rows.append((name, str(seed), str(chunk), f"{wall:.1f}", f"{args.n / wall:.3f}", f"{wall / best:.2f}",
                             str(pointing.scene.unit_chunk()) if hasattr(pointing.scene, "unit_chunk") else "-"))
    harness.write_table(
        "monte_carlo_chunks", "Units per second of a vmapped Monte Carlo chunk by its size", harness.command(args),
        ["scene", "seed", "chunk", "wall (s)", "units per second", "x the fastest chunk", "the scene's unit_chunk()"], rows,
        about=f"One process, `--n {args.n}` units per scene and seed, every chunk size on the same units. Total wall "
              f"{time.perf_counter() - start:.0f} s.")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
