"""The values `tolerax design` and `tolerax tradeoff` hand `propose_design` (`DesignValues`)."""

import dataclasses


@dataclasses.dataclass(frozen=True)
class DesignValues:
    """What `design` and `tradeoff` hand `propose_design`, from the scene file and the flags:
    the `ToleranceProblem`'s parts beside its objective and requirements, the solver, the check,
    and the constraint model every requirement takes: `model` (`--model`, or the scene's one
    name) for all; else each requirement's own (a scene's table by output; `None`: its default,
    `Auto()`). With `secant_units` (`--secant-units K`): a fitted model on K units; where no model
    is named, the automatic one on K units, `Auto(units=K)` (its measurement picks a response
    surface or a line through K units, output by output)."""

    statistic: object
    zones: object
    cost: object
    allow_proxy: bool
    solver: object
    check: object
    model: object = None
    secant_units: int | None = None
    progress: bool = True  # the phase lines (`--quiet`: none)

    def problem(self, pointing, requirements):
        """The `ToleranceProblem` of `pointing` (an objective) and `requirements`."""
        from ..design.requirements import as_requirements
        from ..design.spec import Auto, Secants, ToleranceProblem

        def model(r):
            if self.model is not None:  # --model, or the scene's one name
                return self.model
            if r.model is not None:  # the scene's own for this output (a table by output)
                return r.model if self.secant_units is None or not isinstance(r.model, (Secants, Auto)) else \
                    dataclasses.replace(r.model, units=self.secant_units)
            return None if self.secant_units is None else Auto(units=self.secant_units)  # None: Auto()

        found = tuple(dataclasses.replace(r, model=model(r)) for r in as_requirements(requirements))
        return ToleranceProblem(pointing, found, self.statistic, self.zones, self.cost, self.allow_proxy)
