"""Archard wear per scan cycle of the azimuth stage's clearances, and how it converges with the
save rate and the solver tolerance (`tolerax.physics.wear`).

    python benchmarks/wear_convergence.py [--rates 1000 4000 16000] [--rtols 1e-6 1e-8]
                                          [--duration 1.0] [--lubricant NAME] [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=("planetary", "ideal"))` (fixed base, pitch rigid, the
azimuth stage in full: sun, carrier and three planet-pin clearances), steady start, Tsit5,
`--duration` seconds (default one scan period, 1 s), atol = `--atol-ratio` x rtol (default
1e-3: 1e-9 at rtol 1e-6). For each rtol and save rate (`n_save = rate * duration + 1`), the
worn depth of each contact over the run (`wear_over_run`, the trapezoid rule over the saves)
with the lubricant's median specific wear rate, divided by the number of scan cycles
(duration / period): nm per cycle.

What it measures: diffrax saves by interpolating its dense output, so the save rate does not
change the solution, only how finely the trapezoid samples it; the rows at one rtol differ by the
quadrature error of the saved points, the rows at one rate by the solver's error. The
reference is the finest rate at the tightest rtol. Impacts in the clearances last fractions of
a millisecond: a save rate that does not resolve them misses or over-weights them.
"""

import time

import numpy as np

import tolerax as tx
from tolerax.physics import wear as W

import harness


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--rates", type=float, nargs="+", default=[1000.0, 4000.0, 16000.0], help="saves per second")
    parser.add_argument("--rtols", type=float, nargs="+", default=[1e-6, 1e-8], help="solver relative tolerances")
    parser.add_argument("--atol-ratio", type=float, default=1e-3, help="atol = this x rtol (SI state units)")
    parser.add_argument("--duration", type=float, default=1.0, help="simulated time, s (default: one scan period)")
    parser.add_argument("--lubricant", default="MoS2 sputtered film, vacuum", choices=sorted(W.LUBRICANTS))
    args = harness.parse_args(parser)
    start = time.perf_counter()
    scene = tx.scan("azimuth", fidelity=("planetary", "ideal"))
    period = float(scene.azimuth.drive.period)
    cycles = args.duration / period
    model = W.ArchardWear.from_lubricant(args.lubricant)
    names = W.wear_names(scene.azimuth.stage, model)  # the contacts, then each planet's meshes (flanks)
    rates, rtols = sorted(args.rates), sorted(args.rtols, reverse=True)
    depth, walls, contacts = {}, {}, {}
    for rtol in rtols:
        for rate in rates:
            n_save = round(rate * args.duration) + 1
            wall, result = harness.wall(tx.simulate, scene, args.duration, start="steady", n_save=n_save, rtol=rtol,
                                        atol=args.atol_ratio * rtol)
            worn = W.wear_over_run(scene, result, model)["azimuth"]
            depth[rtol, rate] = np.array([float(worn[c]) for c in names]) / cycles
            walls[rtol, rate] = wall
            contacts[rtol, rate] = np.mean(np.asarray(result.azimuth_contact) > 0.0, axis=0)
            print(f"rtol {rtol:g}, {rate:g}/s: {depth[rtol, rate] * 1e9} nm/cycle, {wall:.1f} s "
                  f"({result.num_steps} steps), {time.perf_counter() - start:.0f} s so far", flush=True)
    ref = depth[rtols[-1], rates[-1]]

    def relative(x, r):
        return [f"{(a - b) / b:+.2e}" if b > 0 else ("0" if a == b else f"{a * 1e9:.3g} nm vs 0") for a, b in zip(x, r)]

    rows, rel_rows, rate_rows = [], [], []
    for rtol in rtols:
        for rate in rates:
            d = depth[rtol, rate]
            rows.append((f"{rtol:g}", f"{rate:g}", *(f"{x * 1e9:.4g}" for x in d), f"{walls[rtol, rate]:.1f}"))
            rel_rows.append((f"{rtol:g}", f"{rate:g}", *relative(d, ref)))
            rate_rows.append((f"{rtol:g}", f"{rate:g}", *relative(d, depth[rtol, rates[-1]]),
                              ", ".join(f"{x:.2%}" for x in contacts[rtol, rate])))
    lub = W.LUBRICANTS[args.lubricant]
    harness.write_table(
        "wear_convergence", "Archard wear per scan cycle of the azimuth stage's clearances: save rate and tolerance",
        harness.command(args),
        ["rtol", "saves/s", *[f"{c} (nm/cycle)" for c in names], "wall s (compile included)"],
        rows,
        about=(f"`tolerax.scan(\"azimuth\", fidelity=(\"planetary\", \"ideal\"))`, steady start, Tsit5, {args.duration:g} s "
               f"({cycles:g} scan cycles of {period:g} s), atol = {args.atol_ratio:g} x rtol; `wear_over_run` with "
               f"`{args.lubricant}` at its median k = {lub.median:.3g} m^3/(N m). Total wall "
               f"{time.perf_counter() - start:.0f} s."),
        notes=[("Depth per cycle (nm) of each clearance contact; a mission's growth is this times its number of cycles, "
                "while the geometry stays close to the run's (see `tolerax.physics.wear`).")],
        sections=[
            harness.Section(f"Relative change against the reference (rtol {rtols[-1]:g}, {rates[-1]:g} saves/s)",
                            ["rtol", "saves/s", *names], rel_rows),
            harness.Section("Quadrature error alone: relative change against the finest save rate at the same rtol, "
                            "and the fraction of saves at which each contact carries force",
                            ["rtol", "saves/s", *names, f"saves in contact ({', '.join(scene.azimuth.stage.contact_names)})"], rate_rows),
        ],
    )


if __name__ == "__main__":
    main()
