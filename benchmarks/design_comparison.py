"""Tolerance design by gradients against derivative-free search, at the same budget (issue 12).

    python benchmarks/design_comparison.py [--requirement 400] [--outer 4] [--inner 6]
        [--methods baseline gradient gradient-long random grid cma optuna random-compute verify]
        [--long-outer 10] [--long-inner 6] [--mode forward] [--verify-units 10] [--results DIR]

The problem is `tolerax.propose_design`'s own (`tolerax.design.propose.design_problem`; the
scene, horizon, units and budget options are `_design.py`'s, shared with `design_tradeoff.py`): on the azimuth
scan (`tolerax.scan("azimuth", fidelity=("lumped", "ideal"))`, 0.6 s from a steady start, one
reversal at 0.25 s), choose per feature the lower limit of the tolerance zone (>= 5 um) and the
band half-width (1-50 um) of the output-bearing and planet-pin clearances and the sun- and
ring-mesh backlash, minimising the ISO 286 cost of the bands subject to mean + 1 std of the RMS
pointing error over 4 fixed manufactured units <= the requirement. Baseline: the paper's 100 um
everywhere, +-10 um.

- `gradient`: `propose_design` (augmented Lagrangian on Adam, smoothing width 1 um then 0.1 um;
  gradients in forward mode through the solves, `--mode reverse` for reverse mode: the same
  derivatives to rounding). Its budget is counted in gradient evaluations (`outer * (inner + 1)`:
  each outer iteration ends with one more gradient). `gradient-long`: the same with a larger
  budget (`--long-outer`, `--long-inner`), to see whether and where it converges; it is not part
  of the equal-budget comparison.
- `random` (uniform in the box), `grid` (the 4 bands on a log grid with every lower limit at its
  minimum - a hint the gradient method is not given), `cma` (CMA-ES, `cma` package, bounded, on
  the penalised cost `C/C0 + 10 max(0, f/R - 1)`), `optuna` (TPE, same penalised cost): each
  evaluates the objective at the final smoothing width (0.1 um), `budget` times, where budget is
  the gradient method's count of gradient evaluations (equal *simulations*), and random search a
  second time with that count times the measured cost of a gradient in forward solves (equal
  *compute*). Each reports the cheapest design it evaluated that meets the requirement.
- Verification (the baseline, the gradient method's design, and any other method's design that
  meets the requirement more cheaply): the design is re-simulated at **planetary** fidelity with a 10x smaller
  smoothing width (0.01 um) on a **fresh** Monte Carlo sample (`--verify-units` units drawn
  uniformly within the proposed bands from a different key; the planetary joint's sun-bearing
  clearance, which the lumped joint does not have, stays at 100 +- 10 um): mean + 1 std of the
  RMS pointing error, and the yield against the requirement with its 95 % Wilson interval.

Each method's outcome is written to `benchmarks/results/design_comparison/<method>.json` (with
`--results DIR`: DIR/design_comparison/) as it finishes, so methods may run in separate processes (e.g. `--methods baseline gradient` in one,
`--methods random grid cma optuna random-compute` in another, then `--methods verify`); the
table is assembled from whatever is there.
"""

import json
import math

import equinox as eqx
import jax
import numpy as np

import tolerax as tx
from tolerax.design.propose import design_problem

import _design
import harness

PENALTY = 10.0


def setup(args):
    pointing = _design.pointing(args)
    return pointing, design_problem(pointing, n_draws=args.draws)


def evaluator(problem, width):
    """`f(z)`: the objective (arcsec) at box coordinates z in [0, 1]^(2n), and `to_x`."""
    lo = np.concatenate([problem.lower.nominal, problem.lower.band])
    hi = np.concatenate([problem.upper.nominal, problem.upper.band])
    n = len(problem.features.names)
    compiled = eqx.filter_jit(problem.objective)

    def to_x(z):
        v = lo + (hi - lo) * np.clip(np.asarray(z, dtype=float), 0.0, 1.0)
        return tx.Design(v[:n], v[n:])

    def f(z):
        return float(compiled(to_x(z), problem.draws, width))

    def to_z(x):
        v = np.concatenate([np.asarray(x.nominal), np.asarray(x.band)])
        return np.where(hi > lo, (v - lo) / np.where(hi > lo, hi - lo, 1.0), 0.0)

    return f, to_x, to_z


