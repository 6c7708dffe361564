"""Command line of tolerax.

- `tolerax demo`: the paper's dual-axis antenna scanning +-0.5 deg on both axes (built-in scene
  `scan`): its pointing error over time, then a short tolerance proposal on the azimuth scan
  (`--bench`: the default joint on its test bench instead).
- `tolerax run SCENE`: simulate a scene file: netCDF time series, plots and a markdown summary.
- `tolerax design [SCENE]`: propose clearances, backlash and tolerance bands that meet an RMS
  pointing requirement at the lowest cost.
- `tolerax montecarlo [SCENE]`: pointing-error distribution and yield over manufacturing errors
  (netCDF, summary JSON, histogram; resumable).
- `tolerax studies`: the reference paper's studies (a JSON table per study).
- `tolerax bench`: compile time and wall time per simulated second of the antenna at each joint
  fidelity (a markdown table).

SCENE is a built-in scene name (`tolerax run --list`) or a path to a .toml scene file (schema:
docs/scene_files.md); design and montecarlo default to `scan-azimuth`. `tolerax COMMAND --help`
lists a command's options.

Exit codes: 0 done, 2 bad input (a bad option, an unreadable or invalid scene file: the message
names the file, line and key), 3 a simulation or optimisation failed.
"""

import argparse
import copy
import json
import math
import os
import pathlib
import shlex
import sys
import time

DEFAULT_SCENE = "scan-azimuth"


def _command(args) -> str:
    """The command line that reproduces this run."""
    return shlex.join(["tolerax", *(sys.argv[1:] if args.argv is None else args.argv)])


def _load() -> str:
    return "load average (1, 5, 15 min): " + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + f" on {os.cpu_count()} CPUs"


def _scene_file(parser, args, **run):
    """`args.scene` (a built-in name or a .toml path) with `--duration`/`--settle` and `run`
    overriding its `[run]` keys; `None` when the file cannot be read or is invalid (the message,
    naming the file, line, table and key, is printed)."""
    from .io import scenefile as F

    try:
        scene_file = F.load_scene(args.scene)
        duration = scene_file.run["duration"] if args.duration is None else args.duration
        settle = scene_file.run["settle"] if args.settle is None else args.settle
        if args.duration is not None and args.settle is None and settle >= duration:
            parser.error(f"--duration {duration} s is not longer than the scene's run.settle = {settle} s: give --settle too")
        return scene_file.replace(duration=args.duration, settle=args.settle, **run)
    except F.SceneFileError as err:
        print(f"tolerax {args.command}: {err}", file=sys.stderr)
        return None


def _with_tolerances(scene_file, band_um=None, distribution=None):
    """`scene_file` with `[tolerances] band` (given in um; replaces the per-feature `bands` too)
    and `distribution` overridden where given."""
    from .io import scenefile as F

    if band_um is None and distribution is None:
        return scene_file
    data = copy.deepcopy(scene_file.data)
    tol = data.setdefault("tolerances", {})
    if band_um is not None:
        tol["band"] = band_um * 1e-6
        tol.pop("bands", None)
    if distribution is not None:
        tol["distribution"] = distribution
    return F.SceneFile.from_data(data, scene_file.name, scene_file.source)


def _has_features(scene_file, command) -> bool:
    from .design.features import design_names

    if design_names(scene_file.build()):
        return True
    print(f"tolerax {command}: scene {scene_file.name!r} models no clearance or backlash (ideal joints only): "
          "nothing to tolerance.", file=sys.stderr)
    return False


# ---------------------------------------------------------------------------------------------
# demo


