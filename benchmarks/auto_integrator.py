"""The automatic integrator on a matrix of scenes: what `simulate` chooses with no option given,
and the candidate for the full planetary stage (`--candidate`, default `tolerax.solve.FAST_STAGE`:
SRK53, rtol 1e-4, the (0.2, 0.2) controller), each one's wall time against the explicit default
(`tolerax.solve.ACCURATE`: Tsit5, rtol 1e-6, I-controller) in one run, and their output errors
against an rtol 1e-10 solve (issue 60). The automatic choice may take the candidate only where
its errors lie inside ACCURATE's own: this is the measurement that decides it.

    python benchmarks/auto_integrator.py [--rounds 2] [--scenes ...] [--before REV] [--results DIR]

    python benchmarks/auto_integrator.py --candidate SRK53:1e-4:0.2:0.2

Scenes (`--scenes`, default all): the stage on its `TestBench` from rest; the antenna with lumped
joints (the azimuth scan, the dual axis turning at 0.98 deg/s); planetary-scaled joints (dual);
full planetary joints (the azimuth scan on a fixed base, the dual axis at 0.98 and at 1.96 deg/s
on the free base, a 0.5 deg slew of both joints, the azimuth joint alone on a fixed base) over
0.5-0.6 s, and the full planetary dual in developed rattle (steady start, 2 s, the window
1-2 s: `rattle_window.py`'s scene). Each row: the automatic choice (`result.integrated_with`);
the default's, the candidate's and the automatic choice's wall time (each compiled first by a
0.01 s run of the same program, then timed once per round, rounds interleaved, the fastest
kept), the candidate's and the automatic choice's ratio to the default; and each one's errors
against the reference (Tsit5, rtol 1e-10, atol 1e-13, I-controller) over
the window: the pointing RMS, peak and jitter (above 20 Hz) relative errors and the largest
clearance-contact force of the joints' bearings (relative); the bench: the largest transmission-error difference
(rad) and the sun meshes' peak force (relative). "inside" says whether each of the candidate's
errors is at most the default's (or below 1e-9 relative, rounding), per output. With `--before
REV`, the developed-rattle row also times tolerax at git revision REV with no option given (its
own default), in the same run: the issue's "faster than 993e755". (The committed result was run
at ae5757d, where the automatic choice on the full stage was the candidate itself: its
"automatic" columns are the candidate's.)
"""

import math
import time

import numpy as np

import tolerax as tx
from tolerax.mechanism.outputs import pointing_metrics

import harness

REFERENCE = tx.Integrator(rtol=1e-10, atol=1e-13, max_steps=50_000_000)
FLOOR = 1e-9  # relative: below it two solves differ by rounding, not by the integrator
CUTOFF = 20.0  # Hz, the jitter's band


def _slew():
    times, angles = [0.0, 0.05, 0.35, 0.5], [0.0, 0.0, math.radians(0.5), math.radians(0.5)]
    return tx.antenna("dual", fidelity="planetary", drive="profile", profile_times=times, profile_angles=angles)


# name -> (build, duration s, start, n_save, window start s)
SCENES = {
    "bench": (lambda: tx.TestBench(), 0.2, "rest", 201, 0.0),
    "lumped azimuth scan": (lambda: tx.load_scene("scan-azimuth").build(), 0.6, "steady", 301, 0.3),
    "lumped dual 0.98 deg/s": (lambda: tx.antenna("dual", fidelity="lumped"), 1.0, "steady", 501, 0.5),
    "planetary-scaled dual": (lambda: tx.antenna("dual", fidelity="planetary-scaled"), 0.5, "steady", 501, 0.25),
    "planetary azimuth scan, fixed base": (lambda: tx.load_scene("scan-azimuth-planetary").build(), 0.6, "steady", 301, 0.3),
    "planetary dual 0.98 deg/s": (lambda: tx.antenna("dual", fidelity="planetary"), 0.5, "steady", 501, 0.25),
    "planetary dual 1.96 deg/s": (lambda: tx.antenna("dual", fidelity="planetary", rate=math.radians(1.96)), 0.5, "steady", 501, 0.25),
    "planetary dual slew 0.5 deg": (_slew, 0.5, "rest", 501, 0.25),
    "planetary azimuth 0.98 deg/s, fixed base": (lambda: tx.antenna("azimuth", fidelity="planetary", base="fixed"), 0.5, "steady",
                                                 501, 0.25),
    "planetary dual, developed rattle": (lambda: tx.antenna("dual", fidelity="planetary"), 2.0, "steady", 2001, 1.0),
}


def outputs(result, window_start):
    ts = np.asarray(result.ts)
    window = ts >= window_start - 1e-12
    if isinstance(result, tx.BenchResult):
        return dict(transmission_error=np.asarray(result.transmission_error)[window],
                    sun_mesh_force=float(np.max(np.abs(np.asarray(result.sun_mesh_force)[window]))))
    m = pointing_metrics(result, window, jitter_cutoff=CUTOFF)
    # Every clearance contact's normal force of both joints (N): the largest over the window.
    forces = [np.abs(np.asarray(f)[window]).max() for f in (result.azimuth_contact, result.pitch_contact) if np.size(f)]
    return dict(pointing_rms=float(m["pointing_rms"]), pointing_peak=float(m["pointing_peak"]),
                pointing_jitter=float(m["pointing_jitter"]), bearing_force=float(max(forces, default=0.0)))