def cost_of(problem, x):
    return float(problem.cost_model.total(x.band, problem.features.size_mm))


class Log:
    """Every evaluation of a derivative-free method: design, cost, objective."""

    def __init__(self, problem, f, to_x, requirement, cost0):
        self.problem, self.f, self.to_x, self.requirement, self.cost0 = problem, f, to_x, requirement, cost0
        self.rows = []

    def __call__(self, z):
        x = self.to_x(z)
        value, cost = self.f(z), cost_of(self.problem, x)
        self.rows.append((np.asarray(z).tolist(), cost, value))
        if not math.isfinite(value):
            return 1e3
        return cost / self.cost0 + PENALTY * max(0.0, value / self.requirement - 1.0)

    def best(self):
        feasible = [r for r in self.rows if math.isfinite(r[2]) and r[2] <= self.requirement]
        if feasible:
            z, cost, value = min(feasible, key=lambda r: r[1])
            return dict(z=z, cost=cost, objective=value, feasible=True)
        z, cost, value = min(self.rows, key=lambda r: r[2] if math.isfinite(r[2]) else np.inf)
        return dict(z=z, cost=cost, objective=value, feasible=False)


def run_gradient(args, pointing, problem, outer, inner):
    wall, report = _design.propose(pointing, args.requirement, args, outer, inner, gradient=args.mode)
    print(report.table(), flush=True)
    x = tx.Design(report.result.x.nominal, report.result.x.band)
    hist = report.result.history
    return dict(
        cost=report.cost, objective=report.objective, feasible=report.objective <= args.requirement * (1 + 1e-3),
        x=dict(limit=np.asarray(x.nominal).tolist(), band=np.asarray(x.band).tolist()),
        evaluations=f"{outer * (inner + 1)} gradients ({args.mode} mode)", wall=wall,
        history=dict(cost=np.asarray(hist.cost).tolist(), objective=np.asarray(hist.objective).tolist()),
        table=report.table(),
    )


def gradient_cost_ratio(problem, f_z, to_x, width):
    """A gradient's wall time in forward solves, measured here, after compilation (best of 2)."""
    z = np.full(2 * len(problem.features.names), 0.5)
    grad = eqx.filter_jit(jax.grad(lambda x: problem.objective(x, problem.draws, width)))
    t_g = harness.timed(grad, to_x(z), repeats=2).run_s
    t_f = harness.timed(f_z, z, repeats=2).run_s
    return t_g / t_f, t_f


def run_derivative_free(method, args, problem, budget):
    f, to_x, to_z = evaluator(problem, args.widths[-1])
    cost0 = cost_of(problem, problem.x0)
    log = Log(problem, f, to_x, args.requirement, cost0)
    dim = 2 * len(problem.features.names)
    rng = np.random.default_rng(args.seed)

    def search():
        if method.startswith("random"):
            for _ in range(budget):
                log(rng.uniform(0.0, 1.0, dim))
        elif method == "grid":
            n = len(problem.features.names)
            levels = max(2, int(math.floor(budget ** (1.0 / n))))
            bands = np.geomspace(problem.lower.band[0], problem.upper.band[0], levels)
            span = np.asarray(problem.upper.band - problem.lower.band)
            for combo in np.array(np.meshgrid(*[bands] * n, indexing="ij")).reshape(n, -1).T[:budget]:
                log(np.concatenate([np.zeros(n), (combo - np.asarray(problem.lower.band)) / span]))
        elif method == "cma":
            import cma

            es = cma.CMAEvolutionStrategy(
                to_z(problem.x0), 0.3, {"bounds": [0.0, 1.0], "maxfevals": budget, "seed": args.seed + 1, "verbose": -9}
            )
            while not es.stop() and len(log.rows) < budget:
                zs = es.ask()
                zs = zs[: budget - len(log.rows)]
                values = [log(z) for z in zs]
                if len(values) < es.popsize:
                    break
                es.tell(zs, values)
        elif method == "optuna":
            import optuna

            optuna.logging.set_verbosity(optuna.logging.WARNING)
            study = optuna.create_study(sampler=optuna.samplers.TPESampler(seed=args.seed))
            study.enqueue_trial({f"z{i}": float(v) for i, v in enumerate(to_z(problem.x0))})
            study.optimize(lambda trial: log(np.array([trial.suggest_float(f"z{i}", 0.0, 1.0) for i in range(dim)])), n_trials=budget)
        else:
            raise ValueError(method)

    wall, _ = harness.wall(search)
    best = log.best()
    x = to_x(best["z"])
    return dict(
        cost=best["cost"], objective=best["objective"], feasible=best["feasible"],
        x=dict(limit=np.asarray(x.nominal).tolist(), band=np.asarray(x.band).tolist()),
        evaluations=f"{len(log.rows)} objective evaluations", wall=wall,
        n_feasible=sum(1 for r in log.rows if r[2] <= args.requirement),
    )