def _demo(parser, args) -> int:
    if args.bench:
        return _demo_bench(parser, args)
    given = [f"--{n}" for n in ("rate", "clearance", "backlash") if getattr(args, n) is not None]
    if given:
        parser.error(f"{', '.join(given)} only apply with --bench (the joint on its test bench)")
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .design import propose as _propose
    from .io import results as R, scenefile as F

    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    command = _command(args)
    load_before = _load()
    # The scan scene's window starts after the first 0.3 s; a shorter demo summarises all of it.
    duration = 1.0 if args.duration is None else args.duration
    scene_file = F.load_scene("scan")
    scene_file = scene_file.replace(duration=duration, settle=0.0 if duration <= scene_file.run["settle"] else None)
    print(f"tolerax demo: {scene_file.title}; {duration} s simulated; results in {out}/")
    start = time.perf_counter()
    result = scene_file.simulate(throw=False, progress=args.progress)
    sim_wall = time.perf_counter() - start
    summary = R.write_results(scene_file, result, out / "scan", wall_s=sim_wall, command=command)
    metrics = summary["metrics"]
    lines = [
        "# tolerax demo", "", "```", command, "```", "",
        f"## 1. {scene_file.title}", "",
        f"{duration} s simulated in {sim_wall:.1f} s of wall time (compilation included); solver: {summary['result']}.",
    ]
    if metrics:
        lines.append(f"Over {metrics['window_s'][0]:.3g}-{metrics['window_s'][1]:.3g} s: RMS pointing error "
                     f"{metrics['pointing_rms_arcsec']:.1f} arcsec, peak {metrics['pointing_peak_arcsec']:.1f} arcsec.")
    lines.append("Files: `scan/` (timeseries.nc, plots, summary.md).")
    report = design_wall = None
    code = 0 if result.success else 3
    if not result.success:
        print("tolerax demo: " + "\n".join(result.failures()), file=sys.stderr)
    elif args.steps > 0:
        pointing = F.load_scene(DEFAULT_SCENE).objective()
        print(f"tolerax demo: tolerance proposal on {DEFAULT_SCENE} ({pointing.duration} s per unit): requirement "
              f"{args.requirement} arcsec on mean + 1 std of the RMS pointing error over {args.draws} units, "
              f"{args.outer} x {args.steps} optimiser steps (a short run: see `tolerax design` for a full one).")
        start = time.perf_counter()
        try:
            report = _propose.propose_design(pointing, args.requirement, n_draws=args.draws, max_outer=args.outer,
                                             inner_steps=args.steps, progress=True)
        except (ValueError, RuntimeError) as err:  # bad sizes; a failed simulation makes the objective NaN
            print(f"tolerax demo: {err}", file=sys.stderr)
            code = 2 if isinstance(err, ValueError) else 3
        design_wall = time.perf_counter() - start
        lines += ["", f"## 2. Tolerance proposal on `{DEFAULT_SCENE}` (lumped azimuth scan, pitch ideal)", ""]
        if report is not None:
            (out / "design").mkdir(exist_ok=True)
            (out / "design" / "design.md").write_text(report.table() + "\n")
            fig = report.plot()
            fig.savefig(out / "design" / "design.png", dpi=120)
            plt.close(fig)
            lines += [f"{args.outer} x {args.steps} optimiser steps over {args.draws} units in {design_wall:.1f} s of wall "
                      "time (compilation included). Files: `design/`.", "", report.table()]
        else:
            lines.append(f"Failed after {design_wall:.1f} s (see the message above).")
    fig = _demo_figure(result, scene_file, report)
    fig.savefig(out / "demo.png", dpi=100)
    plt.close(fig)
    lines += ["", f"Figure: `demo.png`. Machine: {load_before} before, {_load()} after."]
    (out / "demo.md").write_text("\n".join(lines) + "\n")
    print("\n".join(lines))
    return code


