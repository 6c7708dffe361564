"""Work-precision diagrams: wall time against error in the quantities users read, for diffrax
solvers, tolerances, the smoothing width, the paper's fixed 1e-4 s step, and SciPy `solve_ivp`.

    python benchmarks/work_precision.py --scene bench           # the joint on its test bench
    python benchmarks/work_precision.py --scene dual-lumped     # dual-axis antenna, lumped joints
    python benchmarks/work_precision.py --scene dual-planetary  # dual-axis antenna, planetary joints

Writes `benchmarks/results/work_precision_<scene>.{md,json,png}` (`--results DIR`: in DIR). Options: `--quick` (fewer
tolerances), `--methods Tsit5 RK45` (only those methods: a smoke run), `--no-implicit`,
`--no-scipy`, `--duration`, `--render` (rewrite the .md and .png from the saved .json),
`--mass-scalings 10 100` (dual-planetary: Tsit5 on the mass-scaled joints, `fidelity=
"planetary-scaled"`, at each scaling, family `scaled s=N`; their errors are against the full
planetary reference, so they hold the reduced fidelity's model error as well as the solver's).

**Reference.** Dopri8 at rtol 1e-12 (atol 1e-15) and the default smoothing width (1e-9 m, the
smallest the project uses); it is accepted only if Tsit5 at rtol 1e-11, a different method, agrees
with it: the table states their disagreement, which bounds how small an error can be resolved.

**Error** of a run, per quantity, against the reference at the same save times:
- series (output angle or pointing error, tracking speed error): max |x - x_ref| / max |x_ref|;
- peak contact force: |max F - max F_ref| / max(max F_ref, 1 N) (over the save times).

**Work.** Wall time of a solve after compilation (`harness.timed`: best of up to 3 repeats, fewer
once a solve takes 2 s, none after a first call over 120 s; compile time reported separately),
on whatever machine runs the script: ratios within one run are what to read.

**SciPy baseline.** The same equations: the scene's JAX right-hand side, compiled with `jax.jit`
and called from `scipy.integrate.solve_ivp` on the flattened state (with a compiled `jacfwd`
Jacobian for Radau/BDF/LSODA). This is the *favourable* baseline for SciPy: a hand-written NumPy
right-hand side of the same model costs more per call than the compiled one (the table reports
both calls from Python). Tolerances are matched: atol = 1e-3 rtol for both.

**SciPy with a NumPy right-hand side** (bench only, family `scipy-numpy`, skip with
`--no-numpy`): what a Python user without JAX would run, the bench's equations written in plain
NumPy with hand-derived Jacobians (`_numpy_bench.py`), and for Radau/LSODA SciPy's own
finite-difference Jacobian. Before timing it is compared with the JAX right-hand side at 81
states of a Tsit5 run (rtol 1e-8) (`numpy_check`); the table states the largest difference and,
for scale, how far the JAX right-hand side moves under a 1e-15 perturbation of the state.
"""

import dataclasses
import json
import types

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
import scipy.integrate
from jax.flatten_util import ravel_pytree

import tolerax

import harness


# --------------------------------------------------------------------------------------------
# Scenes


@dataclasses.dataclass
class Case:
    name: str
    make: object  # smoothing width (m) -> scene
    start: str  # "rest" or "steady"
    duration: float
    n_save: int
    quantities: object  # (scene, result) -> {name: series}
    description: str


def _bench_make(width):
    return tolerax.TestBench(stage=tolerax.default_stage(smoothing_width=width))


def _bench_quantities(scene, res):
    ts = np.asarray(res.ts)
    speed = np.asarray(res.states[1][:, scene.stage.layout.carrier_theta])
    return {
        "output angle error (arcsec)": np.asarray(res.output_angle_error) / tolerax.ARCSEC,
        "output speed error (urad/s)": (speed - np.asarray(scene.servo.rate(ts))) * 1e6,
        "peak contact force (N)": np.asarray(res.contact_force).max(axis=1),
    }


def _dual_make(fidelity, **options):
    """Smoothing width (m) -> the dual-axis antenna at `fidelity` (`options` go to `antenna`)."""

    def make(width):
        stage = tolerax.default_stage(smoothing_width=width)
        return tolerax.antenna("dual", fidelity=fidelity, azimuth_stage=stage, pitch_stage=stage, **options)

    return make


