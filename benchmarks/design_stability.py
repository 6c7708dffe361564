"""A tolerance design with a pointing-stability requirement beside the lost-motion one, designed
at `--fidelity` (default the full planetary stage, which reads the jitter: issue 40) and verified
on fresh full-stage units, against the design made for lost motion alone.

    python benchmarks/design_stability.py [--fidelity planetary] [--yield 0.9] [--rms-fraction 0.6]
        [--jitter-requirement 0.2] [--secant-units 16] [--verify-units 100] [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=(F, "ideal"))` (+-0.5 deg, 1 s period, steady start,
pitch rigid): F = `planetary` (the full stage) or `planetary-scaled` (mass scaling
`--mass-scaling`; a proxy that reads the jitter about 3x low, `fidelity_adequacy_scan-azimuth.md`:
designing on it needs `allow_proxy=True`, which this script passes then). Tsit5 at `--rtol`
(the jitter is a fraction of an arcsec: a loose tolerance would swamp it), smoothing `--width`.
Over the window `[--settle, --horizon]`, saved at `--save-rate` per second: the RMS pointing
error (the lost-motion part of the budget) and the jitter (`pointing_jitter`: RMS of the error
less its slow part below `--cutoff` Hz).

Why secants: `benchmarks/results/stability_gradient.md` measured the jitter's forward-mode
derivatives against central differences: they disagree at every step, width and horizon (rattle
is chaotic), so both metrics are linearised by a least-squares line through `--secant-units`
units of the zone (`LinearisedYield(secant_units=...)`, forward solves only) with the fit's
residual scatter, and a design's yield on each is the marginal `--yield` quantile.

Two designs by `tolerax.propose_design` (sequential, lower limits >= 5 um, bands 1-50 um, ISO
286 cost, one width, no Monte Carlo check inside: the verification below is the check): (a)
the RMS requirement alone, (b) the RMS and the jitter requirements; (b) is solved twice, with
secant seeds 1 and 2 (`propose_design`'s noise band: its status says whether the two agree to
what the requirements' tolerances resolve). Requirements: RMS `--rms-fraction` x the
baseline's (scene values +- 10 um) linearised quantile, jitter `--jitter-requirement` arcsec
(or `--jitter-fraction` x the baseline's). Each design is verified on `--verify-units` fresh
units at `--verify-fidelity` (default the full stage; `tolerax.monte_carlo`, key 2026): the
yield on each requirement with its 95 % Wilson interval, side by side. `--log-fit`: the jitter's
secant line is fitted to its logarithm (`Secants(log=True)`, `LinearisedYield.log_outputs`:
its scatter over units grows with its level, `results/jitter_reach.md`); writes
`design_stability_<fidelity>_log.md`. `--secant-reach` (m): the secant units span the zone's
middle +- at least this much (`LinearisedYield.secant_reach`: the jitter's trend, about 1 % per
um against a 29 % scatter, resolved over a wider neighbourhood than a tight zone); adds `_reach`.
`--surface LO HI` (m): both outputs fitted once over `--secant-units` units spread over [LO, HI]
for every feature, the design made on that response surface (`design_problem(surface_box=...)`);
adds `_surface`. `--surface-rounds K` (default 4): then up to K - 1 more surfaces, each fitted
over a box about the last design's zones, the design solved again on it and held inside the box
(`Surface(rounds=...)`);
adds `_rounds` (1: the single surface of the earlier results).
"""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.design.propose import design_problem

import _design
import harness

