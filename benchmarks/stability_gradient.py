"""Can the pointing-stability (jitter) metric be differentiated? Forward-mode derivatives of one
manufactured unit's jitter with respect to each clearance and backlash, against central
differences at several steps, by smoothing width and horizon, and the jitter scanned along one
feature to show its roughness (issue 30 item 3, the measurement half).

    python benchmarks/stability_gradient.py [--fidelities planetary-scaled lumped]
        [--mass-scaling 1000] [--horizons 0.6 2.0] [--settle 0.3] [--widths 1e-6 1e-7]
        [--steps 1e-8 1e-7 1e-6] [--features NAME ...] [--save-rate 500] [--cutoff 20]
        [--rtol 1e-6] [--scan-feature azimuth.ring_backlash] [--scan-points 20]
        [--scan-half-range 5e-6] [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=(F, "ideal"))` (azimuth joint scanning +-0.5 deg,
1 s period, pitch rigid, fixed base), steady start, for each F of `--fidelities`;
`planetary-scaled` with its joint's mass scaling set to `--mass-scaling` (the fast planetary
setting). The unit: the scene's own design (`tolerax.design_of`), clearances and backlash at
the scene's values. Objective: `PointingObjective(..., jitter_cutoff=--cutoff)`'s
`pointing_jitter` (arcsec, `tolerax.mechanism.outputs.pointing_jitter`: the RMS over
`[--settle, horizon]` of the pointing error less its slow part below the cutoff), saved at
`--save-rate` per second, Tsit5 at `--rtol` (atol 1e-3 of it). The first reversal is at 0.25 s;
`--settle` starts the window after it, so a 0.6 s horizon holds no further reversal and a 2 s
one three (0.75, 1.25, 1.75 s).

For each fidelity, horizon and width: the jitter and its forward-mode Jacobian from one solve
(`tolerax.design.objectives.value_and_jacobian`, `diffrax.ForwardMode`, one tangent per
feature), and for each feature central differences $(J(p + h) - J(p - h)) / 2h$ at each step
$h$ of `--steps` (m). Disagreement: $|AD - FD| / \\max(|AD|, |FD|)$. Then the jitter at
`--scan-points` points over +-`--scan-half-range` (m) along `--scan-feature`, at each width and
horizon of the first fidelity: its spread about a straight line (roughness) against the slope.
Writes `benchmarks/results/stability_gradient.{md,json}` (`--results DIR`).
"""

import json
import os
import time

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.design.objectives import value_and_jacobian

import harness

UM = 1e-6  # m per um: gradients are reported in arcsec/um


def scene_of(fidelity, mass_scaling):
    scene = tx.scan("azimuth", fidelity=(fidelity, "ideal"))
    if fidelity == "planetary-scaled":
        scene = eqx.tree_at(lambda s: s.azimuth.mass_scaling, scene, jnp.asarray(float(mass_scaling)))
    return scene


def objective(scene, horizon, args):
    return tx.PointingObjective(
        scene, duration=horizon, settle=args.settle, start="steady", n_save=int(round(args.save_rate * horizon)) + 1,
        integrator=tx.Integrator(rtol=args.rtol, atol=1e-3 * args.rtol, max_steps=400_000), jitter_cutoff=args.cutoff,
    )


