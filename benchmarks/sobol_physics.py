"""Global sensitivity on the physics: Sobol indices of the RMS pointing error against the local
gradients at the nominal design (issue 13).

    python benchmarks/sobol_physics.py [--cases a b] [--n-base 256] [--chunk 16]
        [--num-resamples 1000] [--seed 0]

Scene: the built-in design scene `tolerax.load_scene("scan-azimuth")` (lumped azimuth joint
scanning +-0.5 deg at 1 Hz, 0.6 s from steady motion, pointing window after 0.3 s) through its
own `objective()`, at the scene's own smoothing width. Output: `pointing_rms` (arcsec).
Features: the lumped joint's design vector (`tolerax.design_names`: carrier and planet-pin
clearances, sun- and ring-mesh backlash), uniform within their bands. Cases:

- `a`: the paper's 100 um nominal everywhere, +-10 um on every feature (the scene file's
  `[tolerances]`).
- `b`: the gradient method's design of benchmarks/design_comparison.py
  (`results/design_comparison/gradient.json`: per feature a lower limit and a band; nominal =
  limit + band), whose bands differ by up to 5x.

Per case:

1. Local gradient $g = \\partial\\,\\mathrm{RMS} / \\partial x$ at the nominal by forward mode
   (`jax.jacfwd` over the design vector, `diffrax.ForwardMode()` through the solve), and the
   linear (first-order Taylor) variance shares $S^{lin}_i = g_i^2 \\mathrm{Var}(x_i) / \\sum_j
   g_j^2 \\mathrm{Var}(x_j)$ with $\\mathrm{Var}(x_i) = b_i^2 / 3$ for a uniform band of half-width
   $b_i$.
2. `tolerax.sobol_indices` (SALib's Saltelli scheme on a scrambled Sobol' sequence, evaluated by
   the Monte Carlo engine, vmap chunks of `--chunk`): $S_1$ and $S_T$ with SALib's bootstrap
   confidence half-widths (95 %, `--num-resamples`), at $N(d + 2)$ simulations for $N$ =
   `--n-base`, $d$ = 4.
3. The linear model's variance $\\sum_j g_j^2 \\mathrm{Var}(x_j)$ against the variance of the
   Saltelli samples (every row of the scheme has the uniform-box marginal), with a bootstrap
   interval over the base samples: a ratio far from 1 says the response is nonlinear over the
   bands.

Each case is written to `benchmarks/results/sobol_physics.json` as it finishes (cases may run
in separate processes); `.md` and `.png` are assembled from whatever is there.
"""

import argparse
import json
import os
import pathlib
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

import tolerax as tx  # noqa: E402

import _results  # noqa: E402

OUTPUT = "pointing_rms"
UM = 1e-6


def _load() -> str:
    return "/".join(f"{x:.1f}" for x in os.getloadavg())


def tolerances_for(case: str, scene_file, scene) -> tuple[tx.Tolerances, str]:
    """The `Tolerances` of a case and a line describing where they come from."""
    if case == "a":
        return scene_file.tolerances(scene), "the scene file's `[tolerances]`: design_of(scene) +- band"
    path = _results.results_dir() / "design_comparison" / "gradient.json"
    if not path.exists():  # the committed results, when writing elsewhere
        path = pathlib.Path(__file__).parent / "results" / "design_comparison" / "gradient.json"
    x = json.loads(path.read_text())["x"]
    limit, band = np.asarray(x["limit"]), np.asarray(x["band"])
    # design_comparison.py's features are `design_names` of the same lumped scan scene, in order
    # (`tolerax._propose.design_problem`); the length check guards against another scene.
    names = tx.design_names(scene)
    if len(names) != len(band):
        raise ValueError(f"{path} has {len(band)} features, the scene {len(names)}: {names}.")
    return tx.Tolerances(names, limit + band, band), "`benchmarks/results/design_comparison/gradient.json`: nominal = limit + band"


def local_gradient(scene_file, nominal):
    """Value and forward-mode gradient (arcsec/m) of the RMS pointing error at `nominal`, with
    the compile and run wall times (s)."""
    objective = scene_file.objective(adjoint=diffrax.ForwardMode())
    f = lambda x: objective(x)[OUTPUT]  # noqa: E731
    value_and_jac = eqx.filter_jit(lambda x: (f(x), jax.jacfwd(f)(x), objective(x)["success"]))
    x = jnp.asarray(nominal, dtype=float)
    start = time.perf_counter()
    jax.block_until_ready(value_and_jac(x))
    first = time.perf_counter() - start
    start = time.perf_counter()
    value, g, ok = jax.block_until_ready(value_and_jac(x))
    run = time.perf_counter() - start
    if not bool(ok):
        raise RuntimeError("the nominal solve failed")
    return float(value), np.asarray(g), first - run, run


