"""What does a full gradient of the pointing error cost, by each way of computing it? Reverse mode
through the solver (diffrax adjoints: recursive checkpointing with several checkpoint budgets,
and backsolve), forward mode (`diffrax.ForwardMode` with `jax.jacfwd`, one tangent per design
variable), and central differences (2n forward solves), each against a forward solve of the same
objective in the same run, and each against a tight reference gradient (issue 12, Build item 3:
goal, a full gradient in at most 3x a forward solve).

    python benchmarks/gradient_methods.py [--duration 0.6] [--width 1e-6] [--rtol 1e-6]
        [--checkpoints 30 10000] [--reference-rtol 1e-10] [--repeats 3] [--no-backsolve]
        [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=("lumped", "ideal"))` (azimuth joint scanning +-0.5 deg,
1 s period, pitch held rigid, fixed base), steady start. Objective: `PointingObjective`'s RMS
pointing error (arcsec) over the whole run at smoothing width `--width`, 61 saves, Tsit5 with the
objective's `rtol` and `atol = 1e-3 rtol`. Design: the azimuth joint's output-bearing clearance,
planet-pin clearance, sun- and ring-mesh backlash (4 variables, all 100 um).

Each method is compiled by a first call (its compile time is that call minus the best later
one), then timed `--repeats` times (`harness.timed`); the table gives the best and the median.
Writes `benchmarks/results/gradient_methods.md` (`--results DIR`: DIR/gradient_methods.md). The reference gradient is reverse
mode at `--reference-rtol` (atol 1e-3 of it); its own accuracy is stated by the forward-mode
gradient at the same tolerance (two different derivative programs of the same discretisation
error). Central differences use h = `--fd-step` (m).
"""

import os

import diffrax
import equinox as eqx
import jax
import numpy as np

import tolerax as tx