def _dual_quantities(scene, res):
    contacts = np.concatenate([np.asarray(res.azimuth_contact), np.asarray(res.pitch_contact)], axis=1)
    return {
        "pointing error (arcsec)": np.asarray(res.pointing_error) / tolerax.ARCSEC,
        "tracking speed error (urad/s)": np.linalg.norm(np.asarray(res.tracking_speed_error), axis=1) * 1e6,
        "peak contact force (N)": contacts.max(axis=1) if contacts.shape[1] else np.zeros(len(res.ts)),
    }


CASES = {
    "bench": Case(
        "bench", _bench_make, "rest", 0.4, 201, _bench_quantities,
        "default joint on its test bench (100 um clearances and backlash), from rest to 0.98 deg/s "
        "(the pins and output bearing start carrying load at 0.24 s), 0.4 s",
    ),
    "dual-lumped": Case(
        "dual-lumped", _dual_make("lumped"), "steady", 0.5, 201, _dual_quantities,
        "dual-axis antenna, lumped joints, free base, steady start at 0.98 deg/s, 0.5 s",
    ),
    "dual-planetary": Case(
        "dual-planetary", _dual_make("planetary"), "steady", 0.02, 101, _dual_quantities,
        "dual-axis antenna, planetary joints, free base, steady start at 0.98 deg/s, 0.02 s",
    ),
}


# --------------------------------------------------------------------------------------------
# Runners


def run_diffrax(case, scene, solver, rtol, fixed_step=None, max_steps=4_000_000):
    """Solve once to compile, then time; returns (record, quantities)."""

    def run():
        return tolerax.simulate(
            scene, case.duration, start=case.start, n_save=case.n_save, throw=False,
            integrator=tolerax.Integrator(solver=solver, rtol=rtol, atol=1e-3 * rtol, max_steps=max_steps, fixed_step=fixed_step),
        )

    # Up to 3 timed repeats, fewer once a solve takes 2 s; a configuration whose first call takes
    # over 120 s is run once, compilation included (its compile time `nan`, flagged in the table).
    t = harness.timed(run, repeats=3, enough_s=2.0, once_s=120.0)
    res, ok = t.output, t.output.success
    record = dict(
        wall_s=t.run_s,
        compile_s=t.compile_s if t.compile_s > 0 else float("nan"),
        steps=int(res.num_steps),
        rejected=int(res.num_rejected),
        ok=ok,
        result=str(res.result) if not ok else "",
    )
    return record, (case.quantities(scene, res) if ok else None)


def flat_rhs(scene, start):
    """The scene's compiled right-hand side on the flattened state: (f(t, y), y0, unravel)."""
    flat0, unravel = ravel_pytree(scene.initial_state(start))
    f = jax.jit(lambda t, y: ravel_pytree(scene.vector_field(t, unravel(y), None))[0])
    return f, flat0, unravel


