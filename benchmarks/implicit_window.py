"""Implicit solvers on the rattling planetary dual-axis antenna, over a short window once the
rattle has developed.

    python benchmarks/implicit_window.py [--fidelity planetary] [--warmup 0.5] [--window 0.02]
        [--methods Tsit5 Kvaerno5 Kvaerno5-Newton Kvaerno3-Newton] [--rtols 1e-4 1e-6]

Explicit Tsit5 steps at the stability limit of the mesh-held modes (~22 us, `fast_modes.md`);
an L-stable implicit method could step over those modes, if its Newton iteration survives the
contact and flank switches. This measures whether it does. The scene (free base, 0.98 deg/s on
both joints, 100 um clearances and backlash) runs from a steady start to `--warmup` with Tsit5
(rtol 1e-6); from that state each method integrates `[warmup, warmup + window]`, saving 41
samples, against a Tsit5 reference at rtol 1e-9 atol 1e-12. Implicit methods: diffrax's
Kvaerno ESDIRKs with their default root finder (`VeryChord`: Jacobian once per step, tolerances
from the controller) or with `optimistix.Newton` (Jacobian at every iteration, rtol = the
controller's, atol 1e-9). Step budget `--max-steps` per run; a run that exhausts it is reported
as failed with the time it reached. Each configuration is solved twice (compile = first - second).
Writes `benchmarks/results/implicit_window.md`, rewritten after every row.

The same window serves the explicit alternatives (`--output explicit_window`): Bosh3 (3
evaluations per step: along the mesh modes' direction, damping ratio 0.06, its stability radius
per evaluation is 0.675 against Tsit5's 0.429, so where the step is stability-bound it should need
~1.6x fewer evaluations), Dopri5, and Tsit5 with other step control: PI coefficients
(`-PI`: pcoeff 0.3, icoeff 0.3), a step cap just under the ~21.6-22.6 us stability limit that
`fast_modes.md` found in the developed rattle (`-dtmax20us`, so that steps are not rejected
into the unstable mesh modes), and an error norm without the impact-rate states (`-no-v-norm`).
"""

import argparse
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

import tolerax
from tolerax._solve import _NAMES

import _results
import _split

METHODS = {
    "Tsit5": lambda rtol: diffrax.Tsit5(),
    "Bosh3": lambda rtol: diffrax.Bosh3(),
    "Dopri5": lambda rtol: diffrax.Dopri5(),
    "Tsit5-PI": lambda rtol: diffrax.Tsit5(),
    "Tsit5-dtmax20us": lambda rtol: diffrax.Tsit5(),
    "Tsit5-no-v-norm": lambda rtol: diffrax.Tsit5(),
    "Dopri8": lambda rtol: diffrax.Dopri8(),
    "Kvaerno3": lambda rtol: diffrax.Kvaerno3(),
    "Kvaerno5": lambda rtol: diffrax.Kvaerno5(),
    "Kvaerno3-Newton": lambda rtol: diffrax.Kvaerno3(root_finder=optx.Newton(rtol=rtol, atol=1e-9)),
    "Kvaerno5-Newton": lambda rtol: diffrax.Kvaerno5(root_finder=optx.Newton(rtol=rtol, atol=1e-9)),
    "KenCarp3-IMEX": lambda rtol: diffrax.KenCarp3(),
    "KenCarp4-IMEX": lambda rtol: diffrax.KenCarp4(),
}
# IMEX methods take the vector field split in two (`_split`): the joints' internal forces
# implicit, the rest explicit.
SPLIT = {"KenCarp3-IMEX", "KenCarp4-IMEX"}
# Step-control options of the variants (default: diffrax's I-controller, dtmax 1 ms, RMS norm
# over the whole state q, u and impact rates v).
CONTROL = {
    "Tsit5-PI": dict(pcoeff=0.3, icoeff=0.3),
    "Tsit5-dtmax20us": dict(dtmax=2e-5),
    "Tsit5-no-v-norm": dict(norm=lambda y: optx.rms_norm((y[0], y[1]))),
}


def solve(mech, solver, t0, t1, y0, rtol, atol, ts, max_steps, split=False, **control):
    """(solution, compile s, run s): diffrax over [t0, t1] from y0, PID control (dtmax 1 ms unless
    `control` says otherwise); `split`: the IMEX terms of `_split` instead of the whole field."""
    term = diffrax.ODETerm(mech.vector_field)
    if split:
        term = diffrax.MultiTerm(diffrax.ODETerm(_split.external_field(mech)), diffrax.ODETerm(_split.internal_field(mech)))
    ctrl = diffrax.PIDController(rtol=rtol, atol=atol, **{"dtmax": 1e-3, **control})

    @eqx.filter_jit
    def go(y0):
        return diffrax.diffeqsolve(term, solver, t0, t1, 1e-6, y0, saveat=diffrax.SaveAt(ts=ts),
                                   stepsize_controller=ctrl, max_steps=max_steps, throw=False)

    walls = []
    for _ in range(2):
        start = time.perf_counter()
        sol = go(y0)
        jax.block_until_ready(sol.ys)
        walls.append(time.perf_counter() - start)
    return sol, walls[0] - walls[1], walls[1]


