"""`propose_design(method="sequential")` on the design comparison's problem, from several starts,
beside the augmented-Lagrangian default in the same run.

    python benchmarks/design_sequential.py [--requirement 400] [--starts 10 5 30] [--outer 4 --inner 6]

The problem is `benchmarks/design_comparison.py`'s (`tolerax.design.propose.design_problem` on
the lumped azimuth scan, 0.6 s from a steady start, mean + 1 std of the RMS pointing error over 4
fixed units, ISO 286 cost of the full zone width, lower limits >= 5 um): each start is a
different starting band (the starting lower limit is the nominal minus it). Reports per run the
cost, the objective at the proposal (same units, same widths as the optimiser's last), whether
the method says it converged, the gradient evaluations and the wall time (compilation included:
each run compiles its own program).
"""

import numpy as np

import _design
import harness


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--requirement", type=float, default=400.0)
    parser.add_argument("--starts", nargs="+", type=float, default=[10.0, 5.0, 30.0], help="starting bands, um")
    parser.add_argument("--max-iterations", type=int, default=20, help="sequential: gradients per smoothing width at most")
    _design.add_arguments(parser)  # --horizon, --draws; --outer x --inner: the augmented Lagrangian's budget
    args = harness.parse_args(parser)
    pointing = _design.pointing(args)
    rows = []
    runs = [("sequential", band, dict(method="sequential", outer=args.max_iterations)) for band in args.starts]
    runs.append(("augmented-lagrangian", 10.0, {}))
    for method, band, options in runs:
        wall, report = _design.propose(pointing, args.requirement, args, band=band * 1e-6, **options)
        res = report.result
        gradients = int(np.asarray(res.history.steps)[-1]) if method == "sequential" else args.outer * (args.inner + 1)
        rows.append((
            method, f"{band:g}", f"{report.cost:.4f}", f"{report.objective:.2f}", "yes" if report.objective <= args.requirement * 1.01 else "no",
            "yes" if bool(res.converged) else "no", str(gradients), f"{wall:.0f}",
            " ".join(f"{b * 1e6:.2f}" for b in report.band),
        ))
        print(rows[-1], flush=True)
    harness.write_table(
        "design_sequential",
        "Tolerance design by sequential linearisation against the augmented Lagrangian",
        harness.command(args),
        ["method", "start band (um)", "cost (IT7 = 1 per feature)", f"objective (arcsec, <= {args.requirement:g})", "meets (1 %)",
         "converged", "gradients", "wall (s)", "bands (um)"],
        rows,
        about=f"Lumped azimuth scan, {args.horizon} s, mean + 1 std over {args.draws} fixed units; smoothing widths 1 um "
        "then 0.1 um (the sequential method converges at each in turn; the augmented Lagrangian follows the same continuation).",
    )


if __name__ == "__main__":
    main()