def verify(args, pointing, problem, limit, band, key):
    """Fresh units at planetary fidelity and a 10x smaller smoothing width."""
    planetary = _design.pointing(args, "planetary")
    scene = planetary.with_width(tx.design_of(planetary.scene), args.widths[-1] / 10)
    planetary = eqx.tree_at(lambda p: p.scene, planetary, scene)
    # The planetary joint has one feature the lumped one lacks (its sun floats on a bearing):
    # it keeps the baseline's 100 um +- 10 um in every verification.
    designed = dict(zip(problem.features.names, zip(np.asarray(limit) + np.asarray(band), np.asarray(band))))
    baseline = dict(zip(tx.design_names(scene), np.asarray(tx.design_of(scene))))
    nominal, bands = zip(*(designed.get(name, (baseline[name], 10e-6)) for name in baseline))
    tolerances = tx.Tolerances(tuple(baseline), nominal, bands)
    wall, mc = harness.wall(tx.monte_carlo, planetary, tolerances, args.verify_units, key, chunk_size=1, progress=False,
                            requirement={"pointing_rms": args.requirement})
    values = mc.dataset["pointing_rms"].values[mc.dataset["success"].values]
    summary = mc.summary()["pointing_rms"]
    return dict(
        mean_plus_std=float(np.mean(values) + np.std(values, ddof=1)), mean=float(np.mean(values)), n_used=int(summary["n_used"]),
        yield_=float(summary["yield"]), interval=[summary["yield_low"], summary["yield_high"]], wall=wall,
    )


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--requirement", type=float, default=400.0)
    _design.add_arguments(parser)
    parser.add_argument("--widths", type=float, nargs="+", default=[1e-6, 1e-7])
    parser.add_argument("--methods", nargs="+", default=["baseline", "gradient", "random", "grid", "cma", "optuna", "random-compute", "verify"],
                        help="methods to run (gradient-long is not in the default: a larger budget than the others)")
    parser.add_argument("--long-outer", type=int, default=10, help="gradient-long: outer iterations (a budget beyond the others')")
    parser.add_argument("--long-inner", type=int, default=6, help="gradient-long: inner steps")
    parser.add_argument("--mode", default="forward", choices=("forward", "reverse"), help="gradient methods: forward or reverse mode through the solves")
    parser.add_argument("--verify-units", type=int, default=10)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--table-only", action="store_true")
    args = harness.parse_args(parser)
    out = harness.results_dir() / "design_comparison"
    out.mkdir(exist_ok=True)
    pointing, problem = setup(args)
    budget = args.outer * (args.inner + 1)
    for method in [] if args.table_only else args.methods:
        print(f"--- {method}", flush=True)
        if method == "verify":
            run_verification(args, pointing, problem, out)
            continue
        if method == "baseline":
            f, _, to_z = evaluator(problem, args.widths[-1])
            outcome = dict(cost=cost_of(problem, problem.x0), objective=f(to_z(problem.x0)), evaluations="1", wall=0.0,
                           x=dict(limit=np.asarray(problem.x0.nominal).tolist(), band=np.asarray(problem.x0.band).tolist()))
            outcome["feasible"] = outcome["objective"] <= args.requirement
        elif method == "gradient":
            outcome = run_gradient(args, pointing, problem, args.outer, args.inner)
        elif method == "gradient-long":
            outcome = run_gradient(args, pointing, problem, args.long_outer, args.long_inner)
        elif method == "random-compute":
            f, to_x, _ = evaluator(problem, args.widths[-1])
            ratio, t_forward = gradient_cost_ratio(problem, f, to_x, args.widths[-1])
            outcome = run_derivative_free("random-compute", args, problem, int(round(budget * ratio)))
            outcome.update(gradient_in_forward_solves=ratio, forward_wall=t_forward)
        else:
            outcome = run_derivative_free(method, args, problem, budget)
        print(outcome, flush=True)
        (out / f"{method}.json").write_text(json.dumps(outcome, indent=1))
    write(args, problem, out)