def run_scipy(case, scene, method, rtol, numpy_rhs=None):
    """SciPy `solve_ivp` on the compiled JAX right-hand side (with a compiled Jacobian for the
    implicit methods), or on `numpy_rhs` (with SciPy's finite-difference Jacobian)."""
    f, flat0, unravel = flat_rhs(scene, case.start)
    jac = jax.jit(jax.jacfwd(f, argnums=1))
    observe = jax.jit(jax.vmap(scene.observe))
    ts = np.linspace(0.0, case.duration, case.n_save)
    # t as a float64 array every time: a Python float and a NumPy scalar are different jit
    # signatures, and a retrace inside the timed solve would be charged to SciPy.
    f_np = lambda t, y: np.asarray(f(np.float64(t), y))  # noqa: E731
    jac_np = lambda t, y: np.asarray(jac(np.float64(t), y))  # noqa: E731
    implicit = method in ("Radau", "BDF", "LSODA")
    if numpy_rhs is not None:
        f_np, jac_np = numpy_rhs, None
    f_np(0.0, np.asarray(flat0))  # compile
    if implicit and jac_np is not None:
        jac_np(0.0, np.asarray(flat0))

    def solve():
        try:
            return scipy.integrate.solve_ivp(
                f_np, (0.0, case.duration), np.asarray(flat0), method=method, t_eval=ts,
                rtol=rtol, atol=1e-3 * rtol, **({"jac": jac_np} if implicit and jac_np is not None else {}),
            )
        except (ValueError, FloatingPointError, np.linalg.LinAlgError) as error:  # e.g. inf/NaN in a trial Jacobian
            return error

    wall, sol = harness.wall(solve)  # once: a SciPy solve is not compiled, and the slow ones take minutes
    if isinstance(sol, Exception):
        return dict(wall_s=wall, compile_s=0.0, steps=0, nfev=0, njev=0, ok=False, result=f"raised {sol}"), None
    record = dict(wall_s=wall, compile_s=0.0, steps=int(sol.t.size), nfev=int(sol.nfev), njev=int(sol.njev), ok=bool(sol.success), result=sol.message if not sol.success else "")
    if not sol.success or sol.y.shape[1] != ts.size:
        record["ok"] = False
        return record, None
    ys = jax.vmap(unravel)(jnp.asarray(sol.y.T))
    # The scene's own result type from SciPy's states (what `tolerax.simulate` builds from
    # diffrax's), so both families' errors come from the same quantities.
    solution = types.SimpleNamespace(
        ts=jnp.asarray(ts), ys=ys, result=diffrax.RESULTS.successful,
        stats=dict(t_reached=case.duration, num_accepted_steps=sol.t.size, num_rejected_steps=0),
    )
    res = scene.result(solution, observe(jnp.asarray(ts), ys), case.duration)
    return record, case.quantities(scene, res)


def rhs_call_cost(scene, start, repeats=2000):
    """Seconds per call of the compiled right-hand side from Python (dispatch and conversion to
    NumPy included): the median of `repeats` calls after the compiling one."""
    f, flat0, _ = flat_rhs(scene, start)
    y, t = np.asarray(flat0), np.float64(0.0)
    return harness.timed(lambda: np.asarray(f(t, y)), repeats=repeats).median_s


def numpy_check(case, scene, rhs, n_states=81):
    """Largest difference between `rhs` and the compiled JAX right-hand side at states of a Tsit5
    run (rtol 1e-8), relative to each block's largest entry (q', q'', impact-rate rates); and, as
    the yardstick for "equal to rounding", the largest change of the JAX right-hand side itself
    when the state is perturbed by 1e-15 relative (random, seed 0)."""
    f, _, _ = flat_rhs(scene, case.start)
    res = tolerax.simulate(scene, case.duration, start=case.start, n_save=n_states,
                           integrator=tolerax.Integrator(rtol=1e-8, atol=1e-11))
    ys = np.asarray(jax.vmap(lambda *a: ravel_pytree(a)[0])(*res.states))
    n = scene.stage.layout.size
    blocks = {"q'": slice(0, n), "q''": slice(n, 2 * n), "impact-rate rates": slice(2 * n, None)}
    worst = {key: 0.0 for key in blocks}
    rounding = {key: 0.0 for key in blocks}
    rng = np.random.default_rng(0)
    for t, y in zip(np.asarray(res.ts), ys):
        a, b = rhs(t, y), np.asarray(f(np.float64(t), y))
        b_pert = np.asarray(f(np.float64(t), y * (1.0 + 1e-15 * rng.standard_normal(y.size))))
        for key, block in blocks.items():
            scale = np.abs(b[block]).max()
            if scale > 0:
                worst[key] = max(worst[key], float(np.abs(a[block] - b[block]).max() / scale))
                rounding[key] = max(rounding[key], float(np.abs(b_pert[block] - b[block]).max() / scale))
    return dict(difference=worst, jax_rounding=rounding)


def errors(quantities, reference):
    out = {}
    for key, ref in reference.items():
        x = quantities[key]
        if "peak" in key:  # relative to the reference peak, or to 1 N where that is smaller
            out[key] = abs(x.max() - ref.max()) / max(ref.max(), 1.0)
        else:
            out[key] = np.abs(x - ref).max() / max(np.abs(ref).max(), 1e-300)
    return out


# --------------------------------------------------------------------------------------------

