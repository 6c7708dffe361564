"""The scene-file schema and its checker: the keys each table accepts (the builders' own keyword
arguments, read from their signatures, so a builder argument added later is accepted without
editing this module), types checked against the builders' annotations, ranges by the builders
themselves, and every error naming the file, line, table and key (`SceneFileError`).

`tomllib` reports no line numbers for valid keys, so `_line_of` (`tolerax.io.checker`) finds a key's line by scanning
the text for it inside its table. The schema is documented in docs/scene_files.md.
"""

import inspect
import math

import jax.numpy as jnp

from .._defaults import DESIGN_SOLVERS, JITTER_CUTOFF
from ..physics import contact as _contact
from ..design import cost as _cost, features as _design
from ..physics import gears as _gears
from ..mechanism import scenes as _scenes
from ..mechanism.mechanism import Mechanism
from ..mechanism.structure import Geometry, Inertias
from ..mechanism.scene import STARTS, simulate as _simulate
from ..solve import ACCURATE, NAMED_INTEGRATORS, PID_RULES, SOLVERS, Integrator
from .checker import TOP_KEYS, Checker, SceneFileError, SceneFileNote, _accepts, _for_call, _suggest, check_top  # noqa: F401 (the schema's tables, errors)

# ---------------------------------------------------------------------------------------------
# The schema

BUILDERS = {"antenna": _scenes.antenna, "scan": _scenes.scan}
STAGE_KEYS = tuple(f"{joint}_stage" for joint in Mechanism.JOINTS)
# The structure's tables: their keys are the classes' constructor arguments; a mass is one
# number (kg), an inertia (kg m^2) or an offset (m) three.
STRUCTURE_KEYS = {"geometry": Geometry, "inertias": Inertias}
# Contact laws a stage table may name; their constructor arguments are read from the signatures.
CONTACT_LAWS = {cls.__name__: cls for cls in (_contact.BaiZhao, _contact.HertzLN, _contact.Flores, _contact.AdamsImpact)}

_SIM = inspect.signature(_simulate).parameters
# [run]: simulate()'s window (defaults from its signature), the integrator's settings (each
# `tolerax.Integrator` field, None: not given, so `simulate` chooses), the pointing window `settle`.
RUN_KEYS = {
    "duration": (float, None),
    "start": (str, _SIM["start"].default),
    "n_save": (int, _SIM["n_save"].default),
    **{name: ({"solver": str, "max_steps": int}.get(name, float), None) for name in Integrator.FIELDS},
    "integrator": (str, None),  # a preset by name (NAMED_INTEGRATORS), which the keys above refine; None: "auto"
    "settle": (float, 0.0),
}

# name -> (dims after time, unit, long name); what `timeseries` can write.
SERIES = {
    "pointing_error": ((), "rad", "angle between the actual and the commanded boresight"),
    "joint_angle": (("joint",), "rad", "output angle of each joint"),
    "commanded_angle": (("joint",), "rad", "commanded output angle of each joint"),
    "position_error": (("axis",), "m", "reflector centre minus its commanded position (base frame)"),
    "tracking_speed_error": (("axis",), "rad/s", "reflector angular velocity minus the commanded one (base frame)"),
    "runout": (("joint",), "m", "radial runout of each joint output"),
    "output_force": (("joint",), "N", "radial contact force of each joint's output (carrier) bearing"),
    **{
        f"{joint}_contact": ((f"{joint}_contact_name",), "N", f"normal force of each clearance contact of the {joint} joint")
        for joint in Mechanism.JOINTS
    },
    "momentum": (("axis",), "kg m/s", "linear momentum"),
    "angular_momentum": (("axis",), "kg m^2/s", "angular momentum about the world origin"),
    "kinetic_energy": ((), "J", "kinetic energy"),
}
PLOTS = ("pointing_error", "joint_angle", "output_force", "tracking_speed_error")
OUTPUT_KEYS = {"series": (list, list(SERIES)), "plots": (list, ["pointing_error", "joint_angle"]), "dpi": (int, 120)}
DISTRIBUTIONS = ("uniform", "normal")
TOLERANCE_KEYS = {"band": (float, 10e-6), "bands": (dict, {}), "distribution": (str, "uniform"), "requirement": (float, None),
                  "fixed": (list, []), "cost": (dict, {}), "min_clearance": (float | dict, 5e-6), "band_range": (tuple[float, float], (1e-6, 50e-6)),
                  "model": (str | dict, "auto"), "yield": (float, None), "jitter": (float, None), "jitter_cutoff": (float, JITTER_CUTOFF),
                  "require": (dict, {}), "solver": (str, "sequential"), "check": (int | dict, 200)}
