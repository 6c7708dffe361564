"""What `Auto()` measures to choose a requirement's constraint model: the share of an output's
variance over units drawn within the starting zones that a line in the features does not carry
(`tolerax.design.probe.scatter_share`, one minus the adjusted R^2 of a least-squares line), per
scene and output, over several sets of units.

    python benchmarks/auto_model.py [--units K] [--seeds 3] [--scenes scan-azimuth,...] [--generated 1,3,5,12]

Scenes: the embedded ones named (lumped, planetary-scaled, full planetary) and the generated
mechanisms of `design_matrix.py` named by number (never tuned on). At each, the design problem's
starting zone (`design_problem`'s `x0`: the scene's nominals, its band) and the smoothing width
`Sequential()` judges at; `--units` units drawn uniformly within the zones (default: as many as
`Auto()` takes, `PROBE_UNITS`), one `monte_carlo` run per set giving every output, set k from
`jax.random.key(PROBE_KEY + k - 1)` (the first is the one `propose_design` draws). The share is about 0 where the features
determine the output (a tangent or a line reads it) and about 1 where it scatters from unit to
unit for reasons they do not carry (the chaotic rattle's jitter: there a response surface over
the bounds is the model that verified). Writes `auto_model.md` and `auto_model.json`.
"""

import json
import time

import jax
import numpy as np

import harness
import tolerax as tx
from tolerax.design.problem import design_problem
from tolerax.design.spec import SCATTER_SHARE
from tolerax.design.probe import PROBE_KEY, PROBE_UNITS, scatter_share
from tolerax.design.types import Design

OUTPUTS = ("pointing_rms", "pointing_jitter")
NOTES = (
    "How the threshold was set. A first pass (16 units on a Latin hypercube of the zone, a line fitted through them) over "
    "the four embedded scenes of the default `--scenes` and M01, M03, M05, M12 read every RMS share at or below 0.21 "
    "(M05, a free base on the Flores law: curvature over the zone rather than scatter) and the full stage's jitter, the "
    "case the response surface verified on, at 0.64-0.75; SCATTER_SHARE was set to 0.5 then, and M02, M04, M06-M11, "
    "M13-M15 and scan-pitch, never looked at before, read RMS shares at or below 0.002. One set of 16 units read a lumped "
    "jitter anywhere from 0.17 to 0.70, so the measurement moved to more units: 32 on the hypercube (the full stage's "
    "jitter 0.56 / 0.66 / 0.87), then the 50 units drawn at random within the zones that a yield check's first chunk "
    "runs (this table: one compiled program for both). On this table SCATTER_SHARE moved to 0.45: the value in the gap "
    "between the largest lumped reading below it (scan-pitch, 0.43) and the smallest above (M09, 0.50), where every "
    "scene reads the same decision on all three sets of units. It was chosen on this table, so it is not a held-out "
    "result; the held-out evidence is the first pass's (the RMS never near the threshold).",
    "Where it matters: the full stage's jitter reads 0.58 / 0.65 / 0.76 (propose_design draws the first), 0.13 above the "
    "threshold; every RMS at most 0.17, 0.28 below it. The jitter of a lumped joint scatters or not by mechanism (M02, "
    "M04, M13: under 0.08, a line carries it; M06, M07: above 0.79): the measurement, not the output's name, decides. A "
    "lumped joint's jitter is a proxy either way (`check_fidelity`: it is designed only with allow_proxy).",
)


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--units", type=int, default=PROBE_UNITS, help="units per set (default: Auto()'s own)")
    parser.add_argument("--seeds", type=int, default=3)
    parser.add_argument("--scenes", default="scan-azimuth,scan,scan-azimuth-fast,scan-azimuth-planetary")
    parser.add_argument("--generated", default="1,3,5,12", help="design_matrix.py mechanisms (numbers; '' for none)")
    parser.add_argument("--matrix-seed", type=int, default=2026)
    args = harness.parse_args(parser)
    import design_matrix

    cases = [(name, lambda n=name: tx.load_scene(n)) for name in args.scenes.split(",") if name]
    for k in [int(v) for v in args.generated.split(",") if v]:
        m = design_matrix.mechanism(k, args.matrix_seed)
        cases.append((f"{m['key']} ({m['text'].split(';')[0]})", lambda m=m: tx.SceneFile.from_data(m["data"], name=m["key"])))
    width = tx.Sequential().width
    rows, records = [], []
    for name, load in cases:
        scene = load()
        pointing = scene.objective(jitter_cutoff=20.0)
        shares, walls, units = [], [], args.units
        problem = design_problem(pointing, yield_=0.9)
        x = Design(problem.x0.nominal + problem.x0.band, problem.x0.band)  # the starting zones: Design(middle, half-width)
        for seed in range(1, args.seeds + 1):
            start = time.perf_counter()
            shares.append(np.asarray(scatter_share(pointing, OUTPUTS, x, width, units=units,
                                                   key=jax.random.key(PROBE_KEY + seed - 1)), dtype=float))
            walls.append(time.perf_counter() - start)
            print(f"{name} seed {seed}: {dict(zip(OUTPUTS, np.round(shares[-1], 3)))} ({walls[-1]:.0f} s)", flush=True)
        shares = np.asarray(shares)
        records.append(dict(scene=name, features=len(problem.features.names), units=units, shares=shares.tolist(), wall_s=walls))
        rows.append((name, str(len(problem.features.names)), str(units))
                    + tuple(f"{np.mean(shares[:, j]):.2f} [{np.min(shares[:, j]):.2f}, {np.max(shares[:, j]):.2f}]; "
                            f"surface {int(np.sum(shares[:, j] > SCATTER_SHARE))}/{len(shares)}" for j in range(len(OUTPUTS)))
                    + (f"{walls[0]:.0f} / {np.mean(walls[1:]) if len(walls) > 1 else float('nan'):.0f}",))
    (harness.results_dir() / "auto_model.json").write_text(json.dumps(dict(command=harness.command(args), rows=records), indent=1))
    harness.write_table(
        "auto_model", "What Auto() measures: the share of each output's variance over the starting zone a line does not carry",
        harness.command(args), ["scene", "features", "units"] + [f"{o} share: mean [min, max] over seeds; Auto's surface on" for o in OUTPUTS]
        + ["wall s: first (compiles) / later"], rows,
        about=(f"Units drawn uniformly within the starting zones, as many per set as the column says, {args.seeds} sets, smoothing width "
               f"{width:g} m; share = residual variance of the secant line / the outputs' sample variance (1 - adjusted R^2). "
               f"Auto() fits an output on a response surface where its share exceeds {SCATTER_SHARE:g} (the first set is the "
               "one propose_design draws)."), notes=NOTES)


if __name__ == "__main__":
    main()
