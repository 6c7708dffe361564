"""Global sensitivity: which tolerance drives an output, by Sobol indices (SALib).

The samples come from SALib's Sobol' sequence in Saltelli's scheme and are evaluated by the Monte
Carlo engine (`run_samples`), so chunks, backends, checkpoints and resume work as for
`monte_carlo`; SALib then estimates the indices and their bootstrap confidence intervals.
"""

import dataclasses

import jax
import numpy as np
import xarray as xr
from jaxtyping import PRNGKeyArray
from SALib.analyze import sobol as sobol_analyze
from SALib.sample import sobol as sobol_sample
from .montecarlo import MonteCarloResult, Plan, typed_key, check_run, key_settings, run_samples
from .sampling import Tolerances


@dataclasses.dataclass(frozen=True)
class SobolResult:
    """Sobol indices of one output.

    - `indices`: an `xarray.Dataset` along `feature` with `first_order` ($S_i$), `total`
      ($S_{T,i}$) and their confidence half-widths `first_order_conf`, `total_conf`. A feature
      with a zero band is not varied and has indices 0 (with half-width 0).
    - `samples`: the `MonteCarloResult` of every evaluated sample (all outputs).
    """

    indices: xr.Dataset
    samples: MonteCarloResult

    @property
    def first_order(self) -> dict[str, float]:
        return dict(zip(self.indices["feature"].values.tolist(), self.indices["first_order"].values.tolist()))

    @property
    def total(self) -> dict[str, float]:
        return dict(zip(self.indices["feature"].values.tolist(), self.indices["total"].values.tolist()))


def sobol_indices(
    model,
    tolerances: Tolerances,
    n_base: int,
    key: PRNGKeyArray,
    *,
    output: str,
    backend: str = "auto",
    chunk_size: int = 64,
    out=None,
    progress: bool = True,
    client=None,
    workers: int | None = None,
    num_resamples: int = 100,
    confidence: float = 0.95,
) -> SobolResult:
    """First-order and total Sobol indices of `output` with respect to each toleranced feature.

    For an output $Y = f(X_1, \\dots, X_d)$ with independent inputs, the first-order index
    $S_i = \\mathrm{Var}(\\mathrm{E}[Y|X_i]) / \\mathrm{Var}(Y)$ is the share of the variance that
    $X_i$ explains alone, and the total index $S_{T,i} = \\mathrm{E}[\\mathrm{Var}(Y|X_{\\sim i})] /
    \\mathrm{Var}(Y)$ includes its interactions: tighten the tolerance with the largest total index.

    The inputs are spread over the tolerance box (`Tolerances.bounds()`: nominal ± band, the low
    end clipped at `lower`): uniformly for `distribution="uniform"`, and for `"normal"` as a
    normal ($\\sigma$ = band/3) truncated to the box (SALib's `truncnorm`; where the box is
    clipped at `lower` this truncates rather than piling draws at `lower` as `sample` does).
    $N$ = `n_base` base samples give $N(d + 2)$ evaluations ($d$: features with a non-zero band),
    scrambled with a seed derived from `key`.

    Every sample must succeed: SALib's estimators need every output. If some fail, a
    `ValueError` says how many (with `out`, the samples stay on disk for inspection).

    **Arguments:**

    - `model`, `tolerances`, `key`, `backend`, `chunk_size`, `out`, `progress`, `client`,
      `workers`: as for `monte_carlo` (`out` holds Sobol samples, not a `monte_carlo` run).
    - `n_base`: base sample size $N$, a power of 2 (the Sobol' sequence's balance properties).
    - `output`: name of the model output to analyse.
    - `num_resamples`: bootstrap resamples for the confidence intervals.
    - `confidence`: level of the confidence intervals.

    **Returns:**

    A `SobolResult`.
    """
    check_run(tolerances, n_base=n_base, chunk_size=chunk_size)
    if n_base < 2 or n_base & (n_base - 1):
        raise ValueError(f"n_base must be a power of 2 (at least 2) for the Sobol' sequence, got {n_base!r}.")
    key = typed_key(key)
    bounds = tolerances.bounds()
    varied = bounds[:, 1] > bounds[:, 0]
    if not varied.any():
        raise ValueError("Every band is zero: there is nothing to vary.")
    names = [name for name, v in zip(tolerances.names, varied) if v]
    nominal, band = np.asarray(tolerances.nominal), np.asarray(tolerances.band)
    if tolerances.distribution == "uniform":
        problem_bounds, dists = bounds[varied].tolist(), ["unif"] * len(names)
    else:
        rows = np.column_stack([bounds, nominal, band / 3])[varied]
        problem_bounds, dists = rows.tolist(), ["truncnorm"] * len(names)
    problem = {"num_vars": len(names), "names": names, "bounds": problem_bounds, "dists": dists}
    seed = int(np.random.SeedSequence(np.asarray(jax.random.key_data(key)).ravel().tolist()).generate_state(1)[0])
    x = sobol_sample.sample(problem, n_base, calc_second_order=False, seed=seed)
    values = np.tile(nominal, (len(x), 1))
    values[:, varied] = x
    settings = {
        "kind": "sobol", "key": key_settings(key), "tolerances": tolerances.to_json(), "n_base": n_base,
        "seed": seed, "problem": problem,
    }
    plan = Plan(tolerances.names, len(values), int(chunk_size), lambda start, stop: values[start:stop], settings)
    ds = run_samples(model, plan, backend=backend, out=out, progress=progress, client=client, workers=workers,
                     callback=None, units=None)
    samples = MonteCarloResult(ds)
    if output not in samples.outputs:
        raise ValueError(f"Unknown output {output!r}; the outputs are {samples.outputs}.")
    y = ds[output].values.astype(float)
    bad = ~(samples.success & np.isfinite(y))
    if bad.any():
        raise ValueError(
            f"{bad.sum()} of {y.size} Sobol samples failed or gave a non-finite {output!r}; the indices need "
            f"every sample (first failed sample values: {values[np.argmax(bad)].tolist()})."
        )
    si = sobol_analyze.analyze(problem, y, calc_second_order=False, num_resamples=num_resamples,
                               conf_level=confidence, seed=seed)
    columns = {}
    for name in ("S1", "S1_conf", "ST", "ST_conf"):
        column = np.zeros(len(tolerances.names))
        column[varied] = si[name]
        columns[name] = ("feature", column)
    indices = xr.Dataset(
        {"first_order": columns["S1"], "first_order_conf": columns["S1_conf"], "total": columns["ST"],
         "total_conf": columns["ST_conf"]},
        coords={"feature": list(tolerances.names)},
        attrs={"output": output, "n_base": n_base, "confidence": confidence},
    )
    return SobolResult(indices, samples)
