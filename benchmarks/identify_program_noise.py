"""How far apart the same model's compiled programs put the full planetary dual's trajectory:
the cost of a noise-free recording (made by `simulate`) against the model at the truth itself,
through the three programs `identify` evaluates it with (one jitted run; the screen's and the
intervals' check's batch of 65; the central secants' batch of 2p + 1). Zero where the
trajectory is reproducible; what it is, the simulation's own error in the residual.

    taskset -c 0 python benchmarks/identify_program_noise.py > benchmarks/results/identify_program_noise.md
"""

import dataclasses
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.design.objectives import PointingObjective
from tolerax.identification.fit import SECANT_STEP, _costs, _Fit, _fit_and_jacobian
from tolerax.identification.identify import _model_times, _scales, own_width


def main() -> int:
    scene, axes = tx.scan("dual", fidelity="planetary"), ("azimuth", "pitch")
    names = ("azimuth.ring_backlash", "pitch.ring_backlash")
    rec = tx.synthetic_recording(scene, {names[0]: 60e-6, names[1]: 130e-6}, duration=0.35, n_save=141, axes=axes)
    n_save, times = _model_times(rec, rec.duration, None)
    objective = PointingObjective(scene, duration=rec.duration, settle=0.0, n_save=n_save, start="steady").forward_mode()
    fit = _Fit(objective, names, jnp.asarray(_scales(scene, list(names))[1]), jnp.arange(n_save), jnp.asarray([0, 1]),
               jnp.asarray(rec.at(times)))
    width, x, n = own_width(scene), jnp.asarray([60.0, 130.0]), 2 * n_save
    start = time.perf_counter()
    costs = {"one jitted run": float(jnp.sum(eqx.filter_jit(lambda f, v, w: f.residual(v, w))(fit, x, width) ** 2)),
             "the screen's batch of 65": float(np.asarray(_costs(fit, jnp.tile(x, (65, 1)), width))[0]),
             "the secants' batch of 5": float(np.sum(np.asarray(_fit_and_jacobian(dataclasses.replace(fit, secant=SECANT_STEP), x,
                                                                                   width)[3]) ** 2))}
    wall = time.perf_counter() - start
    rows = [f"| {what} | {c:.1f} | {np.sqrt(c / n):.3f} | {c / 7.4:.1f} |" for what, c in costs.items()]
    print("\n".join([
        "# The full planetary dual's trajectory through three compiled programs of the same model", "",
        f"`python benchmarks/identify_program_noise.py` (jax {jax.__version__}; one core; {wall:.0f} s with compilation).", "",
        "A noise-free recording of the full planetary dual (ring backlash 60 µm azimuth, 130 µm pitch, 0.35 s, 141 saves, "
        "both encoders; `simulate`'s run) against the model at the truth itself, through each program `identify` costs it "
        "with. The residual variance of a 20-bit recording with 2 µrad of noise is ~7.4 µrad² (s²).", "",
        f"| program | cost (µrad², {n} residuals) | RMS (µrad) | in s² |", "|---|---|---|---|", *rows]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
