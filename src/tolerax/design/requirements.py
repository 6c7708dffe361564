"""Requirements as data: what a tolerance design must meet.

A `Requirement` names one scalar output of the pointing objective (`PointingObjective`'s
outputs: `pointing_rms`, `pointing_peak`, `pointing_smooth_peak`, `tracking_speed_rms`,
`pointing_jitter`, or one a user's metric adds), its limit, and how tightly the optimiser holds
it. An output added by a user's metric (`AbstractMetric`, `PointingObjective(metrics=...)`) takes
a requirement the same way. A design problem holds any number of them; each is met by the problem's statistic (mean +
k std over a few units, or the yield $Y$: $P(\\text{output} \\le \\text{limit}) \\ge Y$, each
requirement on its own, marginal yields). The optimiser, the Monte Carlo checks, the report,
`proposal.toml` and the command line treat every requirement alike.

A kind of requirement is a value, not a class: which output, which limit. An output whose
unit-to-unit scatter the features do not explain (the jitter of a rattling stage: chaotic) is
linearised over units with that scatter (its constraint model, `model=`: `Secants`, `Surface`;
`Auto()`, the default, gives an output a response surface where it measures that scatter at
the start, and, with nothing measured, the outputs in `SCATTERING_OUTPUTS`); its tolerance then
defaults to twice its fit's standard error.
"""

import contextvars
import dataclasses
import math
import warnings

from .objectives import UNITS

# Outputs whose scatter from unit to unit is mostly not carried by the features (chaotic
# rattle): linearised by secants over units, with the fit's residual scatter, where no
# measurement says otherwise (`Auto()` measures it: `tolerax.design.probe.scatter_share`).
SCATTERING_OUTPUTS = frozenset({"pointing_jitter"})
# Of those, outputs whose scatter grows with their level: their secant line is fitted to their
# logarithm (a relative scatter). Empty: the log fit is opt-in (`Secants(log=True)`).
LOG_FIT_OUTPUTS = frozenset()

NAMES = {
    "pointing_rms": "RMS pointing error", "pointing_peak": "peak pointing error", "pointing_smooth_peak": "smooth peak pointing error",
    "tracking_speed_rms": "RMS tracking speed error", "pointing_jitter": "jitter",
}


