"""A tolerance design for the end of life as well as the beginning (issue 43): the RMS pointing
requirement met at yield `--yield` both as built and after `--years` of wear, against the design
made for the beginning of life alone, both verified by Monte Carlo at both ends of life.

    python benchmarks/design_life.py [--years 10] [--duty 1.0] [--yield 0.9] [--rms-fraction 0.6]
        [--secant-units 32] [--verify-units 50] [--spread] [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=("planetary", "ideal"))` (the azimuth stage in full:
its journal clearances wear, and since ef55dd5 its tooth flanks: the committed result predates
that), steady start, Tsit5 at rtol 1e-6, window [0.3, 0.6] s at 500
saves/s, with `PointingObjective(life=MissionLife.from_years(--years, --duty, MoS2 sputtered
film median, points=2))`: each unit is simulated as built, at mid-life and at the end of life
(3 solves), its outputs `pointing_rms` and `pointing_rms_eol`. Requirement: both at most
`--rms-fraction` x the nominal design's RMS as built (one pointing budget for the whole life).
Both designs by `tolerax.propose_design` on a response surface over [5, 100] um refitted
over the design's zones (`surface_box`, `surface_rounds`; the forward-mode tangents of the full
stage's RMS are not its slopes over a zone: `tests/test_life.py` checks them only in a start-up),
`--secant-units` units per surface, lower limits >= 5 um, bands 1-50 um, ISO 286 cost; no
Monte Carlo check inside (the verification is the check). Verified on `--verify-units` fresh
units each (`tolerax.monte_carlo`, key 2026): the yield at each end of life with its 95 % Wilson
interval. The wear rate is the lubricant's median for every unit, or with `--spread` drawn per
unit log-uniformly over the lubricant's band (`spread_of_lubricant`): then the two-ended
design's secant units draw it too (`MissionLife(spread=...)`: a design over the band) and both
designs are verified with it drawn (results file `design_life_spread`). The beginning-of-life
design is made on the same objective without the life (its one output is the as-built run's,
a third of the solves).
"""

import time

import jax
import numpy as np

import tolerax as tx
from tolerax.design.life import MissionLife, spread_of_lubricant
from tolerax.physics import wear as W

