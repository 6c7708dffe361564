"""How far two correct solves part (the chaos floor), against each integrator's error: is a
looser integrator's error the rattle's own?

`rattle_window.py` and `auto_integrator.py` compare one run of each integrator with one rtol
1e-10 reference. Where the rattle is chaotic, one comparison is one draw. Here the start is
perturbed by `k` x `--step` rad in the azimuth carrier's angle for each `k` in `--ks`; each start
is solved by the reference (Tsit5, rtol 1e-10, atol 1e-13), tolerax's default (`ACCURATE`:
Tsit5, rtol 1e-6), `FAST_STAGE` (SRK53, rtol 1e-4, PI (0.2, 0.2)) and SRK53 at rtol 1e-3 with
the same controller (`--configs` picks); each one's window outputs (pointing RMS, peak, jitter
above 20 Hz, the largest bearing force: `auto_integrator.outputs`) against the same start's
reference as relative errors, and the references of `k` >= 1 against `k` = 0's: the floor, how
far correct solves part under a change no integrator controls. `--scene`: any scene of
`auto_integrator.py`'s matrix (its duration, start, saves and window; default the full planetary
dual in developed rattle, 2 s from a steady start, window 1-2 s). Wall time per solve (each
program compiled first by a 0.01 s run). One process per core: `--rows` collects them,
`--merge` writes the tables (per scene; the verdict per output: a solve's median error inside
the larger of the default's median and the floor's at perturbations >= 1e-9 rad).

    taskset -c 0 python benchmarks/rattle_chaos.py --ks 0 1 --rows /tmp/chaos.jsonl
    taskset -c 1 python benchmarks/rattle_chaos.py --ks 2 3 --rows /tmp/chaos.jsonl
    taskset -c 0 python benchmarks/rattle_chaos.py --ks 1 2 3 --step 1e-9 --rows /tmp/chaos.jsonl
    taskset -c 1 python benchmarks/rattle_chaos.py --scene "planetary dual slew 0.5 deg" --ks 0 1 2 3 --step 1e-9 --rows /tmp/chaos.jsonl
    python benchmarks/rattle_chaos.py --merge --rows /tmp/chaos.jsonl --out benchmarks/results/rattle_chaos.md

The rows of the committed result are `results/rattle_chaos.jsonl` (merge them to rebuild it).
"""

import argparse
import json
import pathlib
import time

import numpy as np

import tolerax as tx
from tolerax.solve import ACCURATE, FAST_STAGE

from auto_integrator import SCENES, outputs

CONFIGS = {"reference": tx.Integrator(rtol=1e-10, atol=1e-13, max_steps=10**7), "default (ACCURATE)": ACCURATE,
           "FAST_STAGE": FAST_STAGE, "SRK53 rtol 1e-3, PI (0.2, 0.2)": tx.Integrator(solver="SRK53", rtol=1e-3, atol=1e-6, pcoeff=0.2,
                                                                                      icoeff=0.2)}
STEP = 1e-12
RATTLE = "planetary dual, developed rattle"  # auto_integrator.SCENES' name for this scene, the default


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--ks", type=int, nargs="+", default=[0, 1], help="starts: k x 1e-12 rad on the azimuth carrier")
    parser.add_argument("--step", type=float, default=STEP, help="the perturbation per k, rad on the azimuth carrier")
    parser.add_argument("--configs", nargs="+", default=list(CONFIGS), choices=list(CONFIGS), metavar="NAME",
                        help=f"which solves to run (default all: {', '.join(map(repr, CONFIGS))})")
    parser.add_argument("--scene", default=RATTLE, choices=[n for n in SCENES if n != "bench"], metavar="SCENE",
                        help="a scene of auto_integrator.py's matrix (its duration, start, saves and window)")
    parser.add_argument("--rows", type=pathlib.Path, required=True, help="jsonl file the rows are appended to / read from")
    parser.add_argument("--merge", action="store_true", help="write the table from --rows")
    parser.add_argument("--out", type=pathlib.Path, default=None)
    args = parser.parse_args(argv)
    if args.merge:
        return merge(args.rows, args.out)
    build, duration, start_kind, n_save, window = SCENES[args.scene]
    scene = build()
    q, *rest = scene.initial_state(start_kind)
    carrier = scene.layout.azimuth_q.start + scene.azimuth.layout.carrier
    configs = {name: CONFIGS[name] for name in args.configs}
    for name, integrator in configs.items():
        tx.simulate(scene, 0.01, n_save=n_save, start=start_kind, integrator=integrator)  # compiled once (the duration is a value)
    for k in args.ks:
        y0 = (q.at[carrier].add(k * args.step), *rest)
        for name, integrator in configs.items():
            start = time.perf_counter()
            res = tx.simulate(scene, duration, n_save=n_save, y0=y0, integrator=integrator)
            wall = time.perf_counter() - start
            row = dict(scene=args.scene, k=k, step=args.step, config=name, wall=wall, steps=int(res.num_steps),
                       **outputs(res, window))
            print(row, flush=True)
            with args.rows.open("a") as f:
                f.write(json.dumps(row) + "\n")
    return 0


