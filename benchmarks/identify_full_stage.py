"""Identifying an as-built unit with the full planetary stage itself: synthetic recordings of the
full stage, identified by the full stage with `identify`'s defaults (the residual's Jacobian
chosen automatically: central secants where the forward-mode one is scrambled by the rattle).

The unit: the azimuth scan (`tx.scan("azimuth", fidelity=("planetary", "ideal"))`, 0.35 s from a
steady start, one reversal) with ring backlash `--truth` µm and every other clearance at the
scene's 100 µm, recorded through a 20-bit encoder (`--bits`) with 2 µrad of noise (`--n` recordings, each
its own noise). Reported per recording: the estimate, its 95 % interval and whether it holds the
truth, whether the interval holds along its profile, the residual against the encoder's noise,
the Jacobian chosen and the wall time (and by phase). `--dual`: the dual scan with both joints at
full planetary fidelity (`tx.scan("dual", fidelity="planetary")`), recorded by both
encoders, both ring backlashes identified at once (azimuth `--truth`, pitch 130 µm). `--spread S`:
each recording's unit its own, its backlashes drawn uniformly within S µm of those (with the
recording's seed): where the model does not reproduce its own run, recordings of one unit share
one realisation of the model's error, so their coverage measures that one draw (the dual's
pitch: all low), not the intervals'. `--forward` also identifies the first recording with the
forward-mode Jacobian (`secant=False`), the former default, for contrast; `--from-truth` fits
each recording again from its truth (`starts=`): a lower residual there than at the default's
estimate says the search missed the basin, the same estimate that the cost's minimum is there.
Each row says how many points the line screen costed (0: it did not run). The coverage of the
intervals is measured, not assumed: over 20 recordings about 19 should hold the truth.

Each run appends its rows to `--rows` (JSON lines), so recordings can be split over processes
(`--first`) and the table written from all of them (`--merge`):

    taskset -c 0 python benchmarks/identify_full_stage.py --first 0 --n 10 --forward --rows /tmp/ifs.jsonl &
    taskset -c 1 python benchmarks/identify_full_stage.py --first 10 --n 10 --rows /tmp/ifs.jsonl
    python benchmarks/identify_full_stage.py --merge --rows /tmp/ifs.jsonl --out benchmarks/results/identify_full_stage.md
    taskset -c 1 python benchmarks/identify_full_stage.py --dual --first 0 --n 10 --rows benchmarks/results/identify_full_stage_dual.jsonl
    python benchmarks/identify_full_stage.py --merge --rows benchmarks/results/identify_full_stage_dual.jsonl --out benchmarks/results/identify_full_stage_dual.md
"""

import argparse
import json
import math
import os
import pathlib
import subprocess
import time

import jax
import jax.numpy as jnp
import numpy as np
from scipy.stats import binom

import tolerax as tx
from tolerax.identification.parameters import with_parameters

NOISE = 2e-6  # rad: the encoders' noise (their steps: --bits)
DURATION, N_SAVE = 0.35, 141
PITCH_TRUTH = 130.0  # µm: --dual's pitch ring backlash (as identify_coverage.py --dual)


