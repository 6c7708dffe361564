"""The mass-scaled planetary joint against the full one (issue 14): cost, and the error of every
output a pointing study reads, over a long horizon.

    python benchmarks/mass_scaling.py [--duration 5.0] [--scalings 10 100 1000] [--rtols 1e-6] [--control-rtol 1e-7] [--window-start 1.0] [--output mass_scaling]
    python benchmarks/mass_scaling.py --render   # rewrite the .md from the saved .json

Writes `benchmarks/results/mass_scaling.{md,json,png}` (`--output`: another stem; `--results DIR`:
in DIR).

Scene: `tolerax.antenna("dual", fidelity=...)` (the `mechanism_cost.py`
scene: free base, 0.98 deg/s on both joints, 100 um clearances and backlash), steady start,
`simulate`'s defaults (Tsit5, rtol 1e-6, atol 1e-9), saved at 2 kHz. Runs, in one process: the
full stage (`PlanetaryJoint`), the control (below), then `MassScaledPlanetaryJoint` at each `--scalings` $s$ (the
fictitious inertia on the sun's and planets' motion relative to the rigid train, $s$ times their
own; see its docstring), each at every `--rtols` (atol 1e-3 rtol). Each is first solved over 10 ms (the same compiled program: that call's time is
reported as compilation), then over the horizon, timed (the scaled runs share one program, only
`mass_scaling` changes).

Outputs, over the window from `--window-start` s (the rattle developed) to the end, each with its
error relative to the full stage's:
- pointing error RMS and peak (arcsec), and its vibration amplitude (`vibration_amplitude`:
  the largest line of its detrended spectrum above 1 Hz);
- tracking speed error RMS (norm of the reflector's angular-velocity error, rad/s);
- bearing contact force per contact family (sun, carrier, planet pins; both joints): time mean
  and peak (N).

**Control: what is chaos, not model.** The rattle is chaotic: any perturbation (a tolerance, a
rounding) changes its trajectory, and outputs that depend on the trajectory's details (impact
peaks, the spectrum's largest line) differ between two equally valid runs of the *same* model.
So the full stage is also run at `--control-rtol` (atol scaled by the same factor), and its
difference to the full stage at rtol 1e-6 is the floor below which a difference says nothing
about the model: a scaled run's difference means something only where it clearly exceeds the
control's.
"""

import json
import os

import jax.numpy as jnp
import numpy as np

import tolerax

import harness

FAMILIES = ("sun", "carrier", "planet")


def scene(scaling):
    if scaling is None:
        return tolerax.antenna("dual", fidelity="planetary")
    return tolerax.antenna("dual", fidelity="planetary-scaled", mass_scaling=float(scaling))


def outputs(res, window_start):
    ts = np.asarray(res.ts)
    w = ts >= window_start
    pe = np.asarray(res.pointing_error)[w] / tolerax.ARCSEC
    speed = np.linalg.norm(np.asarray(res.tracking_speed_error), axis=-1)[w]
    out = {
        "pointing RMS (arcsec)": float(np.sqrt(np.mean(pe**2))),
        "pointing peak (arcsec)": float(np.abs(pe).max()),
        "pointing vibration (arcsec)": float(tolerax.vibration_amplitude(jnp.asarray(pe), jnp.asarray(ts[w]))),
        "speed error RMS (rad/s)": float(np.sqrt(np.mean(speed**2))),
    }
    for joint, forces, names in (
        ("az", res.azimuth_contact, res.azimuth_contact_names),
        ("pitch", res.pitch_contact, res.pitch_contact_names),
    ):
        forces = np.asarray(forces)[w]
        for family in FAMILIES:
            cols = [k for k, n in enumerate(names) if n.startswith(family)]
            if cols:
                out[f"{joint} {family} mean (N)"] = float(forces[:, cols].mean())
                out[f"{joint} {family} peak (N)"] = float(forces[:, cols].max())
    return out, pe, ts[w]


def run(scaling, args, rtol=1e-6):
    mech = scene(scaling)
    n_save = int(round(2000 * args.duration)) + 1
    walls = []
    # First a 10 ms solve: the same program (only the save times' values differ), so it times the
    # compilation (plus 10 ms of simulation) without solving the whole horizon twice.
    for duration in (0.01, args.duration):
        wall, res = harness.wall(tolerax.simulate, mech, duration, n_save=n_save, start="steady", rtol=rtol, atol=1e-3 * rtol)
        walls.append(wall)
        if not res.success:
            raise SystemExit(f"mass_scaling={scaling}: " + "\n".join(res.failures()))
    values, pe, ts = outputs(res, args.window_start)
    record = dict(
        mass_scaling=scaling, rtol=rtol, wall_s=walls[1], compile_s=walls[0], per_sim_s=walls[1] / args.duration,
        steps=int(res.num_steps), rejected=int(res.num_rejected), outputs=values,
    )
    return record, pe, ts


def _label(r):
    if r["mass_scaling"] is None:
        return "planetary (full)" + ("" if r.get("rtol", 1e-6) == 1e-6 else f", control rtol {r['rtol']:g}")
    return f"planetary-scaled, s = {r['mass_scaling']:g}" + ("" if r.get("rtol", 1e-6) == 1e-6 else f", rtol {r['rtol']:g}")


