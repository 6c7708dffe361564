"""The design problem a scene file states (`SceneFile.problem()`): its objective, requirements,
statistic, zones and cost read from the file alone, each piece by one function that
`tolerax design` calls too, so a scene file gives one problem in Python and on the command line.

The `[tolerances]` keys (docs/scene_files.md) and what they become:

- `requirement` (arcsec): `Requirement("pointing_rms", requirement)`, the first requirement;
  `require = {output = limit}`: one more `Requirement` per output; `jitter` (arcsec, with a
  `yield`): `Requirement("pointing_jitter", jitter)`, the objective's jitter read above
  `jitter_cutoff` (Hz). An end-of-life output (`..._eol`) carries the scene's `[life]`; else the
  objective is at the beginning of life.
- `yield`: the statistic `Yield(yield)`; without it `MeanPlusKStd()` (mean + 1 std over a few
  units, no check).
- `model`: every requirement's constraint model (`"auto"`, the default: `Auto()`), or a table of
  them by output (`model = { pointing_jitter = "surface" }`: the outputs it does not name auto).
- `band`/`bands`/`distribution` (the starting zones), `min_clearance`, `band_range`, `fixed`:
  the `Zones`; `cost = {grades, costs}`: a shop's `GradeTable` (default the ISO 286 law).

Beside the problem, how it is solved (`SceneFile.solver()`, `SceneFile.check()`, read by
`solver_of` and `check_of`): `solver` names the design solver (`"sequential"`, the default:
`Sequential()`; `"augmented-lagrangian"`; `"slsqp"`), `check` the Monte Carlo check of a yield
design (its units per check, default 200, 0 for none, or `{units, rounds}`: `Check(units,
rounds)`). So `tx.propose_design(f.problem(), f.solver(), check=f.check())` is what `tolerax
design` on the file does with no option.
"""

import dataclasses

from .schema import TOLERANCE_KEYS, SceneFileError


def tolerance_table(scene_file) -> dict:
    """The scene file's `[tolerances]` table (empty where it has none)."""
    return scene_file.data.get("tolerances", {})


def zones_of(scene_file):
    """The `Zones` of the scene's `[tolerances]`: its zones (`SceneFile.tolerances()`) as the
    start, the functional minima (one number, or per feature with the default elsewhere), the
    half-width range and the fixed features."""
    from ..design.features import design_names
    from ..design.spec import Zones

    tol = tolerance_table(scene_file)
    minima = tol.get("min_clearance", TOLERANCE_KEYS["min_clearance"][1])
    if isinstance(minima, dict):
        minima = [minima.get(name, TOLERANCE_KEYS["min_clearance"][1]) for name in design_names(scene_file.build())]
    return Zones(start=scene_file.tolerances(), min_clearance=minima,
                 band_range=tuple(tol.get("band_range", TOLERANCE_KEYS["band_range"][1])), fixed=tuple(tol.get("fixed", [])))


def cost_of(scene_file):
    """The cost model of `[tolerances] cost` (a shop's price per grade, `GradeTable`), or `None`
    (the ISO 286 law, `IsoGrade()`) without one."""
    tol = tolerance_table(scene_file)
    if not tol.get("cost"):
        return None
    from .schema import cost_model

    return cost_model(None, tol["cost"])


def model_of(name: str):
    """The constraint model a scene's `[tolerances] model` (or `tolerax design --model`) names:
    `None` for `"auto"` (each requirement's default, `Auto()`)."""
    from ..design import spec

    return {"auto": None, "tangents": spec.Tangents(), "secants": spec.Secants(), "surface": spec.Surface()}[name]


def further_requirements(scene_file) -> list:
    """The `[tolerances] require` table's `Requirement`s (output -> limit), in its order."""
    from ..design.requirements import Requirement

    return [Requirement(output, float(limit)) for output, limit in tolerance_table(scene_file).get("require", {}).items()]


def problem_of(scene_file):
    """The `ToleranceProblem` `scene_file` states (module docstring): what `tolerax design` on it
    with no option solves. A scene without a `requirement` is refused, as is an end-of-life
    requirement without a `[life]`."""
    from ..design.requirements import Requirement
    from ..design.spec import MeanPlusKStd, ToleranceProblem, Yield

    tol = tolerance_table(scene_file)
    if tol.get("requirement") is None:
        raise SceneFileError(f"scene {scene_file.name!r} sets no RMS pointing requirement (arcsec), so it states no design "
                             "problem: add one, e.g. requirement = 900.0.", scene_file.source, None, "tolerances", "requirement")
    level, jitter = tol.get("yield"), tol.get("jitter")  # a jitter without a yield: refused when the file was read
    cutoff = None if jitter is None else float(tol.get("jitter_cutoff", TOLERANCE_KEYS["jitter_cutoff"][1]))
    requirements = [Requirement("pointing_rms", float(tol["requirement"])), *further_requirements(scene_file),
                    *([Requirement("pointing_jitter", float(jitter))] if jitter is not None else [])]
    eol = any(r.output.endswith("_eol") for r in requirements)
    if eol and scene_file.life is None:
        raise SceneFileError("an end-of-life requirement (..._eol) needs a [life] table in the scene file "
                             "(docs/scene_files.md).", scene_file.source, None, "tolerances", "require")
    if level is not None:  # one model name for every requirement, or a table of them by output (the others auto)
        models = tol.get("model", "auto")
        named, default = (models, "auto") if isinstance(models, dict) else ({}, models)
        requirements = [dataclasses.replace(r, model=model_of(named.get(r.output, default))) for r in requirements]
    # A [life] costs its points + 1 runs per unit: carried only where a requirement reads the end of life.
    objective = scene_file.objective(jitter_cutoff=cutoff, **({} if eol else {"life": None}))
    return ToleranceProblem(objective, tuple(requirements), MeanPlusKStd() if level is None else Yield(float(level)),
                            zones_of(scene_file), cost_of(scene_file))


def solver_of(scene_file, name: str | None = None, **options):
    """The design solver `[tolerances] solver` names (or `name`, the command line's `--solver`,
    over it), built with `options` (its class's fields: `widths`, a budget)."""
    from ..design import solvers
    from .._defaults import DESIGN_SOLVERS

    name = name or tolerance_table(scene_file).get("solver", TOLERANCE_KEYS["solver"][1])
    return getattr(solvers, DESIGN_SOLVERS[name])(**options)


def check_of(scene_file, units: int | None = None, **options):
    """The Monte Carlo check `[tolerances] check` states (`units` over its units where given,
    the command line's `--check`; `options`: `Check`'s other fields, e.g. its backend), or
    `None` where it says 0 (a yield design's check; `SceneFile.check()` is `None` without a
    yield)."""
    from ..design.check import Check
    from .schema import CHECK_KEYS

    tol = tolerance_table(scene_file)
    check = tol.get("check", TOLERANCE_KEYS["check"][1])
    table = check if isinstance(check, dict) else {"units": check}
    units = table.get("units", CHECK_KEYS["units"][1]) if units is None else units
    if units == 0:
        return None
    return Check(int(units), int(table.get("rounds", CHECK_KEYS["rounds"][1])), **options)
