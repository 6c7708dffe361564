"""Compile time and wall time per simulated second of the dual-axis antenna scene at each joint
fidelity (free base, 0.98 deg/s on both joints, 100 um clearances and backlash, steady start,
Tsit5 rtol 1e-6 atol 1e-9).

    python benchmarks/mechanism_cost.py [--duration 0.5] [--fidelities ideal lumped planetary]

Writes `benchmarks/results/mechanism_cost.md`. Each scene is solved twice: the first call's
time minus the second's is the compile time; the second is the run time (same machine, same run,
so the ratios between fidelities are what to read).
"""

import argparse
import time

import jax

import tolerax

import _results


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=0.5, help="simulated seconds per scene")
    parser.add_argument("--fidelities", nargs="+", choices=list(tolerax.FIDELITIES), default=list(tolerax.FIDELITIES))
    args = parser.parse_args()
    rows = []
    for fid in args.fidelities:
        mech = tolerax.antenna("dual", fidelity=fid)
        start = time.perf_counter()
        res = tolerax.simulate(mech, args.duration, n_save=51, start="steady")
        jax.block_until_ready(res.ts)
        first = time.perf_counter() - start
        start = time.perf_counter()
        res = tolerax.simulate(mech, args.duration, n_save=51, start="steady")
        jax.block_until_ready(res.ts)
        run = time.perf_counter() - start
        lay = mech.layout
        rows.append(
            dict(
                fidelity=fid,
                dofs=lay.size_u,
                contacts=lay.size_v,
                compile_s=first - run,
                per_sim_s=run / args.duration,
                steps_per_sim_s=int(res.num_steps) / args.duration,
                rejected=int(res.num_rejected),
                pointing_rms_arcsec=float((res.pointing_error**2).mean() ** 0.5) / tolerax.ARCSEC,
            )
        )
        print(rows[-1], flush=True)
    base = rows[0]
    _results.write_table(
        "mechanism_cost",
        "Dual-axis mechanism: cost per fidelity",
        _results.command(args),
        [
            "fidelity", "DOFs (u)", "contacts", "compile (s)", "wall s per simulated s", f"x {base['fidelity']}",
            "accepted steps per simulated s", "rejected", "pointing RMS (arcsec)",
        ],
        [
            (
                r["fidelity"], str(r["dofs"]), str(r["contacts"]), f"{r['compile_s']:.1f}", f"{r['per_sim_s']:.2f}",
                f"{r['per_sim_s'] / base['per_sim_s']:.1f}", f"{r['steps_per_sim_s']:.0f}", str(r["rejected"]),
                f"{r['pointing_rms_arcsec']:.1f}",
            )
            for r in rows
        ],
        about=f"{args.duration} s simulated per scene, steady start, 0.98 deg/s both joints.",
    )


if __name__ == "__main__":
    main()
