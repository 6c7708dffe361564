"""The identification's cost along one parameter, the other held: how rugged the residual is
about the truth at the scene's own smoothing width (what Levenberg-Marquardt and the intervals
see between their points).

A synthetic recording of the full planetary dual (`identify_full_stage.py --dual`'s unit and
noise: ring backlash 60 µm azimuth, 130 µm pitch, 20-bit encoders, 2 µrad; `--seed` picks its
noise draw, `--bits` the encoders), its cost $\\lVert r\\rVert^2$ at the pitch ring backlash
`--lo` to `--hi` µm in `--step` µm steps with the azimuth's held at `--azimuth` µm (an
identification's estimate), in one batched run; printed in units of the residual variance
$s^2$ at the lowest point, beside the rise a quadratic with `--se` µm standard error would give.

    taskset -c 0 python benchmarks/identify_cost_profile.py --seed 1 --azimuth 59.975 --out benchmarks/results/identify_cost_profile.md
"""

import argparse
import json
import math
import os
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.design.objectives import PointingObjective
from tolerax.identification.fit import _costs, _Fit
from tolerax.identification.identify import _model_times, _scales, own_width


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=1, help="the recording's noise draw (identify_full_stage.py's seeds; default 1)")
    parser.add_argument("--bits", type=int, default=20, help="the encoders' bits per turn (default 20)")
    parser.add_argument("--azimuth", type=float, default=60.0, help="the azimuth ring backlash held, µm (default 60)")
    parser.add_argument("--lo", type=float, default=127.0)
    parser.add_argument("--hi", type=float, default=131.0)
    parser.add_argument("--step", type=float, default=0.1)
    parser.add_argument("--se", type=float, default=0.31, help="the stated standard error to compare with, µm (default 0.31)")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    args = parser.parse_args(argv)
    scene, axes = tx.scan("dual", fidelity="planetary"), ("azimuth", "pitch")
    names = ("azimuth.ring_backlash", "pitch.ring_backlash")
    rec = tx.synthetic_recording(scene, {names[0]: 60e-6, names[1]: 130e-6}, duration=0.35, n_save=141, noise=2e-6,
                                 quantum=2 * math.pi / 2**args.bits, key=jax.random.key(3000 + args.seed), axes=axes)
    n_save, times = _model_times(rec, rec.duration, None)
    objective = PointingObjective(scene, duration=rec.duration, settle=0.0, n_save=n_save, start="steady").forward_mode()
    fit = _Fit(objective, names, jnp.asarray(_scales(scene, list(names))[1]), jnp.arange(n_save), jnp.asarray([0, 1]),
               jnp.asarray(rec.at(times)))
    pitch = np.round(np.arange(args.lo, args.hi + args.step / 2, args.step), 6)
    start = time.perf_counter()
    cost = np.asarray(_costs(fit, jnp.asarray(np.stack([np.full_like(pitch, args.azimuth), pitch], 1)), own_width(scene)))
    wall = time.perf_counter() - start
    s2 = float(cost.min()) / (2 * n_save - 2)
    best = float(pitch[np.argmin(cost)])
    rows = [f"| {b:.2f} | {(c - cost.min()) / s2:.2f} | {((b - best) / args.se) ** 2:.2f} |" for b, c in zip(pitch, cost)]
    text = "\n".join([
        "# The identification's cost along the pitch ring backlash (full planetary dual)", "",
        f"`python benchmarks/identify_cost_profile.py --seed {args.seed} --bits {args.bits} --azimuth {args.azimuth:g} "
        f"--lo {args.lo:g} --hi {args.hi:g} --step {args.step:g}` ({jax.__version__}, {os.cpu_count()} cores, one used; "
        f"{len(pitch)} points in one batched run, {wall:.0f} s).", "",
        f"Recording seed {3000 + args.seed} of `identify_full_stage.py --dual` (truth: 60 µm azimuth, 130 µm pitch), the azimuth "
        f"held at {args.azimuth:g} µm; the lowest cost at pitch {best:.2f} µm, its residual variance s² = {s2:.2f} µrad². The "
        f"rise over the lowest, in s², beside a quadratic's with the stated standard error {args.se:g} µm (1.96² = 3.84 "
        "bounds a 95 % interval):", "",
        "| pitch ring backlash (µm) | cost rise / s² | quadratic's |", "|---|---|---|", *rows, "",
        "Raw: " + json.dumps({"pitch_um": pitch.tolist(), "cost_urad2": cost.tolist()})])
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
