"""What drives the jitter, at each fidelity: a least-squares line of the jitter over the features
of the paired units `fidelity_adequacy.py` simulated (no new simulation).

    python benchmarks/jitter_drivers.py [--scene scan-azimuth|antenna-dual] [--results DIR]

Reads `results/fidelity_adequacy_<scene>.json` (20 units uniform within +-10 um of 100 um over
the full stage's features, each simulated at every fidelity with the same values) and fits,
per fidelity, jitter = a + sum_i s_i (x_i - 100 um) by ordinary least squares (NumPy), with each
slope's standard error from the residual scatter. A slope whose 95 % interval excludes 0 says a
feature drives the jitter, and its sign in which direction; the fit's R^2 says how much of the
unit-to-unit spread the features explain at all (a chaotic output: little). A proxy reads the
design's question only if it finds the same drivers as the full stage.
"""

import json

import numpy as np
import scipy.stats

import harness


def fit(x, y):
    """OLS of `y` on `x` (n, k) with an intercept: slopes (k,), their standard errors, R^2."""
    n, k = x.shape
    a = np.column_stack([np.ones(n), x])
    coef, *_ = np.linalg.lstsq(a, y, rcond=None)
    resid = y - a @ coef
    dof = n - k - 1
    s2 = float(resid @ resid) / dof
    cov = s2 * np.linalg.inv(a.T @ a)
    r2 = 1.0 - float(resid @ resid) / float(((y - y.mean()) ** 2).sum())
    return coef[1:], np.sqrt(np.diag(cov))[1:], r2, dof


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scene", choices=("scan-azimuth", "antenna-dual"), default="scan-azimuth")
    args = harness.parse_args(parser)
    source = harness.ROOT / "benchmarks" / "results" / f"fidelity_adequacy_{args.scene}.json"
    data = json.loads(source.read_text())
    names = data["features"]
    x = (np.asarray(data["values"]) - 100e-6) * 1e6  # um from the nominal
    rows = []
    for label, outputs in data["results"].items():
        y = np.asarray(outputs["pointing_jitter"])
        ok = np.isfinite(y)
        slopes, se, r2, dof = fit(x[ok], y[ok])
        t = scipy.stats.t.ppf(0.975, dof)
        cells = []
        for s, e in zip(slopes, se):
            mark = "+" if s - t * e > 0 else ("-" if s + t * e < 0 else "")
            cells.append(f"{1e3 * s:+.1f} ± {1e3 * t * e:.1f}{' ' + mark if mark else ''}")
        rows.append((label, f"{np.mean(y[ok]):.3f}", f"{r2:.2f}", *cells))
    harness.write_table(
        f"jitter_drivers_{args.scene}", f"What drives the jitter at each fidelity: {args.scene}", harness.command(args),
        ["fidelity", "mean jitter (arcsec)", "R^2 of the line", *[f"{n} (marcsec/um)" for n in names]], rows,
        about=(f"Least-squares line of the jitter over the features of the {data['units']} paired units of "
               f"`{source.name}` (seed {data['seed']}); each slope with its 95 % interval (Student t, {dof} degrees of freedom); "
               "`+`/`-`: the interval excludes 0 (the feature drives the jitter up / down as it opens)."),
    )


if __name__ == "__main__":
    main()
