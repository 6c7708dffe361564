"""The profile-likelihood bounds of a parameter the linearised interval cannot state (`identify`).

Where the recording does not see a parameter at its estimate ($J_j \\approx 0$: a backlash
larger than the recording ever takes up, its estimate on the plateau above the flank), the
Gauss-Newton standard error is unbounded and the linearised check (`fit._profile`) has no point
inside the bounds to read. The recording may still bound it on one side: the flank at the
plateau's foot. The 95 % profile-likelihood interval is the set of values $v$ whose profile
cost, the others re-minimised,

$$c_p(v) = \\min_{\\theta_{-j}} \\lVert r(v, \\theta_{-j}) \\rVert^2,$$

rises above the estimate's by at most $\\chi^2_{1,0.95}\\,s^2$ (`OPEN_RISE` $s^2$; Venzon & Moolgavkar,
*Appl. Statist.* 37, 1988). Read here in two stages:

1. Along the parameter's own line (the others held at the estimate) on a log-spaced grid out to
   the bounds, in one batched run: that cost is at least the profile's, so where its rise stays
   within the threshold the profile's does too (those values are inside the interval, and a
   side whose whole line stays within is open).
2. From the line's first point past the threshold outward, the profile itself: the others
   re-fitted by Levenberg-Marquardt (`fit._solve`, the parameter held by a reach of 1e-9 about
   the grid point, the same compiled program as the fit's) until its rise exceeds the
   threshold; then `BISECTIONS` re-fits halve (in the logarithm) the bracket between that grid
   point and the one before. The bound is the bracket's outer end: the profile's crossing lies
   inside the bracket, so the interval stated is the wider (conservative) one by at most the
   bracket, an eighth of the grid's spacing (2 % of the value where the grid is coarsest).

The line alone would state a bound tighter than the data support (the others, re-fitted,
absorb part of the rise); the re-fit is what makes it the profile's.
"""

import math

import jax.numpy as jnp
import numpy as np

from .fit import _costs, _in_batches, _solve, _unbounded
from .result import OPEN_RISE

# The grid along each side: GRID points log-spaced from a relative NEAREST of the estimate out to
# the fit's bounds (by default a factor `fit.BOUND` of the scene's value: 1.2x apart in the logarithm over [1 %, 4.6]).
GRID, NEAREST = 32, 0.01
# Levenberg-Marquardt re-fits per side at most, outward from the line's crossing; a side whose
# profile has not crossed by then is stated open (the wider interval).
SOLVES = 6
BISECTIONS = 3


def profile_bounds(fit, x, cost: float, s2: float, width, limits, js, batch: int | None, lm_steps: int, centre, reach):
    """The 95 % profile-likelihood bounds of the parameters `js` about the estimate `x` (module
    docstring), in x's units: `(bounds (p, 2): lower and upper, -inf / inf where open, NaN for the
    parameters not in js; lowest (p,): the lowest cost met along each one's line and profile,
    µrad², NaN where not walked; solves: the re-fits run)`. `cost` (µrad²) is the estimate's,
    `s2` the residual variance (µrad²) the threshold is scaled by, `limits` the fit's bounds
    (lower and upper ends, x's units, (2, p)), `batch` the screen's batch (its compiled program; None: one program for
    this grid), `centre`, `reach` the fit's bounded variable (`fit._bounded`)."""
    bounds, lowest, solves = np.full((x.size, 2), np.nan), np.full(x.size, np.nan), 0
    if not js or not (math.isfinite(s2) and s2 > 0):
        return bounds, lowest, solves
    threshold = OPEN_RISE * s2
    grids = {}  # (j, side): the parameter's values along that side, nearest first
    for j in js:
        for side, (sign, far) in enumerate(((-1.0, math.log(x[j] / limits[0][j])), (1.0, math.log(limits[1][j] / x[j])))):
            grids[j, side] = x[j] * np.exp(sign * np.geomspace(NEAREST, far * (1 - 1e-9), GRID)) if far > NEAREST else np.empty(0)
    points = np.repeat(x[None], sum(g.size for g in grids.values()), axis=0)
    at = 0
    for (j, _), g in grids.items():
        points[at:at + g.size, j] = g
        at += g.size
    if batch is None:
        costs = np.asarray(_costs(fit, jnp.asarray(points), width))
    else:  # the screen's program: padded with the estimate to whole batches
        pad = -len(points) % batch
        costs = np.sum(_in_batches(fit, np.vstack([points, np.repeat(x[None], pad, axis=0)]), width, batch) ** 2, axis=1)[:len(points)]
    at = 0
    free = _unbounded(x, np.asarray(centre), np.asarray(reach))
    for (j, side), g in grids.items():
        line, at = costs[at:at + g.size], at + g.size
        lowest[j] = np.nanmin([lowest[j], cost, *line[np.isfinite(line)]])
        past = np.flatnonzero(~(line - cost <= threshold))  # past the threshold, or a run that failed
        bound = math.inf
        z = free.copy()

        def refit(v):  # the profile's cost at j = v, the others re-fitted from the last re-fit's (None: the run failed)
            nonlocal z, solves
            held_centre, held_reach = np.asarray(centre).copy(), np.asarray(reach).copy()
            held_centre[j], held_reach[j] = math.log(v), 1e-9
            z[j] = 0.0
            z_v, c, _, _ = _solve(fit, jnp.asarray(z), width, int(lm_steps), jnp.asarray(held_centre), jnp.asarray(held_reach))
            solves += 1
            if not math.isfinite(float(c)):
                return None
            z = np.asarray(z_v).copy()
            lowest[j] = min(lowest[j], float(c))
            return float(c)

        if past.size and np.isfinite(line[past[0]]):
            for k in range(past[0], min(past[0] + SOLVES, g.size)):
                c = refit(g[k])
                if c is None:
                    break  # a failed run is no evidence: the side stays open
                if c - cost > threshold:
                    inside, bound = (float(g[k - 1]) if k else float(x[j])), float(g[k])
                    for _ in range(BISECTIONS):
                        middle = math.sqrt(inside * bound)
                        c = refit(middle)
                        if c is None:
                            break
                        inside, bound = (inside, middle) if c - cost > threshold else (middle, bound)
                    break
        bounds[j, side] = bound if math.isfinite(bound) else (-math.inf if side == 0 else math.inf)
    return bounds, lowest, solves
