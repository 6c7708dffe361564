"""Rough wall times, said before a long run starts (the command line's estimates, `studies.run`)."""


# Rough wall seconds per simulated second of one joint at each fidelity, on one core of the
# development machine: half the dual antenna's as `benchmarks/mechanism_cost.py` times it (Tsit5,
# rtol 1e-6, steady start, 0.98 deg/s). A scan's reversals, a tighter tolerance or another
# machine change it by 2x or more: an estimate to say before a long run, not a promise.
ROUGH_COST = {"ideal": 0.03, "lumped": 0.22, "planetary-scaled": 3.2, "planetary": 8.1}


# `tolerax.solve.FAST_STAGE`'s wall time on the full stage, where a run names it, as a fraction
# of the Tsit5 those costs were timed with (benchmarks/README.md, speed: auto_integrator.py).
FAST_STAGE_COST = 0.6


def rough_wall(scene, duration: float, integrator=None) -> float | None:
    """A rough wall time (s) for simulating `scene` over `duration` (s) on one core
    (`ROUGH_COST` per joint; `FAST_STAGE_COST` of it for a full planetary joint where
    `integrator`, default the scene's automatic one, is `FAST_STAGE`), or None for a joint of a
    class tolerax does not know."""
    from .design.fidelity import joint_fidelities
    from .solve import FAST_STAGE

    integrator = scene.automatic_integrator()[0] if integrator is None else integrator
    fast = FAST_STAGE_COST if integrator.replace(max_steps=FAST_STAGE.max_steps) == FAST_STAGE else 1.0
    costs = [ROUGH_COST.get(f) * (fast if f == "planetary" else 1.0) if f in ROUGH_COST else None
             for f in joint_fidelities(scene).values()]
    return None if any(c is None for c in costs) else float(duration) * sum(costs)


def human_seconds(seconds: float) -> str:
    """`42 s`, `7 min`, `3.1 h`, `12 days`, `4.0e+03 years`."""
    for unit, size in (("years", 3.156e7), ("days", 86400.0), ("h", 3600.0), ("min", 60.0)):
        if seconds >= 2 * size:
            value = seconds / size
            return f"{value:.2g} {unit}" if value < 1e4 else f"{value:.1e} {unit}"
    return f"{seconds:.0f} s"


def time_left(spent: float, done: int, total: int) -> str:
    """`", about 7 min left"` at the pace so far (`spent` s over `done` of `total` items), or `""`
    once all are done."""
    left = total - done
    return f", about {human_seconds(spent / done * left)} left" if left > 0 and done > 0 else ""
