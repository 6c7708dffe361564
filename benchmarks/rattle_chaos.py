"""How far two correct solves of the full planetary dual in developed rattle part (the chaos
floor), against each integrator's error there: is a looser integrator's error the rattle's own?

`rattle_window.py` and `auto_integrator.py` compare one run of each integrator with one rtol
1e-10 reference, over the developed rattle (`tx.antenna("dual", fidelity="planetary")`, 2 s from a
steady start, the window 1-2 s). The rattle is chaotic, so one comparison is one draw. Here the
steady start is perturbed by `k` x 1e-12 rad in the azimuth carrier's angle (a rounding-level
change) for each `k` in `--ks`; each start is solved by the reference (Tsit5, rtol 1e-10, atol
1e-13), tolerax's default (`ACCURATE`: Tsit5, rtol 1e-6), `FAST_STAGE` (SRK53, rtol 1e-4, PI
(0.2, 0.2)) and SRK53 at rtol 1e-3 with the same controller; each one's window outputs (pointing
RMS, peak, jitter above 20 Hz, the largest bearing force: `auto_integrator.outputs`) against the
same start's reference as relative errors, and the references of `k` >= 1 against `k` = 0's: the
floor, how far correct solves part under a change no integrator controls. Wall time per solve
(each program compiled first by a 0.01 s run). One process per core: `--rows` collects them,
`--merge` writes the table.

    taskset -c 0 python benchmarks/rattle_chaos.py --ks 0 1 --rows /tmp/chaos.jsonl
    taskset -c 1 python benchmarks/rattle_chaos.py --ks 2 3 --rows /tmp/chaos.jsonl
    python benchmarks/rattle_chaos.py --merge --rows /tmp/chaos.jsonl --out benchmarks/results/rattle_chaos.md
"""

import argparse
import json
import pathlib
import time

import numpy as np

import tolerax as tx
from tolerax.solve import ACCURATE, FAST_STAGE

from auto_integrator import outputs

CONFIGS = {"reference": tx.Integrator(rtol=1e-10, atol=1e-13, max_steps=10**7), "default (ACCURATE)": ACCURATE,
           "FAST_STAGE": FAST_STAGE, "SRK53 rtol 1e-3, PI (0.2, 0.2)": tx.Integrator(solver="SRK53", rtol=1e-3, atol=1e-6, pcoeff=0.2,
                                                                                      icoeff=0.2)}
DURATION, N_SAVE, WINDOW, STEP = 2.0, 2001, 1.0, 1e-12


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ks", type=int, nargs="+", default=[0, 1], help="starts: k x 1e-12 rad on the azimuth carrier")
    parser.add_argument("--rows", type=pathlib.Path, required=True, help="jsonl file the rows are appended to / read from")
    parser.add_argument("--merge", action="store_true", help="write the table from --rows")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    args = parser.parse_args(argv)
    if args.merge:
        return merge(args.rows, args.out)
    scene = tx.antenna("dual", fidelity="planetary")
    q, *rest = scene.initial_state("steady")
    carrier = scene.layout.azimuth_q.start + scene.azimuth.layout.carrier
    for name, integrator in CONFIGS.items():
        tx.simulate(scene, 0.01, n_save=N_SAVE, start="steady", integrator=integrator)  # compiled once (the duration is a value)
    for k in args.ks:
        y0 = (q.at[carrier].add(k * STEP), *rest)
        for name, integrator in CONFIGS.items():
            start = time.perf_counter()
            res = tx.simulate(scene, DURATION, n_save=N_SAVE, y0=y0, integrator=integrator)
            wall = time.perf_counter() - start
            row = dict(k=k, config=name, wall=wall, steps=int(res.num_steps), **outputs(res, WINDOW))
            print(row, flush=True)
            with args.rows.open("a") as f:
                f.write(json.dumps(row) + "\n")
    return 0


def merge(rows_path, out) -> int:
    rows = [json.loads(line) for line in rows_path.read_text().splitlines() if line.strip()]
    keys = ("pointing_rms", "pointing_peak", "pointing_jitter", "bearing_force")
    ref = {r["k"]: r for r in rows if r["config"] == "reference"}
    ks = sorted(ref)
    lines = ["# The developed rattle's chaos floor against each integrator's error", "",
             f"`python benchmarks/rattle_chaos.py` over starts k = {', '.join(map(str, ks))} (k x {STEP:g} rad on the azimuth "
             "carrier); `tx.antenna('dual', fidelity='planetary')`, 2 s from a steady start, window 1-2 s, jitter above 20 Hz. "
             "Each cell: the relative errors against the same start's reference, one per start, then their median.", "",
             "| solves | " + " | ".join(keys) + " | wall s (median) | steps (median) |", "|---|" + "---|" * (len(keys) + 2)]

    def cell(values):
        return " ".join(f"{v:.1e}" for v in values) + f" (median {np.median(values):.1e})"

    floor = [r for k, r in ref.items() if k != ks[0]]
    if floor:
        lines.append("| reference, k against k = 0 (the floor) | " + " | ".join(
            cell([abs(r[key] - ref[ks[0]][key]) / abs(ref[ks[0]][key]) for r in floor]) for key in keys) + " | - | - |")
    for name in CONFIGS:
        mine = [r for r in rows if r["config"] == name and r["k"] in ref]
        errors = [cell([abs(r[key] - ref[r["k"]][key]) / abs(ref[r["k"]][key]) for r in mine]) for key in keys] if name != "reference" else ["-"] * len(keys)
        lines.append(f"| {name} | " + " | ".join(errors) + f" | {np.median([r['wall'] for r in mine]):.1f} | {int(np.median([r['steps'] for r in mine]))} |")
    text = "\n".join(lines)
    print(text)
    if out:
        out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
