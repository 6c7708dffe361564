"""The drag's interval on a lumped unit identified by the lumped joint: does the 20-bit
encoder's rounding, not its noise, widen the estimates' spread past the stated error?

The unit: the azimuth scan (`tx.scan("azimuth", fidelity=("lumped", "ideal"))`, 0.35 s from a
steady start, 141 samples, one reversal), ring backlash 60 µm, drag the scene's 0.05 N m, both
identified with `identify`'s defaults from the scene's values. `--n` recordings (noise keys
`--keys` + k, default 3000 + k: those of `identify_fidelity_bias.py`'s control), each in two versions: through the
20-bit encoder (2 µrad of noise, then rounded to 6.0 µrad steps) and with the same total noise
as Gaussian alone ($\\sqrt{2^2 + 6^2/12}$ = 2.64 µrad, no rounding). Reported per parameter: the
estimates' spread over the mean stated standard error, the RMS of the standardised errors, and
how many 95 % intervals hold the truth.

    python benchmarks/identify_drag_coverage.py --n 20 --out benchmarks/results/identify_drag_coverage.md
"""

import argparse
import math
import os
import pathlib

import jax
import numpy as np

import tolerax as tx
from tolerax.identification.parameters import parameter_values

ENCODER, NOISE = 2 * math.pi / 2**20, 2e-6
NAMES = ("azimuth.ring_backlash", "azimuth.drag_torque")
MODES = ("20-bit encoder (2 µrad noise, rounded)", "Gaussian alone (2.64 µrad)")
KEYS = 3000  # the first recording's noise key by default: identify_fidelity_bias.py's control's


def unit():
    """The lumped unit and its truth (ring backlash 60 µm, the scene's drag)."""
    lumped = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    return lumped, np.array([60e-6, float(parameter_values(lumped, [NAMES[1]])[0])])


def recording(lumped, truth, key, mode):
    """One recording of the unit with noise `key`, in `mode` (`MODES`: rounded, or Gaussian of the same total)."""
    noise, quantum = (NOISE, ENCODER) if mode == MODES[0] else (math.hypot(NOISE, ENCODER / math.sqrt(12)), 0.0)
    return tx.synthetic_recording(lumped, dict(zip(NAMES, truth)), duration=0.35, n_save=141, noise=noise, quantum=quantum,
                                  key=key)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=20, help="recordings (default 20)")
    parser.add_argument("--keys", type=int, default=KEYS, help=f"the first recording's noise key (default {KEYS})")
    parser.add_argument("--out", type=pathlib.Path, default=None, help="write the Markdown result here")
    args = parser.parse_args(argv)
    lumped, truth = unit()
    rows = {mode: [] for mode in MODES}
    for seed in range(args.n):
        key = jax.random.key(args.keys + seed)
        for mode in MODES:
            rec = recording(lumped, truth, key, mode)
            got = tx.identify(lumped, rec, NAMES)
            rows[mode].append((got.estimate, got.standard_error, got.status()))
            print(seed, mode, got.estimate, got.standard_error, got.status(), flush=True)
    lines = ["# The drag's interval: the encoder's rounding against its noise", "",
             f"`python benchmarks/identify_drag_coverage.py --n {args.n}" + (f" --keys {args.keys}" if args.keys != KEYS else "")
             + f"`; {os.cpu_count()} cores; load average "
             f"{os.getloadavg()[0]:.2f} at the end.", "",
             "Lumped azimuth unit (ring backlash 60 µm, drag 0.05 N m) identified by the lumped joint, both parameters from the "
             "scene's values with `identify`'s defaults; the same noise keys in both versions of each recording.", "",
             "| recording | parameter | spread / stated error | RMS standardised error | intervals holding the truth | "
             "standardised errors |", "|---|---|---|---|---|---|"]
    for mode in MODES:
        est = np.array([r[0] for r in rows[mode]])
        se = np.array([r[1] for r in rows[mode]])
        z = (est - truth) / se
        for j, name in enumerate(NAMES):
            lines.append(f"| {mode} | {name} | {np.std(est[:, j], ddof=1) / np.mean(se[:, j]):.2f} | "
                         f"{math.sqrt(np.mean(z[:, j] ** 2)):.2f} | {int(np.sum(np.abs(z[:, j]) <= 1.96))}/{len(z)} | "
                         + " ".join(f"{v:+.2f}" for v in z[:, j]) + " |")
    text = "\n".join(lines)
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