import harness


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--duration", type=float, default=0.6)
    parser.add_argument("--width", type=float, default=1e-6)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--checkpoints", type=int, nargs="*", default=[30, 10000])
    parser.add_argument("--reference-rtol", type=float, default=1e-10)
    parser.add_argument("--fd-step", type=float, default=1e-8)
    parser.add_argument("--repeats", type=int, default=3)
    parser.add_argument("--no-backsolve", action="store_true")
    args = harness.parse_args(parser)

    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    p0 = tx.design_of(scene)
    n = p0.shape[0]
    loads = [os.getloadavg()]

    def objective(rtol, adjoint=None):
        pointing = tx.PointingObjective(
            scene, duration=args.duration, settle=0.0, start="steady", n_save=61,
            integrator=tx.Integrator(rtol=rtol, atol=1e-3 * rtol, max_steps=400_000),
            adjoint=adjoint,
        )
        return lambda p: pointing(p, args.width)["pointing_rms"]

    def steps(rtol):
        pointing = tx.PointingObjective(scene, duration=args.duration, settle=0.0, start="steady", n_save=2,
                                        integrator=tx.Integrator(rtol=rtol, atol=1e-3 * rtol, max_steps=400_000))
        res = pointing.run(p0, args.width)
        return int(res.num_steps), int(res.num_rejected)

    # The reference first: everything else is compared with it.
    ref = harness.timed(eqx.filter_jit(jax.grad(objective(args.reference_rtol))), p0, repeats=1)
    reference = np.asarray(ref.output)
    _, ref_forward = harness.wall(eqx.filter_jit(jax.jacfwd(objective(args.reference_rtol, diffrax.ForwardMode()))), p0)
    ref_check = np.linalg.norm(np.asarray(ref_forward) - reference) / np.linalg.norm(reference)
    loads.append(os.getloadavg())
    print("reference", reference * 1e-6, "forward-mode check", ref_check, flush=True)

    f = objective(args.rtol)
    fwd = harness.timed(eqx.filter_jit(f), p0, repeats=args.repeats)
    rows = []

    def row(method, t, note="", compile_s=None):
        grad = np.asarray(t.output)
        rel = np.linalg.norm(grad - reference) / np.linalg.norm(reference)
        compile_s = t.compile_s if compile_s is None else compile_s
        rows.append([method, f"{compile_s:.0f}", f"{t.run_s:.3f}", f"{t.median_s:.3f}", f"{t.run_s / fwd.run_s:.1f}", f"{rel:.1e}", note])
        print(rows[-1], flush=True)

    rows.append([
        "forward solve (value only)", f"{fwd.compile_s:.0f}", f"{fwd.run_s:.3f}", f"{fwd.median_s:.3f}", "1.0", "",
        f"RMS {float(fwd.output):.3f} arcsec",
    ])
    for label, adjoint in [("default", None)] + [(f"checkpoints={c}", diffrax.RecursiveCheckpointAdjoint(checkpoints=c)) for c in args.checkpoints]:
        row(f"reverse: RecursiveCheckpointAdjoint ({label})",
            harness.timed(eqx.filter_jit(jax.grad(objective(args.rtol, adjoint))), p0, repeats=args.repeats))
    if not args.no_backsolve:
        try:
            row("reverse: BacksolveAdjoint",
                harness.timed(eqx.filter_jit(jax.grad(objective(args.rtol, diffrax.BacksolveAdjoint()))), p0, repeats=args.repeats))
        except Exception as error:  # report what happens, whatever it is
            message = " ".join(str(error).split())[:300]
            rows.append(["reverse: BacksolveAdjoint", "", "", "", "", "", f"fails: {type(error).__name__}: {message}"])
            print(rows[-1], flush=True)
    row(f"forward: ForwardMode + jacfwd ({n} tangents)",
        harness.timed(eqx.filter_jit(jax.jacfwd(objective(args.rtol, diffrax.ForwardMode()))), p0, repeats=args.repeats))
    jf = eqx.filter_jit(f)
    h = args.fd_step

    def central(p):
        return np.array([(jf(p.at[k].add(h)) - jf(p.at[k].add(-h))) / (2 * h) for k in range(n)])

    row(f"central differences ({2 * n} forward solves, h = {h:g} m)", harness.timed(central, p0, repeats=args.repeats),
        "compiled with the forward solve", compile_s=0.0)
    loads.append(os.getloadavg())

    n_steps, n_rejected = steps(args.rtol)
    ref_steps, ref_rejected = steps(args.reference_rtol)
    names = tx.design_names(scene)
    grad_rows = [[name, f"{r * 1e-6:.6g}", f"{fr * 1e-6:.6g}"] for name, r, fr in zip(names, reference, np.asarray(ref_forward))]
    meets = [r[0] for r in rows[1:] if r[4] and float(r[4]) <= 3.0]
    harness.write_table(
        "gradient_methods",
        "Gradient methods: cost as a multiple of a forward solve, and accuracy",
        harness.command(args),
        ["method", "compile (s)", "wall (s, best of %d)" % args.repeats, "wall (s, median)", "x forward (best)",
         "abs(grad - ref) / abs(ref)", "note"],
        rows,
        about=(
            f"Azimuth scan +-0.5 deg, 1 s period, steady start, lumped joint, fixed base; RMS pointing error over "
            f"{args.duration:g} s at smoothing width {args.width:g} m; Tsit5, rtol {args.rtol:g}, atol {1e-3 * args.rtol:g} "
            f"({n_steps} accepted, {n_rejected} rejected steps). Load average (1, 5, 15 min) at start, after the "
            f"reference, at the end: {'; '.join(map(harness.load, loads))} "
            f"(on {os.cpu_count()} cores: the absolute times are slowed by other work; the ratios are within one run)."
        ),
        notes=[
            "Meets the goal of a full gradient in at most 3x a forward solve: "
            + (", ".join(meets) if meets else "none of the methods")
            + ".",
            f"Compile: the first call minus the best later one (a negative or tiny value is noise). Reference: reverse "
            f"mode at rtol {args.reference_rtol:g} ({ref_steps} accepted, {ref_rejected} rejected steps; "
            f"{ref.run_s:.1f} s, compile {ref.compile_s:.0f} s); forward mode at the same tolerance differs from it by "
            f"{ref_check:.1e} (relative), the resolution of the accuracy column. At rtol {args.rtol:g} every method "
            "differentiates a solution with the discretisation error of that tolerance, so their distance from the "
            "reference is mostly the solver's error, not the method's.",
        ],
        sections=[
            harness.Section(
                "Reference gradient (arcsec/um)",
                ["design variable", f"reverse mode, rtol {args.reference_rtol:g}", f"forward mode, rtol {args.reference_rtol:g}"],
                grad_rows,
            )
        ],
    )


if __name__ == "__main__":
    main()