import _design
import harness


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--years", type=float, default=10.0)
    parser.add_argument("--duty", type=float, default=1.0)
    parser.add_argument("--yield", dest="yield_", type=float, default=0.9)
    parser.add_argument("--rms-fraction", type=float, default=0.6)
    parser.add_argument("--secant-units", type=int, default=32)
    parser.add_argument("--surface-rounds", type=int, default=3)
    parser.add_argument("--verify-units", type=int, default=50)
    parser.add_argument("--max-iterations", type=int, default=30)
    parser.add_argument("--width", type=float, default=1e-7)
    parser.add_argument("--lubricant", default="MoS2 sputtered film, vacuum", choices=sorted(W.LUBRICANTS))
    parser.add_argument("--chunk", type=int, default=10)
    parser.add_argument("--spread", action="store_true", help="draw each unit's wear rate over the lubricant's band")
    args = harness.parse_args(parser)
    start = time.perf_counter()
    scene = tx.scan("azimuth", fidelity=("planetary", "ideal"))
    spread = spread_of_lubricant(args.lubricant) if args.spread else None
    life = MissionLife.from_years(args.years, args.duty, W.ArchardWear.from_lubricant(args.lubricant), points=2, spread=spread)
    pointing = tx.PointingObjective(scene, duration=0.6, settle=0.3, start="steady", n_save=301, life=life)
    as_built = tx.PointingObjective(scene, duration=0.6, settle=0.3, start="steady", n_save=301)
    baseline = pointing(tx.design_of(scene), args.width)
    print(f"nominal design: RMS {float(baseline['pointing_rms']):.1f} as built, {float(baseline['pointing_rms_eol']):.1f} at the end "
          "of life (arcsec)", flush=True)
    options = dict(yield_=args.yield_, secant_units=args.secant_units, widths=(args.width,), max_outer=args.max_iterations,
                   check_units=0, progress=True, surface_box=(5e-6, 100e-6), surface_width=args.width,
                   surface_rounds=args.surface_rounds)
    R = args.rms_fraction * float(baseline["pointing_rms"])
    print(f"requirement {R:.1f} arcsec at both ends of life", flush=True)
    designs = {}
    for label, objective, outputs in (("beginning of life alone", as_built, ("pointing_rms",)),
                                      ("beginning and end of life", pointing, ("pointing_rms", "pointing_rms_eol"))):
        requirements = [tx.Requirement(o, R, secants=True) for o in outputs]
        wall, report = harness.wall(tx.propose_design, objective, requirements, **options)
        designs[label] = (report, wall)
        print(f"{label}: cost {report.cost:.3f}, status {report.status}, noise band {report.noise_band}, "
              f"zones {np.round(np.asarray(report.nominal) * 1e6, 1)} +- {np.round(np.asarray(report.band) * 1e6, 1)} um, {wall:.0f} s; "
              f"{report.diagnosis}", flush=True)
        for note in report.notes:
            print(f"  note: {note}", flush=True)
    verify = _design.at_width(pointing, args.width)
    rows = []
    for label, (report, wall) in designs.items():
        tolerances = report.tolerances if spread is None else report.tolerances.joined(life.spread_tolerances())
        vwall, mc = harness.wall(tx.monte_carlo, verify, tolerances, args.verify_units, jax.random.key(2026),
                                 chunk_size=args.chunk, progress=True,
                                 requirement={"pointing_rms": R, "pointing_rms_eol": R})
        summary = mc.summary()
        ok = mc.dataset["success"].values
        cells = []
        for name in ("pointing_rms", "pointing_rms_eol"):
            s = summary[name]
            q = float(np.quantile(mc.dataset[name].values[ok], args.yield_)) if np.any(ok) else float("nan")
            cells += [f"{s['yield']:.3f} [{s['yield_low']:.3f}, {s['yield_high']:.3f}]", f"{q:.1f}"]
        rows.append((label, f"{report.cost:.3f}", report.status,
                     "-" if report.noise_band is None else f"{report.noise_band[0]:.3f} / {report.noise_band[1]:.3f}", *cells,
                     " ".join(f"{m * 1e6:.1f}+-{b * 1e6:.1f}" for m, b in zip(report.nominal, report.band)), f"{wall:.0f}",
                     f"{vwall:.0f}"))
        print(rows[-1], flush=True)
    harness.write_table(
        "design_life" + ("_spread" if spread else ""),
        "A tolerance design for the end of life as well as the beginning, against the beginning of life's alone",
        harness.command(args),
        ["design", "cost (IT7 = 1 per feature)", "status", "noise band (secant seeds 1 / 2)",
         f"verified yield as built [95 % Wilson] (RMS <= {R:.1f})", f"verified {args.yield_:.0%} quantile as built",
         f"verified yield at end of life [95 % Wilson] (RMS <= {R:.1f})", f"verified {args.yield_:.0%} quantile at end of life",
         "zones nominal +- band (um): " + ", ".join(tx.design_names(scene)), "design wall (s)", "verification wall (s)"],
        rows,
        about=(f"Azimuth scan at planetary fidelity, window 0.3-0.6 s, {args.years:g} years at duty {args.duty:g} "
               f"({float(life.operating_time) / 3.15576e7:g} operating years) of `{args.lubricant}` wear ("
               + ("median rate, every unit" if spread is None else f"rate drawn per unit log-uniformly over x{spread[0]:.3g} to "
                  f"x{spread[1]:.3g} the median, in the two-ended design's units and in every verified unit") + "), "
               f"2 life points; requirement RMS <= {R:.1f} arcsec at yield {args.yield_:.0%} ({args.rms_fraction:g} x the nominal "
               f"design's RMS as built); response surfaces of {args.secant_units} units over [5, 100] um then the design's zones (at most "
               f"{args.surface_rounds}); verified on {args.verify_units} fresh units at both ends of life. Nominal design (100 um): "
               f"RMS {float(baseline['pointing_rms']):.1f} as built, {float(baseline['pointing_rms_eol']):.1f} at the end of life. "
               f"Total wall {time.perf_counter() - start:.0f} s, compilation included."),
    )


if __name__ == "__main__":
    main()
