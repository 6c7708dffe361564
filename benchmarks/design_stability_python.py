"""The stability design through the Python API with every default, on the full stage: the same
problem as `tolerax design scan-azimuth-planetary --requirement R --jitter J --yield Y`
(`results/design_stability_defaults.md` at J = 0.2), stated as the README states a problem.

    taskset -c 0 python benchmarks/design_stability_python.py [--jitter 0.2] [--requirement 1061.7]
        [--yield 0.9] [--verify 100] [--seed 0]

The problem, as a user writes it:

    scene = tx.load_scene("scan-azimuth-planetary")
    problem = tx.ToleranceProblem(scene.objective(jitter_cutoff=20.0),
                                  [tx.Requirement("pointing_rms", R), tx.Requirement("pointing_jitter", J)],
                                  statistic=tx.Yield(Y))
    report = tx.propose_design(problem, progress=True)     # Sequential(), Check(200), Auto() on each

(the zones and the cost at their defaults, which are the scene file's: it states no
[tolerances] beyond a 10 um band). The proposal (the zones as drawn) is then written as a scene
file and simulated on `--verify` fresh full-stage units by `tolerax montecarlo` (seed `--seed`,
another stream than the design's check), as `tolerax design --verify` does. Writes
`design_stability_python.md`: the report's status, costs, noise band and checks, the
verification, the wall times, and the report's own table.
"""

import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import harness
import tolerax as tx


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--jitter", type=float, default=0.2, help="arcsec, above 20 Hz")
    parser.add_argument("--requirement", type=float, default=1061.7, help="RMS pointing, arcsec")
    parser.add_argument("--yield", dest="yield_", type=float, default=0.9)
    parser.add_argument("--verify", type=int, default=100, help="fresh full-stage units of the proposal (0: none)")
    parser.add_argument("--seed", type=int, default=0, help="the verification's units")
    parser.add_argument("--scene", default="scan-azimuth-planetary", help="a smoke test on another scene (with --allow-proxy)")
    parser.add_argument("--allow-proxy", action="store_true", help="a jitter read on a lumped joint (a smoke test only)")
    args = harness.parse_args(parser)
    scene = tx.load_scene(args.scene)
    problem = tx.ToleranceProblem(scene.objective(jitter_cutoff=20.0),
                                  [tx.Requirement("pointing_rms", args.requirement), tx.Requirement("pointing_jitter", args.jitter)],
                                  statistic=tx.Yield(args.yield_), allow_proxy=args.allow_proxy)
    start = time.perf_counter()
    report = tx.propose_design(problem, progress=True)
    design_wall = time.perf_counter() - start
    lines = [f"# The stability design through the Python API, every default (jitter {args.jitter:g} arcsec)", "",
             f"`{harness.command(args)}` ({harness.environment()}).", "",
             f"- status: **{report.status}**" + (f" ({report.diagnosis})" if report.diagnosis else ""),
             f"- cost: {report.proposal_cost:.4g} as drawn (whole ISO grades), {report.cost:.4g} continuous"
             + (f"; noise band (the twin set of units): {report.noise_band[0]:.4g} / {report.noise_band[1]:.4g}"
                if report.noise_band else ""),
             f"- design wall time: {design_wall:.0f} s"]
    checks = report.drawable.checks if report.drawable is not None and report.drawable.checks else ()
    lines += [f"- the drawn design's check ({o.requirement.name}): {c.text()}" for o, c in zip(report.outcomes, checks)]
    verify = None
    if args.verify:
        with tempfile.TemporaryDirectory() as tmp:
            proposal = tx.save_scene(scene.with_proposal(report, jitter_cutoff=20.0), Path(tmp) / "proposal.toml")
            begin = time.perf_counter()
            subprocess.run([sys.executable, "-m", "tolerax.cli.main", "montecarlo", str(proposal), "--n", str(args.verify),
                            "--requirement", str(args.requirement), "--jitter", str(args.jitter), "--jitter-cutoff", "20",
                            "--seed", str(args.seed), "--quiet", "--out", str(Path(tmp) / "verify")], check=True)
            verify_wall = time.perf_counter() - begin
            verify = json.loads((Path(tmp) / "verify" / "summary.json").read_text())
        for name, limit in (("pointing_rms", args.requirement), ("pointing_jitter", args.jitter)):
            v = verify[name]
            lines.append(f"- verified on {v['n_used']} fresh units of the proposal (seed {args.seed}): {name} <= {limit:g} in "
                         f"{v['yield']:.3f} [{v['yield_low']:.3f}, {v['yield_high']:.3f}] (95 % Wilson)")
        lines.append(f"- verification wall time: {verify_wall:.0f} s")
    lines += ["", "## The report", "", report.table(), ""]
    out = harness.results_dir() / "design_stability_python.md"
    out.write_text("\n".join(lines) + "\n")
    print("\n".join(lines[:12]))
    print(f"wrote {out}")


if __name__ == "__main__":
    main()
