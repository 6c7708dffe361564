"""Cost of simulating the dual-axis antenna at each joint fidelity: compile time and wall time
per simulated second, measured in one process so that the ratios between fidelities are what to
read (absolute times depend on the machine and on what else runs on it).

Shared by `tolerax bench` and `benchmarks/mechanism_cost.py`.
"""

import time

import jax

from .mechanism.outputs import ARCSEC
from .mechanism.scene import simulate
from .mechanism.scenes import antenna

COLUMNS = (
    "fidelity", "DOFs (u)", "contacts", "compile (s)", "wall s per simulated s", "x {base}",
    "accepted steps per simulated s", "rejected", "pointing RMS (arcsec)",
)


def fidelity_cost(
    fidelity: str,
    duration: float,
    *,
    n_save: int = 51,
    label: str | None = None,
    repeats: int = 1,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    pid: tuple[float, float] = (0.0, 1.0),
    **options,
) -> dict:
    """Compile and run time of `antenna("dual", fidelity=fidelity, **options)` (free base, 0.98
    deg/s on both joints, 100 um clearances and backlash) over `duration` (s) from a steady start.
    `label` names the row (default: the fidelity); `options` go to `antenna` (for example
    `mass_scaling=100.0` with `"planetary-scaled"`); `rtol`, `atol` are the solver's tolerances
    (Tsit5) and `pid` its step-size controller's `(pcoeff, icoeff)` (`simulate`).

    The scene is solved `1 + repeats` times: the fastest of the calls after the first is the run
    time (on a shared or virtual machine noise only ever adds time), the first call's time minus
    it the compile time.

    **Returns:** a dict: `fidelity`, `dofs` (velocity coordinates), `contacts` (clearance contacts),
    `compile_s`, `per_sim_s` (wall s per simulated s), `steps_per_sim_s` (accepted steps per
    simulated s), `rejected` (rejected steps), `pointing_rms_arcsec` (over the whole run).
    """
    mech = antenna("dual", fidelity=fidelity, **options)
    times, res = [], None
    for _ in range(1 + repeats):
        start = time.perf_counter()
        res = simulate(mech, duration, n_save=n_save, start="steady", rtol=rtol, atol=atol, pcoeff=pid[0], icoeff=pid[1])
        jax.block_until_ready(res.ts)
        times.append(time.perf_counter() - start)
    first, run = times[0], min(times[1:])
    lay = mech.layout
    return dict(
        fidelity=fidelity if label is None else label,
        dofs=int(lay.size_u),
        contacts=int(lay.size_v),
        compile_s=first - run,
        per_sim_s=run / duration,
        steps_per_sim_s=int(res.num_steps) / duration,
        rejected=int(res.num_rejected),
        pointing_rms_arcsec=float((res.pointing_error**2).mean() ** 0.5) / ARCSEC,
    )


def cost_table(rows: list[dict]) -> tuple[list[str], list[tuple[str, ...]]]:
    """Column names and formatted cells of `fidelity_cost` rows; the ratio column is relative to
    the first row."""
    base = rows[0]
    columns = [c.format(base=base["fidelity"]) for c in COLUMNS]
    cells = [
        (
            r["fidelity"], str(r["dofs"]), str(r["contacts"]), f"{r['compile_s']:.1f}", f"{r['per_sim_s']:.2f}",
            f"{r['per_sim_s'] / base['per_sim_s']:.1f}", f"{r['steps_per_sim_s']:.0f}", str(r["rejected"]),
            f"{r['pointing_rms_arcsec']:.1f}",
        )
        for r in rows
    ]
    return columns, cells