# [tolerances] model: how `tolerax design` linearises every requirement's yield (`tolerax.design.spec`),
# one name for all, or a table of them by output (`model = { pointing_jitter = "surface" }`: the others auto).
MODELS = ("auto", "tangents", "secants", "surface")
# [tolerances] solver: the design solver by its command-line name (`_defaults.DESIGN_SOLVERS`), and
# check: the Monte Carlo check of a yield design (`tolerax.design.check.Check`), its units per
# check, or a table {units, rounds}; 0 for none.
CHECK_KEYS = {"units": (int, 200), "rounds": (int, 3)}
# [life]: the mission's life (`tolerax.design.life.MissionLife`): operating time and wear data.
LIFE_KEYS = {"years": (float, None), "duty": (float, 1.0), "lubricant": (str, "MoS2 sputtered film, vacuum"),
             "estimate": (str, "median"), "points": (int, 2), "flanks": (bool, True),
             "spread": (bool, False)}


def _signature_keys(fn, skip=()):
    return {name: p for name, p in inspect.signature(fn).parameters.items() if name not in skip}


def _build_stage(chk: Checker, data: dict, table: tuple[str, ...]):
    params = _signature_keys(_gears.default_stage)
    chk.keys(data, table, list(params))
    kwargs = {}
    for key, value in data.items():
        if key == "contact_law":
            kwargs[key] = _build_law(chk, value, table + (key,))
            continue
        chk.typed(data, table, key, params[key].annotation)
        kwargs[key] = _for_call(value)
    try:
        return _gears.default_stage(**kwargs)
    except (ValueError, TypeError) as err:
        raise chk.wrap(err, table, data) from None


def _build_structure(chk: Checker, data, table: tuple[str, ...]):
    cls = STRUCTURE_KEYS[table[-1]]
    if not isinstance(data, dict):
        raise chk.error(f"must be a table of {cls.__name__} arguments, got {data!r}.", table[:-1], table[-1])
    params = _signature_keys(cls.__init__, skip=("self",))
    chk.keys(data, table, list(params))
    for key in data:
        chk.typed(data, table, key, float if key.endswith("mass") else tuple[float, float, float])
    try:
        return cls(**{key: _for_call(value) for key, value in data.items()})
    except (ValueError, TypeError) as err:
        raise chk.wrap(err, table, data) from None


def _build_law(chk: Checker, data, table):
    if not isinstance(data, dict):
        raise chk.error(f"must be a table with `law` = one of {', '.join(CONTACT_LAWS)}, got {data!r}.", table[:-1], table[-1])
    if "law" not in data:
        raise chk.error(f"missing key 'law' (one of {', '.join(CONTACT_LAWS)}).", table)
    if data["law"] not in CONTACT_LAWS:
        raise chk.error(f"unknown contact law {data['law']!r}; use one of {', '.join(CONTACT_LAWS)}.", table, "law")
    cls = CONTACT_LAWS[data["law"]]
    params = _signature_keys(cls.__init__, skip=("self",))
    chk.keys(data, table, ["law", *params])
    kwargs = {}
    for key, value in data.items():
        if key != "law":
            chk.typed(data, table, key, float)
            kwargs[key] = value
    try:
        return cls(**kwargs)
    except (ValueError, TypeError) as err:
        raise chk.wrap(err, table, data) from None


