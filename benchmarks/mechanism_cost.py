"""Compile time and wall time per simulated second of the dual-axis antenna scene at each joint
fidelity (free base, 0.98 deg/s on both joints, 100 um clearances and backlash, steady start,
Tsit5 rtol 1e-6 atol 1e-9).

    python benchmarks/mechanism_cost.py [--duration 0.5] [--fidelities ideal lumped planetary]
        [--scalings 100] [--rtols 1e-5] [--pid 0.3 0.3] [--repeats 3] [--results DIR]

`--scalings` adds a `planetary-scaled` row at each given `mass_scaling` (the fidelity's own row
uses its default, 10), and `--rtols` one more per scaling at each looser relative tolerance, with
atol 1e-3 rtol (the mass-scaled stage's steps are limited by accuracy more than by stability,
archive/fast_modes_scaled.md; what the looser tolerances cost in each output: mass_scaling_rtol.md),
and `--pid` each of those once more with a PI step-size controller;
a note gives each row's pointing RMS against the full planetary row of the same run. The load average before each scene is recorded: absolute wall times mean
something only on an otherwise idle machine (on this 2-core VM a second busy process slowed a
planetary run about 2.5x), and even alone the same solve varies up to ~2.7x from run to run
(host noise), so `--repeats` reports the fastest of several runs. Ratios within one run and step
counts are the robust figures.

Writes `benchmarks/results/mechanism_cost.md` (`--results DIR`: DIR/mechanism_cost.md); the
measurement is `harness.fidelity_cost`. Each scene is solved 1 + `--repeats` times: the first
call's time minus the fastest later one is the compile time; the fastest later one is the run time,
and the median of the later ones is reported beside it (same machine, same run, so the ratios
between fidelities are what to read).
"""

import os

import tolerax

import harness
from harness import cost_table, fidelity_cost


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--duration", type=float, default=0.5, help="simulated seconds per scene")
    parser.add_argument("--fidelities", nargs="+", choices=list(tolerax.FIDELITIES), default=list(tolerax.FIDELITIES))
    parser.add_argument("--scalings", nargs="*", type=float, default=[], help="extra planetary-scaled rows at these mass scalings")
    parser.add_argument("--rtols", nargs="*", type=float, default=[], help="extra planetary-scaled rows per scaling at these rtols")
    parser.add_argument("--pid", nargs=2, type=float, metavar=("PCOEFF", "ICOEFF"), help="each --rtols row again with this step-size controller")
    parser.add_argument("--repeats", type=int, default=1, help="timed runs per scene after the compiling one; the fastest is reported")
    args = harness.parse_args(parser)
    if args.pid and not (args.scalings and args.rtols):
        parser.error("--pid repeats the --rtols rows of each --scalings value: give both")
    rows, loads = [], []
    jobs = [(fid, {}) for fid in args.fidelities]
    jobs += [("planetary-scaled", dict(mass_scaling=s, label=f"planetary-scaled, s = {s:g}")) for s in args.scalings]
    controllers = [((0.0, 1.0), "")] + ([(tuple(args.pid), ", PI ({:g}, {:g})".format(*args.pid))] if args.pid else [])
    jobs += [
        (
            "planetary-scaled",
            dict(mass_scaling=s, rtol=r, atol=1e-3 * r, pid=pid, label=f"planetary-scaled, s = {s:g}, rtol {r:g}{suffix}"),
        )
        for pid, suffix in controllers
        for s in args.scalings
        for r in args.rtols
    ]
    for fid, options in jobs:
        loads.append(os.getloadavg()[0])
        rows.append(fidelity_cost(fid, args.duration, repeats=args.repeats, **options))
        print(rows[-1], flush=True)
    loads.append(os.getloadavg()[0])
    columns, cells = cost_table(rows)
    notes = []
    full = [r for r in rows if r["fidelity"] == "planetary"]
    if full:
        ref = full[0]["pointing_rms_arcsec"]
        notes.append(
            "Pointing RMS against the planetary row (Tsit5 rtol 1e-6; itself within 0.011 % of an rtol 1e-8 run over "
            "1-5 s, archive/long_horizon.md): "
            + "; ".join(f"{r['fidelity']} {100 * (r['pointing_rms_arcsec'] / ref - 1):+.2f} %" for r in rows if r is not full[0])
            + "."
        )
    harness.write_table(
        "mechanism_cost",
        "Dual-axis mechanism: cost per fidelity",
        harness.command(args),
        columns,
        cells,
        about=f"{args.duration} s simulated per scene, steady start, 0.98 deg/s both joints. Load average (1 min) "
        f"before each scene and after the last: {', '.join(f'{x:.2f}' for x in loads)} ({os.cpu_count()} cores).",
        notes=notes,
    )


if __name__ == "__main__":
    main()
