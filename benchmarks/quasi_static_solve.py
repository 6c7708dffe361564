"""What a quasi-static sun and planets would cost: the force balance of one planetary stage's
floating members, solved at every right-hand side.

    python benchmarks/quasi_static_solve.py [--repeats 20]

`fast_modes.md` finds that making the sun's translation and the planets' translation and spin
quasi-static (massless) would lengthen Tsit5's stable step 46-66x on the planetary dual-axis
antenna. The price is a nonlinear solve inside every right-hand side: given the slow coordinates
(sun and carrier rotation, carrier translation), find the sun centre, the planet offsets
$(\\zeta_n, \\eta_n)$ and the planet spins at which the generalised forces on them
(`_planetary.stage_forces`: meshes with time-varying stiffness and backlash, Hertz contacts of
the sun bearing and the planet pins, all smoothed) vanish. Unknowns in metres (spin as $r_{bp}$
times its offset from rolling on the fixed ring), residuals in newtons.

The test state is the loaded steady state of the full stage (`antenna('dual',
fidelity='planetary').initial_state('loaded')`, polished so that every acceleration vanishes): its
floating coordinates are the known answer. Each optimistix solver starts from the nominal position
(all offsets zero, what a right-hand side without memory would have) with rtol 1e-10 and atol
1e-13 m, at most 100 iterations; the table gives iterations, the compiled time of one solve
(best of `--repeats`), its ratio to one right-hand side of the whole antenna in this process
(`rhs_anatomy.timed`: 500 calls inside one program, best of 3), and
the distance to the loaded state. Writes `benchmarks/results/quasi_static_solve.md`.
"""

import argparse
import time

import jax
import jax.numpy as jnp
import lineax as lx
import numpy as np
import optimistix as optx

import tolerax
from tolerax import _planetary
from tolerax._joint import _planet_spin_ratio

import _results
from rhs_anatomy import timed

SOLVERS = {
    "LevenbergMarquardt": ("least_squares", lambda: optx.LevenbergMarquardt(rtol=1e-10, atol=1e-13)),
    "Dogleg": ("least_squares", lambda: optx.Dogleg(rtol=1e-10, atol=1e-13)),
    "Newton (least-squares linear solve)": (
        "root_find", lambda: optx.Newton(rtol=1e-10, atol=1e-13, linear_solver=lx.AutoLinearSolver(well_posed=False))
    ),
}


def best_time(fn, repeats):
    """Best wall time (s) of `repeats` calls of the compiled `fn()`."""
    jax.block_until_ready(fn())
    best = np.inf
    for _ in range(repeats):
        start = time.perf_counter()
        jax.block_until_ready(fn())
        best = min(best, time.perf_counter() - start)
    return best


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--repeats", type=int, default=20, help="timed calls per solver (best is kept)")
    args = parser.parse_args()
    mech = tolerax.antenna("dual", fidelity="planetary")
    joint = mech.azimuth
    stage, lay = joint.stage, joint.stage.layout
    rho, rbp = _planet_spin_ratio(stage), stage.planet_base_radius
    trans = np.array([i for sl in (lay.sun_xy, lay.planet_xy) if sl is not None for i in range(sl.start, sl.stop)])
    spin = np.arange(lay.planet_theta.start, lay.planet_theta.stop)

    def full_q(qj, z):
        q = qj.at[trans].set(z[: len(trans)])
        return q.at[spin].set(rho * qj[lay.carrier_theta] + z[len(trans):] / rbp)

    def residual(z, args):
        qj, uj, vj = args
        force = _planetary.stage_forces(stage, full_q(qj, z), uj, vj).generalised
        return jnp.concatenate([force[trans], force[spin] / rbp])

    start = time.perf_counter()
    q, u, v = mech.initial_state("loaded")
    loaded_s = time.perf_counter() - start
    _, sq, su, sv = next(j for j in mech.joints() if j[0] is joint)
    data = (q[sq], u[su], v[sv])
    z_true = jnp.concatenate([data[0][trans], rbp * (data[0][spin] - rho * data[0][lay.carrier_theta])])
    z0 = jnp.zeros_like(z_true)

    rhs_us = timed(lambda m, t, q_, u_, v_: m.vector_field(t, (q_, u_, v_), None), mech, (jnp.asarray(0.0), q, u, v), 500)
    print(f"one RHS {rhs_us:.1f} us", flush=True)

    rows = []
    for name, (kind, make) in SOLVERS.items():
        solver = make()
        run = getattr(optx, kind)

        @jax.jit
        def solve(z0, data, solver=solver, run=run):
            sol = run(residual, solver, z0, args=data, max_steps=100, throw=False)
            return sol.value, sol.stats["num_steps"], sol.result == optx.RESULTS.successful

        z, steps, ok = solve(z0, data)
        us = best_time(lambda: solve(z0, data), args.repeats) * 1e6
        rows.append([
            name, "yes" if bool(ok) else "no", str(int(steps)), f"{us:.0f}", f"{us / rhs_us:.0f}",
            f"{float(jnp.max(jnp.abs(z - z_true))):.1e}", f"{float(jnp.max(jnp.abs(residual(z, data)))):.1e}",
        ])
        print(rows[-1], flush=True)
    _results.write_table(
        "quasi_static_solve",
        "Quasi-static sun and planets: the force balance a right-hand side would solve",
        _results.command(args),
        ["solver", "converged", "iterations", "µs per solve", "x one antenna RHS", "max |z - loaded| (m)", "max residual (N)"],
        rows,
        about=(f"Azimuth stage of `antenna('dual', fidelity='planetary')` at its loaded steady state ({loaded_s:.0f} s to "
               f"compute); {len(z_true)} unknowns (sun centre, planet offsets, planet spins); one right-hand side of "
               f"the whole antenna: {rhs_us:.1f} µs in this process. Floating offsets at the loaded state (µm): "
               + ", ".join(f"{x:.3g}" for x in np.asarray(z_true) * 1e6) + "."),
    )


if __name__ == "__main__":
    main()
