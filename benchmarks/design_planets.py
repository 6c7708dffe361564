"""Per-planet features designed where they are simulated: the azimuth joint's planetary stage,
every planet's pin clearance and backlash a feature of its own, against the design whose
planets share each feature (issue 30, item 4; `design_antenna_planets.md` showed that lumped
joints cannot design per-planet features).

    python benchmarks/design_planets.py [--yield 0.99] [--fraction 0.5] [--verify-units 200] [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=("planetary-scaled", "ideal"))` at the fast setting
(`scan-azimuth-fast`: masses x1000, rtol 1e-3, atol 1e-6, PI 0.3/0.3), +-0.5 deg at 1 Hz from a
steady start, RMS pointing error over 0.3-0.6 s (101 saves), smoothing 0.1 um. Two designs by
`propose_design(yield_=Y)` (sequential, one smoothing width, secant slopes over 2n + 2 units,
a `--check`-unit Monte Carlo check): (a) `default_stage()`, 5 features, the planets alike;
(b) `default_stage(distinct_planets=True)`, 11 features. Requirement P(RMS <= R) >= Y with R =
`--fraction` of the shared design's baseline linearised quantile (100 +- 10 um everywhere), the
same R for both. Each verified on `--verify-units` fresh units (key 2026) at the same fidelity.
Costs count features: three pins at one grade cost three times one shared pin feature, so the
per-planet design is charged for every part it tolerances (the shared one is not).
"""

import time

import jax
import numpy as np

import tolerax as tx
from tolerax.design.propose import design_problem

import _design
import harness


def pointing_for(distinct: bool, width: float):
    stage = tx.default_stage(distinct_planets=distinct)
    scene = tx.scan("azimuth", fidelity=("planetary-scaled", "ideal"), azimuth_stage=stage, mass_scaling=1000.0)
    objective = tx.PointingObjective(scene, duration=0.6, settle=0.3, start="steady", n_save=101,
                                     integrator=tx.Integrator(rtol=1e-3, atol=1e-6, pcoeff=0.3, icoeff=0.3, max_steps=400_000))
    return objective, _design.at_width(objective, width)


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--yield", dest="yield_", type=float, default=0.99)
    parser.add_argument("--fraction", type=float, default=0.5)
    parser.add_argument("--verify-units", type=int, default=200)
    parser.add_argument("--check", type=int, default=100, help="units of propose_design's Monte Carlo check")
    parser.add_argument("--outer", type=int, default=30, help="gradients at most")
    parser.add_argument("--chunk", type=int, default=10)
    args = harness.parse_args(parser)
    width = 1e-7
    start = time.perf_counter()
    rows, requirement, tables = [], None, []
    for label, distinct in (("planets alike (shared features)", False), ("each planet its own features", True)):
        pointing, verifying = pointing_for(distinct, width)
        n = len(tx.design_names(pointing.scene))
        options = dict(yield_=args.yield_, secant_units=2 * n + 2, widths=(width,), max_outer=args.outer, check_units=args.check)
        if requirement is None:
            problem = design_problem(pointing, yield_=args.yield_, secant_units=2 * n + 2)
            baseline = float(jax.jit(lambda x: problem.objective(x, problem.draws, width))(problem.x0))
            requirement = args.fraction * baseline
            print(f"baseline {args.yield_:.1%} quantile {baseline:.1f} arcsec; requirement {requirement:.1f}", flush=True)
        wall_design, report = harness.wall(tx.propose_design, pointing, requirement, progress=True, **options)
        print(report.table(), flush=True)
        tables += [f"### {label}", "", report.table(), ""]
        zones = tx.Tolerances(report.names, report.nominal, report.band)
        wall_verify, mc = harness.wall(tx.monte_carlo, verifying, zones, args.verify_units, jax.random.key(2026), chunk_size=args.chunk,
                                       progress=True, requirement={"pointing_rms": requirement})
        s = mc.summary()["pointing_rms"]
        values = mc.dataset["pointing_rms"].values[mc.dataset["success"].values]
        rows.append((label, f"{2 * n}", f"{report.cost:.3f}", "yes" if bool(report.result.converged) else "no",
                     f"{report.result.optimality:.2g} / {report.result.band_optimality:.2g} / {report.result.band_optimality_within_noise:.2g}",
                     f"{report.outcomes[0].objective:.1f}", f"{int(s['n_used'])} of {args.verify_units}",
                     f"{s['yield']:.3f} [{s['yield_low']:.3f}, {s['yield_high']:.3f}]",
                     f"{float(np.quantile(values, args.yield_)):.1f}", f"{wall_design:.0f}", f"{wall_verify:.0f}"))
        print(rows[-1], flush=True)
    harness.write_table(
        "design_planets",
        f"Per-planet features designed at planetary fidelity, yield {args.yield_:.0%}",
        harness.command(args),
        ["design", "variables", "cost (IT7 = 1 per feature)", "converged", "optimality residual: all / bands / bands within noise",
         f"linearised {args.yield_:.0%} quantile (arcsec)", "units used", f"verified yield [95 % Wilson] (RMS <= {requirement:.1f})",
         f"verified {args.yield_:.0%} quantile (arcsec)", "design wall (s)", "verification wall (s)"],
        rows,
        about=(f"Azimuth scan, planetary-scaled joint at the fast setting; requirement P(RMS <= {requirement:.1f} arcsec) >= "
               f"{args.yield_:g}; total wall {time.perf_counter() - start:.0f} s, compilation included."),
        notes=["The proposals:", "", *tables],
    )


if __name__ == "__main__":
    main()