def run_verification(args, pointing, problem, out):
    """Verify the baseline, the gradient method's design and every other design that meets the
    requirement more cheaply than it (the verification costs about a minute per unit)."""
    gradient = out / "gradient.json"
    gradient_cost = json.loads(gradient.read_text())["cost"] if gradient.exists() else np.inf
    for path in sorted(out.glob("*.json")):
        o = json.loads(path.read_text())
        if "verification" in o or not (path.stem in ("baseline", "gradient", "gradient-long") or (o["feasible"] and o["cost"] < gradient_cost)):
            continue
        print(f"--- verify {path.stem}", flush=True)
        o["verification"] = verify(args, pointing, problem, o["x"]["limit"], o["x"]["band"], jax.random.key(1000 + args.seed))
        print(o["verification"], flush=True)
        path.write_text(json.dumps(o, indent=1))


def write(args, problem, out):
    rows, notes = [], []
    for method in ["baseline", "gradient", "gradient-long", "random", "grid", "cma", "optuna", "random-compute"]:
        path = out / f"{method}.json"
        if not path.exists():
            continue
        o = json.loads(path.read_text())
        v = o.get("verification")
        bands = ", ".join(f"{b * 1e6:.0f}" for b in o["x"]["band"])
        limits = ", ".join(f"{b * 1e6:.0f}" for b in o["x"]["limit"])
        rows.append((
            method, o["evaluations"], f"{o['wall']:.0f}", f"{o['cost']:.3g}", f"{o['objective']:.0f}", "yes" if o["feasible"] else "no",
            limits, bands, f"{v['mean_plus_std']:.0f}" if v else "not run (no cheaper feasible design)",
            f"{v['yield_']:.2f} [{v['interval'][0]:.2f}, {v['interval'][1]:.2f}] of {v['n_used']}" if v else "",
        ))
        if "gradient_in_forward_solves" in o:
            notes.append(
                f"Measured in the `random-compute` run: one gradient costs {o['gradient_in_forward_solves']:.1f} forward "
                f"evaluations of the objective (a forward evaluation of the 4 units: {o['forward_wall']:.1f} s)."
            )
        if "table" in o:
            notes.append(f"The `{method}` method's proposal:\n\n" + o["table"])
    harness.write_table(
        "design_comparison",
        "Tolerance design: gradients against derivative-free search at the same budget",
        harness.command(args),
        ["method", "budget used", "wall (s)", "cost (IT7 = 1 per feature)", f"objective (arcsec, <= {args.requirement:g})", "meets",
         "lower limits (um)", "bands +- (um)", "planetary, fresh units: mean + std (arcsec)", "planetary yield [95 %]"],
        rows,
        about=(
            "The table is assembled from `results/design_comparison/*.json`, each written by the run of its method "
            "(benchmarks/README.md lists the commands; the command above is the last one). "
            f"Features: {', '.join(problem.features.names)}. Requirement: mean + 1 std of the RMS pointing error over "
            f"{args.draws} fixed units <= {args.requirement:g} arcsec, {args.horizon} s azimuth scan; verification on "
            f"{args.verify_units} fresh units at planetary fidelity, smoothing {args.widths[-1] / 10:g} m."
        ),
        notes=notes,
    )


if __name__ == "__main__":
    main()