def build(chk: Checker, scene: dict):
    table = ("scene",)
    if "kind" not in scene:
        raise chk.error(f"missing key 'kind' (one of {', '.join(BUILDERS)}).", table)
    if scene["kind"] not in BUILDERS:
        raise chk.error(f"unknown scene kind {scene['kind']!r}; use one of {', '.join(BUILDERS)}.", table, "kind")
    builder = BUILDERS[scene["kind"]]
    params = _signature_keys(builder)
    chk.keys(scene, table, ["kind", *params])
    _check_motion_keys(chk, scene, table)
    kwargs = {}
    for key, value in scene.items():
        if key == "kind":
            continue
        if key in STAGE_KEYS:
            if not isinstance(value, dict):
                raise chk.error(f"must be a table of default_stage arguments, got {value!r}.", table, key)
            kwargs[key] = _build_stage(chk, value, table + (key,))
            continue
        if key in STRUCTURE_KEYS:
            kwargs[key] = _build_structure(chk, value, table + (key,))
            continue
        chk.typed(scene, table, key, params[key].annotation)
        kwargs[key] = _for_call(value)
    try:
        model = builder(**kwargs)
        model.check_runnable()  # e.g. nothing to integrate: say so now, not after a compile
    except (ValueError, TypeError) as err:
        raise chk.wrap(err, table, scene) from None
    return model


PLAUSIBLE_AMPLITUDE = 0.3  # rad (17 deg): a scan amplitude above it is noted (`SceneFileNote`), likely degrees typed as radians


def _check_motion_keys(chk: Checker, scene: dict, table):
    """Refuse a motion key the scene's motion ignores (it would be dropped without a word): a
    scan's `amplitude`/`period` beside a tabulated profile; an antenna's `scan_*` keys unless
    `drive = "scan"`, its `profile_*` keys unless `drive = "profile"`."""
    for key in ("amplitude", "scan_amplitude"):
        value = scene.get(key)
        if isinstance(value, (int, float)) and abs(value) > PLAUSIBLE_AMPLITUDE:
            chk.note(f"{value:g} rad is {math.degrees(value):.4g} deg, a wide scan for a pointing mechanism: the file's "
                     f"angles are in radians (for {value:g} deg write {math.radians(value):.6g}). Running it as given.", table, key)
    if scene["kind"] == "scan":
        if "profile_times" in scene or "profile_angles" in scene:
            for key in ("amplitude", "period"):
                if key in scene:
                    raise chk.error(f"the scan follows the tabulated profile (profile_times/profile_angles) and ignores {key!r}: "
                                    "remove it, or the profile.", table, key)
        return
    drive = scene.get("drive", "speed")
    for key, needs in (("scan_amplitude", "scan"), ("scan_period", "scan"), ("profile_times", "profile"), ("profile_angles", "profile")):
        if key in scene and drive != needs:
            raise chk.error(f"drive = {drive!r} ignores {key!r} (it is read with drive = {needs!r}): remove it, or set the "
                            "drive.", table, key)


def _check_run(chk: Checker, run: dict):
    table = ("run",)
    chk.keys(run, table, list(RUN_KEYS), required=("duration",))
    for key in run:
        chk.typed(run, table, key, RUN_KEYS[key][0])
    value = {key: run.get(key, default) for key, (_, default) in RUN_KEYS.items()}
    for key in ("duration", "rtol", "atol", "dt0", "dtmax", "dtmin", "fixed_step"):
        if key in run and not (math.isfinite(run[key]) and run[key] > 0):
            raise chk.error(f"must be a positive finite number, got {run[key]!r}.", table, key)
    for key, (ok, rule) in PID_RULES.items():
        x = value[key]
        if x is not None and not (math.isfinite(x) and ok(x)):
            raise chk.error(f"must be a finite number {rule}, got {x!r} (the default (0, 1) is an I-controller, "
                            "(0.3, 0.3) a PI controller).", table, key)
    if value["solver"] is not None and value["solver"] not in SOLVERS:
        raise chk.error(f"solver {value['solver']!r} is unknown; use one of {sorted(SOLVERS)}, or leave the run settings out "
                        "and the integrator is chosen from the scene (docs/scene_files.md).", table, "solver")
    if value["integrator"] is not None and value["integrator"] not in ("auto", *NAMED_INTEGRATORS):
        raise chk.error(f"integrator {value['integrator']!r} is unknown; use 'auto' (chosen from the scene, the default) or "
                        + ", ".join(repr(n) for n in NAMED_INTEGRATORS) + " (tolerax.solve.NAMED_INTEGRATORS), which the "
                        "other [run] settings given refine.", table, "integrator")
    if value["start"] not in STARTS:
        raise chk.error(f"start={value['start']!r} is unknown; use one of {STARTS}.", table, "start")
    if value["n_save"] < 2:
        raise chk.error(f"must be at least 2 (the start and the end), got {value['n_save']!r}.", table, "n_save")
    if value["max_steps"] is not None and value["max_steps"] < 1:
        raise chk.error(f"must be at least 1, got {value['max_steps']!r}.", table, "max_steps")
    if not (math.isfinite(value["settle"]) and 0.0 <= value["settle"] < value["duration"]):
        raise chk.error(
            f"must satisfy 0 <= settle < duration = {value['duration']!r} s, got {value['settle']!r}.",
            table, "settle" if "settle" in run else "duration",
        )
    steps = {k: ACCURATE.options()[k] if value[k] is None else value[k] for k in ("dt0", "dtmax", "dtmin")}
    if any(k in run for k in steps) and not steps["dtmin"] < steps["dt0"] <= steps["dtmax"]:
        value = value | steps
        raise chk.error(
            f"steps must satisfy dtmin < dt0 <= dtmax, got dtmin={value['dtmin']!r}, dt0={value['dt0']!r}, dtmax={value['dtmax']!r}.",
            table, next((k for k in ("dt0", "dtmax", "dtmin") if k in run), None),
        )


