"""Coverage of `tolerax.identify`'s 95 % intervals on synthetic recordings, and where an
identification's wall time goes.

One unit of the lumped azimuth scan (`tx.scan("azimuth", fidelity=("lumped", "ideal"))`, 0.35 s
with a reversal at 0.25 s, 141 saves) with ring backlash `--truth` µm (the scene says 100),
recorded `--n` times through a 20-bit output encoder (steps of 6.0 µrad) with 2 µrad of noise,
each recording with its own noise; each identified from the scene's 100 µm. Reported: how many
intervals hold the truth (with the binomial probability of so few at a true 95 %), the estimates'
spread against the intervals' stated standard error, and the wall time of the first
identification (tracing and compiling included) against the later ones (the compiled programs
reused).

    python benchmarks/identify_coverage.py --n 40 --out benchmarks/results/identify_coverage.md
    python benchmarks/identify_coverage.py --n 20 --dual --out benchmarks/results/identify_coverage_dual.md
    python benchmarks/identify_coverage.py --n 20 --dual --bits 24 --out benchmarks/results/identify_coverage_dual_24bit.md

`--bits`: the encoder's resolution (20 by default; 24 gives steps of 0.37 µrad, fine against
the noise, where 20 bits' 6.0 µrad steps are three times it and round alike in most recordings).
"""

import argparse
import math
import os
import pathlib
import time

import jax
import numpy as np
from scipy.stats import binom

import tolerax as tx
from tolerax.design.features import design_names, design_of


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=40, help="recordings (default 40)")
    parser.add_argument("--truth", type=float, default=60.0, help="the unit's ring backlash, µm (default 60)")
    parser.add_argument("--out", type=pathlib.Path, default=None, help="write the Markdown result here")
    parser.add_argument("--bits", type=int, default=20,
                        help="the encoder's bits per turn (default 20: steps of 6.0 µrad, three times the noise; 24: 0.37 µrad)")
    parser.add_argument("--dual", action="store_true",
                        help="the lumped dual scan recorded by both encoders: both ring backlashes (azimuth --truth, pitch 130 µm)")
    args = parser.parse_args(argv)
    if args.dual:
        scene, axes = tx.scan("dual", fidelity="lumped"), ("azimuth", "pitch")
        chosen, truths = ("azimuth.ring_backlash", "pitch.ring_backlash"), (args.truth, 130.0)
    else:
        scene, axes = tx.scan("azimuth", fidelity=("lumped", "ideal")), ("azimuth",)
        chosen, truths = ("azimuth.ring_backlash",), (args.truth,)
    names = design_names(scene)
    truth = np.asarray(design_of(scene)).copy()
    for name, value in zip(chosen, truths):
        truth[names.index(name)] = value * 1e-6
    encoder, noise = 2 * math.pi / 2**args.bits, 2e-6
    rows, walls, inside, estimates, errors, per_axis = [], [], 0, [], [], {}
    for seed in range(args.n):
        rec = tx.synthetic_recording(scene, truth, duration=0.35, n_save=141, noise=noise, quantum=encoder,
                                     key=jax.random.key(1000 + seed), axes=axes)
        start = time.perf_counter()
        got = tx.identify(scene, rec, list(chosen), starts=(1.0,))
        walls.append(time.perf_counter() - start)
        lo, hi = got.interval()
        cells = []
        for j, value in enumerate(truths):
            hit = bool(lo[j] <= value * 1e-6 <= hi[j])
            inside += hit
            estimates.append(1e6 * got.estimate[j] - value)
            errors.append(1e6 * got.standard_error[j])
            per_axis.setdefault(j, []).append((hit, 1e6 * got.estimate[j] - value, 1e6 * got.standard_error[j]))
            cells.append(f"{1e6 * got.estimate[j]:.3f} | {1e6 * lo[j]:.3f} – {1e6 * hi[j]:.3f} | {'yes' if hit else 'NO'}")
        rows.append(f"| {seed} | {' | '.join(cells)} | "
                    f"{1e6 * got.sigma:.2f} | {got.steps} | {'yes' if got.converged else 'no'} | {walls[-1]:.1f} |")
        print(rows[-1], flush=True)
    intervals = args.n * len(chosen)
    p_low = binom.cdf(inside, intervals, 0.95)
    what = (f"Lumped dual scan recorded by both encoders, ring backlash {args.truth:g} µm (azimuth) and 130 µm (pitch)"
            if args.dual else f"Lumped azimuth scan, ring backlash {args.truth:g} µm")
    header = " | ".join(f"{n.split('.')[0]}: estimate (µm) | 95 % interval (µm) | holds the truth" for n in chosen)
    text = "\n".join([
        "# Identification: coverage of the 95 % intervals on synthetic recordings", "",
        f"`python benchmarks/identify_coverage.py --n {args.n}{' --dual' if args.dual else ''}"
        f"{'' if args.bits == 20 else f' --bits {args.bits}'}`; {os.cpu_count()} cores, "
        f"one used; load average {os.getloadavg()[0]:.2f} at the end.", "",
        f"{what}, identified from the scene's 100 µm; {args.bits}-bit encoder ({1e6 * encoder:.2f} µrad steps) and 2 µrad of "
        "noise, one draw per recording.", "",
        f"**Coverage: {inside} of {intervals} intervals hold the truth** (P(X <= {inside}) = {p_low:.3f} for X ~ "
        f"Binomial({intervals}, 0.95)). Estimates minus the truth: mean {np.mean(estimates):+.3f} µm, standard deviation "
        f"{np.std(estimates, ddof=1):.3f} µm against the stated standard error's mean {np.mean(errors):.3f} µm.", "",
        *([] if len(chosen) == 1 else [" ".join(
            f"{chosen[j].split('.')[0]}: {sum(h for h, _, _ in v)} of {len(v)} hold the truth, estimates' spread "
            f"{np.std([e for _, e, _ in v], ddof=1):.3f} µm against a stated standard error of {np.mean([s for _, _, s in v]):.3f} µm."
            for j, v in per_axis.items()), ""]),
        f"Wall time: the first identification {walls[0]:.1f} s (tracing and compiling the Levenberg-Marquardt program "
        f"and the Jacobian's included), the later ones {np.median(walls[1:]):.1f} s (median; two smoothing widths, "
        "a forward-mode solve per step).", "",
        f"| recording | {header} | residual sd (µrad) | steps | converged | wall (s) |",
        "|---|" + "---|---|---|" * len(chosen) + "---|---|---|---|", *rows])
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