@dataclasses.dataclass(frozen=True)
class Requirement:
    """`output` at most `limit` (in the output's unit: arcsec, or arcsec/s for a speed).

    **Arguments:**

    - `output`: the name of a scalar output of the pointing objective (`OUTPUTS` in
      `tolerax.design.objectives`), e.g. `"pointing_rms"` or `"pointing_jitter"`.
    - `limit`: the requirement, finite and > 0.
    - `tol` (optional): relative tolerance the optimiser holds it to, in (0, 1); default 1 %,
      or for a secant-fitted output twice its fit's standard error at the start (at least 1 %,
      at most 50 %).
    - `secants`, `log_fit`: deprecated spellings of `model=Secants()` and
      `model=Secants(log=True)` (a `DeprecationWarning` where given otherwise than their
      defaults). Read back, they say how the requirement is linearised: over units
      (`secants`: by default for the outputs in `SCATTERING_OUTPUTS`, and for every
      requirement of a design where one is), on the output's logarithm (`log_fit`).
    - `label` (optional): its name in reports; default from the output.
    - `unit` (optional): the output's unit in reports; default the objective's (`propose_design`
      takes it from `PointingObjective.units`, a metric's own included).
    - `model` (optional): its constraint model, how its yield is linearised
      (`tolerax.design.spec`: `Tangents()`, `Secants()`, `Surface()`; default `Auto()`: tangents,
      moved to secants where they stall, and the `Surface` recipe for a scattering output);
      `secants` and `log_fit` are its older spelling (`Secants(log=...)`).
    - `fidelity` (optional): the joint fidelity it is read at, `"any"`, `"lumped"`,
      `"planetary-scaled"` or `"planetary"`; default `"planetary"` (the full stage) for the
      vibration outputs (`tolerax.design.fidelity.VIBRATION_OUTPUTS`: the jitter), else
      `"any"`. `propose_design` refuses a scene that models a joint below it
      (`tolerax.design.fidelity.check_fidelity`).
    """

    output: str = "pointing_rms"
    limit: float = math.nan
    tol: float | None = None
    secants: bool | None = None
    log_fit: bool | None = None
    label: str | None = None
    unit: str | None = None
    fidelity: str | None = None
    model: object = None

    def __post_init__(self):
        if not isinstance(self.output, str) or not self.output:
            raise ValueError(f"Requirement: output must be the name of an objective's output, e.g. 'pointing_rms', got {self.output!r}.")
        limit = float(self.limit)
        if not (math.isfinite(limit) and limit > 0):
            raise ValueError(f"Requirement({self.output!r}): limit must be finite and > 0 ({self.unit}), got {self.limit!r}.")
        object.__setattr__(self, "limit", limit)
        if self.tol is not None and not 0.0 < float(self.tol) < 1.0:
            raise ValueError(f"Requirement({self.output!r}): tol must be in (0, 1) (relative), got {self.tol!r}.")
        given = (self.secants, self.log_fit)
        if self.secants is None:
            object.__setattr__(self, "secants", self.output in SCATTERING_OUTPUTS)
        if self.log_fit is None:
            object.__setattr__(self, "log_fit", bool(self.secants) and self.output in LOG_FIT_OUTPUTS)
        elif self.log_fit and not self.secants:
            raise ValueError(f"Requirement({self.output!r}): log_fit (a line through the logarithm over units) needs secants=True.")
        if not _RESOLVING.get() and ((given[0] is not None and bool(given[0]) != (self.output in SCATTERING_OUTPUTS))
                                     or (given[1] is not None and bool(given[1]) != (self.output in LOG_FIT_OUTPUTS))):
            warnings.warn(f"Requirement({self.output!r}, secants=..., log_fit=...) is deprecated and goes in the next release: "
                          "give its constraint model, model=tx.Secants() (log_fit: tx.Secants(log=True)) or tx.Tangents().",
                          DeprecationWarning, stacklevel=3)
        if self.unit is None:
            object.__setattr__(self, "unit", UNITS.get(self.output, "arcsec"))
        if self.fidelity not in (None, "any", "lumped", "planetary-scaled", "planetary"):
            raise ValueError(f"Requirement({self.output!r}): fidelity must be 'any', 'lumped', 'planetary-scaled' or 'planetary' "
                             f"(the joint fidelity it is read at), got {self.fidelity!r}.")

    @property
    def name(self) -> str:
        """The requirement's name in reports."""
        return self.label or NAMES.get(self.output, self.output.replace("_", " "))

    def text(self) -> str:
        """E.g. `"RMS pointing error <= 700 arcsec"`."""
        return f"{self.name} <= {self.limit:g} {self.unit}"


_RESOLVING = contextvars.ContextVar("tolerax_resolving_requirements", default=False)


def resolved(requirement: Requirement, **changes) -> Requirement:
    """`dataclasses.replace(requirement, **changes)` for `propose_design`'s own bookkeeping
    (how each requirement is linearised, `secants` and `log_fit`): no deprecation warning."""
    token = _RESOLVING.set(True)
    try:
        return dataclasses.replace(requirement, **changes)
    finally:
        _RESOLVING.reset(token)


def as_requirements(requirement, jitter=None, output: str = "pointing_rms") -> tuple[Requirement, ...]:
    """The requirements of `propose_design`'s arguments: a number (the limit of `output`,
    by default the RMS pointing error, arcsec), a `Requirement`, or a sequence of them; `jitter`
    (arcsec, optional) adds a jitter requirement (the older spelling of
    `Requirement("pointing_jitter", jitter)`)."""
    if isinstance(requirement, Requirement):
        found = [requirement]
    elif isinstance(requirement, (list, tuple)):
        found = [r if isinstance(r, Requirement) else Requirement(output, r) for r in requirement]
    else:
        found = [Requirement(output, requirement)]
    if jitter is not None:
        found.append(Requirement("pointing_jitter", jitter))
    outputs = [r.output for r in found]
    if not found or len(set(outputs)) != len(outputs):
        raise ValueError(f"propose_design: give one requirement or more, each on its own output; got outputs {outputs}.")
    return tuple(found)
