"""`start="loaded"`'s Levenberg-Marquardt polish (`tolerax.mechanism.loaded._polish_loaded`):
its Jacobian by forward mode (optimistix's default, `jac="fwd"`), by reverse mode (`jac="bwd"`),
and taken once per step as a matrix (`once`: `_loaded_equations_once`, a custom JVP, what tolerax
uses): trace, compile and running time, and the solution.

    taskset -c 0 python benchmarks/loaded_state_compile.py [--rounds 2] [--results DIR]

Each workload runs in a fresh process with the compilation cache off: the polish of the loaded
state of `tolerax.antenna("azimuth", fidelity=FIDELITY, rate=0.98 deg/s)` from its joints'
closed forms, exactly `_polish_loaded`'s program with only `options=dict(jac=...)` or the
function changed;
`trace` is tracing and lowering, `compile` XLA's compilation, `run` the fastest of three calls of
the compiled program. With forward mode optimistix hands Levenberg-Marquardt a linearised
function, which its damped solve (QR of [J; sqrt(lambda) I]) materialises again inside the loop;
with reverse mode the Jacobian is a matrix materialised once per step; with `once` it is a matrix
from one forward-mode pass, whose transpose needs no reverse-mode program. The figures are
ratios to forward mode in one run, the largest relative difference from its solution, and the
steps each took.
"""

import harness

CHILD = r"""
import json, math, sys, time
import jax, jax.numpy as jnp, optimistix as optx
import tolerax as tx
from tolerax.mechanism import loaded as L
fidelity, jac = sys.argv[1], sys.argv[2]
mech = tx.antenna("azimuth", fidelity=fidelity, rate=math.radians(0.98))
q, u, _ = mech.initial_state("steady")
guess = q
for joint, sq, _, _ in mech.joints():
    guess = guess.at[sq].set(joint.loaded_coordinates())
x0 = guess[mech.layout.base_q:]
residual = lambda x: L._loaded_residual(mech, q, u, x)
def polish(x0):  # _polish_loaded's program, the Jacobian's mode a choice
    equations = L._loaded_equations_once if jac == "once" else L._loaded_equations
    fn = lambda x, _: equations(x, mech, q, u, x0)
    sol = optx.least_squares(fn, optx.LevenbergMarquardt(rtol=1e-12, atol=1e-14), x0,
                             options=dict(jac="fwd" if jac == "once" else jac), max_steps=200, throw=False)
    return sol.value, jnp.linalg.norm(residual(sol.value)), sol.stats["num_steps"]
t0 = time.perf_counter(); lowered = jax.jit(polish).lower(x0); t1 = time.perf_counter()
compiled = lowered.compile(); t2 = time.perf_counter()
x, norm, steps = jax.block_until_ready(compiled(x0))
runs = []
for _ in range(3):
    t = time.perf_counter(); jax.block_until_ready(compiled(x0)); runs.append(time.perf_counter() - t)
print("RESULT " + json.dumps(dict(trace=t1 - t0, compile=t2 - t1, run=min(runs), steps=int(steps), norm=float(norm),
                                  x=[float(v) for v in x])))
"""

WORKLOADS = ("lumped", "planetary")
CONFIGS = ("fwd", "bwd", "once")


def main():
    import os

    parser = harness.argument_parser(__doc__)
    parser.add_argument("--rounds", type=int, default=2, help="interleaved rounds (the fastest of each kept)")
    parser.add_argument("--workloads", nargs="+", default=list(WORKLOADS), choices=WORKLOADS)
    args = harness.parse_args(parser)
    env = dict(os.environ, TOLERAX_CACHE="off")
    best = harness.interleaved_best(args.rounds, args.workloads, list(CONFIGS),
                                    lambda work, jac: harness.child_result(CHILD, [work, jac], env), ("trace", "compile", "run"))
    rows = []
    for work in args.workloads:
        f = best[(work, "fwd")]
        for mode in CONFIGS[1:]:
            b = best[(work, mode)]
            diff = max(abs(x - y) / max(abs(y), 1e-300) for x, y in zip(b["x"], f["x"], strict=True) if abs(y) > 1e-12)
            rows.append((work, mode, *(f"{f[k]:.2f} / {b[k]:.2f} ({b[k] / f[k]:.2f})" for k in ("trace", "compile", "run")),
                         f"{f['steps']} / {b['steps']}", f"{f['norm']:.3e} / {b['norm']:.3e}", f"{diff:.1e}"))
    harness.write_table(
        "loaded_state_compile", "The loaded state's polish: the Jacobian by forward mode, by reverse mode, and once per step",
        harness.command(args),
        ["azimuth joint fidelity", "mode", "trace s: fwd / mode (ratio)", "compile s: fwd / mode (ratio)", "run s: fwd / mode (ratio)",
         "steps: fwd / mode", "residual norm: fwd / mode", "largest relative difference from fwd's solution (entries over 1e-12)"],
        rows,
        about=f"Fresh process per workload and mode, compilation cache off; the fastest of {args.rounds} interleaved rounds. "
              "`trace`: tracing and lowering; `compile`: XLA; `run`: the fastest of three calls of the compiled program.",
    )


if __name__ == "__main__":
    main()
