"""The former `propose_design(pointing, requirement, **options)` signature, for one release: its
keywords translated to the values that replace them, with a `DeprecationWarning` naming them.

| former keyword | now |
|---|---|
| `method="sequential"`, `widths`, `max_outer` | `solver=Sequential(widths, max_gradients)` |
| `method="augmented-lagrangian"`, `inner_steps`, `learning_rate` | `solver=AugmentedLagrangian(widths, max_outer, inner_steps, learning_rate)` |
| `check_units`, `max_checks`, `check_key` | `check=Check(units, rounds, key)` (`check_units=0`: `check=None`) |
| `yield_`, `n_yield_draws` | `ToleranceProblem(statistic=Yield(level, draws))` |
| `statistic`, `k`, `n_draws`, `key`, `gradient` | `ToleranceProblem(statistic=MeanPlusKStd(k, units, key, adjoint))` (a diffrax adjoint) |
| `band`, `start`, `min_clearance`, `band_range`, `fixed` | `ToleranceProblem(zones=Zones(...))` |
| `cost_model` | `ToleranceProblem(cost=...)` |
| `allow_proxy` | `ToleranceProblem(allow_proxy=...)` |
| `jitter` | `Requirement("pointing_jitter", jitter)` among the requirements |
| `output` | `Requirement(output, limit)` |
| `slope_width` | `Requirement(model=Tangents(slope_width))` |
| `secant_units`, `scatter`, `secant_seed`, `secant_reach`, `log_outputs`, `noise_band` | `Requirement(model=Secants(units, scatter, log, reach, seed, twin))` |
| `surface_box`, `surface_width`, `surface_rounds` | `Requirement(model=Surface(box, width, rounds, ...))` |

The translation keeps the former defaults (a jitter on plain secants over max(16, 2 x features
+ 2) units, no response surface): the former calls give the former answers. The new defaults
(`Auto()`: the response-surface recipe for the jitter) are reached by the new signature.
"""

import dataclasses
import warnings

from .check import Check
from .requirements import as_requirements
from .solvers import AugmentedLagrangian, Sequential
from .spec import MeanPlusKStd, Secants, Surface, Tangents, ToleranceProblem, Yield, Zones, adjoint_named

SOLVER_KEYS = ("method", "widths", "max_outer", "inner_steps", "learning_rate")
CHECK_KEYS = ("check_units", "max_checks", "check_key")
ZONE_KEYS = ("band", "start", "min_clearance", "band_range", "fixed")
MODEL_KEYS = ("slope_width", "secant_units", "scatter", "secant_seed", "secant_reach", "log_outputs", "noise_band",
              "surface_box", "surface_width", "surface_rounds")
STATISTIC_KEYS = ("yield_", "n_yield_draws", "statistic", "k", "n_draws", "key", "gradient")
OTHER_KEYS = ("jitter", "output", "cost_model", "allow_proxy")
KNOWN = frozenset(SOLVER_KEYS + CHECK_KEYS + ZONE_KEYS + MODEL_KEYS + STATISTIC_KEYS + OTHER_KEYS)


