"""Whether a design run's answer is a proposal, and if not, why not and what would change it.

A run ends in one of these states (`diagnose`):

- `"converged"`: the optimiser's stopping test passed at a design that meets every requirement,
  and, where a Monte Carlo check of a yield was run, it found a yield whose 95 % Wilson interval
  reaches the yield asked for and a linear model within `MODEL_OFF` of the units.
- `"infeasible"`: no design within the bounds meets a requirement: the tightest ones (every band
  at its smallest half-width, every lower limit at its smallest or on the bound that lowers the
  output by the sign of its sensitivity at the best design reached) miss it too, as does the
  best design reached. (Tightest by the drawings, not proven by search: a response that falls
  as a clearance opens beyond what its sensitivity shows could hide a feasible design.)
- `"check missed"`: the optimiser met the linearised requirement, but fresh simulated units do
  not: the yield asked for lies above the check's Wilson interval; or the linear model's
  quantile is off from the units' by more than half the requirement (`MODEL_OFF`), either way.
  The linear model does not hold over the zones.
- `"noise-limited"`: not converged where the gradients are estimates (slopes fitted over a few
  units of a chaotic response): the stop could not tell an improvement from the fits' noise;
  or two independent sets of secant units give designs whose costs differ by more than the
  requirements' tolerances resolve (`Secants(twin=True)`, the default of a model fitted over units).
- `"not converged"`: the iteration budget ran out first.

Only `"converged"` is a proposal; the others report the best design reached and say what would
change the outcome (bounds, requirement, units, iterations).
"""

import enum

import numpy as np

from .types import Design


class DesignStatus(str, enum.Enum):
    """What a design's answer is (`DesignReport.status`), as diffrax's `RESULTS` says what a
    solve's is: a proposal (`CONVERGED`) or why the best design reached is not one (above). A
    string too: `status == "converged"` holds, and it prints and serialises as its value."""

    CONVERGED = "converged"
    INFEASIBLE = "infeasible"
    CHECK_MISSED = "check missed"
    NOISE_LIMITED = "noise-limited"
    NOT_CONVERGED = "not converged"

    def __str__(self) -> str:
        return self.value

    def __format__(self, spec: str) -> str:
        return format(self.value, spec)


STATUSES = tuple(s.value for s in DesignStatus)


def _excess(value: float, requirement: float) -> str:
    ratio = value / requirement
    return f"{ratio - 1:+.0%} over it" if ratio < 2 else f"{ratio:.3g} times it"


def tightest(lower: Design, upper: Design, sensitivity=None) -> Design:
    """A tightest design in the box `[lower, upper]` (`Design(lower limit, band)`, m): every
    band at its smallest, every lower limit at its smallest, or, given `sensitivity` (arcsec/m
    over the lower limits, one row per output; rows are summed), on the bound that lowers the
    output by its sign."""
    if sensitivity is None:
        return Design(np.asarray(lower.nominal), np.asarray(lower.band))
    a = np.sum(np.atleast_2d(np.asarray(sensitivity, dtype=float)), axis=0)
    limit = np.where(a < 0, np.asarray(upper.nominal), np.asarray(lower.nominal))
    return Design(limit, np.asarray(lower.band))


def tightest_reach(evaluate, lower: Design, upper: Design, sensitivity=None) -> tuple[list[Design], np.ndarray]:
    """The tightest designs (`tightest`: without `sensitivity`, and with it where given) and the
    values `evaluate(x)` gives there (one row per design, one column per output): what the
    bounds allow at best, the test of infeasibility before a design (`propose_design`) and after
    one (`diagnose`)."""
    designs = [tightest(lower, upper)] + ([] if sensitivity is None else [tightest(lower, upper, sensitivity)])
    return designs, np.array([np.atleast_1d(np.asarray(evaluate(x), dtype=float)) for x in designs])


MODEL_OFF = 0.5  # a check whose linear and simulated quantiles differ by more than this fraction of the requirement