def _demo_figure(result, scene_file, report):
    """Pointing error over time (top) and, with a proposal, baseline against proposed tolerance
    zones (bottom)."""
    import matplotlib.pyplot as plt
    import numpy as np

    from .mechanism.outputs import ARCSEC

    rows = 2 if report is not None else 1
    fig, axes = plt.subplots(rows, 1, figsize=(7, 2.9 * rows + 0.4), squeeze=False)
    ax = axes[0, 0]
    ts = np.asarray(result.ts)
    ax.plot(ts, np.asarray(result.pointing_error) / ARCSEC, lw=1.0, color="C0", label="pointing error")
    settle = scene_file.run["settle"]
    if settle > 0:
        ax.axvline(settle, color="0.6", lw=0.8, ls=":", label="window start")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("pointing error (arcsec)")
    ax.set_title("Dual-axis antenna, both joints scanning ±0.5° at 1 Hz (lumped joints, 100 µm)", fontsize=9)
    ax.legend(fontsize=7, loc="upper left")
    ax2 = ax.twinx()
    command = np.degrees(np.asarray(result.commanded_angle))
    same = np.allclose(command[:, 0], command[:, 1])
    for k, joint in enumerate(("both joints",) if same else ("azimuth", "pitch")):
        ax2.plot(ts, command[:, k], lw=0.7, ls="--", color=f"C{k + 1}", label=f"command, {joint}")
    ax2.set_ylabel("commanded angle (deg)")
    ax2.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3)
    if report is not None:
        ax = axes[1, 0]
        y = np.arange(len(report.names))
        base_nominal, base_band = report.baseline[0], report.baseline[1]
        ax.barh(y + 0.2, 2e6 * base_band, left=1e6 * (base_nominal - base_band), height=0.35, color="0.7",
                label=f"baseline: cost {report.baseline[2]:.3g}, {report.baseline[3]:.0f} arcsec")
        ax.barh(y - 0.2, 2e6 * report.band, left=1e6 * (report.nominal - report.band), height=0.35, color="C0",
                label=f"proposal: cost {report.cost:.3g}, {report.objective:.0f} arcsec")
        ax.set_xlim(0, 1e6 * max(np.max(report.nominal + report.band), np.max(base_nominal + base_band)) * 1.05)
        ax.set_yticks(y, [n.replace("azimuth.", "") for n in report.names], fontsize=8)
        ax.set_xlabel("tolerance zone (µm)")
        ax.set_title(f"Azimuth scan: tolerance zones for {report.requirement:.0f} arcsec (mean + 1 std of the RMS), "
                     f"{len(report.result.history.cost)} outer iterations", fontsize=9)
        ax.legend(fontsize=7, loc="lower left")
        ax.grid(alpha=0.3, axis="x")
    fig.tight_layout()
    return fig


