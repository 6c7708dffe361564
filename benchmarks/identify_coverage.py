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
`--drags A [P]`: the driven joints' drag torques (N m; the scene says 0.05) are the unit's too and
identified beside the backlash (from the scene's values). Each parameter's interval is counted by
what `identify` claims for it (`Identification.status`): a two-sided interval holds the truth
where the truth lies in it, a one-sided one ("bounded below only") where it lies on its side of
the bound; a parameter whose interval does not hold (or that is not determined) claims none and
is counted apart.

    python benchmarks/identify_coverage.py --n 20 --dual --drags 0.04 0.06 --out benchmarks/results/identify_coverage_dual_drags.md

`--pitch P`: the dual's pitch ring backlash (µm, 130 by default). At 250 the truth lies on the
plateau the recording never takes up (flat above ~160 µm): the estimate stops on it (at its
foot, ~164 µm, in 19 of 20) and is no measure of the truth, and its interval is the profile
likelihood's (`Identification.profile_bound`, counted as claimed:
"bounded below only" holds where the truth lies above the bound). Committed (40 of 40 claimed
intervals hold: the azimuth's 20 "determined", the pitch's 20 "bounded below only", 147.9-153.2 µm):

    python benchmarks/identify_coverage.py --n 20 --dual --pitch 250 --out benchmarks/results/identify_coverage_plateau.md

Every run above identifies from the scene's values alone (`starts=(1.0,)`); `--screen` uses
`identify`'s default starts instead (its Sobol screen, the best 2 kept), what a user's call gets:

    python benchmarks/identify_coverage.py --n 20 --screen --out benchmarks/results/identify_coverage_screen.md