def errors(out, ref):
    err = {}
    for k, v in out.items():
        if k == "transmission_error":
            err[k] = float(np.max(np.abs(v - ref[k])))  # rad
        else:
            err[k] = abs(v - ref[k]) / max(abs(ref[k]), 1e-300)
    return err


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--rounds", type=int, default=2)
    parser.add_argument("--scenes", nargs="+", default=list(SCENES), choices=list(SCENES), metavar="SCENE")
    parser.add_argument("--before", default=None, help="git revision timed on the developed-rattle row")
    parser.add_argument("--candidate", default="SRK53:1e-4:0.2:0.2", help="SOLVER:RTOL:PCOEFF:ICOEFF (atol = rtol / 1000)")
    args = harness.parse_args(parser)
    solver, rtol, pcoeff, icoeff = args.candidate.split(":")
    candidate = tx.Integrator(solver, rtol=float(rtol), atol=float(rtol) / 1000, pcoeff=float(pcoeff), icoeff=float(icoeff))
    start_all = time.perf_counter()
    rows, notes = [], []
    for name in args.scenes:
        build, duration, start, n_save, w0 = SCENES[name]
        scene = build()
        run = lambda seconds, pkg=tx, sc=scene, **kw: pkg.simulate(sc, seconds, start=start, n_save=n_save, **kw)  # noqa: E731
        configs = {"default": dict(integrator=tx.solve.ACCURATE), "candidate": dict(integrator=candidate), "auto": {}}
        packages = {"default": tx, "candidate": tx, "auto": tx}
        if args.before and "developed" in name:
            old = harness.tolerax_at(args.before)
            configs[f"@{args.before}"] = {}
            packages[f"@{args.before}"] = old
        scenes = {k: (scene if packages[k] is tx else packages[k].antenna("dual", fidelity="planetary")) for k in configs}
        for k in configs:
            run(0.01, packages[k], scenes[k], **configs[k])  # compile
        best, results = {}, {}
        for _ in range(args.rounds):
            for k in configs:
                wall, res = harness.wall(lambda: run(duration, packages[k], scenes[k], **configs[k]))
                best[k] = min(best.get(k, math.inf), wall)
                results[k] = res
        t0 = time.perf_counter()
        reference = run(duration, integrator=REFERENCE)
        ref_wall = time.perf_counter() - t0
        ref_out = outputs(reference, w0)
        errs = {k: errors(outputs(results[k], w0), ref_out) for k in configs}
        inside = {o: errs["candidate"][o] <= max(errs["default"][o], FLOOR * (o != "transmission_error") or 1e-15)
                  for o in errs["candidate"]}
        rows.append((name, results["auto"].integrated_with, best, results, errs, inside))
        for k in configs:
            if k.startswith("@"):
                notes.append(f"- {name}: tolerax at {k[1:]} (no option): errors " + "; ".join(
                    f"{o.replace('pointing_', '')} {v:.1e}" for o, v in errs[k].items()) + ".")
        notes.append(f"- {name}: {duration} s from `start = \"{start}\"`, {n_save} saves, window from {w0} s; reference "
                     f"{ref_wall:.1f} s, {int(reference.num_steps)} steps; " + ", ".join(f"{k} {v:.6g}" for k, v in ref_out.items()
                                                                                    if k != "transmission_error") + ".")
        print(name, {k: round(v, 2) for k, v in best.items()}, inside, flush=True)
    columns = ["scene", "automatic choice", "default wall (s)", "candidate wall (s)", "automatic wall (s)",
               "default / candidate", "default / automatic", "steps default / candidate", "errors: default", "errors: candidate",
               "errors: automatic", "candidate inside the default's own"]
    table = []
    fmt = lambda e: "; ".join(f"{k.replace('pointing_', '')} {v:.1e}" for k, v in e.items())  # noqa: E731
    for name, why, best, results, errs, inside in rows:
        extra = "".join(f"; {k} (no option) {best[k]:.1f} s, {best[k] / best['candidate']:.2f}x the candidate" for k in best
                        if k.startswith("@"))
        table.append([name, why.split(":")[0], f"{best['default']:.2f}", f"{best['candidate']:.2f}{extra}", f"{best['auto']:.2f}",
                      f"{best['default'] / best['candidate']:.2f}", f"{best['default'] / best['auto']:.2f}",
                      f"{int(results['default'].num_steps)} / {int(results['candidate'].num_steps)}",
                      fmt(errs["default"]), fmt(errs["candidate"]), fmt(errs["auto"]),
                      "yes" if all(inside.values()) else "no: " + ", ".join(k for k, v in inside.items() if not v)])
    harness.write_table(
        "auto_integrator", "The automatic integrator on a matrix of scenes: wall time and errors against today's default",
        harness.command(args), columns, table,
        about=(f"Default: `tolerax.solve.ACCURATE` given explicitly; candidate: {candidate.describe()}; automatic: `simulate` "
               f"with no run option. Reference: Tsit5 at "
               f"rtol 1e-10, atol 1e-13. Rounds: {args.rounds}, the fastest kept. Errors relative (transmission error: rad); "
               f"jitter above {CUTOFF:g} Hz. Total wall {time.perf_counter() - start_all:.0f} s."),
        notes=["Scenes and references:", "\n".join(notes), "Why each choice (`integrated_with`):",
               "\n".join(f"- {name}: {why}" for name, why, *_ in rows)])


if __name__ == "__main__":
    main()
