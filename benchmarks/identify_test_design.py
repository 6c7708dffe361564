"""The test design measured: recordings of the plain scan and of the proposed one, identified.

`tolerax.identification.testdesign.design_test` proposes, at the scene's values (the guess before
the test), the test (a sine scan, or slews with dwells: `--dwells`) that makes the chosen
parameters best determined, from the linearised
information of each candidate. This checks the prediction where it matters: a unit whose
values are not the guess (`--truth`: ring backlash 0.8x the scene's 100 µm, drag 1.2x its
0.05 N m) is recorded `--n` times through each test (a 20-bit
encoder, 6.0 µrad steps, and 2 µrad of noise; the same noise draws for both), each recording
identified with `identify`'s defaults (the best 2 of its screened starts within 2x of the scene's values: 32 for one parameter, 64 for two). The mechanism may run
twice the plain scan's peak rate and four times its amplitude. Reported per parameter and test:
the intervals' stated relative standard error (mean), the estimates' spread over the recordings
(what the stated error claims to be), how many 95 % intervals hold the truth, and the measured
ratio plain / proposed against the predicted one. One core, one process.

    python benchmarks/identify_test_design.py --n 6 --out benchmarks/results/identify_test_design.md
"""

import argparse
import math
import os
import pathlib
import time

import jax
import numpy as np

import tolerax as tx
from tolerax.identification.parameters import parameter_values
from tolerax.identification.testdesign import design_test