def _unit(dual: bool, truth: float):
    """The scene, the encoders recorded, the parameters identified and their true values (µm)."""
    if dual:
        return (tx.scan("dual", fidelity="planetary"), ("azimuth", "pitch"), ("azimuth.ring_backlash", "pitch.ring_backlash"),
                (truth, PITCH_TRUTH))
    return tx.scan("azimuth", fidelity=("planetary", "ideal")), ("azimuth",), ("azimuth.ring_backlash",), (truth,)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--n", type=int, default=4, help="recordings (default 4)")
    parser.add_argument("--truth", type=float, default=60.0, help="the unit's (azimuth) ring backlash, µm (default 60)")
    parser.add_argument("--dual", action="store_true", help=f"the full planetary dual scan recorded by both encoders: both "
                        f"ring backlashes (azimuth --truth, pitch {PITCH_TRUTH:g} µm)")
    parser.add_argument("--forward", action="store_true", help="also the first recording with secant=False (forward mode)")
    parser.add_argument("--first", type=int, default=0, help="the first recording's seed offset (default 0)")
    parser.add_argument("--rows", type=pathlib.Path, default=None, help="append each recording's row here (JSON lines)")
    parser.add_argument("--bits", type=int, default=20, help="the encoders' bits per turn (default 20: 6.0 µrad steps; 24: 0.37)")
    parser.add_argument("--spread", type=float, default=0.0, help="each recording's unit its own: its backlashes drawn uniformly "
                        "within this many µm of --truth (and the pitch's) with the recording's seed (default 0: one unit)")
    parser.add_argument("--from-truth", action="store_true", help="also fit each recording from its truth (starts=[truth]): "
                        "where that ends at a lower residual than the default's estimate, the default's search missed the "
                        "basin; where it ends at the same estimate, the cost's own minimum is there (the model's noise)")
    parser.add_argument("--merge", action="store_true", help="run nothing: write the table from --rows")
    parser.add_argument("--out", type=pathlib.Path, default=None, help="write the Markdown result here")
    args = parser.parse_args(argv)
    if args.merge:
        rows = [json.loads(line) for line in args.rows.read_text().splitlines() if line.strip()]
        return _write(sorted(rows, key=lambda r: (r["asked"] != "default", r["seed"])), args)
    full, axes, names, truths = _unit(args.dual, args.truth)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    rows = []
    runs = [(args.first + k, None) for k in range(args.n)] + ([(args.first, False)] if args.forward else [])
    nominal = truths
    for seed, secant in runs:
        draw = np.random.default_rng(3000 + seed).uniform(-1.0, 1.0, len(names))
        truths = tuple(float(v + args.spread * u) for v, u in zip(nominal, draw))
        rec = tx.synthetic_recording(full, {n: 1e-6 * v for n, v in zip(names, truths)}, duration=DURATION, n_save=N_SAVE,
                                     noise=NOISE, quantum=2 * math.pi / 2**args.bits, key=jax.random.key(3000 + seed), axes=axes)
        start = time.perf_counter()
        got = tx.identify(full, rec, names, secant=secant)
        wall = time.perf_counter() - start
        lo, hi = got.interval()
        rows.append(dict(seed=seed, asked="default" if secant is None else "secant=False", names=names, truth=truths,
                         estimate=[1e6 * v for v in got.estimate], lo=[1e6 * v for v in lo], hi=[1e6 * v for v in hi],
                         hit=[bool(a <= 1e-6 * t <= b) for a, b, t in zip(lo, hi, truths)], holds=list(got.holds()),
                         status=list(got.status()), sd=1e6 * got.residual_sd, converged=got.converged, steps=int(got.steps),
                         wall=wall, phases={k: round(v, 1) for k, v in got.wall.items()},
                         jacobian=got.jacobian.split(":")[0], load=os.getloadavg()[0], dual=args.dual, commit=commit, screened=int(got.screened),
                         bits=args.bits, profile=np.asarray(got.profile).tolist(), model_share=got.model_share().tolist(),
                         model_rms=1e6 * got.model_rms, spread=args.spread, nominal=list(nominal),
                         line_screened=int(got.line_screened)))
        if args.from_truth:  # the same recording fitted from its truth: did the default's search find the cost's basin?
            begun = time.perf_counter()
            # A given start is a multiple of the scene's values: the scene with the truth's, started there.
            at_truth = with_parameters(full, names, jnp.asarray([1e-6 * t for t in truths]))
            there = tx.identify(at_truth, rec, names, starts=(1.0,), secant=secant)
            rows[-1].update(from_truth=dict(estimate=[1e6 * v for v in there.estimate], sd=1e6 * there.residual_sd,
                                            converged=there.converged, steps=int(there.steps),
                                            wall=time.perf_counter() - begun))
        print(rows[-1], flush=True)
        if args.rows:
            with args.rows.open("a") as f:
                f.write(json.dumps(rows[-1]) + "\n")
    return _write(rows, args)


