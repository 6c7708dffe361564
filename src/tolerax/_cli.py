"""Command line of tolerax.

- `tolerax demo`: the default joint on its test bench (plot and summary).
- `tolerax studies`: the reference paper's studies (a JSON table per study).
- `tolerax montecarlo`: pointing-error distribution and yield of the scan scene over
  manufacturing errors (netCDF, summary JSON, histogram; resumable).
- `tolerax design`: a tolerance proposal for the scan scene against a pointing requirement.
- `tolerax run SCENE`: simulate a scene file (a built-in name or a .toml path; docs/scene_files.md):
  netCDF time series, plots and a markdown summary.

Exit codes: 0 done, 2 bad arguments, 3 a simulation or optimisation failed.
"""

import argparse
import json
import math
import pathlib
import shlex
import sys
import time


def _demo(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from . import _bench, _drives, _gears, _scene

    stage = _gears.default_stage(
        sun_clearance=args.clearance * 1e-6,
        carrier_clearance=args.clearance * 1e-6,
        planet_clearance=args.clearance * 1e-6,
        backlash=args.backlash * 1e-6,
    )
    bench = _bench.TestBench(stage, servo=_drives.SpeedServo(math.radians(args.rate)))
    print(
        f"tolerax demo: default joint (ratio {stage.ratio:g}, {stage.n_planets} planets) on its bench, "
        f"{args.rate} deg/s output, clearances {args.clearance} um, backlash {args.backlash} um, "
        f"{args.duration} s simulated."
    )
    start = time.perf_counter()
    result = _scene.simulate(bench, args.duration, n_save=int(round(1000 * args.duration)) + 1, progress=args.progress)
    wall = time.perf_counter() - start
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    angle = np.degrees(np.asarray(result.output_angle))
    force = np.asarray(result.contact_force)
    fig, axes = plt.subplots(3, 1, figsize=(7, 8), sharex=True)
    for k, name in enumerate(result.contact_names):
        axes[0].plot(angle, force[:, k], lw=0.8, label=name)
    axes[0].set_ylabel("radial contact force (N)")
    axes[0].legend(ncol=3, fontsize=8)
    axes[0].set_title("Default joint on the bench: bearing contact forces vs output angle")
    axes[1].plot(angle, np.asarray(result.sun_mesh_force), lw=0.8)
    axes[1].set_ylabel("sun-mesh tooth force (N)")
    axes[2].plot(angle, np.degrees(np.asarray(result.output_angle_error)) * 3600, lw=0.8, label="output angle error")
    axes[2].plot(angle, np.degrees(np.asarray(result.transmission_error)) * 3600, lw=0.8, label="transmission error")
    axes[2].set_ylabel("arcsec")
    axes[2].set_xlabel("output (carrier) angle (deg)")
    axes[2].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(out / "bench.png", dpi=120)
    summary = {
        "simulated_s": args.duration,
        "wall_s_including_compile": round(wall, 2),
        "steps_accepted": int(result.num_steps),
        "steps_rejected": int(result.num_rejected),
        "peak_contact_force_N": {n: float(force[:, k].max()) for k, n in enumerate(result.contact_names)},
        "final_output_angle_error_arcsec": float(np.degrees(result.output_angle_error[-1]) * 3600),
        "final_transmission_error_arcsec": float(np.degrees(result.transmission_error[-1]) * 3600),
        "result": "successful" if result.success else str(result.result),
    }
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    print(f"wrote {out / 'bench.png'} and {out / 'summary.json'}")
    return 0


def _studies(parser, args) -> int:
    from . import _studies as S

    names = args.names or list(S.STUDIES)
    for name in names:
        if name not in S.STUDIES:
            parser.error(f"unknown study {name!r}; choose from {', '.join(S.STUDIES)}")
    if args.size not in S.SIZES:
        parser.error(f"--size must be one of {', '.join(S.SIZES)}, got {args.size!r}")
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in names:
        rows = S.run(name, args.size)
        path = out / f"{name}-{args.size}.json"
        path.write_text(json.dumps(rows, indent=1))
        print(f"wrote {path}")
    return 0


def _scan_objective(args):
    from . import _objectives, _scenes

    fidelity = (args.fidelity, "ideal") if args.mode == "azimuth" else (("ideal", args.fidelity) if args.mode == "pitch" else args.fidelity)
    scene = _scenes.scan(args.mode, fidelity=fidelity)
    return _objectives.PointingObjective(scene, duration=args.duration, settle=args.settle, start="steady", n_save=101)


def _montecarlo(args) -> int:
    import jax
    import matplotlib

    matplotlib.use("Agg")
    from . import _design, _montecarlo as MC
    from ._objectives import UNITS

    pointing = _scan_objective(args)
    tolerances = _design.tolerances_of(pointing.scene, args.band * 1e-6, args.distribution)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    print(f"tolerax montecarlo: {args.n} units of the {args.mode} scan scene, features {', '.join(tolerances.names)} "
          f"at nominal +- {args.band} um ({args.distribution}); checkpoints in {out / 'chunks'} (rerun to resume).")
    res = MC.monte_carlo(pointing, tolerances, args.n, jax.random.key(args.seed), backend=args.backend,
                         chunk_size=args.chunk, out=out / "chunks", units=UNITS,
                         requirement=None if args.requirement is None else {"pointing_rms": args.requirement})
    res.save(out / "montecarlo.nc")
    summary = res.summary()
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    fig = res.plot_histogram("pointing_rms", requirement=args.requirement).figure
    fig.savefig(out / "histogram.png", dpi=120)
    print(res.report())
    print(f"wrote {out / 'montecarlo.nc'}, {out / 'summary.json'} and {out / 'histogram.png'}")
    return 0 if summary["pointing_rms"]["n_failed"] == 0 else 3


def _design_cmd(args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    from . import _propose

    pointing = _scan_objective(args)
    print(f"tolerax design: {args.mode} scan scene, requirement {args.requirement} arcsec (RMS pointing, mean + 1 std "
          f"over {args.draws} units), {args.outer} x {args.inner} optimiser steps.")
    try:
        report = _propose.propose_design(pointing, args.requirement, n_draws=args.draws, max_outer=args.outer,
                                         inner_steps=args.inner)
    except RuntimeError as err:  # a failed simulation makes the objective NaN
        print(f"tolerax design: {err}", file=sys.stderr)
        return 3
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    (out / "design.md").write_text(report.table() + "\n")
    report.plot().savefig(out / "design.png", dpi=120)
    print(report.table())
    print(f"wrote {out / 'design.md'} and {out / 'design.png'}")
    return 0


def _run(parser, args) -> int:
    from . import _scenefile as F

    if args.list:
        for name, title in F.builtin_titles().items():
            print(f"{name:28s} {title}")
        return 0
    if args.scene is None:
        parser.error("run needs a SCENE: a built-in scene name or a .toml file (`tolerax run --list` names the built-in ones)")
    try:
        scene_file = F.load_scene(args.scene)
        run = scene_file.run
        duration = run["duration"] if args.duration is None else args.duration
        settle = run["settle"] if args.settle is None else args.settle
        if args.duration is not None and args.settle is None and settle >= duration:
            parser.error(f"--duration {duration} s is not longer than the scene's run.settle = {settle} s: give --settle too")
        scene_file = scene_file.replace(duration=args.duration, settle=args.settle, n_save=args.n_save, start=args.start)
    except F.SceneFileError as err:
        print(f"tolerax run: {err}", file=sys.stderr)
        return 2
    out = pathlib.Path(args.out if args.out is not None else pathlib.Path("tolerax-out") / scene_file.name)
    print(f"tolerax run: {scene_file.title} ({scene_file.source}); {duration} s simulated; results in {out}/")
    start = time.perf_counter()
    try:
        result = scene_file.simulate(throw=False, progress=args.progress)
    except (ValueError, TypeError) as err:  # values the builders could not see (checked at solve time)
        print(f"tolerax run: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    command = shlex.join(["tolerax", *(sys.argv[1:] if args.argv is None else args.argv)])
    summary = F.write_results(scene_file, result, out, wall_s=wall, command=command)
    print(F._summary_md(summary))
    if not result.success:
        print("tolerax run: " + "\n".join(result.failures()), file=sys.stderr)
        return 3
    return 0


def _positive(text):
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def _non_negative(text):
    value = float(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a non-negative number, got {text!r}")
    return value


def _at_least_two(text):
    value = int(text)
    if value < 2:
        raise argparse.ArgumentTypeError(f"must be an integer >= 2, got {text!r}")
    return value


def _scan_options(parser):
    parser.add_argument("--mode", default="azimuth", choices=("azimuth", "pitch", "dual"), help="which joints scan (default azimuth)")
    parser.add_argument("--fidelity", default="lumped", choices=("lumped", "planetary"), help="fidelity of the scanning joints")
    parser.add_argument("--duration", type=float, default=0.6, help="simulated time per unit, s (default 0.6)")
    parser.add_argument("--settle", type=float, default=0.3, help="start of the pointing window, s (default 0.3)")
    parser.add_argument("--out", default="tolerax-out", help="output folder (default ./tolerax-out)")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="tolerax", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser("demo", help="run the default joint on its test bench, write a plot and a summary")
    demo.add_argument("--duration", type=float, default=2.0, help="simulated time, s (default 2)")
    demo.add_argument("--rate", type=float, default=0.98, help="commanded output rate, deg/s (default 0.98)")
    demo.add_argument("--clearance", type=float, default=100.0, help="every radial clearance, um (default 100)")
    demo.add_argument("--backlash", type=float, default=100.0, help="every mesh backlash, um (default 100)")
    demo.add_argument("--out", default="tolerax-out", help="output folder (default ./tolerax-out)")
    demo.add_argument("--progress", action="store_true", help="show the integrator's progress")
    studies = sub.add_parser("studies", help="run the reference paper's studies, write a JSON table per study")
    studies.add_argument("names", nargs="*", help="studies to run (default: all)")
    studies.add_argument("--size", default="small", help="'small' (seconds) or 'full' (the paper's grids)")
    studies.add_argument("--out", default="tolerax-out", help="output folder (default ./tolerax-out)")
    mc = sub.add_parser("montecarlo", help="pointing-error distribution and yield over manufacturing errors (scan scene)")
    _scan_options(mc)
    mc.add_argument("--n", type=int, default=64, help="manufactured units (default 64)")
    mc.add_argument("--band", type=float, default=10.0, help="tolerance half-width of every feature, um (default 10)")
    mc.add_argument("--distribution", default="uniform", choices=("uniform", "normal"))
    mc.add_argument("--requirement", type=float, default=None, help="pointing requirement for the yield, arcsec RMS")
    mc.add_argument("--backend", default="vmap", choices=("vmap", "processes"))
    mc.add_argument("--chunk", type=int, default=8, help="units per chunk (default 8)")
    mc.add_argument("--seed", type=int, default=0)
    design = sub.add_parser("design", help="propose clearances, backlash and tolerance bands for a pointing requirement (scan scene)")
    _scan_options(design)
    design.add_argument("--requirement", type=float, required=True, help="RMS pointing requirement, arcsec")
    design.add_argument("--draws", type=int, default=4, help="manufactured units in the robust objective (default 4)")
    design.add_argument("--outer", type=int, default=6, help="outer (augmented Lagrangian) iterations (default 6)")
    design.add_argument("--inner", type=int, default=10, help="optimiser steps per outer iteration (default 10)")
    run = sub.add_parser(
        "run", help="simulate a scene file: netCDF time series, plots and a markdown summary",
        description="Simulate a scene file (a built-in scene name or a path to a .toml file; schema in "
        "docs/scene_files.md) and write scene.toml, timeseries.nc, PNG plots, summary.json and summary.md "
        "into the output folder. Exit codes: 0 done, 2 bad input (the message names the key and line), "
        "3 the solver failed (the partial results are still written).",
    )
    run.add_argument("scene", nargs="?", help="built-in scene name (see --list) or path to a .toml scene file")
    run.add_argument("--list", action="store_true", help="list the built-in scenes and exit")
    run.add_argument("--out", default=None, help="output folder (default ./tolerax-out/SCENE_NAME)")
    run.add_argument("--duration", type=_positive, default=None, help="override run.duration, s")
    run.add_argument("--settle", type=_non_negative, default=None, help="override run.settle (start of the pointing window), s")
    run.add_argument("--n-save", type=_at_least_two, default=None, help="override run.n_save (saved times)")
    run.add_argument("--start", choices=("rest", "steady"), default=None, help="override run.start")
    run.add_argument("--progress", action="store_true", help="show the integrator's progress")
    args = parser.parse_args(argv)
    args.argv = argv
    if args.command == "run":
        return _run(run, args)
    if args.command == "studies":
        return _studies(parser, args)
    if args.command in ("montecarlo", "design"):
        if not (math.isfinite(args.duration) and 0 <= args.settle < args.duration):
            parser.error(f"need 0 <= --settle < --duration, got {args.settle} and {args.duration}")
        if args.requirement is not None and not (math.isfinite(args.requirement) and args.requirement > 0):
            parser.error(f"--requirement must be a positive number of arcsec, got {args.requirement}")
        if args.command == "design":
            return _design_cmd(args)
        if args.n < 1 or args.chunk < 1 or not (math.isfinite(args.band) and args.band >= 0):
            parser.error("--n and --chunk must be >= 1 and --band a non-negative number of um")
        return _montecarlo(args)
    for name in ("duration", "clearance", "backlash", "rate"):
        value = getattr(args, name)
        if not math.isfinite(value) or value < 0 or (name == "duration" and value == 0):
            parser.error(f"--{name} must be a finite {'positive' if name == 'duration' else 'non-negative'} number, got {value}")
    if args.command == "demo":
        return _demo(args)
    return 2


if __name__ == "__main__":
    sys.exit(main())
