"""Wall time of one identification, lumped and full planetary, and what it is spent on.

For each scene, a unit (ring backlash 60 µm, the scene says 100; on the lumped joint its drag at
1.4x the scene's as well) recorded over 0.35 s (a reversal at 0.25 s, 141 saves) through a 20-bit
encoder with 2 µrad of noise, identified with `tx.identify`'s defaults (32 screened starts for one parameter, 64 for two, the
best 2 run by Levenberg-Marquardt through the widths 1 µm then the scene's own, on central
secants the scene's own alone), twice: a
first call (every program traced and compiled) and a second on another recording of the same
unit (the compiled programs reused). Each call's wall time by phase (`Identification.wall`),
and beside them the cost of the model it is made of, measured in the same run: one simulation
of the recording's window, one forward-mode Jacobian (the simulation with its tangents) and one
Jacobian by central secants (the 2p + 1 simulations in one batched run: what `identify` uses
where it chooses secants), so that a phase's time reads as a number of solves; and how far the
forward-mode Jacobian is from the secants at the scene's values (the number `identify`'s choice
reads at its first start: `tolerax.identification.fit.SECANT_SWITCH`).

    taskset -c 1 python benchmarks/identify_wall_time.py --out benchmarks/results/identify_wall_time.md

The full planetary stage is identified on central secants (chosen automatically: the
trajectory's forward-mode derivative through the rattle does not carry the backlash,
`tolerax.identification.fit._choose_jacobian`); its estimate is printed beside the truth.
"""

import dataclasses

import argparse
import math
import os
import pathlib
import time

import jax
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.identification import fit as F, identify as I
from tolerax.identification.parameters import parameter_values

ENCODER, NOISE = 2 * math.pi / 2**20, 2e-6  # rad
PHASES = ("check", "screen", "jacobian", "fit", "assess")


def _model_costs(scene, rec, names):
    """(one simulation, one forward-mode Jacobian, one Jacobian by central secants) of the
    identification's window, s, compiled programs warm, and the forward-mode Jacobian's distance
    from the secants at the scene's values (relative to their norm)."""
    fit_scene = tx.PointingObjective(scene, duration=0.35, settle=0.0, n_save=141, start="steady",
                                    integrator=tx.Integrator(max_steps=400_000)).forward_mode()
    n_save, times = I._model_times(rec, 0.35, None)
    units, scale = I._scales(scene, names)
    x0 = np.asarray(parameter_values(scene, names)) / scale
    window = times >= 0.0
    fit = F._Fit(fit_scene, tuple(names), jnp.asarray(scale), jnp.asarray(np.flatnonzero(window)), jnp.asarray([0]),
                 jnp.asarray(rec.at(times[window])))
    width = I.own_width(scene)
    outputs = jax.jit(lambda x, w: fit.outputs(x, w)[0])
    secants = dataclasses.replace(fit, secant=F.SECANT_STEP)
    out, jacobians = [], []
    for program in (outputs, lambda x, w: F._fit_and_jacobian(fit, x, w)[0], lambda x, w: F._fit_and_jacobian(secants, x, w)[0]):
        jacobians.append(np.asarray(program(jnp.asarray(x0), width)))  # compile
        start = time.perf_counter()
        for _ in range(3):
            jax.block_until_ready(program(jnp.asarray(x0 * 1.01), width))
        out.append((time.perf_counter() - start) / 3)
    forward, central = jacobians[1:]
    return out + [float(np.linalg.norm(forward - central) / np.linalg.norm(central))]