OUTPUTS = ("pointing_rms", "pointing_jitter")


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--yield", dest="yield_", type=float, default=0.9)
    parser.add_argument("--fidelity", choices=("planetary", "planetary-scaled"), default="planetary")
    parser.add_argument("--verify-fidelity", choices=("planetary", "planetary-scaled"), default="planetary")
    parser.add_argument("--rms-fraction", type=float, default=0.6)
    parser.add_argument("--jitter-fraction", type=float, default=0.8)
    parser.add_argument("--jitter-requirement", type=float, default=0.2, help="arcsec (0: --jitter-fraction of the baseline's quantile)")
    parser.add_argument("--secant-units", type=int, default=16)
    parser.add_argument("--verify-units", type=int, default=100)
    parser.add_argument("--max-iterations", type=int, default=40)
    parser.add_argument("--jitter-tol", type=float, default=None,
                        help="relative tolerance on the jitter requirement (default: propose_design's, twice the secant fit's "
                        "standard error at the start over the requirement, 0.01 to 0.5); the RMS one is 0.01")
    parser.add_argument("--horizon", type=float, default=0.6)
    parser.add_argument("--settle", type=float, default=0.3)
    parser.add_argument("--save-rate", type=float, default=500.0)
    parser.add_argument("--cutoff", type=float, default=20.0)
    parser.add_argument("--rtol", type=float, default=1e-6)
    parser.add_argument("--width", type=float, default=1e-7)
    parser.add_argument("--mass-scaling", type=float, default=1000.0)
    parser.add_argument("--chunk", type=int, default=10)
    parser.add_argument("--log-fit", action="store_true",
                        help="fit the jitter's secant line to its logarithm (Secants(log=True): a scatter relative to its level)")
    parser.add_argument("--secant-reach", type=float, default=None,
                        help="m: the secant units span the middle +- at least this much (LinearisedYield.secant_reach)")
    parser.add_argument("--check-units", type=int, default=0,
                        help="propose_design's Monte Carlo check and re-solve (SORA) with this many units per check (default 0: "
                        "none, the verification below is the check)")
    parser.add_argument("--surface", type=float, nargs=2, default=None, metavar=("LO", "HI"),
                        help="m: design on a response surface fitted once over units spread over [LO, HI] for every feature "
                        "(design_problem(surface_box=...)), --secant-units of them")
    parser.add_argument("--surface-rounds", type=int, default=4,
                        help="with --surface: at most this many response surfaces, each after the first over the last design's "
                        "zones (Surface(rounds=...); 1: the one surface over [LO, HI])")
    parser.add_argument("--no-scatter", dest="scatter", action="store_false",
                        help="leave the secant fits' residual scatter out of the linearised quantiles (LinearisedYield(scatter=))")
    args = harness.parse_args(parser)
    start = time.perf_counter()

    def objective(fidelity):
        scene = tx.scan("azimuth", fidelity=(fidelity, "ideal"),
                        mass_scaling=float(args.mass_scaling) if fidelity == "planetary-scaled" else None)
        return tx.PointingObjective(scene, duration=args.horizon, settle=args.settle, start="steady",
                                    n_save=int(round(args.save_rate * args.horizon)) + 1, integrator=tx.Integrator(rtol=args.rtol, atol=1e-3 * args.rtol, max_steps=400_000),
                                    jitter_cutoff=args.cutoff)

    pointing = objective(args.fidelity)
    scene = pointing.scene
    both = design_problem(pointing, yield_=args.yield_, secant_units=args.secant_units, output=OUTPUTS, scatter=args.scatter,
                          log_outputs=("pointing_jitter",) if args.log_fit else (), secant_reach=args.secant_reach,
                          surface_box=None if args.surface is None else tuple(args.surface), surface_width=args.width)
    width = jnp.asarray(args.width)
    baseline = np.asarray(eqx.filter_jit(lambda o, x, d, w: o(x, d, w))(both.objective, both.x0, both.draws, width))
    R = np.array([args.rms_fraction, args.jitter_fraction]) * baseline
    if args.jitter_requirement:
        R[1] = args.jitter_requirement
    print(f"baseline {args.yield_:.0%} quantiles: RMS {baseline[0]:.1f}, jitter {baseline[1]:.3f} arcsec; requirements {R}", flush=True)
    # The problem, the solver and the check as values (issue 59): both outputs on one constraint
    # model built from the flags (the jitter's line on its logarithm with --log-fit; the twin
    # solve, the noise band, for the jitter's design), not Auto()'s defaults.
    def model(output):
        common = dict(units=args.secant_units, scatter=args.scatter, reach=args.secant_reach,
                      log=bool(args.log_fit) and output == "pointing_jitter", twin=output == "pointing_jitter")
        if args.surface is None:
            return tx.Secants(**common)
        return tx.Surface(box=tuple(args.surface), width=args.width, rounds=args.surface_rounds, **common)

    solver = tx.Sequential(widths=(args.width,), max_gradients=args.max_iterations)
    check = tx.Check(args.check_units) if args.check_units else None
    rms = tx.Requirement("pointing_rms", float(R[0]), model=model("pointing_rms"))
    jitter = tx.Requirement("pointing_jitter", float(R[1]), tol=args.jitter_tol, model=model("pointing_jitter"))
    designs = {}
    for label, requirements in (("lost motion alone", [rms]), ("lost motion and stability", [rms, jitter])):
        problem = tx.ToleranceProblem(pointing, requirements, tx.Yield(args.yield_), allow_proxy=args.fidelity != "planetary")
        wall, report = harness.wall(tx.propose_design, problem, solver, check=check, progress=True)
        result = report.result
        quantiles = np.asarray(eqx.filter_jit(lambda o, x, d, w: o(x, d, w))(both.objective, result.x, both.draws, width))
        designs[label] = dict(report=report, wall=wall, quantiles=quantiles)
        print(f"{label}: cost {report.cost:.3f}, status {report.status}, noise band {report.noise_band}, quantiles {quantiles}, "
              f"bands {np.round(report.band * 1e6, 1)} um, {wall:.0f} s; {report.diagnosis}", flush=True)
        for note in report.notes:
            print(f"  note: {note}", flush=True)

    verify = _design.at_width(objective(args.verify_fidelity), args.width)
    rows = []
    for label, d in designs.items():
        report = d["report"]
        wall, mc = harness.wall(tx.monte_carlo, verify, report.tolerances, args.verify_units, jax.random.key(2026),
                                chunk_size=args.chunk, progress=True, requirement=dict(zip(OUTPUTS, map(float, R))))
        summary = mc.summary()
        ok = mc.dataset["success"].values
        cells = []
        for name in OUTPUTS:
            s = summary[name]
            q = float(np.quantile(mc.dataset[name].values[ok], args.yield_)) if np.any(ok) else float("nan")
            cells += [f"{s['yield']:.3f} [{s['yield_low']:.3f}, {s['yield_high']:.3f}]", f"{q:.3f}", f"{float(np.mean(mc.dataset[name].values[ok])):.3f}"]
        r = report.result
        band = "-" if report.noise_band is None else f"{report.noise_band[0]:.3f} / {report.noise_band[1]:.3f}"
        rows.append((label, f"{report.cost:.3f}", report.status, band, f"{int(np.asarray(r.history.steps)[-1])}",
                     f"{r.optimality:.2g} / {r.band_optimality:.2g}", f"{d['quantiles'][0]:.1f} / {d['quantiles'][1]:.3f}", *cells,
                     " ".join(f"{m * 1e6:.1f}+-{b * 1e6:.1f}" for m, b in zip(report.nominal, report.band)), f"{d['wall']:.0f}", f"{wall:.0f}"))
        print(rows[-1], flush=True)
    total = time.perf_counter() - start
    harness.write_table(
        f"design_stability_{args.fidelity}" + ("_log" if args.log_fit else "") + ("_reach" if args.secant_reach else "")
        + ("_surface" if args.surface else "") + ("_rounds" if args.surface and args.surface_rounds > 1 else "")
        + ("_checked" if args.check_units else ""),
        f"A stability (jitter) requirement beside the lost-motion one, designed at {args.fidelity} fidelity, verified at "
        f"{args.verify_fidelity}",
        harness.command(args),
        ["design", "cost (IT7 = 1 per feature)", "status", "noise band: cost with secant seeds 1 / 2", "simulation batches",
         "optimality residual: all / bands",
         f"linearised {args.yield_:.0%} quantiles RMS / jitter (arcsec)",
         f"verified RMS yield [95 % Wilson] (<= {R[0]:.1f})", f"verified RMS {args.yield_:.0%} quantile", "verified RMS mean",
         f"verified jitter yield [95 % Wilson] (<= {R[1]:.3f})", f"verified jitter {args.yield_:.0%} quantile", "verified jitter mean",
         "zones nominal +- band (um): " + ", ".join(tx.design_names(scene)), "design wall (s)", "verification wall (s)"],
        rows,
        about=(f"Azimuth scan, designed at {args.fidelity}"
               + (f" (mass scaling {args.mass_scaling:g})" if args.fidelity == "planetary-scaled" else "")
               + f", verified on {args.verify_units} fresh units at {args.verify_fidelity}; window {args.settle}-{args.horizon} s, "
               f"{args.save_rate:g} saves/s, jitter above {args.cutoff:g} Hz; requirements at yield {args.yield_:.0%}: RMS <= {R[0]:.1f} "
               f"({args.rms_fraction:g} x baseline {baseline[0]:.1f}), jitter <= {R[1]:.3f} (baseline {baseline[1]:.3f}) arcsec; both "
               f"linearised by secants over {args.secant_units} units{' with their residual scatter' if args.scatter else ' (lines only)'}"
               + (", the jitter's line fitted to its logarithm (`--log-fit`)" if args.log_fit else "")
               + (f", the secant units spanning at least +-{args.secant_reach * 1e6:g} um (`--secant-reach`)" if args.secant_reach else "")
               + (f", on a response surface fitted over [{args.surface[0] * 1e6:g}, {args.surface[1] * 1e6:g}] um (`--surface`)"
                  + (f", then again over a box about each design's zones (the design held inside it), at most {args.surface_rounds} "
                     "surfaces (`--surface-rounds`)"
                     if args.surface_rounds > 1 else "") if args.surface else "")
               + ". "
               f"Total wall {total:.0f} s, compilation included."),
    )


if __name__ == "__main__":
    main()
