"""When the output (carrier) bearings carry load in the paper's speed study, and why the study's
metrics see 0 N.

    python benchmarks/output_bearing.py [--duration 0.5] [--modes dual azimuth pitch] [--rates 0.49 0.98 1.96]

The 1 s speed study (`tolerax studies` before it moved to 3 s and a 2 s settle; its window is kept
as `"start_up"`) ran each scene 1 s from a steady start and read the output-bearing contact force
over t >= 0.3 s. At 100 um carrier clearance it reports 0 N everywhere, and six of the paper's claims
then differ as "0 N against 0 N". This reruns the same scenes (`tolerax._studies.scenes("speed",
"full")`: dual-axis scenes planetary on both joints, single-axis ones planetary on the driven joint
and lumped on the other) and splits the run at `settle`: the force peak and first contact (> 10 mN) before it, the peak after it, and the
output runout |(x_c, y_c)| after it against the 100 um clearance.
Writes `benchmarks/results/output_bearing.md`, rewritten after every row.
"""

import argparse
import numpy as np

import tolerax
from tolerax._studies import SIZES, scenes

import _results

SETTLE = SIZES["full"].start_up[0]  # s, where the 1 s studies' metrics window started (now "start_up")
UM = 1e-6


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--duration", type=float, default=0.5, help="simulated time per scene (s), > 0.3")
    parser.add_argument("--modes", nargs="+", default=["dual", "azimuth", "pitch"], choices=["dual", "azimuth", "pitch"])
    parser.add_argument("--rates", type=float, nargs="+", default=[0.49, 0.98, 1.96], help="commanded rates (deg/s)")
    args = parser.parse_args()
    if args.duration <= SETTLE:
        parser.error(f"--duration must exceed the study's settle time {SETTLE} s")
    columns = ["mode", "rate (deg/s)", "first contact az / pitch (s)", f"peak force before {SETTLE} s, az / pitch (N)",
               f"peak force after {SETTLE} s, az / pitch (N)", f"runout after {SETTLE} s, az (um, min-max)",
               f"runout after {SETTLE} s, pitch (um, min-max)", "runout at the end, az / pitch (um)"]
    rows = []
    for labels, mech in scenes("speed", "full"):
        mode, deg = labels["mode"], labels["rate"]
        if mode not in args.modes or not any(abs(deg - r) < 1e-9 for r in args.rates):
            continue
        res = tolerax.simulate(mech, args.duration, start="steady", n_save=int(round(args.duration * 2000)) + 1)
        ts = np.asarray(res.ts)
        force = np.asarray(res.output_force)
        runout = np.asarray(res.runout) / UM
        early, late = ts < SETTLE, ts >= SETTLE
        first = []
        for j in range(2):
            hit = force[:, j] > 0.01
            first.append(f"{ts[np.argmax(hit)]:.3f}" if hit.any() else "none")
        pair = lambda a: " / ".join(f"{x:.2f}" for x in a)  # noqa: E731
        rows.append([
            mode, f"{deg:g}", " / ".join(first), pair(force[early].max(0)), pair(force[late].max(0)),
            f"{runout[late, 0].min():.1f}-{runout[late, 0].max():.1f}", f"{runout[late, 1].min():.1f}-{runout[late, 1].max():.1f}",
            " / ".join(f"{x:.1f}" for x in runout[-1]),
        ])
        print(rows[-1], flush=True)
        _results.write_table(
            "output_bearing",
            "Output-bearing contact in the speed study: start-up against the metrics window",
            _results.command(args),
            columns,
            rows,
            about=(f"The speed study's scenes: free base, planetary joints (the non-driven joint of a "
                   f"single-axis scene lumped), 100 um clearances and backlash, steady start, {args.duration:g} s, "
                   f"saved at 2 kHz; output_force and runout of `MechanismResult`. The joint the study reads is the "
                   f"driven one (azimuth for dual)."),
        )


if __name__ == "__main__":
    main()
