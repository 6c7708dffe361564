"""The reference paper's claims on wear, on its own antenna (Table 3 cases): is the azimuth joint's
wear larger than the pitch joint's, and does a higher speed raise it (issue 43).

    python benchmarks/wear_claims.py [--speeds 1 2 4] [--save-rate 4000] [--lubricant NAME] [--results DIR]

Scenes: the built-in scene files `paper-table3-{azimuth,pitch}-{a,b,c}` (the driving joint
planetary, the other lumped at 100 um; 0.98 deg/s from a steady start; each file's run: 3 s,
window after 2 s), saved at `--save-rate` per second (wear_convergence.md: 4000 saves/s
integrates a cycle's wear within 3 %). Case (a) of each joint is run again at `--speeds` times
its rate. For each run, the driving joint's clearance contacts: the mean Archard wear rate over
the window (`tolerax.design.life.window_wear_rates`, `--lubricant` at its median k), in nm per
hour of operation, the mean and peak contact force over the window, and the wear per radian
of output travel (nm/rad: the sliding distance per radian is fixed by the gears, so this is
the force's share of the claim; the rate per hour also grows with the speed's sliding).

The paper's words: "the azimuth joint is more prone to wear or fatigue damage than the pitch
joint when the dual-axis driving mechanism of the satellite antenna is in orbit for a long
time"; a higher speed raises the contact force, which "will increase the joint wear and make
the clearance larger in the long-term operation".
"""

import copy
import time

import numpy as np

import tolerax as tx
from tolerax.design.life import MissionLife, window_wear_rates
from tolerax.io.scenefile import SceneFile
from tolerax.physics import wear as W

import harness

NM_PER_HOUR = 1e9 * 3600.0


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--speeds", type=float, nargs="+", default=[1.0, 2.0, 4.0], help="multiples of case (a)'s rate")
    parser.add_argument("--save-rate", type=float, default=4000.0)
    parser.add_argument("--lubricant", default="MoS2 sputtered film, vacuum", choices=sorted(W.LUBRICANTS))
    args = harness.parse_args(parser)
    start = time.perf_counter()
    life = MissionLife(1.0, W.ArchardWear.from_lubricant(args.lubricant))
    runs = [(joint, case, 1.0) for joint in ("azimuth", "pitch") for case in "abc"]
    runs += [(joint, "a", s) for joint in ("azimuth", "pitch") for s in args.speeds if s != 1.0]
    rows, totals, contact_names = [], {}, None
    for joint, case, speed in runs:
        base = tx.load_scene(f"paper-table3-{joint}-{case}")
        data = copy.deepcopy(base.data)
        data["scene"]["rate"] = float(data["scene"]["rate"]) * speed
        run = data["run"]
        run["n_save"] = int(round(args.save_rate * float(run["duration"]))) + 1
        sf = SceneFile.from_data(data, base.name, base.source)
        scene = sf.build()
        wall, res = harness.wall(sf.simulate)
        saves = np.asarray(res.ts) >= float(run["settle"])
        rates = np.asarray(window_wear_rates(scene, res, saves, life)[joint])  # m per operating second
        forces = np.asarray(getattr(res, f"{joint}_contact"))[saves]
        worn_names = W.wear_names(getattr(scene, joint).stage, life.model(joint))  # the contacts, then the meshes (flanks)
        contact_names = contact_names or worn_names
        if worn_names != contact_names:
            raise ValueError(f"{sf.name}: worn contacts {worn_names} differ from {contact_names}.")
        omega = abs(float(data["scene"]["rate"]))  # rad/s of the output
        totals[joint, case, speed] = rates
        rows.append((joint, case, f"{np.degrees(omega):.3g}", *(f"{r * NM_PER_HOUR:.3g}" for r in rates),
                     f"{rates.max() * NM_PER_HOUR:.3g}", f"{rates.max() / omega * 1e9:.3g}",
                     ", ".join(f"{f:.3g}" for f in forces.mean(axis=0)), ", ".join(f"{f:.3g}" for f in forces.max(axis=0)),
                     f"{wall:.0f}"))
        print(rows[-1], f"({time.perf_counter() - start:.0f} s so far)", flush=True)
    claims = []
    for case in "abc":
        a, p = totals["azimuth", case, 1.0].max(), totals["pitch", case, 1.0].max()
        claims.append((f"({case}) azimuth / pitch, fastest-wearing contact", f"{a / p:.3g}"))
    for joint in ("azimuth", "pitch"):
        for s in sorted(args.speeds):
            if s == 1.0:
                continue
            fast, slow = totals[joint, "a", s].max(), totals[joint, "a", 1.0].max()
            claims.append((f"(a) {joint} x{s:g} speed / x1: per hour, per radian", f"{fast / slow:.3g}, {fast / slow / s:.3g}"))
    lub = W.LUBRICANTS[args.lubricant]
    harness.write_table(
        "wear_claims", "The paper's wear claims on its Table 3 cases: azimuth against pitch, and speed",
        harness.command(args),
        ["driving joint", "case", "speed (deg/s)", *[f"{c} (nm/h)" for c in contact_names], "fastest (nm/h)", "fastest per output radian (nm/rad)",
         "mean contact force over the window (N)", "peak contact force (N)", "wall (s)"],
        rows,
        about=(f"Built-in scenes `paper-table3-*` (driving joint planetary, the other lumped), each file's run (3 s from a steady "
               f"start, window after 2 s) at {args.save_rate:g} saves/s; wear rates over the window with `{args.lubricant}` at its "
               f"median k = {lub.median:.3g} m^3/(N m) (`window_wear_rates`). Total wall {time.perf_counter() - start:.0f} s."),
        sections=[harness.Section("The claims, as ratios", ["comparison", "ratio"], claims)],
    )


if __name__ == "__main__":
    main()