def run(label, scene, truth, names, seeds):
    rows = []
    for k, seed in enumerate(seeds):
        rec = tx.synthetic_recording(scene, truth, duration=0.35, n_save=141, noise=NOISE, quantum=ENCODER, key=jax.random.key(seed))
        start = time.perf_counter()
        got = tx.identify(scene, rec, names)
        total = time.perf_counter() - start
        lo, hi = got.interval()
        shown = ", ".join(f"{n.split('.')[-1]} {I.show(e, u)} ({I.show(a, u)} – {I.show(b, u)})"
                          for n, u, e, a, b in zip(got.names, got.units, got.estimate, lo, hi))
        rows.append((label, "first (compiling)" if k == 0 else "second (compiled)", total, got.wall, got, shown))
        print(label, rows[-1][1], f"{total:.1f} s", {p: round(got.wall.get(p, 0.0), 1) for p in PHASES}, shown,
              f"sigma {1e6 * got.sigma:.2f} urad", flush=True)
    return rows, rec


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--out", type=pathlib.Path, default=None, help="write the Markdown result here")
    parser.add_argument("--skip-planetary", action="store_true", help="the lumped joint only")
    args = parser.parse_args(argv)
    lumped = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    both = ("azimuth.ring_backlash", "azimuth.drag_torque")
    # The lumped case also with Levenberg-Marquardt's termination as it was before RESIDUAL_TOL
    # (every residual's change below LM_TOL (1 + |r|) µrad: under the solve's noise), in the same run.
    cases = [("lumped", lumped, both, F.RESIDUAL_TOL), ("lumped, residual tolerance 1e-4 (before)", lumped, both, F.LM_TOL)]
    if not args.skip_planetary:
        cases.append(("full planetary", tx.scan("azimuth", fidelity=("planetary", "ideal")), ("azimuth.ring_backlash",),
                      F.RESIDUAL_TOL))
    table, costs, kept = [], {}, F.RESIDUAL_TOL
    for label, scene, names, residual_tol in cases:
        F.RESIDUAL_TOL = residual_tol
        jax.clear_caches()  # the programs are traced again with this tolerance
        truth = {"azimuth.ring_backlash": 60e-6}
        if "azimuth.drag_torque" in names:
            truth["azimuth.drag_torque"] = 1.4 * float(scene.azimuth.drag_torque)
        rows, rec = run(label, scene, truth, names, (11, 12))
        if residual_tol == kept:
            costs[label] = _model_costs(scene, rec, names)
            print(label, "one simulation %.3f s, one forward-mode Jacobian %.3f s, one by secants %.3f s, forward mode "
                  "off the secants by %.3g" % tuple(costs[label]), flush=True)
        table += [(r, truth) for r in rows]
    F.RESIDUAL_TOL = kept
    lines = [
        "# Identification: wall time and where it goes", "",
        f"`taskset -c 1 python benchmarks/identify_wall_time.py` (one core); {os.cpu_count()} cores, load average "
        f"{os.getloadavg()[0]:.2f} at the end. The lumped azimuth scan and the full planetary one (pitch ideal), 0.35 s at "
        "141 saves, each unit recorded through a 20-bit encoder with 2 µrad of noise; `tx.identify` with its defaults "
        "(32 screened starts for one parameter, 64 for two, the best 2 through the widths 1 µm and the scene's own on forward mode, the scene's own alone on "
        "central secants). A first call traces and compiles "
        "every program; the second identifies another recording of the same unit with them compiled. The lumped case "
        "twice: with Levenberg-Marquardt's termination as it is (an accepted step that moves the parameters less than "
        "1e-4 (1 + |z|) and changes no residual by more than 0.2 (1 + |r|) µrad) and as it was (1e-4 (1 + |r|) µrad "
        "for the residual too: below the adaptive solve's own noise in it, so at the cost floor every step is "
        "rejected until the step limit).", "",
        "| model | call | wall (s) | check | screen | jacobian | fit | assess | LM steps (last width) | estimate (95 % interval) | truth | residual (µrad) |",
        "|---|---|---:|---:|---:|---:|---:|---:|---:|---|---|---:|",
    ]
    for (label, call, total, wall, got, shown), truth in table:
        t = ", ".join(f"{n.split('.')[-1]} {I.show(v, 'm' if n.endswith('backlash') else 'N m')}" for n, v in truth.items())
        lines.append(f"| {label} | {call} | {total:.1f} | " + " | ".join(f"{wall.get(p, 0.0):.1f}" for p in PHASES)
                     + f" | {got.steps} | {shown} | {t} | {1e6 * got.sigma:.2f} |")
    lines += ["", "The model the phases are made of (compiled, the mean of 3 calls):", "",
              "| model | one simulation of the window (s) | one forward-mode Jacobian (s) | one Jacobian by central secants (s) | "
              "forward mode off the secants (of their norm) | Jacobian identify used | second call's wall in those Jacobians |",
              "|---|---:|---:|---:|---:|---|---:|"]
    for label, (sim, jac, sec, differs) in costs.items():
        second, got = [(total, got) for (lab, call, total, _, got, _), _ in table if lab == label and call.startswith("second")][0]
        used = sec if got.jacobian.startswith("central secants") else jac
        lines.append(f"| {label} | {sim:.3f} | {jac:.3f} | {sec:.3f} | {differs:.3g} | {got.jacobian.split(':')[0].split(' (')[0]} "
                     f"| {second / used:.0f} |")
    text = "\n".join(lines) + "\n"
    print(text)
    if args.out:
        args.out.write_text(text)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
