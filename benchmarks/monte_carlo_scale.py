"""Monte Carlo at scale from the command line (issue 32's must-show): 1000 lumped units of the
0.6 s azimuth scan, and 200 planetary units of it at the fast setting, each as one `tolerax
montecarlo` command in a fresh process, cold (empty persistent compilation cache) then warm (the
cache the cold run wrote), into new output folders.

    python benchmarks/monte_carlo_scale.py [--cases lumped fast] [--lumped-n 1000] [--fast-n 200]
        [--backend processes] [--lumped-chunk 32] [--fast-chunk 8] [--results DIR]

Cases:

- `lumped`: `tolerax montecarlo scan-azimuth --n N` (the azimuth joint's lumped model; 0.6 s from
  steady scanning, window after 0.3 s; four features +- 10 um);
- `fast`: `tolerax montecarlo scan-azimuth-fast --n N` (the full planetary stage with its masses
  scaled x1000, rtol 1e-3, PI controller; five features +- 10 um).

Both with `--backend` and the case's chunk size as given (the defaults: two worker processes, one
pinned to each core, at the chunk sizes that ran fastest after start-up in
`results/monte_carlo_throughput.md` on this machine, with at least a few chunks per worker) and
seed 0. Wall time
is the whole process (imports, tracing, compilation in the driver and each worker, the run,
writing the results); the warm run uses the cache of the cold one. The load average before each
run is recorded: a figure taken with the load above 1.5 on 2 cores is not a quiet-machine figure.
The warm run must give the same samples as the cold one (bitwise: the same programs, read from
the cache instead of compiled), which the script checks.
"""

import json
import pathlib
import sys
import tempfile

import numpy as np
import xarray as xr

import harness

SCENES = {"lumped": "scan-azimuth", "fast": "scan-azimuth-fast"}


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--cases", nargs="+", default=list(SCENES), choices=list(SCENES))
    parser.add_argument("--lumped-n", type=int, default=1000)
    parser.add_argument("--fast-n", type=int, default=200)
    parser.add_argument("--backend", default="processes", choices=("vmap", "processes"))
    parser.add_argument("--lumped-chunk", type=int, default=32)
    parser.add_argument("--fast-chunk", type=int, default=8)
    args = harness.parse_args(parser)
    rows = []
    with tempfile.TemporaryDirectory(prefix="tolerax-scale-") as tmp:
        for case in args.cases:
            n = args.lumped_n if case == "lumped" else args.fast_n
            chunk = args.lumped_chunk if case == "lumped" else args.fast_chunk
            argv = ["montecarlo", SCENES[case], "--n", str(n), "--backend", args.backend, "--chunk", str(chunk)]
            cache = pathlib.Path(tmp) / f"cache-{case}"
            times, loads, samples = [], [], []
            for label in ("cold", "warm"):
                out = pathlib.Path(tmp) / f"{case}-{label}"
                load = harness.load()
                wall = harness.cli(argv, out, cache, quiet_stderr=False)
                times.append(wall)
                loads.append(load)
                ds = xr.load_dataset(out / "montecarlo.nc")
                samples.append(ds)
                print(case, label, f"{wall:.1f} s", f"load {load}", flush=True)
            same = all(np.array_equal(samples[0][v].values, samples[1][v].values) for v in samples[0].data_vars)
            if not same:
                print(f"{case}: the warm run's samples differ from the cold run's", file=sys.stderr)
            summary = json.loads((pathlib.Path(tmp) / f"{case}-warm" / "summary.json").read_text())["pointing_rms"]
            failed = int(summary["n_failed"])
            rows.append((
                case, "`tolerax " + " ".join(argv) + "`", str(n), f"{times[0]:.1f} ({times[0] / 60:.2f} min)",
                f"{times[1]:.1f} ({times[1] / 60:.2f} min)", f"{n / times[0]:.2f}", f"{n / times[1]:.2f}",
                f"{loads[0]} / {loads[1]}", f"{summary['mean']:.1f} +- {summary['std']:.1f}", str(failed),
                "bitwise" if same else "DIFFER",
            ))
    harness.write_table(
        "monte_carlo_scale", "Monte Carlo at scale from the command line, cold and warm", harness.command(args),
        ["case", "command", "units", "cold wall (s)", "warm wall (s)", "units/s cold", "units/s warm",
         "load before cold / warm", "RMS pointing (arcsec), mean +- std", "failed solves", "warm vs cold samples"], rows,
        about="Each command in a fresh process: cold with an empty compilation cache, warm with the cache the cold run "
              "wrote. Whole-process wall time (imports, tracing, compiling in the driver and every worker, the run, "
              "writing results).",
    )
    if any(r[-1] != "bitwise" for r in rows):
        sys.exit(1)


if __name__ == "__main__":
    main()