NAMES = ("azimuth.ring_backlash", "azimuth.drag_torque")
ENCODER, NOISE = 2 * math.pi / 2**20, 2e-6  # rad: a 20-bit encoder's step, its noise
DURATION, N_SAVE = 1.0, 401
PERIODS = (0.25, 0.5, 1.0)  # s: the candidates' periods (amplitudes: design_test's default grid)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=8, help="recordings per test (default 8)")
    parser.add_argument("--truth", type=float, nargs=2, default=(0.8, 1.2), metavar=("BACKLASH", "DRAG"),
                        help="the unit's ring backlash and drag as factors of the scene's (default 0.8 1.2)")
    parser.add_argument("--dwells", type=float, nargs="+", default=(), metavar="S",
                        help="slew tests with these dwells (s) join the candidates (default none: design_test's)")
    parser.add_argument("--out", type=pathlib.Path, default=None, help="write the Markdown result here")
    args = parser.parse_args(argv)
    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    guess = np.asarray(parameter_values(scene, NAMES))
    truth = dict(zip(NAMES, guess * np.array(args.truth)))
    start = time.perf_counter()
    a0 = float(scene.azimuth.drive.amplitude)
    # The mechanism's limits: twice the acceptance scan's peak rate, four times its amplitude.
    proposal = design_test(scene, NAMES, duration=DURATION, n_save=N_SAVE, noise=math.hypot(NOISE, ENCODER / math.sqrt(12)),
                           max_amplitude=4 * a0, max_rate=2 * (2 * math.pi * a0 / 1.0), periods=PERIODS, dwells=args.dwells)
    design_wall = time.perf_counter() - start
    print(proposal.table(), flush=True)
    tests = {"plain": scene, "proposed": proposal.scene}
    results = {k: {"est": [], "se": [], "hit": [], "wall": []} for k in tests}
    for seed in range(args.n):
        for label, test in tests.items():
            rec = tx.synthetic_recording(test, truth, duration=DURATION, n_save=N_SAVE, noise=NOISE, quantum=ENCODER,
                                         key=jax.random.key(2000 + seed))
            t0 = time.perf_counter()
            got = tx.identify(test, rec, NAMES)
            results[label].setdefault("converged", []).append(got.converged)
            results[label].setdefault("sigma", []).append(got.sigma)
            results[label]["wall"].append(time.perf_counter() - t0)
            lo, hi = got.interval()
            true = np.array([truth[n] for n in NAMES])
            results[label]["est"].append(got.estimate / true)
            results[label]["se"].append(got.standard_error / true)
            results[label]["hit"].append((lo <= true) & (true <= hi))
            print(f"{label} {seed}: estimate/truth {np.round(got.estimate / true, 5)}, residual sd {1e6 * got.sigma:.2f} µrad, relative se "
                  f"{np.round(got.standard_error / true, 6)}, converged {got.converged}, {results[label]['wall'][-1]:.1f} s",
                  flush=True)
    summary = {k: {m: np.array(v) for m, v in r.items()} for k, r in results.items()}
    rows = []
    for j, name in enumerate(NAMES):
        cells = []
        for label in tests:
            r = summary[label]
            cells.append(f"{np.mean(r['se'][:, j]):.3g} | {np.std(r['est'][:, j], ddof=1):.3g} | "
                         f"{int(np.sum(r['hit'][:, j]))}/{args.n}")
        measured = np.mean(summary["plain"]["se"][:, j]) / np.mean(summary["proposed"]["se"][:, j])
        spread = np.std(summary["plain"]["est"][:, j], ddof=1) / np.std(summary["proposed"]["est"][:, j], ddof=1)
        rows.append(f"| {name} | {' | '.join(cells)} | {proposal.sharper()[j]:.3g}x | {measured:.3g}x | {spread:.3g}x |")
    a = proposal.amplitude
    text = "\n".join([
        "# Test design, measured: the plain scan against the proposed one", "",
        f"`python benchmarks/identify_test_design.py --n {args.n} --truth {args.truth[0]:g} {args.truth[1]:g}"
        + ("" if not args.dwells else " --dwells " + " ".join(f"{d:g}" for d in args.dwells)) + f"`; {os.cpu_count()} cores, one used; load average "
        f"{os.getloadavg()[0]:.2f} at the end.", "",
        f"Lumped azimuth scan (`tx.scan('azimuth', fidelity=('lumped', 'ideal'))`), {DURATION:g} s recorded, {N_SAVE} "
        f"samples, 20-bit encoder and 2 µrad of noise. The unit: ring backlash {args.truth[0]:g}x and drag {args.truth[1]:g}x the scene's values; the test designed and each recording identified from the scene's values.", "",
        f"Proposed by `design_test` in {design_wall:.1f} s ({len(a)} candidates, compilation included): "
        f"{proposal.test_of(proposal.best)} against the plain {proposal.test_of(proposal.plain)}; limits: amplitude <= {math.degrees(4 * a0):.3g}°, peak rate <= "
        f"{math.degrees(4 * math.pi * a0):.3g} °/s.", "",
        "Per parameter, relative to the truth: the stated standard error (mean over the recordings), the estimates' "
        "spread (standard deviation), the 95 % intervals holding the truth; then plain / proposed as predicted at the "
        "guess, as stated at the estimates and as the spread measured.", "",
        "| parameter | plain: stated | plain: spread | plain: hold | proposed: stated | proposed: spread | proposed: hold | "
        "predicted | stated | spread |", "|---|---|---|---|---|---|---|---|---|---|", *rows, "",
        f"Identification wall time, median: plain {np.median(summary['plain']['wall']):.1f} s, proposed "
        f"{np.median(summary['proposed']['wall']):.1f} s (the first of each includes compilation: "
        f"{summary['plain']['wall'][0]:.1f} s); Levenberg-Marquardt's own convergence test passed on "
        f"{int(np.sum(summary['plain']['converged']))}/{args.n} plain and {int(np.sum(summary['proposed']['converged']))}/"
        f"{args.n} proposed. The residual's standard deviation (a fit in the truth's basin leaves the encoder's "
        f"{1e6 * math.hypot(NOISE, ENCODER / math.sqrt(12)):.2f} µrad): plain "
        f"{', '.join(f'{1e6 * v:.2f}' for v in summary['plain']['sigma'])}; proposed "
        f"{', '.join(f'{1e6 * v:.2f}' for v in summary['proposed']['sigma'])} µrad.", "", "## The candidates", "", proposal.table()])
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
