"""Full-stage Monte Carlo units per minute by solver and step-size controller, on the same units,
against a tight solve of each (issue 41's Monte Carlo must-show).

    python benchmarks/monte_carlo_solvers.py [--n 16] [--band 5e-5] [--chunks 1 8]
        [--configs Tsit5:I:1e-6 Tsit5:PI:1e-6 Bosh3:PI:1e-4 Bosh3:PI:1e-5] [--results DIR]

A configuration is `SOLVER:CONTROLLER:RTOL[:whole|:forward|:original]` as in `rattle_window.py`
(`:whole`: the mechanism's equations of motion solved with the whole mass matrix, as before the
block solve; `:forward`: the planetary joints' deflection Jacobian by forward-mode autodiff, as
before the closed form; `:original`: both. Monte Carlo's batched programs are compiled with
XLA's default options either way, so `:forward` changes only the Jacobian here).

Scene: the built-in `scan-azimuth-planetary` (the azimuth scan at planetary fidelity, 0.6 s from
steady motion, pointing window after 0.3 s), its tolerance zones widened to nominal +-`--band`
(50 um: the units rattle, as the design verifications' do). Every configuration evaluates the
same `--n` units (same key) through the public `tolerax.monte_carlo` (vmap backend) with the
scene's objective at that solver, rtol (atol = rtol / 1000) and controller (I = diffrax's
(0, 1), tolerax's default; PI = (0.3, 0.3)): a warm-up call of
one chunk compiles, then the timed call. **Units per minute** and their ratio to the first
configuration; **errors**: the relative difference of each unit's pointing RMS, peak and jitter
(above 20 Hz) from the reference (Tsit5, rtol 1e-10, I-controller) on the same unit, the median
and the largest over the units. The first configuration's errors are "the solver's own error"
the others are read against.
"""

import time

import equinox as eqx
import jax
import numpy as np

import tolerax as tx
import harness
from rattle_window import CONTROLLERS, Config

OUTPUTS = ("pointing_rms", "pointing_peak", "pointing_jitter")


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--n", type=int, default=16, help="units per configuration")
    parser.add_argument("--band", type=float, default=50e-6, help="zone half-width around every nominal (m)")
    parser.add_argument("--chunks", type=int, nargs="+", default=[1, 8], help="vmap chunk sizes")
    parser.add_argument("--configs", nargs="+", default=["Tsit5:I:1e-6", "Tsit5:PI:1e-6", "Bosh3:PI:1e-4", "Bosh3:PI:1e-5"])
    parser.add_argument("--reference", default="Tsit5:I:1e-10")
    parser.add_argument("--seed", type=int, default=0)
    args = harness.parse_args(parser)
    scene_file = tx.load_scene("scan-azimuth-planetary")
    key = jax.random.key(args.seed)
    start_all = time.perf_counter()

    def objective(config: Config):
        pcoeff, icoeff = CONTROLLERS[config.controller]
        model = scene_file.objective(jitter_cutoff=20.0, solver=config.solver, rtol=config.rtol, atol=1e-3 * config.rtol,
                                     pcoeff=pcoeff, icoeff=icoeff)
        return eqx.tree_at(lambda m: m.scene, model, config.scene(model.scene))

    tolerances = tx.tolerances_of(scene_file.build(), band=args.band)

    def run(config, chunk):
        model = objective(config)
        tx.monte_carlo(model, tolerances, chunk, key, chunk_size=chunk, progress=False)  # compiles
        wall_s, res = harness.wall(lambda: tx.monte_carlo(model, tolerances, args.n, key, chunk_size=chunk, progress=False))
        return wall_s, {k: res.dataset[k].values for k in OUTPUTS}, res.success

    reference = Config.parse(args.reference)
    print(f"reference {reference.label} ...", flush=True)
    ref_wall, ref, ref_ok = run(reference, min(args.chunks))
    rows = []
    base_rate = None
    for chunk in args.chunks:
        for text in args.configs:
            config = Config.parse(text)
            print(f"{config.label} chunk {chunk} ...", flush=True)
            wall_s, out, ok = run(config, chunk)
            rate = 60.0 * args.n / wall_s
            base_rate = rate if base_rate is None else base_rate
            cells = []
            for k in OUTPUTS:
                err = np.abs(out[k] / ref[k] - 1.0)[ok & ref_ok]
                cells.append(f"{np.median(err):.1e} / {np.max(err):.1e}")
            rows.append([config.solver, config.controller, f"{config.rtol:g}", config.program, str(chunk), f"{int(ok.sum())}/{ok.size}",
                         f"{wall_s:.1f}", f"{rate:.1f}", f"{rate / base_rate:.2f}", *cells])
            print(rows[-1], flush=True)
    harness.write_table(
        "monte_carlo_solvers",
        "Full-stage Monte Carlo units per minute by solver and controller, against a tight solve of the same units",
        harness.command(args),
        ["solver", "controller", "rtol", "right-hand side (now, or before: whole M, forward Jacobian, original: both)", "chunk", "succeeded", "wall (s)", "units per minute", "x first row",
         "pointing RMS rel. error (median / max)", "peak rel. error (median / max)", "jitter rel. error (median / max)"],
        rows,
        about=(f"Scene `scan-azimuth-planetary` (0.6 s, window from 0.3 s), zones nominal +-{args.band * 1e6:g} um on its "
               f"{len(tolerances.names)} features, {args.n} units (seed {args.seed}), `tolerax.monte_carlo` with the vmap backend; "
               f"a warm-up call of one chunk compiles first. Reference {reference.label} on the same units: {ref_wall:.0f} s; "
               f"its pointing RMS {np.min(ref['pointing_rms']):.0f}-{np.max(ref['pointing_rms']):.0f} arcsec, jitter "
               f"{np.min(ref['pointing_jitter']):.2f}-{np.max(ref['pointing_jitter']):.2f} arcsec. atol = rtol / 1000. "
               f"Total wall {time.perf_counter() - start_all:.0f} s."),
    )


if __name__ == "__main__":
    main()