def _check_outputs(chk: Checker, outputs: dict):
    table = ("outputs",)
    chk.keys(outputs, table, list(OUTPUT_KEYS))
    for key in outputs:
        chk.typed(outputs, table, key, OUTPUT_KEYS[key][0])
    for key, allowed in (("series", SERIES), ("plots", PLOTS)):
        for name in outputs.get(key, []):
            if name not in allowed:
                raise chk.error(f"unknown output {name!r}; choose from {', '.join(allowed)}.", table, key)
    if "dpi" in outputs and not 10 <= outputs["dpi"] <= 1200:
        raise chk.error(f"must be between 10 and 1200, got {outputs['dpi']!r}.", table, "dpi")


def _check_tolerances(chk: Checker, tol: dict, model):
    table = ("tolerances",)
    chk.keys(tol, table, list(TOLERANCE_KEYS))
    for key in tol:
        chk.typed(tol, table, key, TOLERANCE_KEYS[key][0])
    if "band" in tol and not (math.isfinite(tol["band"]) and tol["band"] >= 0):
        raise chk.error(f"must be a non-negative finite half-width (m), got {tol['band']!r}.", table, "band")
    models = tol.get("model", "auto")
    from ..design.objectives import EOL, OUTPUTS

    outputs = [*OUTPUTS, *(o + EOL for o in OUTPUTS)]
    for output, name in (models.items() if isinstance(models, dict) else [(None, models)]):
        where = (table + ("model",), output) if output is not None else (table, "model")
        if output is not None and output not in outputs:
            raise chk.error(f"{output!r} is not an output a requirement can be on{_suggest(output, outputs)}; the outputs: "
                            f"{', '.join(outputs)}.", *where)
        if name not in MODELS:
            raise chk.error(f"model={name!r} is unknown; use one of {MODELS} (how a design linearises each requirement's "
                            "yield: tolerax.design.spec), one for all or a table by output.", *where)
    if tol.get("solver", "sequential") not in DESIGN_SOLVERS:
        raise chk.error(f"solver={tol['solver']!r} is unknown; use one of {tuple(DESIGN_SOLVERS)} (the design solver: "
                        f"tolerax.{', tolerax.'.join(DESIGN_SOLVERS.values())}){_suggest(tol['solver'], list(DESIGN_SOLVERS))}.",
                        table, "solver")
    if tol.get("solver") == "augmented-lagrangian" and "yield" in tol:
        raise chk.error("the augmented Lagrangian takes no yield (its Monte Carlo check re-solves the design, which it does "
                        "not): use solver = \"sequential\" or \"slsqp\", or drop the yield.", table, "solver")
    check = tol.get("check", 200)
    if isinstance(check, dict):
        chk.keys(check, table + ("check",), list(CHECK_KEYS))
        for key in check:
            chk.typed(check, table + ("check",), key, CHECK_KEYS[key][0])
        if check.get("units", 200) < 2 or check.get("rounds", 3) < 1:
            raise chk.error(f"must have units >= 2 (simulated units per check) and rounds >= 1 (checks at most), got {check!r}.",
                            table, "check")
    elif check < 0 or check == 1:
        raise chk.error(f"must be the units per Monte Carlo check (>= 2), 0 for none, or {{units = 200, rounds = 3}}; got {check!r}.",
                        table, "check")
    if tol.get("distribution", "uniform") not in DISTRIBUTIONS:
        raise chk.error(f"distribution={tol['distribution']!r} is unknown; use one of {DISTRIBUTIONS}.", table, "distribution")
    if "requirement" in tol and not (math.isfinite(tol["requirement"]) and tol["requirement"] > 0):
        raise chk.error(f"must be a positive number of arcsec, got {tol['requirement']!r}.", table, "requirement")
    if "yield" in tol and not 0.0 < tol["yield"] < 1.0:
        raise chk.error(f"must be a fraction in (0, 1), e.g. 0.99, got {tol['yield']!r}.", table, "yield")
    for key in ("jitter", "jitter_cutoff"):
        if key in tol and not (math.isfinite(tol[key]) and tol[key] > 0):
            raise chk.error(f"must be a positive number ({'arcsec' if key == 'jitter' else 'Hz'}), got {tol[key]!r}.", table, key)
    if "jitter" in tol and "yield" not in tol:
        raise chk.error("a jitter requirement needs a yield (both are met by the same fraction of units): add yield = 0.9, say.",
                        table, "jitter")
    from ..design.requirements import Requirement

    for output, limit in tol.get("require", {}).items():
        if output in ("pointing_rms", "pointing_jitter"):
            raise chk.error(f"{output} has its own key ({'requirement' if output == 'pointing_rms' else 'jitter'} = ...); "
                            "require holds the further requirements (pointing_peak, pointing_rms_eol, ...).", table + ("require",), output)
        try:
            Requirement(output, float(limit) if isinstance(limit, (int, float)) and not isinstance(limit, bool) else math.nan)
        except ValueError as err:
            raise chk.error(str(err), table + ("require",), output) from None
    names = _design.design_names(model)
    minima = tol.get("min_clearance", 5e-6)
    for name, value in (minima.items() if isinstance(minima, dict) else [(None, minima)]):
        if name is not None and name not in names:
            raise chk.error(f"{name!r} is not a design feature of this scene{_suggest(name, names)}; its features: "
                            f"{', '.join(names) or 'none'}.", table + ("min_clearance",), name)
        if not (_accepts(value, float) and math.isfinite(value) and value >= 0):
            raise chk.error(f"must be a non-negative finite clearance (m), got {value!r}.", table + ("min_clearance",) if name else table,
                            name or "min_clearance")
    if "band_range" in tol and not (0 < tol["band_range"][0] <= tol["band_range"][1] and math.isfinite(tol["band_range"][1])):
        raise chk.error(f"must be [smallest, largest] half-widths (m) with 0 < smallest <= largest, got {tol['band_range']!r}.",
                        table, "band_range")
    for name in tol.get("fixed", []):
        if name not in names:
            raise chk.error(f"{name!r} is not a design feature of this scene{_suggest(name, names)}; its features: "
                            f"{', '.join(names) or 'none'}.", table, "fixed")
    if tol.get("cost"):
        cost_model(chk, tol["cost"])
    sub = table + ("bands",)
    for name, value in tol.get("bands", {}).items():
        if name not in names:
            raise chk.error(f"{name!r} is not a design feature of this scene{_suggest(name, names)}; its features: "
                            f"{', '.join(names) or 'none'}.", sub, name)
        if not (_accepts(value, float) and math.isfinite(value) and value >= 0):
            raise chk.error(f"must be a non-negative finite half-width (m), got {value!r}.", sub, name)


