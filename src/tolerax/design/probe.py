"""What `Auto()` measures before it picks a requirement's constraint model (`tolerax.design.spec`):
how much of each output's scatter over units of a zone a line in the design features carries.

`scatter_share(pointing, outputs, x, width)` simulates `PROBE_UNITS` units drawn uniformly within
the zones `x` (one `tolerax.monte_carlo` run: the compiled program a yield `Check` runs its chunks
on, so the design's first check compiles nothing more) and fits each output by least squares on
the features,

$$y = a + s\\cdot(v - m) + e,$$

returning $\\hat\\sigma_e^2 / s_y^2$: the residual variance on its degrees of freedom over the
outputs' own sample variance, i.e. one minus the adjusted $R^2$. About 0 for an output the
features determine (a line, or a curve the zone is narrow against: tangents at the zone's
middle read it); about 1 for one that scatters from unit to unit for reasons the features do not
carry (the chaotic rattle's jitter: there a tangent, or a line through one zone's units, reads
noise, and a response surface over the bounds is the model that verified).
"""

import jax
import jax.numpy as jnp
import numpy as np

from .check import AtWidth, unit_tolerances
from .surface import line_fit
from .types import Design
from ..uncertainty.montecarlo import default_chunk, monte_carlo

PROBE_UNITS = 50  # whole chunks of a yield check's (`Check.chunk_size`'s default: 10 or 50): the same compiled program
PROBE_KEY = 3  # the units' key: another stream than the checks' (`Check.key_for`: 1 and 2)


def scatter_share(pointing, outputs, x: Design, width=None, *, units: int = PROBE_UNITS, key=None,
                  chunk_size: int | None = None) -> np.ndarray:
    """The share of each of `outputs`' variance over `units` units drawn uniformly within the
    zones `x` (`Design(middle, half-width)`, m) that a line in the features does not carry (module
    docstring), simulated with `pointing` at smoothing `width` (m; `None`: the objective's own)
    in chunks of `chunk_size` (default: as `Check`'s), from `key` (default
    `jax.random.key(PROBE_KEY)`). Shape (k,), one per output, in [0, 1]; units whose solve failed
    are left out. Features held fixed (a zero half-width) carry nothing and take no degree of
    freedom."""
    outputs = tuple(outputs)
    n = int(np.shape(x.nominal)[0])
    if int(units) < n + 3:
        raise ValueError(f"scatter_share: {units} units leave too few degrees of freedom for a line in {n} features: "
                         f"give at least {n + 3}.")
    tolerances = unit_tolerances(pointing, Design(jnp.asarray(x.nominal), jnp.asarray(x.band)))
    chunk = int(default_chunk(pointing) if chunk_size is None else chunk_size)
    run = monte_carlo(AtWidth(pointing, None if width is None else jnp.asarray(width, dtype=float)), tolerances, int(units),
                      jax.random.key(PROBE_KEY) if key is None else key, chunk_size=min(chunk, int(units)), progress=False)
    ds = run.dataset
    values = np.stack([ds[name].values for name in tolerances.names[:n]], axis=1)
    y = np.stack([np.asarray(ds[o].values, dtype=float) for o in outputs], axis=1)
    ok = np.asarray(ds["success"].values, dtype=bool) & np.all(np.isfinite(y), axis=1)
    band = np.asarray(x.band, dtype=float)
    rows = np.column_stack([np.ones(int(ok.sum())), (values[ok] - np.asarray(x.nominal)) / np.where(band > 0, band, 1.0)])
    _, residual, dof = line_fit(rows, y[ok])
    if dof < 2:
        raise ValueError(f"scatter_share: {int(ok.sum())} of {units} units solved, too few for a line in {n} features.")
    spread = np.var(y[ok], axis=0, ddof=1)
    return np.where(spread > 0, np.minimum(residual / np.where(spread > 0, spread, 1.0), 1.0), 0.0)