def disagreement(ad, fd):
    scale = max(abs(ad), abs(fd))
    return abs(ad - fd) / scale if scale > 0 else 0.0


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--fidelities", nargs="+", default=["planetary-scaled", "lumped"])
    parser.add_argument("--mass-scaling", type=float, default=1000.0)
    parser.add_argument("--horizons", type=float, nargs="+", default=[0.6, 2.0])
    parser.add_argument("--settle", type=float, default=0.3)
    parser.add_argument("--widths", type=float, nargs="+", default=[1e-6, 1e-7])
    parser.add_argument("--steps", type=float, nargs="+", default=[1e-8, 1e-7, 1e-6])
    parser.add_argument("--features", nargs="*", default=[], help="feature names (default: every feature of the scene)")
    parser.add_argument("--save-rate", type=float, default=500.0, help="saves per second")
    parser.add_argument("--cutoff", type=float, default=20.0, help="jitter cutoff (Hz)")
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--scan-feature", default="azimuth.ring_backlash")
    parser.add_argument("--scan-points", type=int, default=20)
    parser.add_argument("--scan-half-range", type=float, default=5e-6)
    args = harness.parse_args(parser)

    rows, records, scans, loads = [], [], [], [os.getloadavg()]
    for fidelity in args.fidelities:
        scene = scene_of(fidelity, args.mass_scaling)
        names, p0 = tx.design_names(scene), tx.design_of(scene)
        features = [n for n in (args.features or names) if n in names]
        for horizon in args.horizons:
            pointing = objective(scene, horizon, args)
            value = eqx.filter_jit(lambda p, w: pointing(p, w))  # noqa: B023 (called in this iteration only)
            jacobian = eqx.filter_jit(lambda p, w: value_and_jacobian(p, pointing, "pointing_jitter", w))  # noqa: B023
            for width in args.widths:
                w = jnp.asarray(width)
                first = width == args.widths[0]  # compiles: time a second call; later widths reuse the program
                fwd = harness.timed(value, p0, w, repeats=1 if first else 0)
                out = fwd.output
                jitter, rms, ok = float(out["pointing_jitter"]), float(out["pointing_rms"]), bool(out["success"])
                jac_t = harness.timed(jacobian, p0, w, repeats=1 if first else 0, once_s=120.0)
                jvalue, jac = jac_t.output
                jac = np.asarray(jac)
                print(f"{fidelity} horizon {horizon:g} width {width:g}: jitter {jitter:.5f} (jacobian's value "
                      f"{float(jvalue):.5f}) RMS {rms:.2f} success {ok}; forward {fwd.run_s:.1f} s (compile "
                      f"{fwd.compile_s:.0f}), jacobian {jac_t.run_s:.1f} s (compile {jac_t.compile_s:.0f})", flush=True)
                start = time.perf_counter()
                for name in features:
                    k = names.index(name)
                    fds, fails = [], 0
                    for h in args.steps:
                        plus, minus = value(p0.at[k].add(h), w), value(p0.at[k].add(-h), w)
                        fails += int(not (bool(plus["success"]) and bool(minus["success"])))
                        fds.append((float(plus["pointing_jitter"]) - float(minus["pointing_jitter"])) / (2 * h))
                    ad = float(jac[k])
                    rec = dict(
                        fidelity=fidelity, horizon=horizon, width=width, feature=name, jitter=jitter, rms=rms, success=ok,
                        ad=ad * UM, fd={f"{h:g}": fd * UM for h, fd in zip(args.steps, fds)},
                        disagreement={f"{h:g}": disagreement(ad, fd) for h, fd in zip(args.steps, fds)},
                        failed_differences=fails, forward_s=fwd.run_s, forward_compile_s=fwd.compile_s,
                        jacobian_s=jac_t.run_s, jacobian_compile_s=jac_t.compile_s,
                    )
                    records.append(rec)
                    rows.append([
                        fidelity, f"{horizon:g}", f"{width:g}", name.split(".", 1)[-1], f"{jitter:.4f}", f"{ad * UM:.4g}",
                        *(f"{fd * UM:.4g} ({disagreement(ad, fd):.1e})" for fd in fds), str(fails) if fails else "",
                    ])
                    print(rows[-1], flush=True)
                fd_s = time.perf_counter() - start
                for rec in records:
                    if (rec["fidelity"], rec["horizon"], rec["width"]) == (fidelity, horizon, width):
                        rec["differences_s"] = fd_s
                if fidelity == args.fidelities[0] and args.scan_points > 0 and args.scan_feature in names:
                    k = names.index(args.scan_feature)
                    offsets = np.linspace(-args.scan_half_range, args.scan_half_range, args.scan_points)
                    start = time.perf_counter()
                    values = []
                    for d in offsets:
                        o = value(p0.at[k].add(d), w)
                        values.append(float(o["pointing_jitter"]) if bool(o["success"]) else float("nan"))
                    values = np.asarray(values)
                    line = np.polyfit(offsets / UM, values, 1)
                    residual = values - np.polyval(line, offsets / UM)
                    scans.append(dict(
                        fidelity=fidelity, horizon=horizon, width=width, feature=args.scan_feature, offsets_um=(offsets / UM).tolist(),
                        jitter=values.tolist(), slope=float(line[0]), roughness=float(np.std(residual)), ad=float(jac[k]) * UM,
                        seconds=time.perf_counter() - start,
                    ))
                    print(f"scan {args.scan_feature}: jitter {values.min():.4f}..{values.max():.4f}, line slope "
                          f"{line[0]:.4g} arcsec/um, residual std {np.std(residual):.4g}, AD {float(jac[k]) * UM:.4g}", flush=True)
                loads.append(os.getloadavg())
                write(args, rows, records, scans, loads)  # after every setting: a killed run keeps what it measured


