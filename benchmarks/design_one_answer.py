"""One problem, one answer: the stability design of `design_stability.py` through its entry
points, and with independent sets of secant units (issue 39, item 5).

    python benchmarks/design_one_answer.py [--seeds 1 2] [--max-iterations 40] [--results DIR]

The problem (as `design_stability.py --yield 0.9 --rms-fraction 0.6 --jitter-requirement 0.2
--secant-units 16 --max-iterations 40`): azimuth scan, planetary-scaled joint (mass scaling
1000), steady start, window 0.3-0.6 s at 500 saves/s, rtol 1e-6, smoothing 0.1 um; at yield
90 %, RMS <= 0.6 x the baseline's linearised quantile and jitter (above 20 Hz) <= 0.2 arcsec,
both linearised by secants over 16 units with their residual scatter.

Rows: (a) `sequential_design` on `design_problem(...)` as `design_stability.py` calls it;
(b) `propose_design(pointing, [Requirement("pointing_rms", R), Requirement("pointing_jitter",
0.2)], ...)` with the same settings, no Monte Carlo check, for each `--seeds` (the seed of the
secant units' Latin hypercube: `LinearisedYield.secant_seed`). (a) and (b) at seed 1 solve the
same problem and must agree to the optimiser's own tolerance; the seeds' spread is the cost's
noise band, what a "converged" answer on fitted slopes can be trusted to. `--cli`: (c) `tolerax
design` on the same scene written as a scene file (`--requirement R --jitter 0.2 --yield 0.9
--model secants --secant-units 16 --widths 1e-7 --outer 40 --check 0 --allow-proxy`), with its own noise band (secant seeds
1 and 2, `propose_design`'s default): the third entry point, and what it says of the band.
"""

import re
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import equinox as eqx
import jax.numpy as jnp
import numpy as np

import harness
import tolerax as tx
from tolerax.design.problem import design_problem
from tolerax.design.surface import secant_standard_error
from tolerax.design.sequential import sequential_design

OUTPUTS = ("pointing_rms", "pointing_jitter")


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--max-iterations", type=int, default=40)
    parser.add_argument("--secant-units", type=int, default=16)
    parser.add_argument("--rms-fraction", type=float, default=0.6)
    parser.add_argument("--jitter-requirement", type=float, default=0.2)
    parser.add_argument("--skip-direct", action="store_true", help="leave out row (a)")
    parser.add_argument("--cli", action="store_true", help="add row (c): tolerax design on the scene as a scene file")
    args = harness.parse_args(parser)
    start = time.perf_counter()
    scene = tx.scan("azimuth", fidelity=("planetary-scaled", "ideal"))
    scene = eqx.tree_at(lambda s: s.azimuth.mass_scaling, scene, jnp.asarray(1000.0))
    pointing = tx.PointingObjective(scene, duration=0.6, settle=0.3, start="steady", n_save=301, integrator=tx.Integrator(max_steps=400_000),
                                    jitter_cutoff=20.0)
    width = 1e-7
    both = design_problem(pointing, yield_=0.9, secant_units=args.secant_units, output=OUTPUTS, scatter=True)
    baseline = np.asarray(eqx.filter_jit(lambda o, x, d, w: o(x, d, w))(both.objective, both.x0, both.draws, jnp.asarray(width)))
    R = np.array([args.rms_fraction * baseline[0], args.jitter_requirement])
    se = np.asarray(secant_standard_error(both.objective.objective, tx.Design(both.x0.nominal + both.x0.band, both.x0.band), width))
    tols = (0.01, min(max(0.01, 2.0 * float(se[1]) / R[1]), 0.5))
    print(f"baseline quantiles {baseline}, requirements {R}, tolerances {tols}", flush=True)
    rows = []

    def row(label, seed, wall, cost, converged, status, batches, quantiles, bands):
        rows.append((label, str(seed), f"{cost:.3f}", "yes" if converged else "no", status, str(batches),
                     f"{quantiles[0]:.1f} / {quantiles[1]:.3f}", " ".join(f"{b * 1e6:.1f}" for b in bands), f"{wall:.0f}"))
        print(rows[-1], flush=True)

    if not args.skip_direct:
        wall, result = harness.wall(
            sequential_design, both.objective, both.features, requirement=tuple(R), lower=both.lower, upper=both.upper,
            draws=both.draws, x0=both.x0, cost_model=both.cost_model, width=jnp.asarray(width), max_iterations=args.max_iterations,
            tol=tols, progress=True, gradient_noise=both.gradient_noise)
        row("(a) sequential_design, as design_stability.py", 1, wall, float(result.cost), bool(result.converged), "-",
            int(np.asarray(result.history.steps)[-1]), np.asarray(result.objective), np.asarray(result.x.band))
    requirements = [tx.Requirement("pointing_rms", float(R[0])), tx.Requirement("pointing_jitter", float(R[1]))]
    for seed in args.seeds:
        wall, report = harness.wall(tx.propose_design, pointing, requirements, widths=(width,), max_outer=args.max_iterations,
                                    yield_=0.9, secant_units=args.secant_units, secant_seed=seed, check_units=0, progress=True,
                                    noise_band=False,  # the seeds are this benchmark's rows
                                    allow_proxy=True)  # the scaled stage's jitter, knowingly: this benchmark is about entry points
        row("(b) propose_design", seed, wall, report.cost, bool(report.result.converged), report.status,
            int(np.asarray(report.result.history.steps)[-1]), [o.objective for o in report.outcomes], report.band)
    if args.cli:
        wall, (cost, status, twin, text) = harness.wall(_cli, R, args)
        band = "" if twin is None else f"; its noise band {cost:.3f} / {twin:.3f} (seeds 1 / 2)"
        rows.append(("(c) tolerax design", "1", f"{cost:.3f}", "-", status + band, "-", "-", "-", f"{wall:.0f}"))
        print(rows[-1], twin, flush=True)
    costs = [float(r[2]) for r in rows if r[0].startswith("(b)")]
    band = (max(costs) - min(costs)) if len(costs) > 1 else float("nan")
    harness.write_table(
        "design_one_answer", "One problem, one answer: the stability design through its entry points and secant seeds",
        harness.command(args),
        ["entry point", "secant seed", "cost", "converged", "status", "gradient batches", "linearised 90% quantiles RMS / jitter (arcsec)",
         "bands +- (um)", "wall (s)"], rows,
        about=(f"Azimuth scan, planetary-scaled x1000, window 0.3-0.6 s at 500/s, rtol 1e-6, width 0.1 um; yield 90 %: RMS <= "
               f"{R[0]:.1f} (0.6 x baseline {baseline[0]:.1f}), jitter <= {R[1]:.3f} arcsec; {args.secant_units} secant units with "
               f"scatter; tolerances {tols[0]:.2f} / {tols[1]:.2f}. Total wall {time.perf_counter() - start:.0f} s."),
        notes=[f"Noise band of the cost over the secant seeds {args.seeds}: {band:.3f} (max - min of the propose_design rows)."],
    )