def bootstrap_variance(y, d, n_resamples, seed):
    """Variance of every Saltelli row and its 95 % percentile interval, resampling base samples
    (SALib orders the rows per base sample: A, AB_1..AB_d, B)."""
    groups = y.reshape(-1, d + 2)
    rng = np.random.default_rng(seed)
    picks = rng.integers(0, len(groups), size=(n_resamples, len(groups)))
    boot = np.array([groups[p].var(ddof=1) for p in picks])
    return float(y.var(ddof=1)), np.percentile(boot, [2.5, 97.5]).tolist()


def run_case(case, args, scene_file):
    objective = scene_file.objective()
    scene = objective.scene
    tolerances, origin = tolerances_for(case, scene_file, scene)
    names = list(tolerances.names)
    nominal, band = np.asarray(tolerances.nominal), np.asarray(tolerances.band)
    print(f"--- case {case}: nominal {nominal / UM} um, band {band / UM} um", flush=True)
    load_start = _load()

    value, g, grad_compile, grad_run = local_gradient(scene_file, nominal)
    print(f"gradient (arcsec/um) {g * UM}, RMS at nominal {value:.3f}; compile {grad_compile:.0f} s, run {grad_run:.1f} s",
          flush=True)
    var_x = band**2 / 3.0
    lin_terms = g**2 * var_x
    var_lin = float(lin_terms.sum())
    s_lin = lin_terms / var_lin

    key = jax.random.key(args.seed)
    # Compile the chunk's program first (one chunk), so the timed call is samples/s after start-up.
    start = time.perf_counter()
    tx.monte_carlo(objective, tolerances, 1, key, chunk_size=args.chunk, progress=False)
    warmup = time.perf_counter() - start
    start = time.perf_counter()
    result = tx.sobol_indices(objective, tolerances, args.n_base, key, output=OUTPUT, chunk_size=args.chunk,
                              num_resamples=args.num_resamples, progress=True)
    wall = time.perf_counter() - start
    y = result.samples.dataset[OUTPUT].values.astype(float)
    d = int((band > 0).sum())
    var_mc, var_mc_ci = bootstrap_variance(y, d, args.num_resamples, args.seed)
    ix = result.indices
    outcome = dict(
        case=case, origin=origin, names=names, nominal=nominal.tolist(), band=band.tolist(),
        rms_nominal=value, gradient=g.tolist(), gradient_method="forward mode: jax.jacfwd, diffrax.ForwardMode()",
        gradient_compile=grad_compile, gradient_wall=grad_run,
        s_lin=s_lin.tolist(), var_lin=var_lin,
        s1=ix["first_order"].values.tolist(), s1_conf=ix["first_order_conf"].values.tolist(),
        st=ix["total"].values.tolist(), st_conf=ix["total_conf"].values.tolist(),
        n_base=args.n_base, n_samples=int(len(y)), chunk=args.chunk, num_resamples=args.num_resamples, seed=args.seed,
        warmup=warmup, wall=wall, rate=len(y) / wall,
        mean_mc=float(y.mean()), min_mc=float(y.min()), max_mc=float(y.max()),
        var_mc=var_mc, var_mc_ci=var_mc_ci, load_start=load_start, load_end=_load(),
        command=_results.command(args), y=y.tolist(),
    )
    outcome.update(taylor_check(outcome))
    print({k: v for k, v in outcome.items() if k != "y"}, flush=True)
    return outcome


class Taylor(eqx.Module):
    """The first-order Taylor model $f(x_0) + g \\cdot (x - x_0)$ of the RMS pointing error, as a
    Monte Carlo model (always successful)."""

    value: jax.Array
    gradient: jax.Array
    nominal: jax.Array

    def __call__(self, x):
        return {OUTPUT: self.value + jnp.dot(self.gradient, x - self.nominal), "success": jnp.array(True)}