KEYS = ("pointing_rms", "pointing_peak", "pointing_jitter", "bearing_force")
SATURATED = 1e-9  # rad: perturbations from this up part the references as far as integration errors do (the floor used)


def merge(rows_path, out) -> int:
    """The tables from `rows_path`: per scene, the floor (references from perturbed starts
    against the unperturbed one, per perturbation size) and each solve's errors against its own
    start's reference; the verdict per output: a solve's median error inside the larger of the
    default's median and the floor's (perturbations >= `SATURATED`)."""
    rows = [json.loads(line) for line in rows_path.read_text().splitlines() if line.strip()]
    for r in rows:  # the first run's rows (the developed rattle at 1e-12) carry neither
        r.setdefault("scene", RATTLE)
        r.setdefault("step", STEP)
    lines = ["# The chaos floor against each integrator's error", "",
             "`python benchmarks/rattle_chaos.py --scene S --ks K... --step D` (merged by `--merge`): each start perturbs the "
             "steady (or resting) start by k x D rad on the azimuth carrier; every start is solved by the reference (Tsit5, "
             "rtol 1e-10) and the solves below. Cells: relative errors, one per start, then their median. The floor: the "
             "references of perturbed starts against the unperturbed one's.", ""]
    for scene in dict.fromkeys(r["scene"] for r in rows):
        mine = [r for r in rows if r["scene"] == scene]
        ref = {(r["step"], r["k"]) if r["k"] else 0: r for r in mine if r["config"] == "reference"}
        if 0 not in ref:
            continue
        base = ref[0]

        def rel(r, key, against):
            return abs(r[key] - against[key]) / abs(against[key])

        def cell(values):
            return " ".join(f"{v:.1e}" for v in values) + f" (median {np.median(values):.1e})" if values else "-"

        lines += [f"## {scene}", "", "| solves | " + " | ".join(KEYS) + " | wall s (median) | steps (median) | median inside "
                  "max(default's, floor's) |", "|---|" + "---|" * (len(KEYS) + 3)]
        floors = {}
        for step in sorted({s for s in (k[0] for k in ref if k) }):
            perturbed = [r for k, r in ref.items() if k and k[0] == step]
            lines.append(f"| references, start perturbed by k x {step:g} rad, against k = 0 (the floor) | "
                         + " | ".join(cell([rel(r, key, base) for r in perturbed]) for key in KEYS) + " | - | - | - |")
            if step >= SATURATED:
                for key in KEYS:
                    floors.setdefault(key, []).extend(rel(r, key, base) for r in perturbed)
        medians = {}
        for name in CONFIGS:
            solved = [(r, ref.get((r["step"], r["k"]) if r["k"] else 0)) for r in mine if r["config"] == name]
            solved = [(r, against) for r, against in solved if against is not None]
            if not solved:
                continue
            walls = f"{np.median([r['wall'] for r, _ in solved]):.1f} | {int(np.median([r['steps'] for r, _ in solved]))}"
            if name == "reference":
                lines.append(f"| {name} | " + " | ".join("-" for _ in KEYS) + f" | {walls} | - |")
                continue
            errs = {key: [rel(r, key, against) for r, against in solved] for key in KEYS}
            medians[name] = {key: float(np.median(v)) for key, v in errs.items()}
            bound = {key: max(medians.get("default (ACCURATE)", {}).get(key, 0.0), float(np.median(floors.get(key, [0.0]))))
                     for key in KEYS}
            verdict = "-" if name == "default (ACCURATE)" else (
                "yes" if all(medians[name][k] <= bound[k] for k in KEYS) else "no: " + ", ".join(
                    k for k in KEYS if medians[name][k] > bound[k]))
            lines.append(f"| {name} | " + " | ".join(cell(errs[key]) for key in KEYS) + f" | {walls} | {verdict} |")
        lines.append("")
    text = "\n".join(lines)
    print(text)
    if out:
        out.write_text(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
