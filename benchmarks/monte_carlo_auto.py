"""Full-fidelity Monte Carlo from the command line with no option given, today against the
package as it was at a named revision (`--before`, its own defaults: issue 60's "full-fidelity
Monte Carlo units per minute with no option given >= 2x today's default", today being the
issue's filing, b4ed2f1), and against today's command in one process (`--backend vmap`): units
per minute, and whether today's two rows' outputs are bitwise the same.

    python benchmarks/monte_carlo_auto.py [--scene scan-azimuth-planetary] [--n 128] [--rounds 1] [--before b4ed2f1] [--api]

Each row is `tolerax montecarlo SCENE --n N` in a fresh process (imports, tracing, compilation
or the compilation cache, the run, writing its results), with the options in the row and no
other (today's rows add `--quiet`, which only silences the progress lines). Today's no-option
row: `backend="auto"` (this process and a worker process on each idle core) in chunks of the
scene's `unit_chunk()`. The `--before` row runs that revision's own command line (its source,
`harness.tolerax_at`, in this environment) with its defaults (there: one process, chunks of 8).
Rounds interleave the rows and the fastest is kept (these machines are noisy). One compilation
cache for all, warmed by a first untimed run of each row (of `--warm-n` units), so the rows
compare running, not compiling: what a user's second command pays. Units per minute: N over the
wall. The machine should be otherwise idle: "auto" adds workers only on idle cores. `--api`: also
`tx.monte_carlo(objective, tolerances, n, key)` with no option (what a notebook calls), today and at
`--before` (there chunks of 64, the Python default then; the command line's was 8).
"""

import pathlib
import sys
import tempfile

import numpy as np
import xarray as xr

import harness


def before_cli(rev):
    """`argv -> [python, ...]`: the command line of tolerax as it was at `rev` (its source renamed
    `tolerax_at_<sha>` by `harness.tolerax_at`, run as `python -m ... .cli.main` would be)."""
    module = harness.tolerax_at(rev)
    folder = str(pathlib.Path(module.__file__).parent.parent)
    code = (f"import runpy, sys; sys.path.insert(0, {folder!r}); sys.argv = ['tolerax'] + sys.argv[1:]; "
            f"runpy.run_module('{module.__name__}.cli.main', run_name='__main__')")
    return lambda argv: [sys.executable, "-c", code, *argv]


API_CODE = """
import sys, importlib
folder, name, scene, n, out = sys.argv[1:6]
if folder:
    sys.path.insert(0, folder)
tx = importlib.import_module(name)
import jax
sf = tx.load_scene(scene)
result = tx.monte_carlo(sf.objective(), sf.tolerances(), int(n), jax.random.key(0))
result.dataset.to_netcdf(out)
"""