METHODS = ("Tsit5", "Dopri5", "Dopri8", "Bosh3", "Kvaerno3", "Kvaerno5", "RK45", "DOP853", "Radau", "LSODA")


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--scene", choices=sorted(CASES), default="bench")
    parser.add_argument("--quick", action="store_true", help="fewer tolerances (a smoke run)")
    parser.add_argument("--methods", nargs="+", choices=METHODS, help="run only these methods (a smoke run); the reference always runs")
    parser.add_argument("--no-implicit", action="store_true", help="skip diffrax's implicit solvers")
    parser.add_argument("--no-scipy", action="store_true", help="skip the SciPy baseline")
    parser.add_argument("--no-numpy", action="store_true", help="skip SciPy on the NumPy right-hand side (bench)")
    parser.add_argument("--scipy-rtols", type=float, nargs="+", help="SciPy tolerances (default: 1e-4 ... 1e-8; --quick: 1e-4 1e-6)")
    parser.add_argument("--numpy-rtols", type=float, nargs="+", default=[1e-4, 1e-6], help="tolerances of SciPy on the NumPy right-hand side (RK45, Radau, LSODA)")
    parser.add_argument("--duration", type=float, help="override the scene's simulated time (s)")
    parser.add_argument("--mass-scalings", type=float, nargs="+", default=[], help="dual-planetary only: Tsit5 rows on mass-scaled joints at these scalings (family 'scaled s=N')")
    parser.add_argument("--render", action="store_true", help="rewrite the .md and .png from the scene's saved .json (no runs)")
    args = harness.parse_args(parser)
    case = CASES[args.scene]
    if args.mass_scalings and case.name != "dual-planetary":
        parser.error("--mass-scalings needs --scene dual-planetary (the scaled joints replace planetary ones)")
    if args.render:
        saved = json.loads((harness.results_dir() / f"work_precision_{case.name}.json").read_text())
        case = dataclasses.replace(case, duration=saved["duration"], description=saved["scene"])
        # JSON written before the command was recorded: the default run of this scene.
        command = saved.get("command", f"python benchmarks/work_precision.py --scene {case.name}")
        env = saved.get("environment", f"environment not recorded; rendered from the saved JSON at {harness.commit()}")
        write(case, command, saved["rows"], saved["reference"], saved["reference_check"], saved["rhs_call_s"], saved.get("numpy"), env)
        return
    if args.duration:
        case = dataclasses.replace(case, duration=args.duration, description=case.description.rsplit(",", 1)[0] + f", {args.duration:g} s")
    wanted = lambda name: args.methods is None or name in args.methods  # noqa: E731
    default_width = 1e-9
    scene = case.make(default_width)
    rows = []
    call = rhs_call_cost(scene, case.start)
    command = harness.command(args)
    numpy_info = None
    if case.name == "bench" and not (args.no_scipy or args.no_numpy):
        from _numpy_bench import numpy_rhs

        np_rhs = numpy_rhs(scene)
        y0 = np.asarray(ravel_pytree(scene.initial_state(case.start))[0])
        call_s = harness.timed(np_rhs, 0.1, y0, repeats=200).median_s
        numpy_info = dict(call_s=call_s, check=numpy_check(case, scene, np_rhs))
        print("NumPy right-hand side:", numpy_info, flush=True)
    # Reference, checked by a second method.
    ref_rec, reference = run_diffrax(case, scene, diffrax.Dopri8(), 1e-12)
    if reference is None:
        raise SystemExit(f"reference solve failed: {ref_rec['result']}")
    check_rec, check = run_diffrax(case, scene, diffrax.Tsit5(), 1e-11)
    agreement = errors(check, reference) if check is not None else None
    print("reference Dopri8 1e-12 vs Tsit5 1e-11:", agreement, flush=True)

    def log(row):
        rows.append(row)
        # Rewrite the results after every row: a run of this size takes an hour or more, and a
        # killed run keeps what it measured (the table says which rows exist).
        write(case, command, rows, ref_rec, agreement, call, numpy_info)
        errs = row.get("errors") or {}
        print(
            f"{row['family']:>9} {row['method']:>16} rtol={row['rtol']:<8g} eps={row['eps']:<8g} "
            f"wall={row['wall_s']:8.3f}s compile={row['compile_s']:6.1f}s steps={row['steps']:>8} ok={row['ok']} "
            + " ".join(f"{v:.2e}" for v in errs.values()),
            flush=True,
        )

    tolerances = [1e-4, 1e-6, 1e-8] if args.quick else [1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9]
    explicit = [("Tsit5", diffrax.Tsit5()), ("Dopri5", diffrax.Dopri5()), ("Dopri8", diffrax.Dopri8()), ("Bosh3", diffrax.Bosh3())]
    implicit = [] if args.no_implicit else [("Kvaerno3", diffrax.Kvaerno3()), ("Kvaerno5", diffrax.Kvaerno5())]
    explicit = [(n, s) for n, s in explicit if wanted(n)]
    implicit = [(n, s) for n, s in implicit if wanted(n)]
    implicit_tols = [1e-4] if args.quick else [1e-3, 1e-5]
    for name, solver in explicit + implicit:
        for rtol in tolerances if (name, solver) in explicit else implicit_tols:
            # Implicit solvers get a 20k-step budget: on this problem their chord iterations often
            # fail across contact switches and steps are rejected again and again (bench: more
            # rejected than accepted steps, ~4 ms per step; see work_precision_bench.md).
            budget = 20_000 if (name, solver) in implicit else 4_000_000
            rec, qs = run_diffrax(case, scene, solver, rtol, max_steps=budget)
            log(dict(family="diffrax", method=name, rtol=rtol, eps=default_width, **rec, errors=errors(qs, reference) if qs else None))
    # The paper's multibody setting: a fixed 1e-4 s step.
    for name, solver in ([("Tsit5", diffrax.Tsit5())] if wanted("Tsit5") else []) + implicit:
        rec, qs = run_diffrax(case, scene, solver, 1e-8, fixed_step=1e-4, max_steps=max(4_000_000, int(case.duration / 1e-4) + 1))
        log(dict(family="fixed 1e-4", method=name, rtol=float("nan"), eps=default_width, **rec, errors=errors(qs, reference) if qs else None))
    # Smoothing width: how far a wider (cheaper) smoothing moves the answer.
    for width in (1e-8, 1e-7, 1e-6) if wanted("Tsit5") else ():
        rec, qs = run_diffrax(case, case.make(width), diffrax.Tsit5(), 1e-6)
        log(dict(family="eps", method="Tsit5", rtol=1e-6, eps=width, **rec, errors=errors(qs, reference) if qs else None))
    # The reduced fidelity: mass-scaled planetary joints (errors against the full reference).
    for scaling in args.mass_scalings if wanted("Tsit5") else ():
        scaled = _dual_make("planetary-scaled", mass_scaling=scaling)(default_width)
        for rtol in [1e-4, 1e-6] if args.quick else [1e-4, 1e-5, 1e-6, 1e-7, 1e-8]:
            rec, qs = run_diffrax(case, scaled, diffrax.Tsit5(), rtol)
            log(dict(family=f"scaled s={scaling:g}", method="Tsit5", rtol=rtol, eps=default_width, **rec, errors=errors(qs, reference) if qs else None))
    # SciPy on the same compiled equations.
    if not args.no_scipy:
        scipy_tols = args.scipy_rtols or ([1e-4, 1e-6] if args.quick else [1e-4, 1e-5, 1e-6, 1e-7, 1e-8])
        # The NumPy right-hand side costs ~4x a compiled call from Python: fewer methods and tolerances.
        families = [("scipy", None, ("RK45", "DOP853", "Radau", "LSODA"), scipy_tols)]
        if numpy_info:
            families.append(("scipy-numpy", np_rhs, ("RK45", "Radau", "LSODA"), args.numpy_rtols))
        for family, rhs, methods, tols in families:
            for method in filter(wanted, methods):
                for rtol in tols:
                    rec, qs = run_scipy(case, scene, method, rtol, numpy_rhs=rhs)
                    log(dict(family=family, method=method, rtol=rtol, eps=default_width, **rec, errors=errors(qs, reference) if qs else None))
                    if rec["wall_s"] > 600:
                        break  # tighter tolerances only cost more


