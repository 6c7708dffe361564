"""The lowest jitter the design bounds can reach on the full planetary stage, and which
clearances set it: the measured feasibility of `design_stability.py`'s stability requirement
(issue 40), without the optimiser or its linear model.

    python benchmarks/jitter_reach.py [--designs 32] [--units 8] [--confirm 3] [--confirm-units 32]
        [--requirement 0.2] [--yield 0.9] [--results DIR]

Scene and objective as `design_stability.py` (azimuth scan on the full planetary stage, steady
start, window 0.3-0.6 s, 500 saves/s, jitter above 20 Hz, Tsit5 rtol 1e-6, width 0.1 um). Its
design bounds: every zone's lower limit in [5, 90] um, half-width in [1, 50] um. A unit's
jitter can be made no more repeatable than its clearances are: the tightest bands (1 um) leave
the jitter as a function of the five zone middles plus the chaos of rattle. So:

1. **Screen**: `--designs` zone middles over [6, 91] um^5 (scrambled Sobol, `scipy.stats.qmc`,
   seed `--seed`) plus the tightest corner (every middle at 6 um), each with 1 um half-widths,
   `--units` units each drawn uniformly in the zones (`tx.sample`, key 2026 + design index):
   mean jitter and the share of units meeting `--requirement`.
2. **Confirm**: the `--confirm` designs with the lowest mean jitter get `--confirm-units` fresh
   units: their yield on the requirement with its 95 % Wilson interval. If no confirmed
   interval reaches `--yield`, the requirement is out of reach of what was sampled (a sample,
   not a proof: the table gives the lowest reached).
3. **Drivers over the bounds**: a least-squares line of each screened design's mean jitter over
   its five middles (slopes with 95 % intervals, R^2): which clearances move the jitter across
   the whole design space (jitter_drivers.md did this within +-10 um of 100 um, where no slope
   was significant).
"""

import json
import time

import equinox as eqx
import jax
import numpy as np
import scipy.stats
import scipy.stats.qmc

import tolerax as tx

import harness
import jitter_drivers


