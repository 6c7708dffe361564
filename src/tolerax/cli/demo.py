"""`tolerax demo`: the dual-axis antenna's pointing error over time and a short tolerance proposal, or the
default joint on its test bench (`--bench`)."""

import json
import math
import pathlib
import sys
import time

from .._files import atomic_write, save_figure
from .common import DEFAULT_SCENE, check_out, claim_out, command_line, load_average


def demo_command(parser, args) -> int:
    check_out(parser, args.out, "demo", force=args.force)
    args.solver = args.solver or "sequential"
    if args.bench:
        return _demo_bench(parser, args)
    given = [f"--{n}" for n in ("rate", "clearance", "backlash") if getattr(args, n) is not None]
    if given:
        parser.error(f"{', '.join(given)} only apply with --bench (the joint on its test bench)")
    import matplotlib.pyplot as plt

    from ..design import propose as _propose
    from ..io import results as R, scenefile as F

    out = pathlib.Path(args.out)
    claim_out(out, "demo", fresh=args.force)
    command = command_line(args)
    load_before = load_average()
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
              f"solver {args.solver} (see `tolerax design` for the options).")
        start = time.perf_counter()
        try:
            from ..design import solvers, spec

            solver = (solvers.Sequential(max_gradients=20 if args.outer is None else args.outer) if args.solver == "sequential"
                      else solvers.AugmentedLagrangian(max_outer=3 if args.outer is None else args.outer, inner_steps=args.steps))
            problem = spec.ToleranceProblem(pointing, args.requirement, spec.MeanPlusKStd(units=args.draws))
            report = _propose.propose_design(problem, solver, progress=True)
        except (ValueError, RuntimeError) as err:  # bad sizes; a failed simulation makes the objective NaN
            print(f"tolerax demo: {err}", file=sys.stderr)
            code = 2 if isinstance(err, ValueError) else 3
        design_wall = time.perf_counter() - start
        lines += ["", f"## 2. Tolerance proposal on `{DEFAULT_SCENE}` (lumped azimuth scan, pitch ideal)", ""]
        if report is not None:
            (out / "design").mkdir(exist_ok=True)
            atomic_write(out / "design" / "design.md", report.table() + "\n")
            for fig, name in ((report.plot(), "design.png"), (report.plot_history(), "design_history.png")):
                save_figure(fig, out / "design" / name, dpi=120)
                plt.close(fig)
            used = int(report.result.history.steps[-1])
            lines += [f"{used} {'gradients' if args.solver == 'sequential' else 'optimiser steps'} over {args.draws} units "
                      f"({args.solver}) in {design_wall:.1f} s of wall time (compilation included). Files: `design/`.", "",
                      report.table()]
        else:
            lines.append(f"Failed after {design_wall:.1f} s (see the message above).")
    fig = _demo_figure(result, scene_file, report)
    save_figure(fig, out / "demo.png", dpi=100)
    plt.close(fig)
    lines += ["", f"Figure: `demo.png`. Machine: {load_before} before, {load_average()} after."]
    atomic_write(out / "demo.md", "\n".join(lines) + "\n")
    print("\n".join(lines))
    return code


def _demo_figure(result, scene_file, report):
    """Pointing error over time (top) and, with a proposal, baseline against proposed tolerance
    zones (bottom)."""
    import matplotlib.pyplot as plt
    import numpy as np

    from ..mechanism.mechanism import Mechanism
    from ..mechanism.outputs import ARCSEC

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
    for k, joint in enumerate(("both joints",) if same else Mechanism.JOINTS):
        ax2.plot(ts, command[:, k], lw=0.7, ls="--", color=f"C{k + 1}", label=f"command, {joint}")
    ax2.set_ylabel("commanded angle (deg)")
    ax2.legend(fontsize=7, loc="upper right")
    ax.grid(alpha=0.3)
    if report is not None:
        report.plot_zones(axes[1, 0], f"Azimuth scan: tolerance zones for {report.outcomes[0].requirement.limit:.0f} arcsec (mean + 1 std of the RMS), "
                                      f"{len(report.result.history.cost)} iterations")
    fig.tight_layout()
    return fig


def _demo_bench(parser, args) -> int:
    import matplotlib.pyplot as plt
    import numpy as np

    from ..mechanism import bench as _bench
    from ..mechanism import drives as _drives
    from ..physics import gears as _gears
    from ..mechanism import scene as _scene

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
    claim_out(out, "demo", fresh=args.force)
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
    save_figure(fig, out / "bench.png", dpi=120)
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
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    print(json.dumps(summary, indent=2))
    print(f"wrote {out / 'bench.png'} and {out / 'summary.json'}")
    return 0