def _demo_bench(parser, args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from .mechanism import bench as _bench
    from .mechanism import drives as _drives
    from .physics import gears as _gears
    from .mechanism import scene as _scene

    rate = 0.98 if args.rate is None else args.rate
    clearance = 100.0 if args.clearance is None else args.clearance
    backlash = 100.0 if args.backlash is None else args.backlash
    duration = 2.0 if args.duration is None else args.duration
    for name, value in (("rate", rate), ("clearance", clearance), ("backlash", backlash)):
        if not (math.isfinite(value) and value >= 0):
            parser.error(f"--{name} must be a finite non-negative number, got {value}")
    stage = _gears.default_stage(
        sun_clearance=clearance * 1e-6,
        carrier_clearance=clearance * 1e-6,
        planet_clearance=clearance * 1e-6,
        backlash=backlash * 1e-6,
    )
    bench = _bench.TestBench(stage, servo=_drives.SpeedServo(math.radians(rate)))
    print(
        f"tolerax demo --bench: default joint (ratio {stage.ratio:g}, {stage.n_planets} planets) on its bench, "
        f"{rate} deg/s output, clearances {clearance} um, backlash {backlash} um, {duration} s simulated."
    )
    start = time.perf_counter()
    result = _scene.simulate(bench, duration, n_save=int(round(1000 * duration)) + 1, progress=args.progress)
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
    plt.close(fig)
    summary = {
        "simulated_s": duration,
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
    from . import studies as S

    names = args.names or list(S.STUDIES)
    for name in names:
        if name not in S.STUDIES:
            parser.error(f"unknown study {name!r}; choose from {', '.join(S.STUDIES)}")
    if args.size not in S.SIZES:
        parser.error(f"--size must be one of {', '.join(S.SIZES)}, got {args.size!r}")
    try:
        S.size_spec(args.size, args.duration, args.settle)
    except ValueError as err:
        parser.error(str(err))
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in names:
        path = out / f"{name}-{args.size}.json"
        done = json.loads(path.read_text()) if args.resume and path.exists() else []

        def save(rows, path=path, done=done):
            # Every row so far, and the earlier run's rows this run has not reached yet, so an
            # interrupted run loses only the scene it was on.
            later = [r for r in done if not any(r is k for k in rows)]
            tmp = path.with_suffix(".json.tmp")
            tmp.write_text(json.dumps(rows + later, indent=1))
            tmp.replace(path)

        rows = S.run(name, args.size, duration=args.duration, settle=args.settle, done=done, on_row=save)
        save(rows, done=[])
        print(f"wrote {path}")
    return 0


def _montecarlo(parser, args) -> int:
    import jax
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .uncertainty import montecarlo as MC
    from .io import scenefile as F
    from .design.objectives import UNITS

    scene_file = _scene_file(parser, args)
    if scene_file is None:
        return 2
    scene_file = _with_tolerances(scene_file, args.band, args.distribution)
    if not _has_features(scene_file, "montecarlo"):
        return 2
    requirement = args.requirement if args.requirement is not None else scene_file.requirement
    pointing = scene_file.objective()
    tolerances = scene_file.tolerances(pointing.scene)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    bands = ", ".join(f"{n} +-{b * 1e6:.3g}" for n, b in zip(tolerances.names, tolerances.band.tolist()))
    print(f"tolerax montecarlo: {args.n} units of {scene_file.name} ({scene_file.source}), {pointing.duration} s each, "
          f"window from {pointing.settle} s; features at nominal {bands} um ({tolerances.distribution}); "
          f"checkpoints in {out / 'chunks'} (rerun to resume).")
    try:
        res = MC.monte_carlo(pointing, tolerances, args.n, jax.random.key(args.seed), backend=args.backend,
                             chunk_size=args.chunk, out=out / "chunks", units=UNITS,
                             requirement=None if requirement is None else {"pointing_rms": requirement})
    except ValueError as err:  # e.g. checkpoints of other settings in the output folder
        print(f"tolerax montecarlo: {err}", file=sys.stderr)
        return 2
    F.save_scene(scene_file, out / "scene.toml")  # after the checkpoints were accepted as this run's
    res.save(out / "montecarlo.nc")
    summary = res.summary()
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    fig = res.plot_histogram("pointing_rms", requirement=requirement).figure
    fig.savefig(out / "histogram.png", dpi=120)
    plt.close(fig)
    print(res.report())
    print(f"wrote {out / 'scene.toml'}, {out / 'montecarlo.nc'}, {out / 'summary.json'} and {out / 'histogram.png'}")
    return 0 if summary["pointing_rms"]["n_failed"] == 0 else 3


def _design_cmd(parser, args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from .design import propose as _propose
    from .io import scenefile as F

    scene_file = _scene_file(parser, args)
    if scene_file is None:
        return 2
    requirement = args.requirement if args.requirement is not None else scene_file.requirement
    if requirement is None:
        parser.error(f"scene {scene_file.name!r} sets no [tolerances] requirement: give --requirement (arcsec, RMS pointing)")
    if not _has_features(scene_file, "design"):
        return 2
    tol = scene_file.data.get("tolerances", {})
    band = tol.get("band", F.TOLERANCE_KEYS["band"][1])
    if tol.get("bands"):
        print(f"tolerax design: the optimiser starts every feature at the scene's band +-{band * 1e6:g} um; "
              "the per-feature [tolerances.bands] are not used.")
    pointing = scene_file.objective()
    print(f"tolerax design: {scene_file.name} ({scene_file.source}), {pointing.duration} s per unit, window from "
          f"{pointing.settle} s; requirement {requirement} arcsec (RMS pointing, mean + 1 std over {args.draws} units "
          f"drawn uniformly within the bands), {args.outer} x {args.inner} optimiser steps.")
    start = time.perf_counter()
    try:
        report = _propose.propose_design(pointing, requirement, band=band, n_draws=args.draws, max_outer=args.outer,
                                         inner_steps=args.inner, progress=True)
    except ValueError as err:  # e.g. a starting band outside the optimiser's range
        print(f"tolerax design: {err}", file=sys.stderr)
        return 2
    except RuntimeError as err:  # a failed simulation makes the objective NaN
        print(f"tolerax design: {err}", file=sys.stderr)
        return 3
    wall = time.perf_counter() - start
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    F.save_scene(scene_file, out / "scene.toml")
    text = "\n".join([report.table(), "", f"{wall:.1f} s of wall time (compilation included); {_load()}.", "",
                      "Reproduce with:", "", "```", _command(args), "```"])
    (out / "design.md").write_text(text + "\n")
    fig = report.plot()
    fig.savefig(out / "design.png", dpi=120)
    plt.close(fig)
    print(text)
    print(f"wrote {out / 'scene.toml'}, {out / 'design.md'} and {out / 'design.png'}")
    return 0


def _run(parser, args) -> int:
    from .io import results as R, scenefile as F

    if args.list:
        for name, title in F.builtin_titles().items():
            print(f"{name:28s} {title}")
        return 0
    if args.scene is None:
        parser.error("run needs a SCENE: a built-in scene name or a .toml file (`tolerax run --list` names the built-in ones)")
    scene_file = _scene_file(parser, args, n_save=args.n_save, start=args.start)
    if scene_file is None:
        return 2
    out = pathlib.Path(args.out if args.out is not None else pathlib.Path("tolerax-out") / scene_file.name)
    print(f"tolerax run: {scene_file.title} ({scene_file.source}); {scene_file.run['duration']} s simulated; results in {out}/")
    start = time.perf_counter()
    try:
        result = scene_file.simulate(throw=False, progress=args.progress)
    except (ValueError, TypeError) as err:  # values the builders could not see (checked at solve time)
        print(f"tolerax run: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    summary = R.write_results(scene_file, result, out, wall_s=wall, command=_command(args))
    print(R.summary_md(summary))
    if not result.success:
        print("tolerax run: " + "\n".join(result.failures()), file=sys.stderr)
        return 3
    return 0


def _bench_cmd(parser, args) -> int:
    from . import __version__
    from . import timing as _timing
    from .mechanism import FIDELITIES

    fidelities = args.fidelities or list(FIDELITIES)
    for fid in fidelities:
        if fid not in FIDELITIES:
            parser.error(f"unknown fidelity {fid!r}; choose from {', '.join(FIDELITIES)}")
    import jax

    out = pathlib.Path(args.out)
    load_before = _load()
    rows = []
    for fid in fidelities:
        print(f"tolerax bench: {fid} joints, {args.duration} s simulated, solved twice ...", flush=True)
        rows.append(_timing.fidelity_cost(fid, args.duration))
    columns, cells = _timing.cost_table(rows)
    lines = [
        "# Dual-axis antenna: cost per joint fidelity", "",
        f"`{_command(args)}` (tolerax {__version__}, jax {jax.__version__}, {jax.default_backend()}). "
        f"{args.duration} s simulated per fidelity from a steady start, 0.98 deg/s on both joints, free base; each "
        "scene solved twice: run time = the second solve, compile time = the first minus the second.", "",
        "| " + " | ".join(columns) + " |", "|" + "---|" * len(columns),
        *("| " + " | ".join(row) + " |" for row in cells), "",
        f"Machine: {load_before} before, {_load()} after. Read the ratios within this table; absolute times depend "
        "on the machine and on what else runs on it. A short horizon understates the cost of joints with "
        "clearances: the impacts that set their step size may not have started yet (compare --duration 0.5 and "
        "benchmarks/results/mechanism_cost.md).",
    ]
    text = "\n".join(lines) + "\n"
    out.mkdir(parents=True, exist_ok=True)
    (out / "bench.md").write_text(text)
    (out / "bench.json").write_text(json.dumps({"command": _command(args), "duration_s": args.duration, "rows": rows,
                                                "load_before": load_before, "load_after": _load()}, indent=2))
    print(text)
    print(f"wrote {out / 'bench.md'} and {out / 'bench.json'}")
    return 0


# ---------------------------------------------------------------------------------------------
# Arguments


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


def _count(minimum):
    def count(text):
        value = int(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {text!r}")
        return value

    count.__name__ = f"integer >= {minimum}"  # argparse names it in "invalid ... value"
    return count


def _scene_options(parser, what):
    parser.add_argument("scene", nargs="?", default=DEFAULT_SCENE,
                        help=f"built-in scene name (`tolerax run --list`) or path to a .toml scene file (default {DEFAULT_SCENE}); "
                        f"its [run] settings set the {what} horizon and window, its [tolerances] the bands and requirement")
    parser.add_argument("--duration", type=_positive, default=None, help="override run.duration (simulated time per unit), s")
    parser.add_argument("--settle", type=_non_negative, default=None, help="override run.settle (start of the pointing window), s")
    parser.add_argument("--out", default="tolerax-out", help="output folder (default ./tolerax-out)")


EPILOG = "Exit codes: 0 done, 2 bad input (the message names the scene file's key and line), 3 a simulation failed."


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="tolerax", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo", help="the dual-axis antenna: pointing error over time and a short tolerance proposal",
        description="Simulate the built-in scene `scan` (the paper's dual-axis antenna, both joints scanning +-0.5 deg "
        "at 1 Hz, lumped joints with 100 um clearances and backlash) and plot its pointing error over time; then "
        f"propose tolerances for `{DEFAULT_SCENE}` with a few optimiser steps. Writes demo.png, demo.md, scan/ (as "
        "`tolerax run`) and design/ into the output folder. --bench runs the default joint on its test bench instead.",
        epilog=EPILOG,
    )
    demo.add_argument("--duration", type=_positive, default=None,
                      help="simulated time, s (default 1, one scan period; with --bench 2); the pointing window starts at 0.3 s "
                      "when the run is longer")
    demo.add_argument("--steps", type=_count(0), default=6,
                      help="optimiser steps per outer iteration of the proposal (default 6; 0 skips the proposal)")
    demo.add_argument("--outer", type=_count(1), default=3, help="outer (augmented Lagrangian) iterations (default 3)")
    demo.add_argument("--draws", type=_count(2), default=2,
                      help="manufactured units in the robust objective, mean + 1 std (default 2, at least 2)")
    demo.add_argument("--requirement", type=_positive, default=700.0,
                      help="RMS pointing requirement of the proposal, arcsec (default 700)")
    demo.add_argument("--bench", action="store_true", help="run the default joint on its test bench instead (bench.png, summary.json)")
    demo.add_argument("--rate", type=float, default=None, help="with --bench: commanded output rate, deg/s (default 0.98)")
    demo.add_argument("--clearance", type=float, default=None, help="with --bench: every radial clearance, um (default 100)")
    demo.add_argument("--backlash", type=float, default=None, help="with --bench: every mesh backlash, um (default 100)")
    demo.add_argument("--out", default="tolerax-out", help="output folder (default ./tolerax-out)")
    demo.add_argument("--progress", action="store_true", help="show the integrator's progress")
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
    run.add_argument("--n-save", type=_count(2), default=None, help="override run.n_save (saved times)")
    run.add_argument("--start", choices=("rest", "steady", "loaded"), default=None, help="override run.start")
    run.add_argument("--progress", action="store_true", help="show the integrator's progress")
    design = sub.add_parser(
        "design", help="propose clearances, backlash and tolerance bands for a pointing requirement",
        description="Propose, for each clearance and backlash of the scene, the tolerance zone (lower limit and "
        "half-width) of lowest cost (ISO 286 grades) whose mean + 1 std of the RMS pointing error over a few "
        "manufactured units meets the requirement (tolerax.propose_design). Starts from the scene's design and "
        "its [tolerances] band. Writes scene.toml, design.md and design.png.",
        epilog=EPILOG,
    )
    _scene_options(design, "design")
    design.add_argument("--requirement", type=_positive, default=None,
                        help="RMS pointing requirement, arcsec (default: the scene's [tolerances] requirement)")
    design.add_argument("--draws", type=_count(2), default=4,
                        help="manufactured units in the robust objective, mean + 1 std (default 4, at least 2)")
    design.add_argument("--outer", type=_count(1), default=6, help="outer (augmented Lagrangian) iterations (default 6)")
    design.add_argument("--inner", type=_count(1), default=10, help="optimiser steps per outer iteration (default 10)")
    mc = sub.add_parser(
        "montecarlo", help="pointing-error distribution and yield over manufacturing errors",
        description="Simulate manufactured units of the scene, each clearance and backlash drawn within its "
        "[tolerances] band, and write their pointing statistics (montecarlo.nc), a summary (summary.json, with "
        "the yield when a requirement is known) and a histogram. Chunks are checkpointed under OUT/chunks: "
        "rerun the same command to resume.",
        epilog=EPILOG,
    )
    _scene_options(mc, "per-unit")
    mc.add_argument("--n", type=_count(1), default=64, help="manufactured units (default 64)")
    mc.add_argument("--band", type=_non_negative, default=None,
                    help="override the tolerance half-width of every feature, um (default: the scene's [tolerances])")
    mc.add_argument("--distribution", default=None, choices=("uniform", "normal"), help="override [tolerances] distribution")
    mc.add_argument("--requirement", type=_positive, default=None,
                    help="RMS pointing requirement for the yield, arcsec (default: the scene's [tolerances] requirement)")
    mc.add_argument("--backend", default="vmap", choices=("vmap", "processes"))
    mc.add_argument("--chunk", type=_count(1), default=8, help="units per chunk (default 8)")
    mc.add_argument("--seed", type=int, default=0)
    studies = sub.add_parser("studies", help="run the reference paper's studies, write a JSON table per study")
    studies.add_argument("names", nargs="*", help="studies to run (default: all)")
    studies.add_argument("--size", default="small", help="'small' (seconds) or 'full' (the paper's grids)")
    studies.add_argument("--out", default="tolerax-out", help="output folder (default ./tolerax-out)")
    studies.add_argument("--duration", type=_positive, default=None,
                         help="simulated time per scene, s (default: the size's, full 3 s)")
    studies.add_argument("--settle", type=float, default=None,
                         help="metrics from this time on, s (default: the size's, full 2 s)")
    studies.add_argument("--resume", action="store_true",
                         help="keep the rows of STUDY-SIZE.json in --out whose scene and horizon match; run the rest")
    bench = sub.add_parser(
        "bench", help="compile time and wall time per simulated second of the antenna per joint fidelity",
        description="Time the dual-axis antenna (0.98 deg/s on both joints, 100 um clearances and backlash, free "
        "base, steady start) at each joint fidelity: each scene is solved twice, the second solve gives the wall "
        "time per simulated second, the first minus the second the compile time. Prints a markdown table and "
        "writes bench.md and bench.json into the output folder. Ratios between rows are what to read; a short "
        "horizon understates the cost of the joints with clearances (their impacts may not have started).",
    )
    bench.add_argument("--duration", type=_positive, default=0.1, help="simulated time per fidelity, s (default 0.1)")
    bench.add_argument("--fidelities", nargs="+", default=None, metavar="FIDELITY",
                       help="joint fidelities to time (default: all of tolerax.FIDELITIES: ideal lumped planetary planetary-scaled)")
    bench.add_argument("--out", default="tolerax-out", help="output folder (default ./tolerax-out)")
    args = parser.parse_args(argv)
    args.argv = argv
    commands = {
        "demo": (demo, _demo), "run": (run, _run), "design": (design, _design_cmd), "montecarlo": (mc, _montecarlo),
        "studies": (parser, _studies), "bench": (bench, _bench_cmd),
    }
    command_parser, command = commands[args.command]
    return command(command_parser, args)


if __name__ == "__main__":
    sys.exit(main())