SCENE = """title = "design_one_answer: the stability problem's scene"
[scene]
kind = "scan"
mode = "azimuth"
fidelity = ["planetary-scaled", "ideal"]
mass_scaling = 1000.0
[run]
duration = 0.6
settle = 0.3
start = "steady"
n_save = 301
rtol = 1e-6
atol = 1e-9
[tolerances]
band = 1e-5
"""


def _cli(R, args):
    """Row (c): `tolerax design` in a subprocess on the problem's scene as a scene file:
    `(cost, status, the noise band's other cost or None, the report's first line)` read back
    from its design.md."""
    with tempfile.TemporaryDirectory() as tmp:
        scene = Path(tmp) / "stability.toml"
        scene.write_text(SCENE)
        cmd = [sys.executable, "-c", "import sys; from tolerax.cli import main; sys.exit(main())", "design", str(scene),
               "--requirement", repr(float(R[0])), "--jitter", repr(float(R[1])), "--yield", "0.9", "--model", "secants",
               "--secant-units", str(args.secant_units), "--widths", "1e-7", "--outer", str(args.max_iterations), "--check", "0",
               "--allow-proxy", "--out", str(Path(tmp) / "out")]
        done = subprocess.run(cmd, capture_output=True, text=True)
        if done.returncode not in (0, 4):
            raise RuntimeError(f"tolerax design failed ({done.returncode}):\n{done.stderr[-3000:]}")
        text = (Path(tmp) / "out" / "design.md").read_text()
    head = text.splitlines()[0] if not text.startswith("**Not a proposal") else text.split("\n\n")[1]
    cost = float(re.search(r"cost ([0-9.]+)", head).group(1))
    status = re.match(r"\*\*Not a proposal: ([a-z -]+)\.", text)
    twin = re.search(r"Cost noise band: ([0-9.]+) with these secant units, ([0-9.]+)", text)
    return (cost, status.group(1) if status else "converged", None if twin is None else float(twin.group(2)),
            text.splitlines()[0])


if __name__ == "__main__":
    main()
