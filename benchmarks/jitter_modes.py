"""Why the mass-scaled stage reads the jitter low: where in frequency each fidelity's jitter
lies, which scaled family takes it down, and what the scaling moves in the stage's dynamics
(issue 40).

    python benchmarks/jitter_modes.py [--units 6] [--rate 8000] [--results DIR]

Scene: `tolerax.scan("azimuth", fidelity=(F, "ideal"))` (fixed base, pitch rigid: 15
coordinates, the azimuth stage's), F the full stage and `planetary-scaled` at mass scaling
10, 100 and 1000 with its default families (sun and planet translations, planet spin), and at
1000 with one family at a time. Each is run on the same `--units` units (the scene's values
and units drawn within +-10 um of them, key 0), steady start, Tsit5 rtol 1e-6, 0.6 s, saved
at `--rate` per second.

1. **Where the jitter lies in frequency.** `pointing_jitter` over the window 0.3-0.6 s with
   the cutoff at each band edge: J(a)^2 - J(b)^2 is the pointing error's power in [a, b) (the
   sine transform's bins are orthogonal; the two end cubics it projects out leak a little), so
   the table gives the RMS per band, 20 Hz up to the Nyquist frequency, and the jitter as the
   design reads it (500 saves/s: what lies above 250 Hz aliases into the band).
2. **What the scaling moves.** At the steady start (every contact loaded on one side) the
   eigenvalues of the whole vector field's Jacobian df/dy (`jax.jacfwd`, damping and servo
   included) with |lambda| between 5 Hz and the Nyquist frequency: the oscillatory ones
   (frequency |lambda|/2 pi, damping ratio -Re/|lambda|) and the real ones (overdamped poles,
   |lambda|/2 pi), each fidelity's. The clearances' contacts are held as they are there:
   during the rattle members float in their clearances and the linearisation changes from
   instant to instant, so it describes the loaded stage, not the rattle itself. The real poles
   near 1.6 kHz are the contact law's impact memory (`v`: the impact rates, relaxing at
   1e4/s), alone or coupled with the members whose impacts they remember.
"""

import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

import tolerax as tx
from tolerax.mechanism.outputs import pointing_jitter

import harness

SETTINGS = (("full stage", None, None), ("scaled x10", 10.0, None), ("scaled x100", 100.0, None), ("scaled x1000", 1000.0, None),
            ("x1000: planet spin only", 1000.0, ("planet_spin",)), ("x1000: planet translation only", 1000.0, ("planet_translation",)),
            ("x1000: sun translation only", 1000.0, ("sun_translation",)))
BANDS = (20.0, 100.0, 250.0, 1000.0, 2000.0)


def build(scaling, families):
    if scaling is None:
        return tx.scan("azimuth", fidelity=("planetary", "ideal"))
    scene = tx.scan("azimuth", fidelity=("planetary-scaled", "ideal"), mass_scaling=scaling)
    if families is None:
        return scene
    j = scene.azimuth
    return eqx.tree_at(lambda s: s.azimuth, scene, tx.MassScaledPlanetaryJoint(j.stage, j.drive, j.motor_inertia, j.drag_torque,
                                                                                 mass_scaling=scaling, families=families))


def poles(scene, y, high):
    """(oscillatory (Hz, damping ratio) pairs, real poles (Hz)) of df/dy at state `y`, t = 0,
    with 5 Hz < |lambda|/2 pi < `high`."""
    flat, unravel = ravel_pytree(y)
    jac = jax.jacfwd(lambda x: ravel_pytree(scene.vector_field(0.0, unravel(x), None))[0])(flat)
    lam = np.linalg.eigvals(np.asarray(jac))
    lam = lam[(lam.imag >= 0) & (np.abs(lam) > 2 * np.pi * 5.0) & (np.abs(lam) < 2 * np.pi * high)]
    hz = np.abs(lam) / (2 * np.pi)
    oscillatory = lam.imag > 1e-6 * np.abs(lam)
    return sorted(zip(hz[oscillatory], -lam.real[oscillatory] / np.abs(lam[oscillatory]))), sorted(hz[~oscillatory])


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--units", type=int, default=6)
    parser.add_argument("--rate", type=float, default=8000.0, help="saves per second")
    args = harness.parse_args(parser)
    start = time.perf_counter()
    duration, settle = 0.6, 0.3
    n_save = int(round(args.rate * duration)) + 1
    stride = int(round(args.rate / 500.0))
    base = build(None, None)
    zones = tx.tolerances_of(base, 10e-6)
    values = np.vstack([np.asarray(zones.nominal), np.asarray(tx.sample(zones, jax.random.key(0), args.units - 1))])
    edges = [e for e in BANDS if e < args.rate / 2] + [args.rate / 2]
    band_rows, pole_rows = [], []
    for label, scaling, families in SETTINGS:
        scene = build(scaling, families)
        powers, design_jitters = [], []
        for row in values:
            res = tx.simulate(tx.with_design(scene, jnp.asarray(row)), duration, start="steady", n_save=n_save,
                              integrator=tx.Integrator(rtol=1e-6, atol=1e-9))
            ts, err = np.asarray(res.ts), np.asarray(res.pointing_error)
            window = ts >= settle - 1e-12
            e, dt = err[window], float(ts[1] - ts[0])
            j = np.array([float(pointing_jitter(e, dt, cutoff)) for cutoff in edges[:-1]] + [0.0])
            powers.append(j[:-1] ** 2 - j[1:] ** 2)
            design_jitters.append(float(pointing_jitter(err[::stride][window[::stride]], dt * stride, 20.0)))
        p = np.mean(powers, axis=0)
        band_rows.append((label, *(f"{np.sqrt(max(x, 0.0)):.3f}" for x in p), f"{np.sqrt(p.sum()):.3f}",
                          f"{np.mean(design_jitters):.3f}"))
        y0 = jax.tree.map(lambda x: x[0], tx.simulate(scene, 1e-3, start="steady", n_save=2).states)
        osc, real = poles(scene, y0, args.rate / 2)
        pole_rows.append((label, ", ".join(f"{f:.0f} ({z:.3f})" for f, z in osc) or "-", ", ".join(f"{f:.0f}" for f in real) or "-"))
        print(band_rows[-1], pole_rows[-1], f"{time.perf_counter() - start:.0f} s", flush=True)
    band_names = [f"{a:g}-{b:g} Hz" for a, b in zip(edges[:-1], edges[1:])]
    harness.write_table(
        "jitter_modes", "Why the mass-scaled stage reads the jitter low: the jitter's spectrum and the stage's poles (azimuth scan)",
        harness.command(args),
        ["fidelity", *[f"RMS {b} (arcsec)" for b in band_names], f"jitter 20 Hz-{args.rate / 2:g} Hz (arcsec)",
         "jitter as designed (500 saves/s)"],
        band_rows,
        about=(f"{args.units} units (the scene's values and {args.units - 1} within +-10 um, key 0), each at every fidelity; "
               f"window {settle}-{duration} s saved at {args.rate:g}/s; RMS per band from `pointing_jitter` at each edge, the "
               f"power averaged over the units. Total wall {time.perf_counter() - start:.0f} s, compilation included."),
        sections=[harness.Section(
            f"Poles of the loaded stage (steady start) between 5 and {args.rate / 2:g} Hz",
            ["fidelity", "oscillatory: frequency Hz (damping ratio)", "real (overdamped) poles, Hz"], pole_rows)],
    )


if __name__ == "__main__":
    main()
