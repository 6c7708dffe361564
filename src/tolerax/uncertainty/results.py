"""The result of a Monte Carlo run: every sample's outputs as an `xarray.Dataset`, statistics
(yield with its Wilson interval, quantiles), the features that drive an output (rank
correlation), and plots."""

import json
import os
import pathlib
from collections.abc import Mapping

import numpy as np
import scipy.stats
import xarray as xr

from .checkpoint import atomic_write

QUANTILES = (0.5, 0.9, 0.95, 0.99)


def wilson_interval(successes, trials, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval for a proportion (`scipy.stats.binomtest(...).proportion_ci`, method
    "wilson"), elementwise over `successes` and `trials`. Unlike the normal approximation it stays
    inside [0, 1] and is not empty at $\\hat p \\in \\{0, 1\\}$."""

    def one(k, n):
        ci = scipy.stats.binomtest(int(k), int(n)).proportion_ci(confidence_level=confidence, method="wilson")
        return ci.low, ci.high

    low, high = np.vectorize(one, otypes=[float, float])(successes, trials)
    return low, high


class MonteCarloResult:
    """Every sample of a Monte Carlo run, as `dataset`: an `xarray.Dataset` along `sample` with one
    variable per model output, `success`, and the sampled values as coordinates named by feature
    (m); `dataset.attrs["settings"]` is the run's manifest (JSON).

    Statistics use the samples whose `success` is true and whose output is finite; the others
    are counted (`n_failed`, `n_nonfinite`), never averaged in.
    """

    def __init__(self, dataset: xr.Dataset, requirement: float | Mapping[str, float] | None = None):
        self.dataset = dataset
        self.requirement = requirement

    @property
    def features(self) -> tuple[str, ...]:
        return tuple(json.loads(self.dataset.attrs["settings"])["names"])

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(name for name in self.dataset.data_vars if name != "success")

    @property
    def success(self) -> np.ndarray:
        return self.dataset["success"].values

    def save(self, path: str | os.PathLike) -> None:
        """Write the dataset to netCDF (h5netcdf), atomically."""
        path = pathlib.Path(path)
        atomic_write(path, lambda tmp: self.dataset.to_netcdf(tmp, engine="h5netcdf"))

    @classmethod
    def load(cls, path: str | os.PathLike, requirement=None) -> "MonteCarloResult":
        """Read a result written by `save`."""
        return cls(xr.load_dataset(path, engine="h5netcdf"), requirement)

    def _used(self, output: str) -> tuple[np.ndarray, np.ndarray]:
        if output not in self.outputs:
            raise ValueError(f"Unknown output {output!r}; the outputs are {self.outputs}.")
        y = self.dataset[output].values
        used = self.success & np.isfinite(y)
        if not used.any():
            raise ValueError(f"No successful sample with a finite {output!r} ({(~self.success).sum()} failed).")
        return y, used

    def summary(self, requirement: float | Mapping[str, float] | None = None, confidence: float = 0.95) -> dict:
        """Statistics per output over the successful samples.

        **Arguments:**

        - `requirement`: a threshold (output units) for every output, or a mapping output ->
          threshold; default the run's `requirement`.
        - `confidence`: level of the yield's Wilson score interval.

        **Returns:**

        `{output: {...}}` with `n_samples`, `n_failed` (solver failures), `n_nonfinite`
        (successful but non-finite output), `n_used`, `mean`, `std` (ddof 1), `min`, `max`,
        `q50`, `q90`, `q95`, `q99`, and with a requirement `requirement`, `yield` (fraction of the
        used samples with output <= requirement) and `yield_low`, `yield_high`.
        """
        requirement = self.requirement if requirement is None else requirement
        table = {}
        for output in self.outputs:
            y, used = self._used(output)
            values = y[used].astype(float)
            row = dict(
                n_samples=y.size, n_failed=int((~self.success).sum()),
                n_nonfinite=int((self.success & ~np.isfinite(y)).sum()), n_used=int(used.sum()),
                mean=float(values.mean()), std=float(values.std(ddof=1)) if values.size > 1 else 0.0,
                min=float(values.min()), max=float(values.max()),
            )
            row |= {f"q{round(100 * q)}": float(np.quantile(values, q)) for q in QUANTILES}
            limit = requirement.get(output) if isinstance(requirement, Mapping) else requirement
            if limit is not None:
                passed = int((values <= limit).sum())
                low, high = wilson_interval(passed, values.size, confidence)
                row |= {"requirement": float(limit), "yield": passed / values.size,
                        "yield_low": float(low), "yield_high": float(high)}
            table[output] = row
        return table

    def report(self, requirement=None) -> str:
        """The summary as readable lines."""
        lines = []
        for output, row in self.summary(requirement).items():
            unit = self.dataset[output].attrs.get("units")
            u = f" {unit}" if unit else ""
            text = (f"{output}: {row['n_used']} of {row['n_samples']} samples used ({row['n_failed']} failed, "
                    f"{row['n_nonfinite']} non-finite); mean {row['mean']:.6g}{u}, std {row['std']:.6g}{u}, "
                    f"q50/q90/q95/q99 {row['q50']:.6g}/{row['q90']:.6g}/{row['q95']:.6g}/{row['q99']:.6g}{u}")
            if "yield" in row:
                text += (f"; yield at <= {row['requirement']:.6g}{u}: {row['yield']:.4f} "
                         f"[{row['yield_low']:.4f}, {row['yield_high']:.4f}] (95 % Wilson)")
            lines.append(text)
        return "\n".join(lines)

    def drivers(self, output: str) -> dict[str, float]:
        """Spearman rank correlation (`scipy.stats.spearmanr`: tied values share their mean rank) of
        `output` with each feature over the used samples (0 for a feature that does not vary),
        strongest first."""
        y, used = self._used(output)
        result = {}
        for name in self.features:
            x = self.dataset[name].values[used]
            varies = np.ptp(x) > 0 and np.ptp(y[used]) > 0
            result[name] = float(scipy.stats.spearmanr(x, y[used]).statistic) if varies else 0.0
        return dict(sorted(result.items(), key=lambda item: -abs(item[1])))

    def _label(self, name: str, units: Mapping[str, str] | None) -> str:
        unit = (units or {}).get(name, self.dataset[name].attrs.get("units"))
        return f"{name} ({unit})" if unit else name

    @staticmethod
    def _axes(ax):
        import matplotlib.pyplot as plt

        return plt.subplots()[1] if ax is None else ax

    def plot_histogram(self, output: str, *, requirement=None, units=None, bins="auto", ax=None):
        """Histogram of `output` over the used samples, with the requirement as a vertical line
        (and the yield in the legend). `bins`: as `numpy.histogram`'s (default `"auto"`: a few
        bins for a few samples, more for many)."""
        ax = self._axes(ax)
        y, used = self._used(output)
        ax.hist(y[used], bins=bins)
        requirement = self.requirement if requirement is None else requirement
        limit = requirement.get(output) if isinstance(requirement, Mapping) else requirement
        if limit is not None:
            passed = float(np.mean(y[used] <= limit)) if used.any() else float("nan")
            ax.axvline(limit, color="k", linestyle="--", label=f"requirement {limit:g} (yield {passed:.3f})")
            ax.legend(fontsize=8)
        ax.set_xlabel(self._label(output, units))
        ax.set_ylabel("samples")
        ax.set_title(f"{used.sum()} of {y.size} samples ({(~self.success).sum()} failed)")
        return ax

    def plot_yield_curve(self, output: str, *, units=None, confidence: float = 0.95, ax=None):
        """Yield (fraction of used samples with output <= requirement) against the requirement,
        with its Wilson score band."""
        ax = self._axes(ax)
        y, used = self._used(output)
        values = np.sort(y[used])
        passed = np.arange(1, values.size + 1)
        low, high = wilson_interval(passed, values.size, confidence)
        ax.step(values, passed / values.size, where="post", label="yield")
        ax.fill_between(values, low, high, step="post", alpha=0.3, label=f"{confidence:.0%} interval")
        ax.set_xlabel("requirement on " + self._label(output, units))
        ax.set_ylabel("yield")
        ax.legend()
        return ax

    def plot_scatter(self, output: str, *, driver: str | None = None, units=None, ax=None):
        """`output` against `driver` (default: the feature with the strongest rank correlation);
        the failed samples' driver values are marked along the bottom."""
        ax = self._axes(ax)
        y, used = self._used(output)
        driver = driver or next(iter(self.drivers(output)))
        x = self.dataset[driver].values
        ax.plot(x[used], y[used], ".", alpha=0.5, label="samples")
        failed = ~self.success
        if failed.any():
            ax.plot(x[failed], np.full(failed.sum(), y[used].min()), "x", color="red", label="failed")
        ax.set_xlabel(self._label(driver, units))
        ax.set_ylabel(self._label(output, units))
        ax.legend()
        return ax