"""

import argparse
import collections
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
    parser.add_argument("--pitch", type=float, default=130.0, help="the dual's pitch ring backlash, µm (default 130)")
    parser.add_argument("--drags", type=float, nargs="+", default=None, metavar="NM",
                        help="the drag torques of the driven joints (N m), identified too (module docstring)")
    parser.add_argument("--screen", action="store_true",
                        help="identify's default starts (its Sobol screen, the best 2 kept) instead of the scene's values alone")
    args = parser.parse_args(argv)
    if args.dual:
        scene, axes = tx.scan("dual", fidelity="lumped"), ("azimuth", "pitch")
        chosen, truths = ("azimuth.ring_backlash", "pitch.ring_backlash"), (args.truth, args.pitch)
    else:
        scene, axes = tx.scan("azimuth", fidelity=("lumped", "ideal")), ("azimuth",)
        chosen, truths = ("azimuth.ring_backlash",), (args.truth,)
    units = (1e-6,) * len(chosen)  # the printed unit of each parameter in SI: µm for the backlash, N m for a drag
    if args.drags:
        if len(args.drags) != len(axes):
            parser.error(f"--drags: one drag torque per driven joint ({len(axes)})")
        chosen, truths = chosen + tuple(f"{a}.drag_torque" for a in axes), truths + tuple(args.drags)
        units += (1.0,) * len(axes)
    names = design_names(scene)
    truth = np.asarray(design_of(scene)).copy()
    for name, value, unit in zip(chosen, truths, units):
        if name in names:
            truth[names.index(name)] = value * unit
    values = dict(zip(names, truth)) | {n: v * u for n, v, u in zip(chosen, truths, units) if n not in names}
    encoder, noise = 2 * math.pi / 2**args.bits, 2e-6
    rows, walls, inside, unclaimed, estimates, errors, per_axis, statuses = [], [], 0, 0, [], [], {}, {}
    for seed in range(args.n):
        rec = tx.synthetic_recording(scene, values, duration=0.35, n_save=141, noise=noise, quantum=encoder,
                                     key=jax.random.key(1000 + seed), axes=axes)
        start = time.perf_counter()
        got = tx.identify(scene, rec, list(chosen), **({} if args.screen else dict(starts=(1.0,))))
        walls.append(time.perf_counter() - start)
        lo, hi = got.bounds()  # the linearised intervals, or the profile likelihood's where it was read
        cells = []
        for j, (value, unit, status) in enumerate(zip(truths, units, got.status())):
            claimed = status not in ("interval does not hold", "not determined")
            low = -np.inf if status == "bounded above only" else lo[j] / unit
            high = np.inf if status == "bounded below only" else hi[j] / unit
            hit = bool(low <= value <= high)
            inside += hit and claimed
            unclaimed += not claimed
            if unit == 1e-6 and claimed:
                estimates.append(got.estimate[j] / unit - value)
                errors.append(got.standard_error[j] / unit)
            statuses.setdefault(j, []).append(status)
            per_axis.setdefault(j, []).append((hit, got.estimate[j] / unit - value, got.standard_error[j] / unit, claimed))
            shown = "not claimed" if not claimed else "yes" if hit else "NO"
            cells.append(f"{got.estimate[j] / unit:.4g} | {low:.4g} – {high:.4g} ({status}) | {shown}")
        rows.append(f"| {seed} | {' | '.join(cells)} | "
                    f"{1e6 * got.sigma:.2f} | {got.steps} | {'yes' if got.converged else 'no'} | {walls[-1]:.1f} |")
        print(rows[-1], flush=True)
    intervals = args.n * len(chosen) - unclaimed
    p_low = binom.cdf(inside, intervals, 0.95)
    what = (f"Lumped dual scan recorded by both encoders, ring backlash {args.truth:g} µm (azimuth) and {args.pitch:g} µm (pitch)"
            if args.dual else f"Lumped azimuth scan, ring backlash {args.truth:g} µm")
    if args.drags:
        what += f", drag torques {' and '.join(f'{d:g}' for d in args.drags)} N m (identified too, from the scene's 0.05)"
    header = " | ".join(f"{n}: estimate ({'µm' if u == 1e-6 else 'N m'}) | 95 % interval (status) | holds the truth"
                        for n, u in zip(chosen, units))
    started = "identify's default screen of starts, the best 2 kept" if args.screen else "from the scene's values alone"
    text = "\n".join([
        "# Identification: coverage of the 95 % intervals on synthetic recordings", "",
        f"`python benchmarks/identify_coverage.py --n {args.n}{' --dual' if args.dual else ''}"
        f"{f' --pitch {args.pitch:g}' if args.pitch != 130.0 else ''}"
        f"{'' if args.bits == 20 else f' --bits {args.bits}'}{' --drags ' + ' '.join(f'{d:g}' for d in args.drags) if args.drags else ''}{' --screen' if args.screen else ''}`; "
        f"{os.cpu_count()} cores, "
        f"one used; load average {os.getloadavg()[0]:.2f} at the end.", "",
        f"{what}, identified from the scene's 100 µm ({started}); {args.bits}-bit encoder ({1e6 * encoder:.2f} µrad steps) and 2 µrad of "
        "noise, one draw per recording.", "",
        f"**Coverage: {inside} of {intervals} intervals hold the truth** (P(X <= {inside}) = {p_low:.3f} for X ~ "
        f"Binomial({intervals}, 0.95)){f'; {unclaimed} parameters claimed no interval' if unclaimed else ''}. Backlash estimates minus the truth{' (where an interval was claimed)' if unclaimed else ''}: mean {np.mean(estimates):+.3f} µm, standard deviation "
        f"{np.std(estimates, ddof=1):.3f} µm against the stated standard error's mean {np.mean(errors):.3f} µm.", "",
        *([] if len(chosen) == 1 else [" ".join(
            f"{chosen[j]}: {sum(h and c for h, _, _, c in v)} of {sum(c for *_, c in v)} claimed hold the truth "
            f"({', '.join(f'{n} {s}' for s, n in collections.Counter(statuses[j]).most_common())}); claimed estimates' spread "
            f"{np.std([e for _, e, _, c in v if c], ddof=1) if sum(c for *_, c in v) > 1 else float('nan'):.3g} against a stated "
            f"standard error of {np.mean([s for _, _, s, c in v if c]) if any(c for *_, c in v) else float('nan'):.3g} "
            f"({'µm' if units[j] == 1e-6 else 'N m'})." for j, v in per_axis.items()), ""]),
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