def write(case, command, rows, ref_rec, agreement, call, numpy_info=None, env=None):
    """Write the .json, .md and .png; `env`: the environment a saved run recorded (default: this
    process's, `harness.environment()`)."""
    stem = harness.results_dir() / f"work_precision_{case.name}"
    keys = list(next((r["errors"] for r in rows if r["errors"]), agreement or {}).keys())
    env = env or harness.environment()
    payload = dict(
        scene=case.description, duration=case.duration, command=command, environment=env, reference=ref_rec,
        reference_check=agreement, rhs_call_s=call, numpy=numpy_info, rows=rows,
    )
    stem.with_suffix(".json").write_text(json.dumps(payload, indent=1, default=float))
    table = []
    for r in rows:
        if r["errors"]:
            errs = [f"{r['errors'][k]:.1e}" for k in keys]
        else:
            errs = ["failed: " + (r["result"] or "no result")[:60]] + [""] * (len(keys) - 1)
        steps = f"{r['steps']} ({r['rejected']} rejected)" if not r["family"].startswith("scipy") else f"{r.get('nfev', 0)} f-evals, {r.get('njev', 0)} Jacobians"
        table.append([r["family"], r["method"], f"{r['rtol']:g}", f"{r['eps']:g}", f"{r['wall_s']:.3f}", f"{r['compile_s']:.1f}", steps, *errs])
    harness.write_table(
        stem.name,
        f"Work-precision: {case.name}",
        command,
        ["family", "method", "rtol", "eps (m)", "wall (s)", "compile (s)", "accepted steps (rejected) / SciPy evaluations", *keys],
        table,
        about=f"Scene: {case.description}.",
        env=env,
        intro=[
            f"Reference: Dopri8 rtol 1e-12, {ref_rec['steps']} steps, {ref_rec['wall_s']:.1f} s. "
            "Tsit5 at rtol 1e-11 disagrees with it by "
            + ", ".join(f"{k}: {v:.1e}" for k, v in (agreement or {}).items())
            + " (errors below this are not resolved).",
            f"One call of the compiled right-hand side from Python: {call * 1e6:.0f} us."
            + (f" One call of the NumPy right-hand side (`_numpy_bench.py`, family scipy-numpy): "
               f"{numpy_info['call_s'] * 1e6:.0f} us; it differs from the JAX one, at 81 states of a Tsit5 run "
               f"(rtol 1e-8), by at most " + ", ".join(f"{v:.1e} ({k})" for k, v in numpy_info["check"]["difference"].items())
               + " of each block's largest entry; the JAX right-hand side itself moves by up to "
               + ", ".join(f"{v:.1e}" for v in numpy_info["check"]["jax_rounding"].values())
               + " when the state is perturbed by 1e-15 (the impact-rate rate of a sun journal ~10 nm from its centre "
               "divides by that distance)." if numpy_info else ""),
            "Errors are relative (see the script's docstring); wall time after compilation, best of up to 3; "
            "compile 'nan': the first call was not slower than the timed ones (timing noise, or a configuration "
            "whose first call took over 120 s and was timed once, compilation included).",
        ],
    )
    if keys:
        plot(case, rows, keys, stem.with_suffix(".png"))


def plot(case, rows, keys, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, len(keys), figsize=(5 * len(keys), 4.2), constrained_layout=True)
    groups = {}
    for r in rows:
        if r["errors"]:
            label = f"{r['family']} {r['method']}" if r["family"] != "diffrax" else r["method"]
            groups.setdefault(label, []).append(r)
    for ax, key in zip(axes, keys):
        for label, rs in groups.items():
            style = "--" if label.startswith("scipy") else "-"
            marker = "s" if label.startswith(("fixed", "eps")) else "^" if label.startswith("scaled") else "o"
            ax.loglog([max(r["errors"][key], 1e-16) for r in rs], [r["wall_s"] for r in rs], style, marker=marker, label=label)
        ax.set_xlabel(f"relative error: {key}")
        ax.set_ylabel("wall time (s)")
        ax.grid(True, which="both", alpha=0.3)
    axes[0].legend(fontsize=7)
    fig.suptitle(f"Work-precision, {case.description}", fontsize=9)
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