def taylor_check(o):
    """Separate the estimator's error from the physics' nonlinearity, on the very points of the
    physics run (same tolerances, key and N, so SALib draws the same Saltelli points):

    - `tolerax.sobol_indices` of the Taylor model: its exact indices are S_lin, so their distance
      from S_lin is the estimator's error at this N (scrambled Sobol' points integrate a linear
      model far better than the iid bootstrap half-widths say);
    - the share of Var(RMS) the Taylor model leaves unexplained, and the least-squares linear fit
      over the samples: its slopes are secants over the bands, to set against the tangent g.
    """
    tolerances = tx.Tolerances(tuple(o["names"]), o["nominal"], o["band"])
    model = Taylor(jnp.asarray(o["rms_nominal"]), jnp.asarray(o["gradient"]), jnp.asarray(o["nominal"]))
    result = tx.sobol_indices(model, tolerances, o["n_base"], jax.random.key(o["seed"]), output=OUTPUT,
                              chunk_size=o["n_samples"], num_resamples=o["num_resamples"], progress=False)
    ds = result.samples.dataset
    x = np.column_stack([ds[name].values for name in o["names"]])
    y, y_taylor = np.asarray(o["y"]), ds[OUTPUT].values
    if len(y) != len(y_taylor):
        raise ValueError("the Taylor run drew a different number of points than the physics run")
    design = np.column_stack([np.ones(len(x)), (x - np.asarray(o["nominal"])) / UM])
    coef, *_ = np.linalg.lstsq(design, y, rcond=None)
    fit = design @ coef
    return dict(
        s1_taylor=result.indices["first_order"].values.tolist(), st_taylor=result.indices["total"].values.tolist(),
        s1_taylor_conf=result.indices["first_order_conf"].values.tolist(),
        unexplained_taylor=float(np.var(y - y_taylor, ddof=1) / np.var(y, ddof=1)),
        unexplained_fit=float(np.var(y - fit, ddof=1) / np.var(y, ddof=1)),
        secant=(coef[1:] * 1.0).tolist(), fit_intercept=float(coef[0]),
    )


def ranking_note(o):
    """Whether the bootstrap intervals alone rank neighbouring features by ST, and, where they
    overlap, the N (a power of 2) at which both half-widths would be below half the gap, taking
    half-widths to fall as 1/sqrt(N)."""
    order = np.argsort(o["st"])[::-1]
    short = [n.split(".")[-1] for n in o["names"]]
    parts = []
    for i, j in zip(order[:-1], order[1:]):
        gap = o["st"][i] - o["st"][j]
        conf = max(o["st_conf"][i], o["st_conf"][j])
        if o["st"][i] - o["st_conf"][i] > o["st"][j] + o["st_conf"][j]:
            parts.append(f"{short[i]} > {short[j]} (intervals apart)")
        elif gap < 0.01:  # no N separates two indices that are equal (e.g. equal gradient and band)
            parts.append(f"{short[i]} and {short[j]} equal within {gap:.3f}, intervals overlap")
        else:
            n = 2 ** int(np.ceil(np.log2(o["n_base"] * (conf / (gap / 2)) ** 2)))
            d = len(o["names"])
            parts.append(f"{short[i]} vs {short[j]}: intervals overlap (gap {gap:.3f}); apart at N ~ {n} "
                         f"({n * (d + 2)} simulations, {n * (d + 2) / o['rate'] / 3600:.1f} h at this run's rate)")
    return "Ranking by ST on SALib's intervals alone: " + "; ".join(parts) + "."


def _pm(x, c):
    return f"{x:.3f} ± {c:.3f}"


