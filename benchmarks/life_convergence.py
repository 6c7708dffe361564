"""End-of-life pointing and clearance growth against the number of life points (issue 43): how
many re-simulations the growth's integration needs (`MissionLife(points=...)`).

    python benchmarks/life_convergence.py [--points 1 2 4 8] [--years 10] [--duty 1.0] [--lubricant NAME] [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=("planetary", "ideal"))` (100 um clearances and
backlash, the azimuth stage in full), steady start, Tsit5 at rtol 1e-6; the window is one whole
scan period after 0.3 s of settling ([0.3, 1.3] s) at 4000 saves/s (wear_convergence.md: a
cycle's wear within 3 %), so the window's wear rate is a duty cycle's. `--years` of operation
at `--duty` with `--lubricant`'s median wear rate. For each number of points K, the clearance
growth at the end of life per contact (explicit Euler over K steps, each step's wear rate from
a re-simulation at the clearances grown so far: `PointingObjective(life=...).over_life`) and
the end-of-life RMS pointing error and jitter; errors against the finest K. Euler's error falls
as 1/K where the rates change smoothly with the clearances; the table says whether they do here.
"""

import time

import equinox as eqx
import numpy as np

import tolerax as tx
from tolerax.design.life import MissionLife
from tolerax.physics import wear as W

import harness


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--points", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--years", type=float, default=10.0)
    parser.add_argument("--duty", type=float, default=1.0)
    parser.add_argument("--lubricant", default="MoS2 sputtered film, vacuum", choices=sorted(W.LUBRICANTS))
    parser.add_argument("--save-rate", type=float, default=4000.0)
    args = harness.parse_args(parser)
    start = time.perf_counter()
    scene = tx.scan("azimuth", fidelity=("planetary", "ideal"))
    period = float(scene.azimuth.drive.period)
    settle, duration = 0.3, 0.3 + period
    values = tx.design_of(scene)
    results = {}
    for k in sorted(args.points):
        life = MissionLife.from_years(args.years, args.duty, W.ArchardWear.from_lubricant(args.lubricant), points=k)
        names = W.wear_names(scene.azimuth.stage, life.model("azimuth"))  # the contacts, then each planet's meshes (flanks)
        pointing = tx.PointingObjective(scene, duration=duration, settle=settle, start="steady",
                                        n_save=int(round(args.save_rate * duration)) + 1, jitter_cutoff=20.0, life=life)
        wall, (outputs, depths) = harness.wall(eqx.filter_jit(lambda p, v: p.over_life(v)), pointing, values)
        results[k] = dict(depth=np.asarray(depths["azimuth"])[-1], rms=np.asarray(outputs["pointing_rms"]),
                          jitter=np.asarray(outputs["pointing_jitter"]), ok=bool(np.all(outputs["success"])), wall=wall)
        r = results[k]
        print(k, r["depth"] * 1e6, r["rms"][[0, -1]], r["jitter"][[0, -1]], f"{wall:.0f} s", flush=True)
    ref = results[max(results)]
    rows = []
    for k, r in results.items():
        rel = (r["depth"] - ref["depth"]) / np.where(ref["depth"] > 0, ref["depth"], 1.0)
        rows.append((str(k), *(f"{d * 1e6:.3g}" for d in r["depth"]), f"{r['rms'][0]:.1f}", f"{r['rms'][-1]:.1f}",
                     f"{r['jitter'][0]:.3f}", f"{r['jitter'][-1]:.3f}", f"{np.max(np.abs(rel)):.2%}",
                     f"{(r['rms'][-1] - ref['rms'][-1]) / ref['rms'][-1]:+.2%}", str(r["ok"]), f"{r['wall']:.0f}"))
    lub = W.LUBRICANTS[args.lubricant]
    harness.write_table(
        "life_convergence", "End-of-life clearance growth and pointing against the number of life points",
        harness.command(args),
        ["life points K", *[f"{c} growth (um)" for c in names], "RMS at beginning of life (arcsec)", "RMS at end of life (arcsec)",
         "jitter at beginning of life (arcsec)", "jitter at end of life (arcsec)", "largest growth error vs finest K",
         "end-of-life RMS error vs finest K", "all solves succeeded", "wall (s, compile included)"],
        rows,
        about=(f"`tolerax.scan('azimuth', fidelity=('planetary', 'ideal'))` at its 100 um design, steady start, window "
               f"[{settle:g}, {duration:g}] s (one scan period) at {args.save_rate:g} saves/s; {args.years:g} years at duty {args.duty:g} "
               f"with `{args.lubricant}` (median k = {lub.median:.3g} m^3/(N m)); explicit Euler over K life points, each a "
               f"re-simulation at the clearances grown so far. Total wall {time.perf_counter() - start:.0f} s."),
    )


if __name__ == "__main__":
    main()
