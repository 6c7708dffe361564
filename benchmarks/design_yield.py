"""A yield requirement on a fast scan: the simulated design against the geometric stack-up's,
both verified on fresh units (issue 30, must-show 2).

    python benchmarks/design_yield.py [--amplitude 2] [--period 0.5] [--yield 0.99] [--fraction 0.5]
        [--verify-units 400] [--calibration 8] [--results DIR]

Scene: the azimuth scan at lumped fidelity (`tolerax.scan("azimuth", amplitude=, period=)`),
+-2 deg at 2 Hz by default, 0.6 s from a steady start, RMS pointing error over the run (61 saves).
Requirement: P(RMS <= R) >= Y over units made uniformly within the bands, R = `--fraction` of
the baseline design's linearised Y-quantile (100 um +- 10 um everywhere) unless `--requirement`
is given. Features, bounds and cost as `propose_design`'s (lower limits >= 5 um, bands 1-50 um,
ISO 286 cost of the full zone).

- `simulated`: `propose_design(yield_=Y)`: the Y-quantile linearised at the zone middles from one
  simulation with a tangent per feature, rebuilt at each iterate, then a 200-unit Monte Carlo
  check and its shift.
- `geometric stack-up`: what an engineer does from the drawings: the one-sided lost motion
  O = w . v (`lost_motion_weights`: 4.39 arcsec/um per backlash, 8.25 per um of pin clearance,
  0 for the output bearing), RMS modelled as alpha + beta * O with alpha, beta fitted on
  `--calibration` simulated units (Latin hypercube of 5-60 um), and the yield as the Y-quantile
  of that model over the bands (the same Sobol draws and quantile estimate); its cheapest design
  is solved exactly (`sequential_design` on the model).

Both designs are then simulated on `--verify-units` fresh units (a key neither saw): yield with
its 95 % Wilson interval, and cost. The table also gives the simulated sensitivities at the
simulated design beside the stack-up's weights (per um, normalised to the sun backlash).
"""

import math
import time

import jax
import jax.numpy as jnp
import numpy as np
import scipy.stats

import tolerax as tx
from tolerax.design.features import lost_motion_weights
from tolerax.design.propose import design_problem
from tolerax.design.check import yield_check
from tolerax.design.reliability import LinearisedYield, linear_quantile
from tolerax.design.sequential import sequential_design