def render(payload, stem):
    """Write the .md from a run's payload (the environment it recorded, where it did)."""
    env = payload.get("environment", f"environment not recorded; rendered from the saved JSON at {harness.commit()}")
    runs = payload["runs"]
    full = runs[0]
    keys = list(full["outputs"])
    columns = ["fidelity", "wall s / simulated s", "speed-up", "accepted steps (rejected)", "mean step (us)"]
    rows = []
    for r in runs:
        rows.append([
            _label(r), f"{r['per_sim_s']:.2f}", f"{full['per_sim_s'] / r['per_sim_s']:.1f}x",
            f"{r['steps']} ({r['rejected']})", f"{1e6 * payload['duration'] / r['steps']:.1f}",
        ])
    out_rows = []
    for k in keys:
        ref = full["outputs"][k]
        cells = [k, f"{ref:.4g}"]
        for r in runs[1:]:
            x = r["outputs"][k]
            rel = (x - ref) / abs(ref) if ref else float("nan")
            cells.append(f"{x:.4g} ({100 * rel:+.1f} %)")
        out_rows.append(cells)
    section = harness.Section(
        f"Outputs over {payload['window_start']:g}-{payload['duration']:g} s (relative difference to the full stage)",
        ["output", "planetary (full)"] + [_label(r).replace("planetary-scaled, ", "").replace("planetary (full), ", "full, ") for r in runs[1:]],
        out_rows,
        notes=[
            "Contact families: `sun` and `carrier` bearings, `planet` the three pins together (mean over "
            "time and pins, peak over both). Peak forces are the largest saved value (2 kHz samples), "
            "not the true impact peak.",
            "The control column is the same full model at a tighter tolerance: its difference is the chaotic "
            "spread of that output, the floor for reading the scaled columns.",
        ],
    )
    harness.write_table(
        stem.name,
        "Mass-scaled planetary joints against the full stage",
        payload["command"],
        columns,
        rows,
        about=f"Scene: dual-axis antenna, free base, 0.98 deg/s on both joints, 100 um clearances and backlash, steady start, {payload['duration']:g} s, Tsit5, rtol 1e-6 (atol 1e-9) unless a row says otherwise (atol 1e-3 rtol).",
        intro=[f"Load averages (1 min) at each run's start: {', '.join(f'{x:.2f}' for x in payload['load'])}."],
        sections=[section],
        env=env,
    )


def plot(payload, traces, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax_t, ax_f) = plt.subplots(1, 2, figsize=(11, 4), constrained_layout=True)
    for (label, pe, ts) in traces:
        last = ts >= ts[-1] - 0.2
        ax_t.plot(ts[last], pe[last], lw=0.8, label=label)
        detrended = pe - np.polyval(np.polyfit(ts, pe, 1), ts)
        freqs = np.fft.rfftfreq(len(pe), d=ts[1] - ts[0])
        ax_f.semilogy(freqs[1:], 2 * np.abs(np.fft.rfft(detrended))[1:] / len(pe), lw=0.7, label=label)
    ax_t.set_xlabel("time (s)")
    ax_t.set_ylabel("pointing error (arcsec)")
    ax_t.set_title("last 0.2 s")
    ax_f.set_xlabel("frequency (Hz)")
    ax_f.set_ylabel("amplitude (arcsec)")
    ax_f.set_title(f"spectrum over {payload['window_start']:g}-{payload['duration']:g} s")
    ax_t.legend(fontsize=7)
    fig.savefig(path, dpi=110)


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--duration", type=float, default=5.0, help="simulated time (s)")
    parser.add_argument("--scalings", type=float, nargs="+", default=[10.0, 100.0, 1000.0], help="mass_scaling values")
    parser.add_argument("--rtols", type=float, nargs="+", default=[1e-6], help="rtols of the scaled runs (atol 1e-3 rtol)")
    parser.add_argument("--output", default="mass_scaling", help="results file stem")
    parser.add_argument("--control-rtol", type=float, default=1e-7, help="rtol of the full stage's control run (atol 1e-3 rtol); 0: none")
    parser.add_argument("--window-start", type=float, default=1.0, help="start of the output window (s)")
    parser.add_argument("--render", action="store_true", help="rewrite the .md from the saved .json (no runs, no figure)")
    args = harness.parse_args(parser)
    stem = harness.results_dir() / args.output
    if args.render:
        render(json.loads(stem.with_suffix(".json").read_text()), stem)
        return
    if not 0.0 <= args.window_start < args.duration:
        parser.error("--window-start must lie in [0, duration)")
    payload = dict(command=harness.command(args), duration=args.duration, window_start=args.window_start, runs=[], load=[])
    traces = []
    runs = [(None, 1e-6)] + ([(None, args.control_rtol)] if args.control_rtol else []) + [(s, r) for s in args.scalings for r in args.rtols]
    for scaling, rtol in runs:
        payload["load"].append(os.getloadavg()[0])
        print(f"mass_scaling={scaling}, rtol={rtol:g}: {args.duration} s ...", flush=True)
        record, pe, ts = run(scaling, args, rtol)
        print(json.dumps(record), flush=True)
        payload["runs"].append(record)
        payload["environment"] = harness.environment()
        traces.append((_label(record).replace("planetary-scaled, ", ""), pe, ts))
        stem.with_suffix(".json").write_text(json.dumps(payload, indent=1))
    render(payload, stem)
    plot(payload, traces, stem.with_suffix(".png"))


if __name__ == "__main__":
    main()
