"""Do gradients of the pointing error mean anything when the joints rattle? Reverse-mode
gradients against central finite differences as the horizon grows, at several smoothing widths
(issue 12, item 4; docs/MODEL.md §7: chaotic rattle can make pathwise gradients grow without
bound).

    python benchmarks/gradient_horizon.py [--horizons 0.3 0.6 1.0] [--widths 1e-9 1e-7 1e-6]

Scene: `tolerax.scan("azimuth", fidelity=("lumped", "ideal"))`: the azimuth joint scans
+-0.5 deg with a 1 s period (reversals at 0.25 s and 0.75 s) from a steady start; the pitch joint
is held rigid. Objective: RMS pointing error (arcsec) over the whole run,
`PointingObjective(..., settle=0)`. Design: the azimuth joint's output-bearing clearance,
planet-pin clearance, sun- and ring-mesh backlash, all 100 um.

For each horizon and width: the reverse-mode gradient (diffrax `RecursiveCheckpointAdjoint`),
central differences at h = 10 nm and 100 nm, the relative difference |AD - FD(10 nm)| / |FD|,
and the finite differences' own spread |FD(10 nm) - FD(100 nm)| / |FD| (how smooth the
objective is at that scale: where AD and FD differ by much more than FD's spread, the pathwise
gradient no longer describes the objective).
"""

import argparse
import time

import equinox as eqx
import jax
import numpy as np

import tolerax as tx

import _results


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--horizons", type=float, nargs="+", default=[0.3, 0.6, 1.0])
    parser.add_argument("--widths", type=float, nargs="+", default=[1e-9, 1e-7, 1e-6])
    args = parser.parse_args()
    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    names = tx.design_names(scene)
    p0 = tx.design_of(scene)
    rows = []
    for horizon in args.horizons:
        pointing = tx.PointingObjective(scene, duration=horizon, settle=0.0, start="steady", n_save=101)
        f = eqx.filter_jit(lambda p, w: pointing(p, w)["pointing_rms"])
        grad = eqx.filter_jit(jax.grad(lambda p, w: pointing(p, w)["pointing_rms"]))
        for width in args.widths:
            jax.block_until_ready(grad(p0, width))
            start = time.perf_counter()
            ad = np.asarray(jax.block_until_ready(grad(p0, width)))
            t_grad = time.perf_counter() - start
            value = float(f(p0, width))  # compiles
            start = time.perf_counter()
            jax.block_until_ready(f(p0, width))
            t_fwd = time.perf_counter() - start
            fd = {h: np.array([(f(p0.at[k].add(h), width) - f(p0.at[k].add(-h), width)) / (2 * h) for k in range(len(p0))]) for h in (1e-8, 1e-7)}
            scale = np.linalg.norm(fd[1e-8])
            rel = np.linalg.norm(ad - fd[1e-8]) / scale if scale > 0 else float("nan")
            spread = np.linalg.norm(fd[1e-8] - fd[1e-7]) / scale if scale > 0 else float("nan")
            rows.append(
                [f"{horizon:g}", f"{width:g}", f"{value:.1f}"]
                + [f"{a * 1e-6:.3g} / {b * 1e-6:.3g}" for a, b in zip(ad, fd[1e-8])]
                + [f"{rel:.2g}", f"{spread:.2g}", f"{t_grad / t_fwd:.1f}"]
            )
            print(rows[-1], flush=True)
    _results.write_table(
        "gradient_horizon",
        "Pointing-error gradients against finite differences, by horizon and smoothing width",
        _results.command(args),
        ["horizon (s)", "width (m)", "RMS pointing (arcsec)"]
        + [f"{n} AD / FD (arcsec/um)" for n in names]
        + ["abs(AD - FD) / abs(FD)", "FD spread (10 vs 100 nm)", "gradient / forward time"],
        rows,
        about="Azimuth scan +-0.5 deg, 1 s period, steady start, lumped joint, fixed base.",
    )


if __name__ == "__main__":
    main()