def write(args, rows, records, scans, loads):
    steps = [f"{h:g}" for h in args.steps]
    columns = ["fidelity", "horizon (s)", "width (m)", "feature", "jitter (arcsec)", "forward mode (arcsec/um)",
               *(f"central diff. h = {h} m (disagreement)" for h in steps), "failed solves"]
    cost_rows, seen = [], set()
    for r in records:
        key = (r["fidelity"], r["horizon"], r["width"])
        if key in seen:
            continue
        seen.add(key)
        cost_rows.append([r["fidelity"], f"{r['horizon']:g}", f"{r['width']:g}", f"{r['rms']:.1f}", f"{r['forward_compile_s']:.0f}",
                          f"{r['forward_s']:.1f}", f"{r['jacobian_compile_s']:.0f}", f"{r['jacobian_s']:.1f}",
                          f"{r['jacobian_s'] / r['forward_s']:.1f}", f"{r.get('differences_s', float('nan')):.0f}"])
    summary = []
    for key in {(r["fidelity"], r["horizon"], r["width"]): None for r in records}:
        sub = [r for r in records if (r["fidelity"], r["horizon"], r["width"]) == key]
        summary.append([key[0], f"{key[1]:g}", f"{key[2]:g}",
                        *(f"{np.median([r['disagreement'][h] for r in sub]):.1e} / {max(r['disagreement'][h] for r in sub):.1e}" for h in steps)])
    scan_rows = [[s["fidelity"], f"{s['horizon']:g}", f"{s['width']:g}", s["feature"].split(".", 1)[-1],
                  f"{np.nanmin(s['jitter']):.4f} .. {np.nanmax(s['jitter']):.4f}", f"{s['slope']:.4g}", f"{s['ad']:.4g}",
                  f"{s['roughness']:.3g}", f"{s['roughness'] / max(abs(s['slope']) * 2 * args.scan_half_range / UM / (args.scan_points - 1), 1e-300):.2g}",
                  f"{s['seconds']:.0f}"] for s in scans]
    sections = [
        harness.Section("Disagreement by setting (median / worst over the features)", ["fidelity", "horizon (s)", "width (m)",
                        *(f"h = {h} m" for h in steps)], summary),
        harness.Section("Cost", ["fidelity", "horizon (s)", "width (m)", "pointing RMS (arcsec)", "forward compile (s)", "forward (s)",
                                 "Jacobian compile (s)", "Jacobian (s)", "Jacobian / forward", "all differences (s)"], cost_rows,
                        ["Compile: the first call minus the second (`harness.timed`), at each horizon's first width; later widths "
                         "reuse the compiled programs (compile `nan`, one call timed). A Jacobian whose first call took over 120 s "
                         "was not repeated (compile `nan`, its time includes compilation)."]),
    ]
    if scans:
        sections.append(harness.Section(
            f"Jitter along {args.scan_feature}, {args.scan_points} points over +-{args.scan_half_range / UM:g} um", [
                "fidelity", "horizon (s)", "width (m)", "feature", "jitter range (arcsec)", "straight-line slope (arcsec/um)",
                "forward mode at the centre (arcsec/um)", "residual std about the line (arcsec)",
                "residual std / the line's change per point", "wall (s)"], scan_rows,
            ["A smooth function over +-5 um is nearly a straight line there: its residual is far below the line's change "
             "from one point to the next (ratio << 1). A rough one has residuals as large as that change or larger; its "
             "local derivative then says nothing about the trend."]))
    about = (
        f"Azimuth scan +-0.5 deg, 1 s period, steady start, fixed base, pitch rigid; `planetary-scaled` at mass scaling "
        f"{args.mass_scaling:g}. Jitter: RMS over [{args.settle:g} s, horizon] of the pointing error less its slow part "
        f"below {args.cutoff:g} Hz, {args.save_rate:g} saves per second; Tsit5 rtol {args.rtol:g}, atol {1e-3 * args.rtol:g}. "
        f"Load average (1, 5, 15 min) at the start and after each setting: {'; '.join(map(harness.load, loads))} "
        f"(on {os.cpu_count()} cores)."
    )
    harness.write_table(
        "stability_gradient", "Pointing stability (jitter): forward-mode gradient against central differences", harness.command(args),
        columns, rows, about=about,
        intro=["Each row: one feature's derivative of one unit's jitter (arcsec/um) by forward mode and by central differences "
               "at each step h, with |AD - FD| / max(|AD|, |FD|) in brackets."],
        sections=sections,
    )
    path = harness.results_dir() / "stability_gradient.json"
    path.write_text(json.dumps(dict(command=harness.command(args), env=harness.environment(), records=records, scans=scans), indent=1))


if __name__ == "__main__":
    main()
