"""A single solve pinned to one core against the same solve free to use every core.

    python benchmarks/pinning.py [--fidelities planetary lumped] [--duration 0.3] [--rounds 3]

Writes `benchmarks/results/pinning.md`. Each configuration runs in a fresh Python process
(the processor affinity must be set before JAX creates its CPU client, whose thread pool is
sized by it): `pinned` restricts the process to one core with `os.sched_setaffinity` before
importing JAX, as `taskset -c N` would; `free` leaves it on every core. The processes alternate
(free, pinned, free, pinned, ...) for `--rounds` rounds, so a slow spell of the machine hits both.
In each process the dual-axis antenna is solved once to compile, then three times from a steady
start over `--duration` seconds (`tolerax.simulate`, Tsit5 rtol 1e-6); the fastest of the three
is that process's time. The table gives, per configuration, the fastest and the median over the
rounds of those times, and the steps (the same in every process: pinning changes no result).

Why it can matter: XLA's CPU runtime executes a program's independent kernels concurrently on
its thread pool. The antenna's right-hand side is ~220 kernels of a few microseconds each
(`rhs_anatomy.md`), too small to gain from a second core and large enough in number to pay for
handing work between threads.
"""

import argparse
import json
import os
import statistics
import subprocess
import sys

import _results


def child(fidelity: str, duration: float, pinned: bool) -> None:
    if pinned:
        os.sched_setaffinity(0, {max(os.sched_getaffinity(0))})
    import time

    import jax

    import tolerax

    mech = tolerax.antenna("dual", fidelity=fidelity)
    res = tolerax.simulate(mech, duration, start="steady", n_save=11)
    times = []
    for _ in range(3):
        start = time.perf_counter()
        res = tolerax.simulate(mech, duration, start="steady", n_save=11)
        jax.block_until_ready(res.ts)
        times.append(time.perf_counter() - start)
    print(json.dumps(dict(best=min(times), steps=int(res.num_steps), rejected=int(res.num_rejected), cores=len(os.sched_getaffinity(0)))))


def run(fidelity: str, duration: float, pinned: bool) -> dict:
    cmd = [sys.executable, __file__, "--child", fidelity, str(duration), "1" if pinned else "0"]
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out.strip().splitlines()[-1])


def main():
    if len(sys.argv) > 1 and sys.argv[1] == "--child":
        child(sys.argv[2], float(sys.argv[3]), sys.argv[4] == "1")
        return
    parser = argparse.ArgumentParser()
    parser.add_argument("--fidelities", nargs="+", default=["planetary", "lumped"])
    parser.add_argument("--duration", type=float, default=0.3, help="simulated seconds per solve")
    parser.add_argument("--rounds", type=int, default=3, help="processes per configuration, alternating")
    args = parser.parse_args()
    rows, load = [], [os.getloadavg()[0]]
    for fid in args.fidelities:
        got = {"free": [], "pinned": []}
        for _ in range(args.rounds):
            for mode in got:
                got[mode].append(run(fid, args.duration, mode == "pinned"))
                print(fid, mode, got[mode][-1], flush=True)
        steps = {(r["steps"], r["rejected"]) for rs in got.values() for r in rs}
        best = {mode: [r["best"] for r in rs] for mode, rs in got.items()}
        for mode, times in best.items():
            rows.append(
                [
                    fid,
                    f"{mode} ({got[mode][0]['cores']} core{'s' if got[mode][0]['cores'] > 1 else ''})",
                    f"{min(times):.3f}",
                    f"{statistics.median(times):.3f}",
                    " ".join(f"{t:.3f}" for t in times),
                    f"{min(times) / args.duration:.2f}",
                    f"{statistics.median(best['pinned']) / statistics.median(best['free']):.2f}" if mode == "pinned" else "1.00",
                    " / ".join(f"{a}, {r}" for a, r in sorted(steps)),
                ]
            )
        load.append(os.getloadavg()[0])
    _results.write_table(
        "pinning",
        "A single solve pinned to one core against free",
        _results.command(args),
        ["fidelity", "process", "fastest (s)", "median (s)", "each process (s)", "fastest, wall per simulated s", "median x free", "steps (accepted, rejected)"],
        rows,
        about=f"Dual-axis antenna, steady start, {args.duration} s, Tsit5 rtol 1e-6; {args.rounds} processes per row, "
        f"alternating; each process's time is the fastest of three solves after the compiling one. Load average "
        f"(1 min) at start and after each fidelity: {', '.join(f'{x:.2f}' for x in load)}.",
    )


if __name__ == "__main__":
    main()
