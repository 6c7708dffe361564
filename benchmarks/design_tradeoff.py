"""The trade-off curve of tolerance design: the cheapest design's cost against the required
pointing accuracy, one `propose_design` run per requirement (issue 12, item 8).

    python benchmarks/design_tradeoff.py [--requirements 300 500 800] [--method sequential] [--results DIR]

Same problem as `benchmarks/design_comparison.py` (`_design.py`): the azimuth scan (lumped, 0.6 s, steady start),
mean + 1 std of the RMS pointing error over 4 fixed manufactured units, lower limits of every
tolerance zone >= 5 um, bands 1-50 um, ISO 286 cost (1 per feature at IT7). Every run reuses one
compiled optimiser iteration: only the requirement's value changes. Writes
`benchmarks/results/design_tradeoff.md`, `.png` and `.json` (the points, which
`notebooks/design_and_yield.ipynb` plots at its small size; `--results DIR`: in DIR).
"""

import json

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tolerax as tx  # noqa: E402

import _design  # noqa: E402
import harness  # noqa: E402


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--requirements", type=float, nargs="+", default=[300.0, 500.0, 800.0])
    _design.add_arguments(parser)
    args = harness.parse_args(parser)
    pointing = _design.pointing(args)
    rows, points, curve = [], [], []
    for requirement in args.requirements:
        wall, report = _design.propose(pointing, requirement, args)
        print(report.table(), flush=True)
        met = report.objective <= requirement * (1 + 1e-3)
        points.append((requirement, report.cost, met))
        curve.append(dict(
            requirement=requirement, objective=report.objective, met=bool(met), cost=report.cost, baseline_cost=report.baseline[2],
            baseline_objective=report.baseline[3], names=list(report.names), nominal=report.nominal.tolist(), band=report.band.tolist(),
            grade=report.grade.tolist(), wall=wall,
        ))
        rows.append((
            f"{requirement:g}", f"{report.objective:.0f}", "yes" if met else "no", f"{report.cost:.3g}", f"{report.baseline[2]:.3g}",
            ", ".join(f"{b * 1e6:.0f}" for b in report.band),
            ", ".join(f"IT{g:.1f}" for g in report.grade),
            ", ".join(f"{(n - b) * 1e6:.0f}" for n, b in zip(report.nominal, report.band)),
            f"{report.multiplier:.3g}", f"{wall:.0f}",
        ))
    fig, ax = plt.subplots(figsize=(5, 3.5))
    req, cost, met = (np.array(v) for v in zip(*points))
    ax.plot(req, cost, "-", color="C0")
    ax.plot(req[met], cost[met], "o", color="C0", label="requirement met")
    ax.plot(req[~met], cost[~met], "x", color="C3", label="not met within the budget")
    ax.set_xlabel("required pointing error, mean + 1 std of RMS (arcsec)")
    ax.set_ylabel("tolerance cost (1 per feature at IT7)")
    ax.legend()
    fig.tight_layout()
    png = harness.results_dir() / "design_tradeoff.png"
    fig.savefig(png, dpi=120)
    (harness.results_dir() / "design_tradeoff.json").write_text(json.dumps(dict(command=harness.command(args), points=curve), indent=1))
    harness.write_table(
        "design_tradeoff",
        "Tolerance cost against required pointing accuracy",
        harness.command(args),
        ["requirement (arcsec)", "objective (arcsec)", "met", "cost", "baseline cost", "bands +- (um)", "ISO grades", "lower limits (um)",
         "multiplier (cost per arcsec)", "wall (s)"],
        rows,
        about=(
            f"Features in order: {', '.join(tx.design_names(pointing.scene))}. method {args.method} (max_outer {args.outer}, inner {args.inner}). "
            f"Figure: `{png.name}`. The multiplier is the optimiser's estimate of d cost / d requirement (its sign reversed)."
        ),
    )


if __name__ == "__main__":
    main()