def api(rev=None):
    """`argv -> [python, ...]` running `tolerax.monte_carlo(scene.objective(), scene.tolerances(), n,
    jax.random.key(0))` with no option (argv: `montecarlo SCENE --n N ... --out OUT`, as the command
    line's rows), today's package or the one at `rev`; the units written to OUT/montecarlo.nc."""
    folder, name = "", "tolerax"
    if rev is not None:
        module = harness.tolerax_at(rev)
        folder, name = str(pathlib.Path(module.__file__).parent.parent), module.__name__

    def command(argv):
        scene, n, out = argv[1], argv[argv.index("--n") + 1], pathlib.Path(argv[argv.index("--out") + 1])
        out.mkdir(parents=True, exist_ok=True)
        return [sys.executable, "-c", API_CODE, folder, name, scene, n, str(out / "montecarlo.nc")]

    return command


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scene", default="scan-azimuth-planetary")
    parser.add_argument("--n", type=int, default=128)
    parser.add_argument("--rounds", type=int, default=1)
    parser.add_argument("--warm-n", type=int, default=16,
                        help="units of the untimed warm-up runs (the same chunk sizes compile the same programs)")
    parser.add_argument("--before", default="b4ed2f1", help="the revision whose no-option command is the baseline")
    parser.add_argument("--api", action="store_true",
                        help="also the Python call with no option (`tx.monte_carlo(objective, tolerances, n, key)`), today and "
                        "at --before, in fresh processes as the command's rows")
    args = harness.parse_args(parser)
    work = pathlib.Path(tempfile.mkdtemp(prefix="mc_auto_"))
    cache = work / "cache"
    rows = {  # name: (command line, options)
        "no option (today: auto, this process and a worker on each idle core; the scene's chunk)": (None, ["--quiet"]),
        "--backend vmap (today, this process alone; the scene's chunk)": (None, ["--quiet", "--backend", "vmap"]),
        f"no option at {args.before} (then: one process, chunks of 8)": (before_cli(args.before), []),
    }
    if args.api:
        rows |= {
            "Python, no option (today: `tx.monte_carlo(objective, tolerances, n, key)`: auto, the scene's chunk)": (api(), []),
            f"Python, no option at {args.before} (then: one process, chunks of 64)": (api(args.before), []),
        }
    names = list(rows)
    for k, (command, extra) in enumerate(rows.values()):  # warm the cache: each row's programs compiled once, untimed
        harness.cli(["montecarlo", args.scene, "--n", str(args.warm_n), *extra], work / f"warm{k}", cache, command=command)
    walls = {name: [] for name in rows}
    for r in range(args.rounds):
        for k, (name, (command, extra)) in enumerate(rows.items()):
            wall = harness.cli(["montecarlo", args.scene, "--n", str(args.n), *extra], work / f"row{k}_{r}", cache, command=command)
            walls[name].append(wall)
            print(f"round {r}: {name}: {wall:.1f} s", flush=True)
    data = {name: xr.load_dataset(work / f"row{k}_0" / "montecarlo.nc") for k, name in enumerate(rows)}
    auto, alone, before = (data[n] for n in names[:3])
    outputs = [v for v in auto.data_vars if v in alone.data_vars and v != "success"]
    same = all(np.array_equal(auto[v].values, alone[v].values) for v in outputs)
    # Each row against its own baseline: the command's rows against the command at --before, the Python rows against the
    # Python call there.
    baseline = {name: names[2] if k < 3 else names[4] for k, name in enumerate(names)}
    table = []
    for name in names:
        best = min(walls[name])
        rate = args.n / best * 60
        ds = data[name]
        table.append((name, " / ".join(f"{w:.1f}" for w in walls[name]), f"{best:.1f}", f"{rate:.1f}",
                      f"{min(walls[baseline[name]]) / best:.2f}",
                      f"{float(ds['pointing_rms'].mean()):.2f} +- {float(ds['pointing_rms'].std()):.2f}",
                      f"{int(ds['success'].sum())}/{args.n}"))

    def differs(a, b):
        d = np.abs(a["pointing_rms"].values / b["pointing_rms"].values - 1.0)
        return f"median {np.median(d):.1e}, largest {d.max():.1e}"

    notes = [f"Today's no option against `--backend vmap`: the units' outputs ({', '.join(outputs)}) bitwise the same: "
             f"**{'yes' if same else 'NO'}**. At {args.before} against today: the same units (the same draws), pointing RMS "
             f"relative difference per unit, {differs(before, auto)} (0 where the two versions compute each unit's bits alike, "
             "whatever the chunks)."]
    if args.api:
        notes.append(f"The Python call today against the command today: {differs(data[names[3]], auto)}; at {args.before} "
                     f"(chunks of 64) against today: {differs(data[names[4]], auto)}.")
    harness.write_table(
        "monte_carlo_auto", "Full-fidelity Monte Carlo with no option given, today against the package at the issue's filing",
        harness.command(args),
        ["how it is run", "wall per round (s)", "fastest (s)", "units per minute", f"x the same at {args.before}",
         "pointing RMS (arcsec)", "succeeded"], table,
        about=(f"`tolerax montecarlo {args.scene} --n {args.n}` (and with `--api` the Python call on the same scene) in a fresh "
               "process per run, whole-process wall time, the compilation cache warm (one untimed run of each row first), "
               "rounds interleaved."),
        notes=notes)

if __name__ == "__main__":
    main()
