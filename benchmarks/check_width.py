"""The design's Monte Carlo check reads its units at the design solver's smoothing width, a proxy
for the scene's own: the same units of a design simulated at both, paired.

    taskset -c 0 python benchmarks/check_width.py --scene FILE [--units 100] [--width 1e-7] [--results DIR]

`--scene`: a scene file with zones, e.g. the `proposal.toml` that `tolerax design` writes
(`tolerax design scan-azimuth-planetary --requirement 1061.7 --jitter 0.2 --yield 0.9 --out DIR`).
Its units (`--units`, drawn uniformly within its `[tolerances]` zones from one key) are
simulated twice with its `[run]` settings through `tolerax.monte_carlo`: at smoothing `--width`
(m; `Sequential()`'s last, 1e-7 m, the width `Check` simulates at: `propose_design`'s checks, the
drawn design's) and at the scene's own (what `tolerax montecarlo` and `--verify` simulate).
Reported per output: each width's yield at the file's requirement (and jitter requirement), 90 %
quantile and mean, the paired ratio's median, and how many units meet a requirement at one width
only.
"""

import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.design.check import AtWidth
from tolerax.uncertainty.montecarlo import monte_carlo

import harness


def main(argv=None) -> int:
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scene", type=pathlib.Path, required=True)
    parser.add_argument("--units", type=int, default=100)
    parser.add_argument("--width", type=float, default=1e-7, help="the check's smoothing width, m (default Sequential()'s last)")
    parser.add_argument("--key", type=int, default=11)
    args = harness.parse_args(parser, argv)
    sf = tx.load_scene(str(args.scene))
    tol = sf.tolerances()
    limits = {"pointing_rms": float(sf.data["tolerances"]["requirement"])}
    if "jitter" in sf.data["tolerances"]:
        limits["pointing_jitter"] = float(sf.data["tolerances"]["jitter"])
    pointing = sf.objective(**({"jitter_cutoff": float(sf.data["tolerances"].get("jitter_cutoff", 20.0))} if "pointing_jitter" in limits else {}))
    scene_width = float(pointing.scene.azimuth.stage.smoothing_width) if hasattr(pointing.scene.azimuth, "stage") else float("nan")
    runs, walls = {}, {}
    for label, width in (("check", args.width), ("scene", None)):
        start = time.perf_counter()
        run = monte_carlo(AtWidth(pointing, None if width is None else jnp.asarray(width)), tol, args.units,
                          jax.random.key(args.key), chunk_size=50, progress=False)
        walls[label] = time.perf_counter() - start
        ds = run.dataset
        ok = np.asarray(ds["success"].values, dtype=bool)
        runs[label] = {o: np.where(ok, np.asarray(ds[o].values, dtype=float), np.nan) for o in limits}
        print(label, f"{walls[label]:.0f} s", flush=True)
    rows = []
    for output, limit in limits.items():
        a, b = runs["check"][output], runs["scene"][output]
        both = np.isfinite(a) & np.isfinite(b)
        a, b = a[both], b[both]
        rows.append((output, f"{limit:g}", f"{np.mean(a <= limit):.3f}", f"{np.mean(b <= limit):.3f}", f"{np.quantile(a, 0.9):.4g}",
                     f"{np.quantile(b, 0.9):.4g}", f"{a.mean():.4g}", f"{b.mean():.4g}", f"{np.median(a / b):.3f}",
                     f"{int(np.sum((a <= limit) & (b > limit)))} / {int(np.sum((a > limit) & (b <= limit)))}", str(int(both.sum()))))
        print(rows[-1], flush=True)
    title = "The design check's smoothing width against the scene's own, on the same units"
    harness.write_table(
        "check_width", title, harness.command(args),
        ["output", "requirement", f"yield at {args.width:g} m (check)", f"yield at the scene's {scene_width:g} m",
         "q90 (check)", "q90 (scene)", "mean (check)", "mean (scene)", "paired ratio check / scene (median)",
         "units meeting it at the check's width only / at the scene's only", "units"],
        rows, notes=[f"Scene file `{args.scene.name}`, {args.units} units (key {args.key}) drawn within its zones, simulated with its "
                     f"[run] settings at both widths ({walls['check']:.0f} s and {walls['scene']:.0f} s)."])
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