def wilson(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return centre - half, centre + half


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--designs", type=int, default=32)
    parser.add_argument("--units", type=int, default=8)
    parser.add_argument("--confirm", type=int, default=3)
    parser.add_argument("--confirm-units", type=int, default=32)
    parser.add_argument("--requirement", type=float, default=0.2, help="jitter, arcsec")
    parser.add_argument("--yield", dest="yield_", type=float, default=0.9)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--band", type=float, default=1e-6, help="half-width of every zone (m)")
    args = harness.parse_args(parser)
    start = time.perf_counter()
    scene = tx.scan("azimuth", fidelity=("planetary", "ideal"))
    pointing = tx.PointingObjective(scene, duration=0.6, settle=0.3, start="steady", n_save=301, integrator=tx.Integrator(max_steps=400_000),
                                    jitter_cutoff=20.0)
    pointing = eqx.tree_at(lambda p: p.scene, pointing, pointing.with_width(tx.design_of(scene), 1e-7))
    names = tx.design_names(scene)
    lo, hi = 5e-6 + args.band, 90e-6 + args.band
    middles = lo + (hi - lo) * scipy.stats.qmc.Sobol(len(names), scramble=True, seed=args.seed).random(args.designs)
    middles = np.vstack([np.full(len(names), lo), middles])
    run = eqx.filter_jit(jax.vmap(lambda p, v: p(v), in_axes=(None, 0)))

    def units(middle, n, key):
        zones = tx.Tolerances(names, middle, np.full(len(names), args.band))
        values = np.asarray(tx.sample(zones, jax.random.key(key), n))
        got = run(pointing, values)
        jit = np.asarray(got["pointing_jitter"])
        return jit[np.asarray(got["success"])]

    screened = []
    for i, middle in enumerate(middles):
        jit = units(middle, args.units, 2026 + i)
        screened.append(jit)
        print(f"design {i}: middles {np.round(middle * 1e6, 1)} um, jitter mean {jit.mean():.3f}, "
              f"met {np.mean(jit <= args.requirement):.2f} ({time.perf_counter() - start:.0f} s)", flush=True)
    means = np.array([j.mean() for j in screened])
    spread = dict(sd=np.array([j.std(ddof=1) for j in screened]), sd_log=np.array([np.log(j).std(ddof=1) for j in screened]))
    (harness.results_dir() / "jitter_reach.json").write_text(json.dumps(dict(
        command=harness.command(args), names=list(names), middles=middles.tolist(), band=args.band,
        jitter=[j.tolist() for j in screened]), indent=1))
    order = np.argsort(means)
    rows = []
    for rank, i in enumerate(order[: args.confirm]):
        jit = units(middles[i], args.confirm_units, 9000 + int(i))
        k = int(np.sum(jit <= args.requirement))
        w = wilson(k, jit.size)
        rows.append((f"confirmed {rank + 1}: design {i}" + (" (tightest corner)" if i == 0 else ""),
                     " ".join(f"{m * 1e6:.1f}" for m in middles[i]), str(jit.size), f"{jit.mean():.3f}",
                     f"{np.quantile(jit, args.yield_):.3f}", f"{k / jit.size:.3f} [{w[0]:.3f}, {w[1]:.3f}]"))
        print(rows[-1], flush=True)
    for label, i in (("screened: tightest corner", 0), ("screened: lowest mean", int(order[0])),
                     ("screened: median design", int(order[len(order) // 2])), ("screened: highest mean", int(order[-1]))):
        jit = screened[i]
        k = int(np.sum(jit <= args.requirement))
        w = wilson(k, jit.size)
        rows.append((f"{label} (design {i})", " ".join(f"{m * 1e6:.1f}" for m in middles[i]), str(jit.size),
                     f"{jit.mean():.3f}", f"{np.quantile(jit, args.yield_):.3f}", f"{k / jit.size:.3f} [{w[0]:.3f}, {w[1]:.3f}]"))
    pooled = np.concatenate(screened)
    slopes, se, r2, dof = jitter_drivers.fit((middles - lo) * 1e6, means)
    t = scipy.stats.t.ppf(0.975, dof)
    drivers = []
    for name, s, e in zip(names, slopes, se):
        mark = "raises it" if s - t * e > 0 else ("lowers it" if s + t * e < 0 else "no significant slope")
        drivers.append(f"{name} {1e3 * s:+.2f} ± {1e3 * t * e:.2f} marcsec/um ({mark})")
    best = rows[0]
    harness.write_table(
        "jitter_reach", "The jitter the design bounds reach on the full planetary stage (azimuth scan)", harness.command(args),
        ["design", "zone middles (um): " + ", ".join(names), "units", "mean jitter (arcsec)",
         f"{args.yield_:.0%} quantile (arcsec)", f"yield on jitter <= {args.requirement:g} [95 % Wilson]"],
        rows,
        about=(f"{len(middles)} designs (the tightest corner and {args.designs} scrambled-Sobol middles over "
               f"[{lo * 1e6:.0f}, {hi * 1e6:.0f}] um, seed {args.seed}), each at +-{args.band * 1e6:g} um, {args.units} units each; "
               f"the {args.confirm} lowest by mean jitter confirmed on {args.confirm_units} fresh units. Pooled over the screen: "
               f"{np.mean(pooled <= args.requirement):.3f} of {pooled.size} units met {args.requirement:g} arcsec; design means "
               f"{means.min():.3f}-{means.max():.3f} arcsec (median {np.median(means):.3f}). Scatter within a design: the standard "
               f"deviation over its units grows with its mean (correlation {np.corrcoef(means, spread['sd'])[0, 1]:.2f}; "
               f"coefficient of variation median {np.median(spread['sd'] / means):.2f}), that of the log jitter "
               f"{np.corrcoef(means, spread['sd_log'])[0, 1]:.2f} (median {np.median(spread['sd_log']):.2f}). Line of the design means over the "
               f"middles (R^2 {r2:.2f}, {dof} dof): " + "; ".join(drivers) + f". Best confirmed: {best[0]}, yield {best[5]}. "
               f"Total wall {time.perf_counter() - start:.0f} s, compilation included."),
    )


if __name__ == "__main__":
    main()
