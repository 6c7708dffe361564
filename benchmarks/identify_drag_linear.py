"""Is the lumped drag's under-covering interval the encoder's rounding? The linearised estimator
with the 20-bit encoder's exact rounding, against the same with Gaussian noise.

`identify_drag_coverage.py` found the drag's 95 % interval holding in 15 of 20 recordings
through the 20-bit encoder (spread 1.37x the stated error) and 18 of 20 with Gaussian noise of
the same total (1.27x). This separates the noise model from the model's nonlinearity: at the
same unit (the azimuth scan, lumped, ring backlash 60 µm, drag 0.05 N m, 0.35 s, 141 samples)
the output $y$ and its Jacobian $J$ in the two parameters (central differences at ±1 %, from
noise-free `tx.synthetic_recording`s: independent of `identify`'s code) define the linear
model; `--draws` recordings $y + e$ are drawn, $e$ the exact rounding of $y + n$ to 6.0 µrad
steps ($n$ 2 µrad Gaussian), or Gaussian noise of the same total
($\\sqrt{2^2 + 6^2/12}$ µrad), and each is fitted by least squares with the interval
`identify` states ($s^2 (J^TJ)^{-1}$, $s^2$ from the residual). Reported: how often each 95 %
interval holds and the standardised errors' spread; where the rounding errors gather (samples
whose output moves less than half a step per save: a stall). `--recordings N`: the linear fit
of `identify_drag_coverage.py`'s own N recordings (the same keys and noise, both versions), each
one's standardised errors, to set beside that benchmark's nonlinear ones: where the two agree,
the draws, not the fit's nonlinearity, made the misses.

    python benchmarks/identify_drag_linear.py --draws 20000 --recordings 20 --out benchmarks/results/identify_drag_linear.md
"""

import argparse
import math
import pathlib

import jax
import numpy as np

import tolerax as tx

from identify_drag_coverage import ENCODER, KEYS, MODES, NAMES, NOISE, recording, unit


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--draws", type=int, default=20000, help="noise draws (default 20000)")
    parser.add_argument("--recordings", type=int, default=0, help="identify_drag_coverage.py's first N recordings, linearly fitted")
    parser.add_argument("--out", type=pathlib.Path, default=None, help="write the Markdown result here")
    args = parser.parse_args(argv)
    scene, truth = unit()  # identify_drag_coverage.py's

    def output(values):
        rec = tx.synthetic_recording(scene, dict(zip(NAMES, values)), duration=0.35, n_save=141)
        return np.asarray(rec.measured)[:, 0]

    y = output(truth)
    J = np.stack([(output(truth * (1 + 0.01 * np.eye(2)[j])) - output(truth * (1 - 0.01 * np.eye(2)[j]))) / (0.02 * truth[j])
                  for j in range(2)], axis=1)
    rng = np.random.default_rng(0)
    total = math.hypot(NOISE, ENCODER / math.sqrt(12))
    stall = int(np.sum(np.abs(np.diff(y)) < ENCODER / 2))
    cov = np.linalg.inv(J.T @ J)
    rows = []
    for label in ("20-bit encoder (2 µrad noise, rounded)", f"Gaussian alone ({1e6 * total:.2f} µrad)"):
        n = rng.normal(size=(args.draws, y.size))
        e = ENCODER * np.round((y + NOISE * n) / ENCODER) - y if label.startswith("20") else total * n
        d = np.linalg.solve(J.T @ J, J.T @ e.T)
        s2 = np.sum((e.T - J @ d) ** 2, axis=0) / (y.size - 2)
        z = d / np.sqrt(np.outer(np.diag(cov), s2))
        for j, name in enumerate(NAMES):
            rows.append(f"| {label} | {name} | {np.mean(np.abs(z[j]) < 1.96):.4f} | {np.std(z[j]):.3f} | {np.mean(z[j]):+.3f} |")
    same = []
    for label, mode in zip(("20-bit encoder", "Gaussian alone"), MODES):
        z = []
        for seed in range(args.recordings):  # identify_drag_coverage.py's recordings: the same keys, noise and rounding
            rec = recording(scene, truth, jax.random.key(KEYS + seed), mode)
            e = np.asarray(rec.measured)[:, 0] - y
            d = np.linalg.solve(J.T @ J, J.T @ e)
            z.append(d / np.sqrt(np.diag(cov) * np.sum((e - J @ d) ** 2) / (y.size - 2)))
        if z:
            z = np.array(z)
            same += [f"| {label} | {name} | {int(np.sum(np.abs(z[:, j]) <= 1.96))}/{len(z)} | {math.sqrt(np.mean(z[:, j] ** 2)):.2f} | "
                     + " ".join(f"{v:+.2f}" for v in z[:, j]) + " |" for j, name in enumerate(NAMES)]
    weights = np.abs((J @ cov)[:, 1])
    top = np.argsort(-weights)[:8]
    text = "\n".join([
        "# The drag's interval under the linearised model: the encoder's rounding against Gaussian noise", "",
        f"`python benchmarks/identify_drag_linear.py --draws {args.draws} --recordings {args.recordings}`", "",
        f"Lumped azimuth scan, ring backlash 60 µm, drag {truth[1]:g} N m, 0.35 s, 141 samples; the output's span "
        f"{np.ptp(y) / ENCODER:.0f} encoder steps; samples moving less than half a step per save (a stall): {stall}. "
        f"The drag's estimate leans most on samples {', '.join(str(int(k)) for k in sorted(top))} (of 0-140), their "
        f"outputs at {', '.join(f'{v:.2f}' for v in (y[sorted(top)] / ENCODER) % 1)} of a step.", "",
        "| noise | parameter | 95 % intervals holding | standardised errors' spread | their mean |", "|---|---|---|---|---|",
        *rows] + ([] if not same else [
        "", f"`identify_drag_coverage.py`'s first {args.recordings} recordings (keys 3000 + k), each fitted by the linear model:", "",
        "| recording | parameter | intervals holding the truth | RMS standardised error | standardised errors |",
        "|---|---|---|---|---|", *same]))
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