# A cost that moved by less than this (relative) over the last SETTLED_STEPS steps has settled:
# the diagnosis of a design that met its requirements without passing its stopping test then says
# that more iterations would not lower it (the status is unchanged: the stopping test decides).
SETTLED, SETTLED_STEPS = 0.01, 5


def diagnose(*, objective, requirement, tol, converged, iterations, labels, evaluate=None, lower=None, upper=None,
             sensitivity=None, checks=(), yield_=None, noisy=False, bounds_text="", stalled=False,
             solver=None, settled=None) -> tuple[str, str]:
    """`(status, diagnosis)` of a design run (module docstring); the diagnosis is empty when
    converged.

    **Arguments:**

    - `objective`, `requirement`, `tol`: per requirement, the value reached (arcsec), the
      requirement it was held to (arcsec) and its relative tolerance (arrays of one shape).
    - `converged`: the optimiser's own stopping test; `iterations`: gradients it used.
    - `labels`: a name per requirement for the text (e.g. "RMS pointing 99.0 % quantile").
    - `evaluate(x) -> values` (per requirement, arcsec), `lower`, `upper` (`Design` boxes, m),
      `sensitivity` (arcsec/m over the lower limits, a row per requirement): to test
      infeasibility at the tightest designs (`tightest`) where the best design misses; two
      evaluations.
    - `checks`: the returned design's Monte Carlo checks (`YieldCheck`, one per requirement);
      `yield_`: the yield asked for.
    - `noisy`: the gradients are estimates (secant fits); `stalled`: the optimiser's steps
      stopped being accepted at its smallest trust region (`OptimisationResult.stalled`).
    - `bounds_text`: what the user sets the bounds with (named in the advice).
    - `solver`: the design solver that ran (`AbstractDesignMethod`; default `Sequential`): its
      own options are the ones the advice names.
    - `settled` (optional): the relative spread of the cost over the last `SETTLED_STEPS` steps
      at the last width; at most `SETTLED` on a design that meets its requirements, the advice is
      that more iterations would not lower the cost (not that they might).
    """
    name, budget = (("Sequential", "max_gradients") if solver is None else (type(solver).__name__, solver.budget))
    more_iterations = f"more iterations ({name}({budget}=...), --outer)"
    wider = f"a wider first smoothing width ({name}(widths=...), --widths)"
    wider_last = f"a wider last smoothing width ({name}(widths=...), --widths)"
    secants = "model=Secants(units=...), --secant-units" + (
        "" if solver is None or solver.fitted else f"; with Sequential(), as {name} takes tangent slopes only")
    f, r, t = (np.atleast_1d(np.asarray(v, dtype=float)) for v in (objective, requirement, tol))
    t = np.broadcast_to(t, r.shape)
    missing = f > r * (1 + t)
    if np.any(missing) and evaluate is not None:
        # The tightest designs: every lower limit at its minimum, and on the bounds its sensitivity
        # says lower the output (which may be noise); the best of them and of the design reached.
        reach = np.min(np.vstack([tightest_reach(evaluate, lower, upper, sensitivity)[1], f]), axis=0)
        out = reach > r * (1 + t)
        if np.any(out):
            k = int(np.argmax(np.where(out, reach / r, -np.inf)))
            return "infeasible", (
                f"No design within the bounds meets the {labels[k]} requirement of {r[k]:.4g} arcsec: the tightest designs (every "
                f"band at its smallest, the lower limits at their smallest or on the bounds their sensitivities say lower it) and "
                f"the best design reached (shown below, {f[k]:.4g}) reach {reach[k]:.4g} arcsec at best ({_excess(reach[k], r[k])}). "
                f"To change it: a requirement of at least {reach[k]:.4g} arcsec, lower functional minima or a smaller smallest "
                f"band{bounds_text}, or a stiffer mechanism (the sensitivities below say which features drive it).")
    if np.any(missing):
        k = int(np.argmax(np.where(missing, f / r, -np.inf)))
        how = (f"stalled after {iterations} gradients (its steps stopped being accepted at the smallest trust region)" if stalled
               else f"after {iterations} gradients")
        return ("noise-limited" if noisy else "not converged"), (
            f"The optimiser {how}, and the best design reached misses the {labels[k]} requirement ({f[k]:.4g} against "
            f"{r[k]:.4g} arcsec)" + (", though the tightest designs in the bounds meet it" if evaluate is not None else "")
            + ". To change it: "
            + ("" if stalled else more_iterations + ", ")
            + wider + ", or "
            + ("more units in the model that fitted the slopes (its units=..., --secant-units, which keeps the model): they are "
               "fits over units of a chaotic response." if noisy else f"slopes fitted over units ({secants})."))
    for k, check in enumerate(checks):
        if abs(check.quantile_linear - check.quantile_simulated) > MODEL_OFF * check.requirement:
            return "check missed", (
                f"The linear model of the {labels[k]} does not hold over these zones: on {check.n - check.n_failed} fresh simulated "
                f"units its {check.q:.1%} quantile reads {check.quantile_linear:.4g} arcsec where the units' is "
                f"{check.quantile_simulated:.4g} (yield {check.yield_simulated:.3f} [{check.interval[0]:.3f}, {check.interval[1]:.3f}] "
                f"at {check.requirement:.4g} arcsec), so the design was optimised on a wrong model. To change it: fit it over "
                f"units ({secants}), take the slopes at a wider smoothing width (Tangents(slope_width=...)), or narrow the "
                "band range.")
        if check.missed:  # checks are of yield designs: check.q is the yield asked
            return "check missed", (
                f"The optimiser met the linearised {labels[k]} requirement, but {check.n - check.n_failed} fresh simulated units "
                f"do not: yield {check.yield_simulated:.3f} [{check.interval[0]:.3f}, {check.interval[1]:.3f}] (95 % Wilson) "
                f"against {yield_:.1%} asked; {check.q:.1%} quantile simulated {check.quantile_simulated:.4g}, linear model "
                f"{check.quantile_linear:.4g} arcsec. The linear model does not hold over these zones. To change it: fit it "
                f"over units ({secants}), narrow the band range, or allow more checks (Check(rounds=...)).")
    if not converged and stalled:
        return ("noise-limited" if noisy else "not converged"), (
            f"The design meets the requirements but the optimiser stalled after {iterations} gradients: its steps stopped "
            "being accepted at the smallest trust region, so the linear model does not predict the response even over tiny "
            "steps (rough at this smoothing width, or noisy); a cheaper design may exist. To change it: a wider smoothing "
            f"width first ({name}(widths=...), --widths), or "
            + ("more units in the model that fitted the slopes (its units=..., --secant-units, which keeps the model)." if noisy
               else f"fit the slopes over units ({secants})."))
    if not converged and settled is not None and settled <= SETTLED and not noisy:
        return "not converged", (
            f"The design meets the requirements and its cost has settled (within {settled:.2%} over its last {SETTLED_STEPS} "
            f"steps), but its stopping test did not pass within {iterations} gradients: at the last smoothing width the "
            "objective is rough at the steps' scale (impacts), and the optimality test reads that roughness; more iterations "
            "would move the design about, not lower its cost. To accept the best design reached: the command line's "
            f"--allow-unconverged writes it as proposal.toml. To change it: {wider_last}, which judges the design on a smoother "
            "model (farther from the exact contacts).")
    if not converged:
        return ("noise-limited" if noisy else "not converged"), (
            f"The design meets the requirements but its stopping test did not pass within {iterations} gradients: a cheaper "
            "design may exist. To change it: " + more_iterations
            + (", the same model on more units (its units=..., --secant-units, which keeps the model)" if noisy else "") + ".")
    return "converged", ""