def from_legacy(pointing, requirement, check, options: dict):
    """`(ToleranceProblem, solver, check)` from the former arguments `pointing`, `requirement`
    and keyword `options` (module docstring), with a `DeprecationWarning`."""
    from .propose import DEFAULT_CHECK

    unknown = sorted(set(options) - KNOWN)
    if unknown:
        raise TypeError(f"propose_design: unknown keyword(s) {', '.join(unknown)}.")
    if check is not DEFAULT_CHECK:
        raise TypeError("propose_design: check= takes a Check with a ToleranceProblem; the former signature takes check_units=.")
    if requirement is None:
        raise TypeError("propose_design: give a ToleranceProblem (or, the former signature, a pointing objective and a requirement).")
    warnings.warn(
        "propose_design(pointing, requirement, **options) is deprecated and goes in the next release: give "
        "propose_design(ToleranceProblem(pointing, requirements, statistic=Yield(...), zones=Zones(...)), Sequential(...), "
        f"check=Check(...)) (tolerax.design.legacy maps each keyword; here: {', '.join(sorted(options)) or 'none'}).",
        DeprecationWarning, stacklevel=3)
    get = options.get
    method = get("method", "sequential")
    if method not in ("augmented-lagrangian", "sequential"):
        raise ValueError(f"propose_design: method must be 'augmented-lagrangian' or 'sequential', got {method!r}.")
    widths = tuple(get("widths", (1e-6, 1e-7)))
    if method == "sequential":
        solver = Sequential(widths, 20 if get("max_outer") is None else int(get("max_outer")))
    else:
        solver = AugmentedLagrangian(widths, 6 if get("max_outer") is None else int(get("max_outer")), int(get("inner_steps", 10)),
                                     float(get("learning_rate", 0.1)))
    yield_ = get("yield_")
    if yield_ is not None:
        statistic = Yield(float(yield_), int(get("n_yield_draws", 16384)))
    else:
        if get("statistic", "mean+kstd") != "mean+kstd":
            raise ValueError(f"propose_design: statistic {get('statistic')!r} is not offered; MeanPlusKStd(k) or Yield(level).")
        statistic = MeanPlusKStd(float(get("k", 1.0)), int(get("n_draws", 4)), get("key"),
                                 adjoint_named(get("gradient", "forward"), "propose_design"))
    units = (200 if yield_ is not None else 0) if get("check_units") is None else int(get("check_units"))
    if units and yield_ is None:
        raise ValueError("propose_design: check_units needs a yield requirement (yield_=...), the thing it checks.")
    if units and method != "sequential":
        raise ValueError("propose_design: a yield requirement's Monte Carlo check needs method='sequential' (or check_units=0).")
    check = Check(units, int(get("max_checks", 3)), get("check_key")) if units else None
    if int(get("surface_rounds", 4)) < 1:
        raise ValueError(f"propose_design: surface_rounds must be >= 1 (1: one response surface), got {get('surface_rounds')!r}.")
    requirements = as_requirements(requirement, get("jitter"), get("output", "pointing_rms"))
    if pointing.uncertain_inputs and get("scatter") is False:
        raise ValueError(f"propose_design: each unit draws {', '.join(pointing.uncertain_inputs)} (the life's spread), whose "
                         "secant fits keep the scatter of what neither the features nor the rate explain: leave scatter on.")
    flagged = any(r.secants for r in requirements) or bool(pointing.uncertain_inputs)
    models = _models(requirements, flagged, options)
    zones = Zones(**{k: options[k] for k in ZONE_KEYS if k in options})
    problem = ToleranceProblem(pointing, tuple(dataclasses.replace(r, model=m) for r, m in zip(requirements, models)), statistic,
                               zones, get("cost_model"), bool(get("allow_proxy", False)))
    return problem, solver, check


def _models(requirements, flagged: bool, options: dict) -> list:
    """One constraint model per requirement as the former keywords set them: tangents (with
    `slope_width`, rescued on secants after a stall) unless secants were flagged (a jitter, a
    `Requirement(secants=True)`, a wear-rate spread) or `secant_units` given; then secants for
    all, on a surface where `surface_box` was given."""
    get = options.get
    if get("secant_units") is None and not flagged:
        if get("surface_box") is not None:
            raise ValueError("propose_design: surface_box needs secant_units (a response surface is fitted over units).")
        return [Tangents(get("slope_width")) for _ in requirements]
    scatter = get("scatter", True if flagged else False)
    logs = set(get("log_outputs", [r.output for r in requirements if r.secants and r.log_fit]))
    twin = get("noise_band") if get("noise_band") is not None else flagged
    common = dict(units=get("secant_units"), scatter=bool(scatter), reach=get("secant_reach"), seed=int(get("secant_seed", 1)),
                  twin=bool(twin))
    if get("surface_box") is not None:  # here secant_units is given or flagged requirements set its default
        return [Surface(box=tuple(get("surface_box")), width=get("surface_width"), rounds=int(get("surface_rounds", 4)),
                        log=r.output in logs, **common) for r in requirements]
    return [Secants(log=r.output in logs, **common) for r in requirements]
