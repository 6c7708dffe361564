"""Full-fidelity Monte Carlo from the command line with no option given (`backend="auto"`:
chunks computed in the command's own process and in worker processes on idle cores beside it)
against the same command in one process (`--backend vmap`), and against the package's default
integrator (the scene with `[run]` Tsit5, rtol 1e-6, atol 1e-9, I-controller: `tolerax.solve.ACCURATE`,
which the built-in scene's Bosh3 replaced) in one process: units per minute, and
whether the units' outputs are bitwise the same (issue 60: "full-fidelity Monte Carlo units per
minute with no option given >= 2x today's default").

    python benchmarks/monte_carlo_auto.py [--scene scan-azimuth-planetary] [--n 64] [--chunk 8] [--rounds 2]

Each row is `tolerax montecarlo SCENE --n N --chunk C` in a fresh process (imports, tracing,
compilation or the compilation cache, the run, writing its results), with the options in the
row; rounds interleave the rows and the fastest is kept (these machines are noisy). One
compilation cache for all, warmed by a first untimed run of each row (of `--warm-n` units), so the rows compare
running, not compiling: what a user's second command pays. Units per minute: N over the wall.
The machine should be otherwise idle: "auto" adds workers only on idle cores.
"""

import pathlib
import tempfile

import numpy as np
import xarray as xr

import tolerax as tx
from tolerax.io.scenefile import save_scene

import harness

ROWS = {
    "no option (auto: this process and workers on idle cores; the scene's [run] integrator)": [],
    "--backend vmap (this process alone; the scene's [run] integrator)": ["--backend", "vmap"],
    "--backend vmap, the scene with the package's default integrator (one process; Tsit5, rtol 1e-6, atol 1e-9, I-controller)":
        ["--backend", "vmap"],  # and the scene file written below in place of the scene's name
}


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scene", default="scan-azimuth-planetary")
    parser.add_argument("--n", type=int, default=64)
    parser.add_argument("--chunk", type=int, default=8)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--warm-n", type=int, default=None,
                        help="units of the untimed warm-up runs (default --n; the same --chunk compiles the same programs)")
    args = harness.parse_args(parser)
    work = pathlib.Path(tempfile.mkdtemp(prefix="mc_auto_"))
    cache = work / "cache"
    accurate = work / "accurate.toml"
    save_scene(tx.load_scene(args.scene).replace(solver="Tsit5", rtol=1e-6, atol=1e-9, pcoeff=0.0, icoeff=1.0), accurate)
    scenes = [args.scene, args.scene, str(accurate)]
    tail = ["--n", str(args.n), "--chunk", str(args.chunk), "--quiet", "--force"]
    walls = {name: [] for name in ROWS}
    for k, (name, extra) in enumerate(ROWS.items()):  # warm the cache: each row's programs compiled once, untimed
        warm = ["--n", str(args.warm_n or args.n), *tail[2:]]
        harness.cli(["montecarlo", scenes[k], *warm, *extra], work / "warm", cache)
    for r in range(args.rounds):
        for k, (name, extra) in enumerate(ROWS.items()):
            wall = harness.cli(["montecarlo", scenes[k], *tail, *extra], work / f"row{k}", cache)
            walls[name].append(wall)
            print(f"round {r}: {name}: {wall:.1f} s", flush=True)
    data = {name: xr.load_dataset(work / f"row{k}" / "montecarlo.nc") for k, name in enumerate(ROWS)}
    names = list(ROWS)
    auto, alone, accurate = (data[n] for n in names)
    outputs = [v for v in auto.data_vars if v != "success"]
    same = all(np.array_equal(auto[v].values, alone[v].values) for v in outputs)
    base_rate = args.n / min(walls[names[2]]) * 60
    rows = []
    for name in names:
        best = min(walls[name])
        rate = args.n / best * 60
        ds = data[name]
        rows.append((name, " / ".join(f"{w:.1f}" for w in walls[name]), f"{best:.1f}", f"{rate:.1f}", f"{rate / base_rate:.2f}",
                     f"{float(ds['pointing_rms'].mean()):.2f} +- {float(ds['pointing_rms'].std()):.2f}",
                     f"{int(ds['success'].sum())}/{args.n}"))
    differs = np.abs(accurate["pointing_rms"].values / alone["pointing_rms"].values - 1.0)
    harness.write_table(
        "monte_carlo_auto", "Full-fidelity Monte Carlo with no option given against one process and the default integrator",
        harness.command(args),
        ["command options", "wall per round (s)", "fastest (s)", "units per minute", "x the last row", "pointing RMS (arcsec)",
         "succeeded"], rows,
        about=(f"`tolerax montecarlo {args.scene} --n {args.n} --chunk {args.chunk}` in a fresh process per run, whole-process "
               "wall time, the compilation cache warm (one untimed run of each row first), rounds interleaved."),
        notes=[f"No option against `--backend vmap`: the units' outputs ({', '.join(outputs)}) bitwise the same: "
               f"**{'yes' if same else 'NO'}**. The package's default integrator against the scene's: pointing RMS relative "
               f"difference per unit, median {np.median(differs):.1e}, largest {differs.max():.1e} (two integrators, each within "
               "its own error and the rattle's chaos floor: `rattle_chaos.md`)."])


if __name__ == "__main__":
    main()