def _write(rows, args) -> int:
    sigma = math.hypot(NOISE, 2 * math.pi / 2 ** rows[0].get("bits", 20) / math.sqrt(12))
    names, truths, dual = rows[0]["names"], rows[0].get("nominal", rows[0]["truth"]), rows[0]["dual"]
    spread = max(r.get("spread", 0.0) for r in rows)  # > 0: each recording's unit drawn (--spread)
    default = [r for r in rows if r["asked"] == "default"]
    commit = ", ".join(sorted({r["commit"] for r in rows if "commit" in r})) or subprocess.run(  # the runs' own, else the merge's
        ["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True).stdout.strip()
    cells = lambda r, j: ((f"{r['truth'][j]:.3f} | " if spread else "")  # noqa: E731
                          + f"{r['estimate'][j]:.3f} | {r['lo'][j]:.3f} – {r['hi'][j]:.3f} | {'yes' if r['hit'][j] else 'NO'} | "
                          f"{r['holds'][j]} | {r['status'][j]}" + (f" | {100 * r['model_share'][j]:.0f}" if "model_share" in r else " | –"))
    table = [f"| {r['seed']} | {r['asked']} | " + " | ".join(cells(r, j) for j in range(len(names))) + f" | {r['sd']:.2f} | "
             f"{'yes' if r['converged'] else 'no'} | {r['jacobian']} | {r['wall']:.0f} |" for r in rows]
    hits = sum(sum(r["hit"]) for r in default)
    intervals = len(default) * len(names)
    per = []
    for j, (name, truth) in enumerate(zip(names, truths)):
        err = [r["estimate"][j] - r["truth"][j] for r in default]
        shares = [r["model_share"][j] for r in default if "model_share" in r]
        per.append(f"{name}: {sum(r['hit'][j] for r in default)}/{len(default)} hold the truth "
                   + (f"(drawn within ±{spread:g} µm of {truth:g})" if spread else f"{truth:g} µm")
                   + f", estimates {np.mean(err):+.3f} µm from it on average, their errors' spread "
                   f"{np.std(err, ddof=1) if len(err) > 1 else float('nan'):.3f} µm "
                   f"against a stated standard error of {np.mean([(r['hi'][j] - r['lo'][j]) / 3.92 for r in default]):.3f}"
                   + (f" ({100 * np.mean(shares):.0f} % of its variance the model's own realisations', on average over "
                      f"{len(shares)})" if shares else "")
                   + f", {sum(r['holds'][j] is True for r in default)}/{len(default)} hold along their profiles")
    phases = {k: np.median([r["phases"].get(k, 0.0) for r in default]) for k in default[0]["phases"]} if default else {}
    unit = ("Dual scan, both joints at full planetary fidelity, recorded by both encoders" if dual else
            "Azimuth scan at full planetary fidelity")
    backlash = (f"ring backlash {truths[0]:g} µm (azimuth) and {truths[1]:g} µm (pitch)" if dual else f"ring backlash {truths[0]:g} µm")
    backlash += f", each recording's unit drawn uniformly within ±{spread:g} µm of those" if spread else ""
    text = "\n".join([
        "# Identifying the full planetary stage with the full stage" + (": the dual axis" if dual else ""), "",
        f"`python benchmarks/identify_full_stage.py{' --dual' if dual else ''}` over {len(default)} recordings (seeds "
        f"{', '.join(str(3000 + r['seed']) for r in default)}), split over processes as the script's docstring shows (tolerax "
        f"at {commit}, jax {jax.__version__}; {os.cpu_count()} cores, one per process; load average "
        f"{min(r['load'] for r in rows):.2f}-{max(r['load'] for r in rows):.2f} at the rows' ends).", "",
        f"{unit}, {DURATION:g} s from a steady start, {N_SAVE} samples; the unit's {backlash}, every other clearance the "
        f"scene's 100 µm; a {rows[0].get('bits', 20)}-bit encoder and 2 µrad of noise ({1e6 * sigma:.2f} µrad together); identified by the same "
        f"full-stage model with `identify`'s defaults (the best 2 of {rows[0].get('screened', 33) - 1} screened starts and the "
        "scene's values, within 2x of them; on "
        "central secants, as chosen here, at the scene's own smoothing width alone).", "",
        f"- default: **intervals holding the truth {hits}/{intervals}** (binomial P(X <= {hits}) = "
        f"{binom.cdf(hits, intervals, 0.95):.2f} at a true 95 %); converged {sum(r['converged'] for r in default)}/{len(default)}; "
        f"Levenberg-Marquardt steps {min(r['steps'] for r in default)}-{max(r['steps'] for r in default)} (the best start's); "
        f"residual sd {min(r['sd'] for r in default):.2f}-{max(r['sd'] for r in default):.2f} µrad against the encoder's "
        f"{1e6 * sigma:.2f}; wall {min(r['wall'] for r in default):.0f}-{max(r['wall'] for r in default):.0f} s (compilation in "
        "each process's first).",
        *(f"- {line}." for line in per),
        "- where the wall time goes (median seconds per phase, `Identification.wall`): "
        + ", ".join(f"{k} {v:.0f}" for k, v in phases.items()) + ".", "",
        "| recording | Jacobian asked | " + " | ".join(
            f"{n.split('.')[0] + ': ' if dual else ''}" + ("truth (µm) | " if spread else "") + "estimate (µm) | 95 % interval "
            "(µm) | holds the truth | holds along its profile | status | the model's share of the variance (%)" for n in names)
        + " | residual sd (µrad) | converged | Jacobian used | wall (s) |",
        "|---|---|" + ("---|" * (7 if spread else 6)) * len(names) + "---|---|---|---|", *table])
    print(text)
    if args.out:
        args.out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