def write(cases):
    sections = []
    ordered = [cases[c] for c in sorted(cases)]
    for o in ordered:
        case_rows = []
        for i, name in enumerate(o["names"]):
            case_rows.append((
                name.split(".")[-1], f"{o['nominal'][i] / UM:.1f} ± {o['band'][i] / UM:.1f}",
                f"{o['gradient'][i] * UM:.3g}", f"{o['secant'][i]:.3g}", f"{o['s_lin'][i]:.3f}",
                _pm(o["s1"][i], o["s1_conf"][i]), _pm(o["st"][i], o["st_conf"][i]), f"{o['st'][i] - o['s1'][i]:+.3f}",
                f"{o['s1_taylor'][i]:.3f} / {o['st_taylor'][i]:.3f}",
            ))
        ratio = o["var_lin"] / o["var_mc"]
        lo, hi = o["var_lin"] / o["var_mc_ci"][1], o["var_lin"] / o["var_mc_ci"][0]
        case_notes = [
            f"Tolerances: {o['origin']}. RMS at the nominal {o['rms_nominal']:.1f} arcsec; over the Saltelli samples mean "
            f"{o['mean_mc']:.1f}, range {o['min_mc']:.1f} to {o['max_mc']:.1f} arcsec. Gradient by {o['gradient_method']} "
            f"({o['gradient_wall']:.1f} s after {o['gradient_compile']:.0f} s of compilation). Sobol: N = {o['n_base']} base "
            f"samples, {o['n_samples']} simulations (N(d + 2), d = 4), vmap chunks of {o['chunk']}, {o['wall'] / 60:.1f} min "
            f"({o['rate']:.2f} samples/s after a {o['warmup']:.0f} s compile); 95 % bootstrap half-widths from "
            f"{o['num_resamples']} resamples. Sum of S1 {sum(o['s1']):.3f}, of ST {sum(o['st']):.3f}, of S_lin 1. "
            f"Load (1/5/15 min) at the start {o['load_start']}, at the end {o['load_end']}.",
            f"Variance: linear model sum g_i^2 b_i^2 / 3 = {o['var_lin']:.4g} arcsec^2 (std {np.sqrt(o['var_lin']):.1f}); "
            f"Saltelli samples {o['var_mc']:.4g} arcsec^2 (std {np.sqrt(o['var_mc']):.1f}, 95 % bootstrap over base samples "
            f"[{o['var_mc_ci'][0]:.4g}, {o['var_mc_ci'][1]:.4g}]). Ratio linear / Monte Carlo {ratio:.3f} [{lo:.3f}, {hi:.3f}]. "
            f"Share of Var(RMS) over the samples left unexplained by the Taylor model at the nominal: "
            f"{o['unexplained_taylor']:.4f}; by the least-squares linear fit over the samples: {o['unexplained_fit']:.4f} "
            f"(its intercept {o['fit_intercept']:.1f} arcsec against f(nominal) {o['rms_nominal']:.1f}).",
        ]
        case_notes.append(ranking_note(o))
        heading = f"Case {o['case']}: " + ("the paper's 100 um +- 10 um everywhere" if o["case"] == "a"
                                            else "the gradient method's design (unequal bands)")
        sections.append(_results.Section(heading, COLUMNS, case_rows, case_notes + READING.get(o["case"], [])))
    png = plot(ordered)
    first = sections[0]
    _results.write_table(
        "sobol_physics",
        "Sobol indices of the RMS pointing error on the physics, against local gradients",
        ordered[-1]["command"],
        first.columns, first.rows,
        about=(
            "Scene `tolerax.load_scene(\"scan-azimuth\")` and its `objective()` (lumped azimuth joint, +-0.5 deg at 1 Hz, "
            "0.6 s from steady motion, window after 0.3 s, the scene's smoothing width 1 nm); output `pointing_rms` "
            "(arcsec); features uniform within their bands. Columns: band (um), gradient d RMS / d x at the nominal "
            "(arcsec/um, `jax.jacfwd` with `diffrax.ForwardMode()`), secant = slope of the least-squares linear fit of RMS on "
            "the features over the Saltelli samples (arcsec/um), S_lin = g_i^2 Var(x_i) / sum_j g_j^2 Var(x_j) with Var = "
            "b^2/3, S1 and ST (`tolerax.sobol_indices`, SALib) with 95 % bootstrap half-widths, ST - S1 (interactions), and "
            "S1 / ST that the same estimator gives for the first-order Taylor model on the same points (exact value: "
            "S_lin; the difference is the estimator's own error at this N). The command is the last run's; each case's "
            "settings are in its notes and in `sobol_physics.json`."
        ),
        intro=[f"Figure: `{png.name}` (S1 and ST with their half-widths as whiskers, next to S_lin).", CAVEATS,
               f"## {first.heading}"],
        notes=list(first.notes),
        sections=sections[1:],
    )


COLUMNS = ["feature", "nominal ± band (um)", "gradient at nominal (arcsec/um)", "secant over the samples (arcsec/um)",
           "S_lin", "S1 ± 95 %", "ST ± 95 %", "ST - S1", "S1 / ST of the Taylor model, same points"]