def rhs_per_step(solver):
    """Right-hand-side evaluations per attempted step of an explicit Runge-Kutta method (its
    stages, less one where the last stage is reused as the next step's first); None otherwise."""
    if not isinstance(solver, diffrax.AbstractERK):
        return None
    tableau = solver.tableau
    return len(tableau.b_sol) - (1 if tableau.fsal else 0)


def outputs(mech, sol):
    """Pointing error (arcsec) and the tracking speed error (urad/s, 3 components) at the saves."""
    obs = jax.vmap(mech.observe)(sol.ts, sol.ys)
    return np.asarray(obs.pointing_error) / tolerax.ARCSEC, np.asarray(obs.tracking_speed_error) * 1e6


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--fidelity", default="planetary", choices=["planetary", "planetary-scaled"])
    parser.add_argument("--warmup", type=float, default=0.5, help="Tsit5 run before the window (s)")
    parser.add_argument("--window", type=float, default=0.02, help="window length (s)")
    parser.add_argument("--methods", nargs="+", default=["Tsit5", "Kvaerno5", "Kvaerno5-Newton", "Kvaerno3-Newton"], choices=list(METHODS))
    parser.add_argument("--rtols", type=float, nargs="+", default=[1e-4, 1e-6])
    parser.add_argument("--max-steps", type=int, default=20000, help="step budget of each window run")
    parser.add_argument("--output", default="implicit_window", choices=["implicit_window", "explicit_window", "imex_window"], help="result file name")
    args = parser.parse_args()

    mech = tolerax.antenna("dual", fidelity=args.fidelity)
    t0, t1 = args.warmup, args.warmup + args.window
    sol, _, warm = solve(mech, diffrax.Tsit5(), 0.0, t0, mech.initial_state("steady"), 1e-6, 1e-9, jnp.array([t0]), 10**7)
    y0 = jax.tree.map(lambda x: x[-1], sol.ys)
    ts = jnp.linspace(t0, t1, 41)
    ref, _, ref_wall = solve(mech, diffrax.Tsit5(), t0, t1, y0, 1e-9, 1e-12, ts, 10**7)
    ref_p, ref_w = outputs(mech, ref)
    columns = ["method", "rtol", "result", "accepted (rejected)", "compile (s)", "wall (s)", "wall per simulated s",
               "us per attempted step", "RHS evaluations", "pointing diff (arcsec, max)", "speed-error diff (urad/s, max)"]
    rows = []

    def write():
        _results.write_table(
            args.output,
            {"implicit_window": "Implicit solvers on the rattling planetary dual-axis antenna",
             "explicit_window": "Explicit solvers and step control on the rattling planetary dual-axis antenna",
             "imex_window": "IMEX solvers (joints' internal forces implicit) on the rattling planetary dual-axis antenna"}[args.output],
            _results.command(args),
            columns,
            rows,
            about=(f"Fidelity {args.fidelity}; window {t0:g}-{t1:g} s from the state Tsit5 (rtol 1e-6) reached at "
                   f"{t0:g} s ({int(sol.stats['num_accepted_steps'])} steps, {warm:.1f} s); reference Tsit5 rtol 1e-9 "
                   f"atol 1e-12 ({int(ref.stats['num_accepted_steps'])} steps, {ref_wall:.2f} s). atol 1e-9 throughout; "
                   f"differences are the largest over the window's 41 samples. Over the window the pointing error "
                   f"ranges {ref_p.min():.1f}-{ref_p.max():.1f} arcsec and the tracking speed error reaches "
                   f"{np.abs(ref_w).max():.0f} urad/s."),
        )

    for name in args.methods:
        for rtol in args.rtols:
            print(f"{name} rtol {rtol:g} ...", flush=True)
            solver = METHODS[name](rtol)
            s, compile_s, wall = solve(
                mech, solver, t0, t1, y0, rtol, 1e-9, ts, args.max_steps, split=name in SPLIT, **CONTROL.get(name, {})
            )
            acc, rej = int(s.stats["num_accepted_steps"]), int(s.stats["num_rejected_steps"])
            ok = bool(s.result == diffrax.RESULTS.successful)
            if ok:
                p, w = outputs(mech, s)
                dp, dw = f"{np.abs(p - ref_p).max():.2e}", f"{np.abs(w - ref_w).max():.2e}"
            else:
                dp = dw = ""
            reached = float(s.ts[jnp.isfinite(s.ts)].max()) if bool(jnp.isfinite(s.ts).any()) else t0
            result = "ok" if ok else f"failed at {reached:.4f} s: {_NAMES[int(s.result._value)]}"
            evals = rhs_per_step(solver)
            rows.append([name, f"{rtol:g}", result, f"{acc} ({rej})", f"{compile_s:.1f}", f"{wall:.2f}",
                         f"{wall / args.window:.1f}", f"{1e6 * wall / max(acc + rej, 1):.0f}",
                         "—" if evals is None else str(evals * (acc + rej)), dp, dw])
            print(rows[-1], flush=True)
            write()


if __name__ == "__main__":
    main()
