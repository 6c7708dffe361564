"""How far apart the same model's compiled programs put the full planetary dual's trajectory:
the cost of a noise-free recording (made by `simulate`) against the model at the truth itself,
through the three programs `identify` evaluates it with (one jitted run; the screen's and the
intervals' check's batch of 65; the central secants' batch of 2p + 1). Zero where the
trajectory is reproducible; what it is, the simulation's own error in the residual. Then what
each such difference does to the estimate: the Gauss-Newton step it makes from the truth (the
secants' Jacobian), for each program and for 16 realisations at each of four relative
perturbations of the parameters (`identify`'s model term takes them at 1e-9: `fit._model_noise`).

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
from tolerax.identification.fit import SECANT_STEP, _Fit, _fit_and_jacobian, _residuals
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
    jac, _, _, at_secants = (np.asarray(a) for a in _fit_and_jacobian(dataclasses.replace(fit, secant=SECANT_STEP), x, width))
    residuals = {"one jitted run": np.asarray(eqx.filter_jit(lambda f, v, w: f.residual(v, w))(fit, x, width)),
                 "the screen's batch of 65": np.asarray(_residuals(fit, jnp.tile(x, (65, 1)), width))[0],
                 "the secants' batch of 5": at_secants}
    inverse = np.linalg.inv(jac.T @ jac)
    step = lambda r: -(r @ jac) @ inverse  # noqa: E731  (the Gauss-Newton step from the truth, µm; r: rows of residuals)
    sizes, g = (1e-11, 1e-9, 1e-7, 1e-6), np.random.default_rng(0).standard_normal((16, 2))
    points = np.vstack([np.asarray(x)[None] * (1 + e * g) for e in sizes])
    realised = np.asarray(_residuals(fit, jnp.asarray(np.vstack([points, np.tile(np.asarray(x), (65 - len(points), 1))])), width))
    wall = time.perf_counter() - start
    rows = [f"| {what} | {np.sum(r**2):.1f} | {np.sqrt(np.mean(r**2)):.3f} | {np.sum(r**2) / 7.4:.1f} | "
            + " | ".join(f"{v:+.3f}" for v in step(r)) + " |" for what, r in residuals.items()]
    more = []
    for i, e in enumerate(sizes):
        k = slice(16 * i, 16 * i + 16)
        shifts = step(realised[k] - (points[k] - np.asarray(x)[None]) @ jac.T)  # the linearised move taken out
        more.append(f"| {e:g} | {np.sqrt(np.mean(realised[k] ** 2)):.3f} | " + " | ".join(
            f"{shifts[:, j].mean():+.3f} | {shifts[:, j].std(ddof=1):.3f} | {shifts[:, j].min():+.3f} to {shifts[:, j].max():+.3f}"
            for j in range(2)) + " |")
    print("\n".join([
        "# The full planetary dual's trajectory through three compiled programs of the same model", "",
        f"`python benchmarks/identify_program_noise.py` (jax {jax.__version__}; one core; {wall:.0f} s with compilation).", "",
        "A noise-free recording of the full planetary dual (ring backlash 60 µm azimuth, 130 µm pitch, 0.35 s, 141 saves, "
        "both encoders; `simulate`'s run) against the model at the truth itself, through each program `identify` costs it "
        "with, and the Gauss-Newton step each residual makes from the truth (the estimate a noise-free fit would move to, "
        "linearised; the central secants' Jacobian at the truth). The residual variance of a 20-bit recording with 2 µrad "
        "of noise is ~7.4 µrad² (s²).", "",
        f"| program | cost (µrad², {n} residuals) | RMS (µrad) | in s² | step: azimuth (µm) | step: pitch (µm) |",
        "|---|---|---|---|---|---|", *rows, "",
        "The same model at 16 points a relative perturbation from the truth (fixed pseudo-random directions, in one batch of "
        "65), each point's residual against the recording with its linearised move taken out: its RMS, and the step it "
        "makes (mean, standard deviation, range over the 16):", "",
        "| perturbation | RMS (µrad) | azimuth: mean | sd | range (µm) | pitch: mean | sd | range (µm) |",
        "|---|---|---|---|---|---|---|---|", *more]))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