def cost_model(chk: Checker | None, cost: dict):
    """The `GradeTable` of a `[tolerances.cost]` table (`grades`, `costs`: a shop's relative
    price per ISO grade); with a checker, its errors name the line."""
    table = ("tolerances", "cost")
    try:
        if chk is not None:
            chk.keys(cost, table, ["grades", "costs"], required=("grades", "costs"))
            for key in ("grades", "costs"):
                if not (isinstance(cost[key], list) and all(_accepts(v, float) for v in cost[key])):
                    raise chk.error(f"must be a list of numbers, got {cost[key]!r}.", table, key)
        return _cost.GradeTable(cost["grades"], cost["costs"])
    except ValueError as err:
        if chk is None or isinstance(err, SceneFileError):
            raise
        raise chk.wrap(err, table, cost) from None


def _apply_design(chk: Checker, design: dict, model):
    """`model` with the nominal clearances and backlash of `[design]` (m, by feature name: what
    `tolerax design` writes into its proposal) set over the builder's values."""
    if not design:
        return model
    names = _design.design_names(model)
    values = [float(v) for v in _design.design_of(model)]
    for name, value in design.items():
        if name not in names:
            raise chk.error(f"{name!r} is not a design feature of this scene{_suggest(name, names)}; its features: "
                            f"{', '.join(names) or 'none'}.", ("design",), name)
        if not (_accepts(value, float) and math.isfinite(value) and value >= 0):
            raise chk.error(f"must be a non-negative finite clearance or backlash (m), got {value!r}.", ("design",), name)
        values[names.index(name)] = float(value)
    return _design.with_design(model, jnp.asarray(values))


