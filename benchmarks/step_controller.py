"""PID coefficients of the step-size controller on the rattling planetary antenna (issue 14,
item 2: "a controller tuned for impacts").

    python benchmarks/step_controller.py [--scaling 100] [--duration 1.5] [--jobs 2]

`tolerax.simulate` uses diffrax's `PIDController` as an I-controller (pcoeff 0, icoeff 1, its
default). Each configuration runs in its own process with the controller's coefficients patched
in (`tolerax._solve._NanSafePID`, looked up when the solve is traced), on
`antenna("dual", fidelity="planetary-scaled", mass_scaling=...)` from the steady start, Tsit5
rtol 1e-6. Counts of accepted and rejected steps are what to read (deterministic); wall times
come from processes that share the machine. Writes `benchmarks/results/step_controller.md`.
"""

import argparse
import concurrent.futures
import functools
import json
import subprocess
import sys
import time

import _results

CONFIGS = ((0.0, 1.0), (0.4, 0.3), (0.3, 0.3), (0.2, 0.4))  # (pcoeff, icoeff); the first is diffrax's default


def _one(pcoeff, icoeff, scaling, duration):
    import jax
    import numpy as np

    import tolerax
    import tolerax._solve as S

    S._NanSafePID = functools.partial(S._NanSafePID, pcoeff=pcoeff, icoeff=icoeff)
    mech = tolerax.antenna("dual", fidelity="planetary-scaled", mass_scaling=scaling)
    n = int(round(duration * 1000)) + 1
    tolerax.simulate(mech, 1e-3, n_save=n, start="steady")  # compiles
    began = time.perf_counter()
    res = tolerax.simulate(mech, duration, n_save=n, start="steady")
    jax.block_until_ready(res.ts)
    wall = time.perf_counter() - began
    ts, pe = np.asarray(res.ts), np.asarray(res.pointing_error)
    late = ts >= duration - 0.5
    rms = float(np.sqrt((pe[late] ** 2).mean())) / tolerax.ARCSEC
    return dict(pcoeff=pcoeff, icoeff=icoeff, wall=wall, steps=int(res.num_steps), rejected=int(res.num_rejected), rms=rms)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--scaling", type=float, default=100.0)
    parser.add_argument("--duration", type=float, default=1.5)
    parser.add_argument("--jobs", type=int, default=2, help="configurations run at once (one process each)")
    parser.add_argument("--one", nargs=2, type=float, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.one:
        print(json.dumps(_one(*args.one, args.scaling, args.duration)))
        return

    def launch(cfg):
        cmd = [sys.executable, __file__, "--one", str(cfg[0]), str(cfg[1]), "--scaling", str(args.scaling), "--duration", str(args.duration)]
        out = subprocess.run(cmd, capture_output=True, text=True, check=True).stdout
        return json.loads(out.strip().splitlines()[-1])

    with concurrent.futures.ThreadPoolExecutor(args.jobs) as pool:
        rows = list(pool.map(launch, CONFIGS))
    base = rows[0]["steps"] + rows[0]["rejected"]
    cells = [
        (
            f"{r['pcoeff']:g}", f"{r['icoeff']:g}", str(r["steps"]), str(r["rejected"]),
            f"{100 * r['rejected'] / (r['steps'] + r['rejected']):.0f} %", str(r["steps"] + r["rejected"]),
            f"{(r['steps'] + r['rejected']) / base:.3f}", f"{r['wall']:.1f}", f"{r['rms']:.1f}",
        )
        for r in rows
    ]
    _results.write_table(
        "step_controller",
        "Step-size controller coefficients on the rattling planetary antenna",
        _results.command(args),
        ["pcoeff", "icoeff", "accepted", "rejected", "rejected share", "attempted", "attempted / default",
         "wall (s, shared machine)", "pointing RMS over the last 0.5 s (arcsec)"],
        cells,
        about=(
            f"Dual-axis antenna, planetary-scaled joints (mass_scaling {args.scaling:g}), 0.98 deg/s, steady start, "
            f"{args.duration} s, Tsit5 rtol 1e-6 atol 1e-9; first row: diffrax's default I-controller (what tolerax uses)."
        ),
        notes=[
            "A step costs the same whether it is accepted or rejected, so attempted steps measure the work. "
            "The PI settings cut rejections but take more accepted steps: the step is held by the stiff "
            "mesh-held modes' stability limit (fast_modes.md; loaded_start.md: a quiet run takes as many steps), "
            "not by impacts a controller could anticipate."
        ],
    )


if __name__ == "__main__":
    main()