# The reading of each case, written after looking at the numbers of the committed run (N = 256,
# seed 0); a rerun with other settings must check it still holds.
READING: dict[str, list[str]] = {
    "a": [
        "Reading it: gradients and Sobol agree. The ranking planet-pin clearance (0.64) > sun = ring backlash (0.18 "
        "each) >> output-bearing (carrier) clearance (~0) is the same by S_lin, S1 and ST, and S1 matches S_lin to "
        "0.001. The response is linear and additive over +-10 um: the Taylor model at the nominal leaves 0.05 % of "
        "Var(RMS) unexplained, the linear / Monte Carlo variance ratio is 1 within its interval, and ST - S1 is 0 to "
        "three decimals. The lumped joint explains it: it sees the three mesh-side features only through its gaps "
        "(drive flank kappa c_p, back flank s + r + kappa c_p, kappa = cos(alpha_s) + cos(alpha_r) = 1.88, "
        "`tolerax._joint.lumped_mesh`), so the sun and ring gradients are identical and the planet-pin gradient is "
        "kappa times theirs (7.31 / 3.89 = 1.88), as if the RMS depended on the back-flank gap alone and linearly; "
        "the rattle's nonlinearity does not show in the RMS over these bands. The carrier clearance is the one "
        "feature whose secant over the samples differs from its tangent at the nominal (0.35 against 0.17 "
        "arcsec/um), a nonlinearity, but it carries under 0.2 % of the variance either way; no feature has a zero "
        "gradient and Sobol weight. SALib's +-0.07-0.12 half-widths are iid-bootstrap intervals and overstate the "
        "error of scrambled Sobol' points on this smooth response: the same estimator on the Taylor model at the "
        "same points lands within 0.001 of the exact S_lin.",
    ],
    "b": [
        "Reading it: again linear and additive (the Taylor model leaves 0.06 % of the variance, the variance ratio is "
        "0.98 [0.90, 1.08], ST - S1 = 0), and Sobol agrees with S_lin to 0.001: ring backlash 0.38 > planet-pin "
        "clearance 0.34 > sun backlash 0.28 >> carrier clearance 0.000. Here the gradient alone would mislead the "
        "designer: by |g| the planet-pin clearance (8.3 arcsec/um) ranks first and the backlashes tie (4.4), but "
        "weighted by the bands (+-9.8, +-16.7, +-19.7 um) the ring backlash carries the most variance, and sun and "
        "ring differ only through their bands (0.276 / 0.385 = (16.7 / 19.7)^2). The carrier's 50 um band, 5x the "
        "planet-pin band, costs no pointing variance. On SALib's intervals alone, ring, planet pin and sun cannot be "
        "ranked at N = 256 (the ranking line gives the N that would separate them); the Taylor check shows the point "
        "estimates are far better than those intervals, and, the response being linear over the bands, S_lin from "
        "one forward-mode gradient (about 10 s) ranks the tolerances as the 1536 simulations (13 min) do.",
    ],
}

CAVEATS = (
    "Limits: the lumped joint only (the planetary joint adds the sun-bearing clearance and per-planet contacts, "
    "where interactions could appear), the scene's 1 nm smoothing width, uniform bands, one 0.6 s scan with the "
    "window after 0.3 s, and one output (RMS; the peak error may be less linear). The Saltelli variance counts "
    "every row of the scheme (each has the uniform-box marginal); its interval resamples base samples."
)


def plot(ordered):
    fig, axes = plt.subplots(1, len(ordered), figsize=(6 * len(ordered), 4), squeeze=False)
    for ax, o in zip(axes[0], ordered):
        labels = [n.split(".")[-1].replace("_", "\n") for n in o["names"]]
        x = np.arange(len(labels))
        w = 0.27
        ax.bar(x - w, o["s1"], w, yerr=o["s1_conf"], capsize=3, label="S1 (Sobol)")
        ax.bar(x, o["st"], w, yerr=o["st_conf"], capsize=3, label="ST (Sobol)")
        ax.bar(x + w, o["s_lin"], w, label="S_lin (gradient)")
        ax.set_xticks(x, labels)
        ax.axhline(0.0, color="k", lw=0.5)
        bands = ", ".join(f"{b / UM:.0f}" for b in o["band"])
        ax.set_title(f"case {o['case']}: bands ± {bands} um; N = {o['n_base']}", fontsize=10)
        ax.set_ylabel("share of Var(RMS pointing error)")
        ax.legend(fontsize=8)
    fig.tight_layout()
    png = _results.results_dir() / "sobol_physics.png"
    fig.savefig(png, dpi=120)
    plt.close(fig)
    return png


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--cases", nargs="+", choices=("a", "b"), default=["a", "b"])
    parser.add_argument("--n-base", type=int, default=256)
    parser.add_argument("--chunk", type=int, default=16)
    parser.add_argument("--num-resamples", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--table-only", action="store_true")
    args = parser.parse_args()
    path = _results.results_dir() / "sobol_physics.json"
    cases = json.loads(path.read_text()) if path.exists() else {}
    scene_file = tx.load_scene("scan-azimuth")
    for case in [] if args.table_only else args.cases:
        cases[case] = run_case(case, args, scene_file)
        path.write_text(json.dumps(cases, indent=1))
        write(cases)
    if args.table_only:
        for o in cases.values():
            if "s1_taylor" not in o:  # a case run before the Taylor check existed: its points are redrawn
                o.update(taylor_check(o))
        path.write_text(json.dumps(cases, indent=1))
        write(cases)


if __name__ == "__main__":
    main()