def validate(data: dict, text: str, source: str):
    """Check `data` (parsed from `text`); return the model it builds."""
    chk = Checker(text, source)
    check_top(chk, data)
    _check_run(chk, data["run"])
    _check_outputs(chk, data.get("outputs", {}))
    model = _apply_design(chk, data.get("design", {}), build(chk, data["scene"]))
    _check_tolerances(chk, data.get("tolerances", {}), model)
    if "life" in data:
        life(chk, data["life"], model)
    return model


def life(chk: Checker | None, table_data: dict, model):
    """The `MissionLife` of a `[life]` table (`years` in orbit, `duty` the fraction of them in the
    simulated regime, `lubricant` a `tolerax.physics.wear.LUBRICANTS` name at `estimate`, `points`
    life points); with a checker, its errors name the line."""
    from ..design.life import MissionLife, spread_of_lubricant, worn_joints
    from ..physics import wear as _wear

    table = ("life",)
    if chk is not None:
        chk.keys(table_data, table, list(LIFE_KEYS), required=("years",))
        for key in table_data:
            chk.typed(table_data, table, key, LIFE_KEYS[key][0])
        value = {key: table_data.get(key, default) for key, (_, default) in LIFE_KEYS.items()}
        if not (math.isfinite(value["years"]) and value["years"] >= 0):
            raise chk.error(f"must be a non-negative number of years, got {value['years']!r}.", table, "years")
        if not 0.0 <= value["duty"] <= 1.0:
            raise chk.error(f"is the fraction of the life spent in the simulated regime, 0-1; got {value['duty']!r}.", table, "duty")
        if value["lubricant"] not in _wear.LUBRICANTS:
            raise chk.error(f"unknown lubricant {value['lubricant']!r}{_suggest(value['lubricant'], _wear.LUBRICANTS)}; known: "
                            f"{', '.join(sorted(_wear.LUBRICANTS))}.", table, "lubricant")
        if value["estimate"] not in _wear.ESTIMATES:
            raise chk.error(f"estimate={value['estimate']!r} is unknown; use one of {_wear.ESTIMATES}.", table, "estimate")
        if value["points"] < 1:
            raise chk.error(f"must be at least 1 (Euler steps over the life), got {value['points']!r}.", table, "points")
    else:
        value = {key: table_data.get(key, default) for key, (_, default) in LIFE_KEYS.items()}
    wear = _wear.ArchardWear.from_lubricant(value["lubricant"], value["estimate"], flanks=bool(value["flanks"]))
    spread = spread_of_lubricant(value["lubricant"], value["estimate"]) if value["spread"] else None
    result = MissionLife.from_years(value["years"], value["duty"], wear, int(value["points"]), spread)
    if chk is not None and not worn_joints(model, result):
        raise chk.error("nothing wears in this scene: [life] needs a joint at planetary fidelity with clearance contacts "
                        "(ideal and lumped joints do not wear).", table, None)
    return result
