"""Compile time and wall time per simulated second of the dual-axis antenna scene at each joint
fidelity (free base, 0.98 deg/s on both joints, 100 um clearances and backlash, steady start,
Tsit5 rtol 1e-6 atol 1e-9).

    python benchmarks/mechanism_cost.py [--duration 0.5]

Writes `benchmarks/results/mechanism_cost.md`. Each scene is solved twice: the first call's
time minus the second's is the compile time; the second is the run time (same machine, same run,
so the ratios between fidelities are what to read).
"""

import argparse
import pathlib
import time

import jax

import tolerax
from tolerax import _mechanism as M


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=0.5, help="simulated seconds per scene")
    args = parser.parse_args()
    rows = []
    for fid in ("ideal", "lumped", "planetary"):
        mech = M.antenna("dual", fidelity=fid)
        start = time.perf_counter()
        res = M.simulate(mech, args.duration, n_save=51, steady=True)
        jax.block_until_ready(res.ts)
        first = time.perf_counter() - start
        start = time.perf_counter()
        res = M.simulate(mech, args.duration, n_save=51, steady=True)
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
                pointing_rms_arcsec=float((res.pointing_error**2).mean() ** 0.5) * 206264.8,
            )
        )
        print(rows[-1], flush=True)
    base = rows[0]["per_sim_s"]
    lines = [
        "# Dual-axis mechanism: cost per fidelity",
        "",
        f"`python benchmarks/mechanism_cost.py --duration {args.duration}` (tolerax {tolerax.__version__}, "
        f"{jax.devices()[0].platform}, {args.duration} s simulated per scene, steady start, 0.98 deg/s both joints).",
        "",
        "| fidelity | DOFs (u) | contacts | compile (s) | wall s per simulated s | x ideal | accepted steps per simulated s | rejected | pointing RMS (arcsec) |",
        "|---|---|---|---|---|---|---|---|---|",
    ]
    for r in rows:
        lines.append(
            f"| {r['fidelity']} | {r['dofs']} | {r['contacts']} | {r['compile_s']:.1f} | {r['per_sim_s']:.2f} | "
            f"{r['per_sim_s'] / base:.1f} | {r['steps_per_sim_s']:.0f} | {r['rejected']} | {r['pointing_rms_arcsec']:.1f} |"
        )
    out = pathlib.Path(__file__).parent / "results" / "mechanism_cost.md"
    out.write_text("\n".join(lines) + "\n")
    print(out.read_text())


if __name__ == "__main__":
    main()
