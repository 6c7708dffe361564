"""The tolerance-design problem both design benchmarks solve (`design_comparison.py`,
`design_tradeoff.py`): the azimuth scan (`tolerax.scan("azimuth", fidelity=("lumped",
"ideal"))`, steady start, one reversal at 0.25 s), the RMS pointing error over `--horizon` s (61
saves, no settling window) of `--draws` fixed manufactured units, and an optimiser budget of
`--outer` x `--inner` steps per `tolerax.propose_design` run (the values API: `ToleranceProblem`,
`Sequential` or `AugmentedLagrangian`)."""

import equinox as eqx
import numpy as np

import tolerax as tx

import harness


def add_arguments(parser):
    """The problem's options, shared by both scripts (same names, same defaults)."""
    parser.add_argument("--horizon", type=float, default=0.6, help="simulated time per unit (s)")
    parser.add_argument("--draws", type=int, default=4, help="manufactured units in the robust objective")
    parser.add_argument("--method", default="sequential", choices=("sequential", "augmented-lagrangian"), help="propose_design's method")
    parser.add_argument("--outer", type=int, default=None,
                        help="propose_design's max_outer (sequential: gradients per width, default 20; augmented Lagrangian: outer iterations)")
    parser.add_argument("--inner", type=int, default=6, help="augmented Lagrangian: inner steps per outer iteration")


def pointing(args, fidelity="lumped"):
    """The objective `propose_design` is given: `PointingObjective` on the azimuth scan at
    `fidelity` (the design is made on lumped joints, verified on planetary ones)."""
    scene = tx.scan("azimuth", fidelity=(fidelity, "ideal"))
    return tx.PointingObjective(scene, duration=args.horizon, settle=0.0, start="steady", n_save=61)


def propose(pointing, requirement, args, yield_=None, secant_units=None):
    """`(seconds, report)`: one `tolerax.propose_design` run at `requirement` (arcsec, the RMS
    pointing error) timed by `harness.wall`: mean + 1 std over `--draws` units, or the yield
    `yield_` (checked on 200 fresh units, `propose_design`'s default check); its slopes by
    tangents (`Auto()`), or a line through `secant_units` units of the zone; `--method`'s
    solver on `--outer` x `--inner` steps (each solver's own default where not given)."""
    statistic = tx.MeanPlusKStd(units=args.draws) if yield_ is None else tx.Yield(yield_)
    model = None if secant_units is None else tx.Secants(units=secant_units, scatter=False, twin=False)
    problem = tx.ToleranceProblem(pointing, tx.Requirement("pointing_rms", requirement, model=model), statistic)
    if args.method == "sequential":
        solver = tx.Sequential() if args.outer is None else tx.Sequential(max_gradients=args.outer)
    else:
        solver = tx.AugmentedLagrangian(inner_steps=args.inner, **({} if args.outer is None else {"max_outer": args.outer}))
    return harness.wall(tx.propose_design, problem, solver)


def at_width(pointing, width):
    """`pointing` with every stage's smoothing width set to `width` (m)."""
    return eqx.tree_at(lambda q: q.scene, pointing, pointing.with_width(tx.design_of(pointing.scene), width))


def designed_tolerances(scene, names, nominal, band, other_band=10e-6):
    """`tx.Tolerances` over every feature of `scene`: the designed ones (`names`, zone middles
    `nominal` and half-widths `band`, m) and the others, which the design model lacks (the
    planetary joint's sun bearing), at the scene's own value +- `other_band` (m)."""
    designed = dict(zip(names, zip(np.asarray(nominal, dtype=float), np.asarray(band, dtype=float))))
    all_names = tx.design_names(scene)
    middles, bands = zip(*(designed.get(name, (float(v), other_band)) for name, v in zip(all_names, np.asarray(tx.design_of(scene)))))
    return tx.Tolerances(all_names, middles, bands)