import harness


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--amplitude", type=float, default=2.0, help="scan amplitude, deg")
    parser.add_argument("--period", type=float, default=0.5, help="scan period, s")
    parser.add_argument("--horizon", type=float, default=0.6, help="simulated time per unit, s")
    parser.add_argument("--yield", dest="yield_", type=float, default=0.99)
    parser.add_argument("--requirement", type=float, default=None, help="arcsec (default: --fraction of the baseline's quantile)")
    parser.add_argument("--fraction", type=float, default=0.5)
    parser.add_argument("--calibration", type=int, default=8, help="stack-up: simulated units that calibrate it")
    parser.add_argument("--check-units", type=int, default=200, help="the simulated design's Monte Carlo check")
    parser.add_argument("--verify-units", type=int, default=400)
    args = harness.parse_args(parser)
    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"), amplitude=math.radians(args.amplitude), period=args.period)
    pointing = tx.PointingObjective(scene, duration=args.horizon, settle=0.0, start="steady", n_save=61)
    problem = design_problem(pointing, yield_=args.yield_)
    width = 1e-7
    names = problem.features.names
    n = len(names)
    baseline = float(jax.jit(lambda x: problem.objective(x, problem.draws, width))(problem.x0))
    R = args.requirement if args.requirement is not None else args.fraction * baseline
    print(f"baseline {args.yield_:.1%} quantile {baseline:.1f} arcsec; requirement {R:.1f}", flush=True)

    # --- the simulated design
    wall_sim, report = harness.wall(tx.propose_design, pointing, R, yield_=args.yield_, check_units=args.check_units)
    print(report.table(), flush=True)

    # --- the geometric stack-up
    start = time.perf_counter()
    weights = jnp.asarray(lost_motion_weights(scene))
    units = 5e-6 + 55e-6 * scipy.stats.qmc.LatinHypercube(d=n, seed=0).random(args.calibration)
    run = jax.jit(lambda v: pointing(v, width)["pointing_rms"])
    rms = np.array([float(run(jnp.asarray(v))) for v in units])
    lost = units @ np.asarray(weights)
    beta, alpha = np.polyfit(lost, rms, 1)
    r2 = float(np.corrcoef(lost, rms)[0, 1] ** 2)

    def model(x, draws, _width):  # x = Design(lower limit, band), as the problem's objective reads it
        middle = tx.Design(x.nominal + x.band, x.band)
        return alpha + linear_quantile(jnp.dot(beta * weights, middle.nominal), beta * weights, middle, draws, args.yield_)

    stack = sequential_design(model, problem.features, requirement=R, lower=problem.lower, upper=problem.upper, draws=problem.draws,
                              x0=problem.x0, cost_model=problem.cost_model, max_iterations=20, trust_region=1.0)
    wall_stack = time.perf_counter() - start

    # --- verification on fresh units
    designs = {
        "simulated (propose_design)": (tx.Design(jnp.asarray(report.nominal), jnp.asarray(report.band)), float(report.cost), wall_sim),
        "geometric stack-up": (tx.Design(stack.x.nominal + stack.x.band, stack.x.band), float(stack.cost), wall_stack),
    }
    objective = LinearisedYield(pointing, q=args.yield_)
    rows, verified = [], {}
    for label, (x, cost, wall) in designs.items():
        t0 = time.perf_counter()
        check = yield_check(objective, x, R, args.verify_units, jax.random.key(2024), width=width)
        verified[label] = check
        print(label, check.text(), f"({time.perf_counter() - t0:.0f} s)", flush=True)
        rows.append((
            label, f"{cost:.3f}", f"{wall:.0f}", ", ".join(f"{v * 1e6:.1f}" for v in np.asarray(x.nominal - x.band)),
            ", ".join(f"{v * 1e6:.1f}" for v in np.asarray(x.band)), str(check.n - check.n_failed),
            f"{check.yield_simulated:.3f} [{check.interval[0]:.3f}, {check.interval[1]:.3f}]",
            f"{check.quantile_simulated:.1f}",
        ))
    s = np.asarray(report.outcomes[0].sensitivity.nominal)
    w = np.asarray(weights)
    ref = list(names).index("azimuth.sun_backlash")
    weights_row = [
        "Per um of each feature, relative to the sun backlash: simulated at the proposal "
        + ", ".join(f"{name.split('.')[-1]} {s[k] / s[ref]:.2f}" for k, name in enumerate(names))
        + "; drawings (the stack-up) " + ", ".join(f"{name.split('.')[-1]} {w[k] / w[ref]:.2f}" for k, name in enumerate(names))
        + f". Stack-up calibration: RMS = {alpha:.1f} + {beta:.3f} O (arcsec), R^2 = {r2:.3f} over {args.calibration} units.",
    ]
    harness.write_table(
        "design_yield",
        f"Yield {args.yield_:.0%} on a +-{args.amplitude:g} deg, {1 / args.period:g} Hz scan: simulated design against the geometric stack-up",
        harness.command(args),
        ["design", "cost (IT7 = 1 per feature)", "design wall (s, compilation included)", "lower limits (um)", "bands +- (um)",
         "fresh units", f"verified yield [95 % Wilson] (RMS <= {R:.1f} arcsec)", f"verified {args.yield_:.0%} quantile (arcsec)"],
        rows,
        about=(f"Lumped azimuth scan, {args.horizon} s from a steady start; requirement P(RMS <= {R:.1f} arcsec) >= {args.yield_:g} "
               f"({args.fraction:g} x the baseline's linearised quantile {baseline:.1f}); features {', '.join(names)}; smoothing "
               f"width {width:g} m. Verification on {args.verify_units} fresh units (key 2024) at the design fidelity."),
        notes=weights_row + ["The simulated design's report:", report.table()],
    )


if __name__ == "__main__":
    main()
