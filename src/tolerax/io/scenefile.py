"""Scene files: a mechanism, its run settings, outputs and tolerances described in TOML.

A scene file describes the *builder call* (`antenna(...)` or `scan(...)`, with `default_stage`
keyword arguments for each joint's gear data), not the model's pytree: the file stays readable
and stable while the internals change. The schema is documented in docs/scene_files.md. The keys
of `[scene]` and of the stage tables are the builders' own keyword arguments, read from their
signatures, so a builder argument added later is accepted without editing this module.

Scene files are data: nothing in them is evaluated or imported. Types are checked against the
builders' annotations; ranges by the builders themselves (their messages name the argument), and
every error names the file, the line, the table and the key (`SceneFileError`). `tomllib` reports
no line numbers for valid keys, so `_line_of` finds a key's line by scanning the text for it
inside its table.

- `load_scene(name_or_path)`: a built-in scene (`builtin_scenes()`) or a `.toml` file.
- `parse_scene(text)`: the same from a string.
- `save_scene(scene_file, path)` / `SceneFile.to_toml()`: write it back (comments are not kept).
- `SceneFile.build()`: the `Mechanism`; `simulate()`, `objective()`, `tolerances()` for the runs.
- `timeseries(scene_file, result)`: the result as an `xarray.Dataset` with units.
"""

import dataclasses
import importlib.resources
import inspect
import json
import math
import os
import pathlib
import re
import tomllib
import types
import typing

import numpy as np

from ..physics import contact as _contact
from ..design import features as _design
from ..physics import gears as _gears
from ..mechanism import scenes as _scenes
from ..mechanism.scene import STARTS, simulate as _simulate
from ..solve import PID_RULES

# ---------------------------------------------------------------------------------------------
# The schema

BUILDERS = {"antenna": _scenes.antenna, "scan": _scenes.scan}
STAGE_KEYS = ("azimuth_stage", "pitch_stage")
# Contact laws a stage table may name; their constructor arguments are read from the signatures.
CONTACT_LAWS = {cls.__name__: cls for cls in (_contact.BaiZhao, _contact.HertzLN, _contact.Flores, _contact.AdamsImpact)}

_SIM = inspect.signature(_simulate).parameters
# [run]: simulate()'s numeric settings (defaults from its signature), the pointing window `settle`.
RUN_KEYS = {
    "duration": (float, None),
    "start": (str, _SIM["start"].default),
    "n_save": (int, _SIM["n_save"].default),
    "rtol": (float, _SIM["rtol"].default),
    "atol": (float, _SIM["atol"].default),
    "dt0": (float, _SIM["dt0"].default),
    "dtmax": (float, _SIM["dtmax"].default),
    "dtmin": (float, _SIM["dtmin"].default),
    "max_steps": (int, _SIM["max_steps"].default),
    "fixed_step": (float, None),
    "pcoeff": (float, _SIM["pcoeff"].default),
    "icoeff": (float, _SIM["icoeff"].default),
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
    "azimuth_contact": (("azimuth_contact_name",), "N", "normal force of each clearance contact of the azimuth joint"),
    "pitch_contact": (("pitch_contact_name",), "N", "normal force of each clearance contact of the pitch joint"),
    "momentum": (("axis",), "kg m/s", "linear momentum"),
    "angular_momentum": (("axis",), "kg m^2/s", "angular momentum about the world origin"),
    "kinetic_energy": ((), "J", "kinetic energy"),
}
PLOTS = ("pointing_error", "joint_angle", "output_force", "tracking_speed_error")
OUTPUT_KEYS = {"series": (list, list(SERIES)), "plots": (list, ["pointing_error", "joint_angle"]), "dpi": (int, 120)}
DISTRIBUTIONS = ("uniform", "normal")
TOLERANCE_KEYS = {"band": (float, 10e-6), "bands": (dict, {}), "distribution": (str, "uniform"), "requirement": (float, None)}
TOP_KEYS = {"title": str, "description": str, "scene": dict, "run": dict, "outputs": dict, "tolerances": dict}


class SceneFileError(ValueError):
    """A scene file that cannot be read: bad TOML, an unknown key, a wrong type or value.

    `source`, `line` (1-based, or `None` when it cannot be located), `table` (e.g.
    `"scene.azimuth_stage"`) and `key` say where; the message says what is allowed."""

    def __init__(self, message: str, source: str = "<string>", line: int | None = None, table: str = "", key: str | None = None):
        self.message, self.source, self.line, self.table, self.key = message, source, line, table, key
        where = f"{source}:{line}" if line is not None else source
        what = f"[{table}] " if table else ""
        what += f"{key}: " if key is not None else ""
        super().__init__(f"{where}: {what}{message}")


# ---------------------------------------------------------------------------------------------
# Finding lines


def _header(line: str) -> tuple[str, ...] | None:
    m = re.match(r"^\[\[?\s*([^\]]*?)\s*\]\]?\s*(#.*)?$", line)
    if m is None:
        return None
    return tuple(part.strip().strip("\"'") for part in m.group(1).split("."))


def _line_of(text: str, table: tuple[str, ...], key: str | None = None) -> int | None:
    """The line of `key` inside `[table]` (or of the table's header when `key` is None).

    Scans the text: the current table is the last `[header]` seen; a key line starts with the key
    (bare or quoted) and `=`. Keys written another way (dotted `a.b.key = `, inline tables
    `a = { key = ... }`) fall back to the first line where the key is followed by `=`, and
    then to the table's header line."""
    lines = text.splitlines()
    current: tuple[str, ...] = ()
    header_line = None
    quoted = re.escape(key) if key is not None else None
    own = re.compile(rf"^([\"']?){quoted}\1\s*=") if key is not None else None
    for i, raw in enumerate(lines, 1):
        line = raw.strip()
        head = _header(line) if line.startswith("[") else None
        if head is not None:
            current = head
            if current == table:
                header_line = header_line or i
                if key is None:
                    return i
            continue
        if key is not None and current == table and own.match(line):
            return i
    if key is not None:
        loose = re.compile(rf"(^|[.\s{{,])([\"']?){quoted}\2\s*=")
        for i, raw in enumerate(lines, 1):
            if loose.search(raw.split("#", 1)[0]):
                return i
    return header_line


# ---------------------------------------------------------------------------------------------
# Types from annotations


def _accepts(value, ann) -> bool:
    origin = typing.get_origin(ann)
    if origin in (typing.Union, types.UnionType):
        return any(_accepts(value, a) for a in typing.get_args(ann) if a is not type(None))
    if ann is float:
        return isinstance(value, (int, float)) and not isinstance(value, bool)
    if ann is int:
        return isinstance(value, int) and not isinstance(value, bool)
    if ann is bool:
        return isinstance(value, bool)
    if ann is str:
        return isinstance(value, str)
    if ann is list:
        return isinstance(value, list)
    if ann is dict:
        return isinstance(value, dict)
    if origin is tuple:
        args = typing.get_args(ann)
        return isinstance(value, list) and len(value) == len(args) and all(_accepts(v, a) for v, a in zip(value, args))
    return False


def _type_text(ann) -> str:
    origin = typing.get_origin(ann)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_text(a) for a in typing.get_args(ann) if a is not type(None))
    if origin is tuple:
        args = typing.get_args(ann)
        return f"a list of {len(args)} ({', '.join(_type_text(a) for a in args)})"
    return {float: "a number", int: "an integer", bool: "true or false", str: "a string", list: "a list", dict: "a table"}.get(
        ann, getattr(ann, "__name__", str(ann))
    )


def _toml_type(value) -> str:
    return {bool: "a boolean", int: "an integer", float: "a float", str: "a string", list: "an array", dict: "a table"}.get(
        type(value), type(value).__name__
    )


def _for_call(value):
    """TOML arrays become tuples for the builders (pairs such as `fidelity`, `torques`)."""
    return tuple(_for_call(v) for v in value) if isinstance(value, list) else value


# ---------------------------------------------------------------------------------------------
# Validation


class _Checker:
    def __init__(self, text: str, source: str):
        self.text, self.source = text, source

    def error(self, message, table: tuple[str, ...] = (), key=None):
        line = _line_of(self.text, table, key)
        return SceneFileError(message, self.source, line, ".".join(table), key)

    def keys(self, data: dict, table: tuple[str, ...], allowed, required=()):
        for key in data:
            if key not in allowed:
                raise self.error(f"unknown key {key!r}; allowed keys: {', '.join(allowed)}.", table, key)
        for key in required:
            if key not in data:
                raise self.error(f"missing key {key!r}.", table)

    def typed(self, data: dict, table: tuple[str, ...], key: str, ann):
        value = data[key]
        if not _accepts(value, ann):
            raise self.error(f"must be {_type_text(ann)}, got {value!r} ({_toml_type(value)}).", table, key)

    def wrap(self, err: Exception, table: tuple[str, ...], data: dict):
        """A builder's error, located at the first key of `table` its message names."""
        message = str(err)
        for key in data:
            if re.search(rf"\b{re.escape(key)}\b", message):
                return self.error(message, table, key)
        return self.error(message, table)


def _signature_keys(fn, skip=()):
    return {name: p for name, p in inspect.signature(fn).parameters.items() if name not in skip}


def _build_stage(chk: _Checker, data: dict, table: tuple[str, ...]):
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


def _build_law(chk: _Checker, data, table):
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


def _build(chk: _Checker, scene: dict):
    table = ("scene",)
    if "kind" not in scene:
        raise chk.error(f"missing key 'kind' (one of {', '.join(BUILDERS)}).", table)
    if scene["kind"] not in BUILDERS:
        raise chk.error(f"unknown scene kind {scene['kind']!r}; use one of {', '.join(BUILDERS)}.", table, "kind")
    builder = BUILDERS[scene["kind"]]
    params = _signature_keys(builder)
    chk.keys(scene, table, ["kind", *params])
    kwargs = {}
    for key, value in scene.items():
        if key == "kind":
            continue
        if key in STAGE_KEYS:
            if not isinstance(value, dict):
                raise chk.error(f"must be a table of default_stage arguments, got {value!r}.", table, key)
            kwargs[key] = _build_stage(chk, value, table + (key,))
            continue
        chk.typed(scene, table, key, params[key].annotation)
        kwargs[key] = _for_call(value)
    try:
        model = builder(**kwargs)
        model.check_runnable()  # e.g. nothing to integrate: say so now, not after a compile
    except (ValueError, TypeError) as err:
        raise chk.wrap(err, table, scene) from None
    return model


def _check_run(chk: _Checker, run: dict):
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
        if not (math.isfinite(x) and ok(x)):
            raise chk.error(f"must be a finite number {rule}, got {x!r} (the default (0, 1) is an I-controller, "
                            "(0.3, 0.3) a PI controller).", table, key)
    if value["start"] not in STARTS:
        raise chk.error(f"start={value['start']!r} is unknown; use one of {STARTS}.", table, "start")
    if value["n_save"] < 2:
        raise chk.error(f"must be at least 2 (the start and the end), got {value['n_save']!r}.", table, "n_save")
    if value["max_steps"] < 1:
        raise chk.error(f"must be at least 1, got {value['max_steps']!r}.", table, "max_steps")
    if not (math.isfinite(value["settle"]) and 0.0 <= value["settle"] < value["duration"]):
        raise chk.error(
            f"must satisfy 0 <= settle < duration = {value['duration']!r} s, got {value['settle']!r}.",
            table, "settle" if "settle" in run else "duration",
        )
    if not value["dtmin"] < value["dt0"] <= value["dtmax"]:
        raise chk.error(
            f"steps must satisfy dtmin < dt0 <= dtmax, got dtmin={value['dtmin']!r}, dt0={value['dt0']!r}, dtmax={value['dtmax']!r}.",
            table, next((k for k in ("dt0", "dtmax", "dtmin") if k in run), None),
        )


def _check_outputs(chk: _Checker, outputs: dict):
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


def _check_tolerances(chk: _Checker, tol: dict, model):
    table = ("tolerances",)
    chk.keys(tol, table, list(TOLERANCE_KEYS))
    for key in tol:
        chk.typed(tol, table, key, TOLERANCE_KEYS[key][0])
    if "band" in tol and not (math.isfinite(tol["band"]) and tol["band"] >= 0):
        raise chk.error(f"must be a non-negative finite half-width (m), got {tol['band']!r}.", table, "band")
    if tol.get("distribution", "uniform") not in DISTRIBUTIONS:
        raise chk.error(f"distribution={tol['distribution']!r} is unknown; use one of {DISTRIBUTIONS}.", table, "distribution")
    if "requirement" in tol and not (math.isfinite(tol["requirement"]) and tol["requirement"] > 0):
        raise chk.error(f"must be a positive number of arcsec, got {tol['requirement']!r}.", table, "requirement")
    names = _design.design_names(model)
    sub = table + ("bands",)
    for name, value in tol.get("bands", {}).items():
        if name not in names:
            raise chk.error(f"{name!r} is not a design feature of this scene; its features: {', '.join(names) or 'none'}.", sub, name)
        if not (_accepts(value, float) and math.isfinite(value) and value >= 0):
            raise chk.error(f"must be a non-negative finite half-width (m), got {value!r}.", sub, name)


def _validate(data: dict, text: str, source: str):
    """Check `data` (parsed from `text`); return the model it builds."""
    chk = _Checker(text, source)
    for key, value in data.items():
        if key not in TOP_KEYS:
            raise chk.error(f"unknown key {key!r}; allowed at the top level: {', '.join(TOP_KEYS)}.", (), key)
        if not _accepts(value, TOP_KEYS[key]):
            raise chk.error(f"must be {_type_text(TOP_KEYS[key])}, got {_toml_type(value)}.", (), key)
    for key in ("scene", "run"):
        if key not in data:
            raise chk.error(f"missing table [{key}].")
    _check_run(chk, data["run"])
    _check_outputs(chk, data.get("outputs", {}))
    model = _build(chk, data["scene"])
    _check_tolerances(chk, data.get("tolerances", {}), model)
    return model


# ---------------------------------------------------------------------------------------------
# The description


@dataclasses.dataclass(frozen=True, eq=False)
class SceneFile:
    """A validated scene description: the TOML data, where it came from, and what it builds.

    **Fields:** `data` (the parsed TOML: nested dicts of numbers, strings, booleans and lists),
    `name` (the built-in name or the file's stem), `source` (a path, `builtin:NAME` or
    `<string>`). Two `SceneFile`s are equal when their `data` are; comments are not part of
    the description. Build one with `load_scene`, `parse_scene`, or `SceneFile.from_data`.
    """

    data: dict
    name: str = "scene"
    source: str = "<string>"
    _model: object = dataclasses.field(default=None, repr=False)  # built while validating; immutable

    @classmethod
    def from_data(cls, data: dict, name: str = "scene", source: str = "<data>") -> "SceneFile":
        """Validate `data` (as `tomllib` would return it) through its TOML text, so that errors
        carry line numbers."""
        try:
            text = _dumps(data)
        except TypeError as err:
            raise SceneFileError(str(err), source) from None
        return parse_scene(text, name=name, source=source)

    def __eq__(self, other):
        return isinstance(other, SceneFile) and _canonical(self.data) == _canonical(other.data)

    __hash__ = None

    @property
    def title(self) -> str:
        return self.data.get("title", self.name)

    @property
    def run(self) -> dict:
        """`[run]` with its defaults filled in."""
        given = self.data["run"]
        return {key: given.get(key, default) for key, (_, default) in RUN_KEYS.items()}

    @property
    def outputs(self) -> dict:
        """`[outputs]` with its defaults filled in."""
        given = self.data.get("outputs", {})
        return {key: given.get(key, default) for key, (_, default) in OUTPUT_KEYS.items()}

    def build(self):
        """The `Mechanism` this file describes."""
        if self._model is not None:
            return self._model
        return _build(_Checker(self.to_toml(), self.source), self.data["scene"])

    def replace(self, **run) -> "SceneFile":
        """This description with `[run]` keys changed (e.g. `duration=0.1`), validated again."""
        data = _copy(self.data)
        changed = {k: v for k, v in run.items() if v is not None}
        data["run"].update(changed)
        try:
            return SceneFile.from_data(data, self.name, self.source)
        except SceneFileError as err:  # its line would be one of the regenerated text: drop it
            what = ", ".join(f"{k}={v!r}" for k, v in changed.items())
            raise SceneFileError(f"{err.message} (after setting {what})", self.source, None, err.table, err.key) from None

    def simulate(self, *, throw: bool = True, progress: bool = False):
        """`simulate(self.build(), ...)` with the `[run]` settings; the `MechanismResult`."""
        run = self.run
        kwargs = {k: v for k, v in run.items() if k not in ("duration", "settle") and v is not None}
        return _simulate(self.build(), run["duration"], throw=throw, progress=progress, **kwargs)

    def objective(self, **kwargs):
        """A `PointingObjective` on this scene over the window `[settle, duration]` (s), with the
        `[run]` settings (keyword arguments override them)."""
        from ..design.objectives import PointingObjective

        run = self.run
        opts = dict(duration=run["duration"], settle=run["settle"], start=run["start"], n_save=run["n_save"],
                    rtol=run["rtol"], atol=run["atol"], max_steps=run["max_steps"], pcoeff=run["pcoeff"], icoeff=run["icoeff"])
        return PointingObjective(self.build(), **{**opts, **kwargs})

    def tolerances(self, scene=None):
        """The `Tolerances` of `[tolerances]` around the design of `scene` (default `build()`):
        `band` (m) for every feature, `bands` per feature, drawn `distribution`-ly."""
        scene = self.build() if scene is None else scene
        tol = self.data.get("tolerances", {})
        names = _design.design_names(scene)
        band = [tol.get("bands", {}).get(n, tol.get("band", TOLERANCE_KEYS["band"][1])) for n in names]
        return _design.tolerances_of(scene, np.asarray(band, dtype=float), tol.get("distribution", "uniform"))

    @property
    def requirement(self) -> float | None:
        """RMS pointing requirement (arcsec) of `[tolerances]`, if given."""
        return self.data.get("tolerances", {}).get("requirement")

    def to_toml(self) -> str:
        """The description as TOML text (`parse_scene` of it gives an equal `SceneFile`)."""
        return _dumps(self.data)


def _copy(data):
    if isinstance(data, dict):
        return {k: _copy(v) for k, v in data.items()}
    if isinstance(data, list):
        return [_copy(v) for v in data]
    return data


def _canonical(x):
    """Compare descriptions by value and type (1 and 1.0 differ: an integer tooth count is not a float)."""
    if isinstance(x, dict):
        return {k: _canonical(v) for k, v in x.items()}
    if isinstance(x, list):
        return [_canonical(v) for v in x]
    if isinstance(x, float) and math.isnan(x):
        return ("nan",)
    return (type(x).__name__, x)


def parse_scene(text: str, *, name: str = "scene", source: str = "<string>") -> SceneFile:
    """A `SceneFile` from TOML `text`; `SceneFileError` (naming the line and key) if it is not a
    valid scene."""
    try:
        data = tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        m = re.search(r"\(at line (\d+), column \d+\)", str(err))
        raise SceneFileError(f"invalid TOML: {err}", source, int(m.group(1)) if m else None) from None
    model = _validate(data, text, source)
    return SceneFile(data, name, source, model)


def builtin_scenes() -> tuple[str, ...]:
    """Names of the scene files shipped with tolerax (`load_scene(name)`)."""
    folder = importlib.resources.files("tolerax") / "scenes"
    return tuple(sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml")))


def load_scene(scene: str | os.PathLike) -> SceneFile:
    """A built-in scene by name (`builtin_scenes()`, e.g. `"scan"`) or a scene file by path.

    A string is read as a path when it names an existing file, ends in `.toml` or contains a
    path separator; otherwise as a built-in name. Raises `SceneFileError` (a `ValueError`) for a
    missing or invalid file, naming the line and key."""
    text_arg = os.fspath(scene)
    as_path = isinstance(scene, os.PathLike) or text_arg.endswith(".toml") or os.sep in text_arg or "/" in text_arg
    if as_path or os.path.isfile(text_arg):
        path = pathlib.Path(text_arg)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as err:
            raise SceneFileError(f"cannot read the scene file: {err}", str(path)) from None
        return parse_scene(text, name=path.stem, source=str(path))
    names = builtin_scenes()
    if text_arg not in names:
        raise SceneFileError(f"no built-in scene {text_arg!r} and no such file; built-in scenes: {', '.join(names)}.", text_arg)
    return parse_scene(_builtin_text(text_arg), name=text_arg, source=f"builtin:{text_arg}")


def _builtin_text(name: str) -> str:
    return (importlib.resources.files("tolerax") / "scenes" / f"{name}.toml").read_text(encoding="utf-8")


def builtin_titles() -> dict[str, str]:
    """`{name: title}` of the built-in scenes, read without building them."""
    return {name: tomllib.loads(_builtin_text(name)).get("title", name) for name in builtin_scenes()}


def save_scene(scene_file: SceneFile, path: str | os.PathLike) -> pathlib.Path:
    """Write `scene_file` as TOML to `path` (comments of the original are not kept)."""
    path = pathlib.Path(path)
    path.write_text(scene_file.to_toml(), encoding="utf-8")
    return path


# ---------------------------------------------------------------------------------------------
# A TOML writer for this schema: tables of scalars and arrays of scalars, nothing more.

_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def _key(key: str) -> str:
    return key if _BARE.match(key) else _string(key)


def _string(value: str) -> str:
    # JSON's escapes (\" \\ \n \t \uXXXX ...) are valid TOML basic-string escapes; TOML also
    # forbids a raw DEL.
    return json.dumps(value, ensure_ascii=False).replace("\x7f", "\\u007f")


def _value(value) -> str:
    if isinstance(value, bool):
        return "true" if value else "false"
    if isinstance(value, int):
        return str(value)
    if isinstance(value, float):
        if math.isnan(value):
            return "nan"
        if math.isinf(value):
            return "inf" if value > 0 else "-inf"
        # The shortest text that reads back to the same float64: 1e-05 rather than 1.0000000000000001e-05
        # (repr is already shortest), 1e+07 rather than 10000000.0.
        plain, sci = repr(value), np.format_float_scientific(value, unique=True, trim="-")
        return sci if len(sci) < len(plain) else plain
    if isinstance(value, str):
        return _string(value)
    if isinstance(value, (list, tuple)):
        return "[" + ", ".join(_value(v) for v in value) + "]"
    raise TypeError(f"a scene file holds numbers, strings, booleans and lists; got {value!r} ({type(value).__name__}).")


def _dumps(data: dict) -> str:
    out: list[str] = []

    def table(path: tuple[str, ...], body: dict):
        scalars = {k: v for k, v in body.items() if not isinstance(v, dict)}
        tables = {k: v for k, v in body.items() if isinstance(v, dict)}
        if path and (scalars or not tables):
            if out:
                out.append("")
            out.append("[" + ".".join(_key(p) for p in path) + "]")
        out.extend(f"{_key(k)} = {_value(v)}" for k, v in scalars.items())
        for k, v in tables.items():
            table(path + (k,), v)

    table((), data)
    return "\n".join(out) + "\n"


# ---------------------------------------------------------------------------------------------
# Results


def timeseries(scene_file: SceneFile, result, series=None):
    """The time series of a `MechanismResult` as an `xarray.Dataset` (SI units in each
    variable's `units` attribute; the scene file's TOML and the solver report in the global
    attributes). `series`: names from `SERIES` (default `[outputs] series`). Contact series of
    a joint without clearances (no columns) are left out."""
    import xarray as xr

    from . import __version__

    series = scene_file.outputs["series"] if series is None else series
    coords = {
        "time": ("time", np.asarray(result.ts), {"units": "s", "long_name": "simulated time"}),
        "joint": ("joint", ["azimuth", "pitch"]),
        "axis": ("axis", ["x", "y", "z"], {"long_name": "base (spacecraft) frame axis"}),
        "azimuth_contact_name": ("azimuth_contact_name", list(result.azimuth_contact_names)),
        "pitch_contact_name": ("pitch_contact_name", list(result.pitch_contact_names)),
    }
    variables = {}
    for name in series:
        dims, unit, long_name = SERIES[name]
        values = np.asarray(getattr(result, name))
        if values.size == 0:
            continue
        variables[name] = (("time", *dims), values, {"units": unit, "long_name": long_name})
    used = {d for dims, _, _ in variables.values() for d in dims}
    ds = xr.Dataset(variables, coords={k: v for k, v in coords.items() if k in used})
    ds.attrs.update(
        scene=scene_file.name,
        title=scene_file.title,
        scene_toml=scene_file.to_toml(),
        tolerax_version=__version__,
        solver_result="successful" if result.success else "; ".join(result.failures()),
        t_reached_s=float(result.t_reached),
        steps_accepted=int(result.num_steps),
        steps_rejected=int(result.num_rejected),
    )
    return ds


def _window_stats(scene_file: SceneFile, result) -> dict:
    """Summary numbers over the window `t >= settle` (units in the key names)."""
    from ..mechanism.outputs import ARCSEC

    ts = np.asarray(result.ts)
    finite = np.isfinite(ts) & np.all(np.isfinite(np.asarray(result.joint_angle)), axis=1)
    w = finite & (ts >= scene_file.run["settle"])
    if not np.any(w):
        return {}
    e = np.asarray(result.pointing_error)[w] / ARCSEC
    speed = np.linalg.norm(np.asarray(result.tracking_speed_error)[w], axis=1) / ARCSEC
    force = np.asarray(result.output_force)[w]
    runout = np.asarray(result.runout)[w]
    angle = np.degrees(np.asarray(result.joint_angle)[w])
    out = dict(
        window_s=[float(ts[w][0]), float(ts[w][-1])],
        pointing_rms_arcsec=float(np.sqrt(np.mean(e**2))),
        pointing_peak_arcsec=float(e.max()),
        tracking_speed_error_rms_arcsec_s=float(np.sqrt(np.mean(speed**2))),
    )
    for k, joint in enumerate(("azimuth", "pitch")):
        out[f"{joint}_output_force_peak_N"] = float(force[:, k].max())
        out[f"{joint}_runout_peak_um"] = float(runout[:, k].max() * 1e6)
        out[f"{joint}_angle_range_deg"] = [float(angle[:, k].min()), float(angle[:, k].max())]
    return out


def _plot(name: str, result, settle: float, title: str):
    import matplotlib.pyplot as plt

    from ..mechanism.outputs import ARCSEC

    ts = np.asarray(result.ts)
    fig, ax = plt.subplots(figsize=(7, 3.6))
    if name == "pointing_error":
        ax.plot(ts, np.asarray(result.pointing_error) / ARCSEC, lw=0.8)
        ax.set_ylabel("pointing error (arcsec)")
    elif name == "joint_angle":
        for k, joint in enumerate(("azimuth", "pitch")):
            line, = ax.plot(ts, np.degrees(np.asarray(result.joint_angle[:, k])), lw=0.8, label=f"{joint}")
            ax.plot(ts, np.degrees(np.asarray(result.commanded_angle[:, k])), lw=0.8, ls="--", color=line.get_color(), label=f"{joint} commanded")
        ax.set_ylabel("output angle (deg)")
        ax.legend(fontsize=8)
    elif name == "output_force":
        for k, joint in enumerate(("azimuth", "pitch")):
            ax.plot(ts, np.asarray(result.output_force[:, k]), lw=0.8, label=joint)
        ax.set_ylabel("output-bearing radial contact force (N)")
        ax.legend(fontsize=8)
    elif name == "tracking_speed_error":
        for k, axis in enumerate("xyz"):
            ax.plot(ts, np.asarray(result.tracking_speed_error[:, k]) / ARCSEC, lw=0.8, label=axis)
        ax.set_ylabel("tracking speed error (arcsec/s)")
        ax.legend(fontsize=8, title="base frame")
    if settle > 0:
        ax.axvline(settle, color="0.6", lw=0.8, ls=":", label="window start")
    ax.set_xlabel("time (s)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def write_results(scene_file: SceneFile, result, out: str | os.PathLike, *, wall_s: float | None = None, command: str | None = None) -> dict:
    """Write a run's results into the folder `out`: `scene.toml` (the scene as run),
    `timeseries.nc` (netCDF, h5netcdf engine; `timeseries`), one PNG per `[outputs] plots`,
    `summary.json` and `summary.md`. Returns the summary dict."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    save_scene(scene_file, out / "scene.toml")
    ds = timeseries(scene_file, result)
    ds.to_netcdf(out / "timeseries.nc", engine="h5netcdf")
    settings = scene_file.outputs
    plots = []
    for name in settings["plots"]:
        fig = _plot(name, result, scene_file.run["settle"], f"{scene_file.name}: {name.replace('_', ' ')}")
        fig.savefig(out / f"{name}.png", dpi=settings["dpi"])
        plt.close(fig)
        plots.append(f"{name}.png")
    model = scene_file.build()
    summary = dict(
        scene=scene_file.name,
        title=scene_file.title,
        source=scene_file.source,
        run={k: v for k, v in scene_file.run.items() if v is not None},
        result="successful" if result.success else "failed",
        failures=result.failures(),
        t_reached_s=float(result.t_reached),
        steps_accepted=int(result.num_steps),
        steps_rejected=int(result.num_rejected),
        wall_s_including_compile=None if wall_s is None else round(wall_s, 2),
        design_um={n: float(v) * 1e6 for n, v in zip(_design.design_names(model), np.asarray(_design.design_of(model)))},
        metrics=_window_stats(scene_file, result),
        files=["scene.toml", "timeseries.nc", *plots, "summary.json", "summary.md"],
        command=command,
    )
    (out / "summary.json").write_text(json.dumps(summary, indent=2))
    (out / "summary.md").write_text(_summary_md(summary))
    return summary


def _summary_md(s: dict) -> str:
    lines = [f"# {s['title']}", "", f"Scene `{s['scene']}` ({s['source']}); the scene as run is `scene.toml`.", ""]
    if s["command"]:
        lines += ["Reproduce with:", "", "```", s["command"], "```", ""]
    run = s["run"]
    lines += [
        "## Run", "",
        f"- {run['duration']} s simulated from `start = \"{run['start']}\"`, {run['n_save']} saved times, "
        f"rtol {run['rtol']:g}, atol {run['atol']:g}; pointing window from {run['settle']} s.",
        f"- Solver: **{s['result']}**, reached {s['t_reached_s']:.6g} s in {s['steps_accepted']} accepted and "
        f"{s['steps_rejected']} rejected steps"
        + (f"; {s['wall_s_including_compile']} s of wall time including compilation." if s["wall_s_including_compile"] is not None else "."),
    ]
    lines += [f"- Failure: {line}" for line in s["failures"]]
    if s["design_um"]:
        lines += ["", "## Design (clearances and backlash)", "", "| feature | value (µm) |", "|---|---|"]
        lines += [f"| {n} | {v:.4g} |" for n, v in s["design_um"].items()]
    m = s["metrics"]
    if m:
        lines += ["", f"## Results over {m['window_s'][0]:.4g}-{m['window_s'][1]:.4g} s", "", "| quantity | value |", "|---|---|"]
        lines += [
            f"| RMS pointing error | {m['pointing_rms_arcsec']:.4g} arcsec |",
            f"| peak pointing error | {m['pointing_peak_arcsec']:.4g} arcsec |",
            f"| RMS tracking speed error | {m['tracking_speed_error_rms_arcsec_s']:.4g} arcsec/s |",
        ]
        for joint in ("azimuth", "pitch"):
            lo, hi = m[f"{joint}_angle_range_deg"]
            lines += [
                f"| {joint} output angle | {lo:.4g} to {hi:.4g} deg |",
                f"| {joint} peak output-bearing force | {m[f'{joint}_output_force_peak_N']:.4g} N |",
                f"| {joint} peak runout | {m[f'{joint}_runout_peak_um']:.4g} µm |",
            ]
    lines += ["", "## Files", ""] + [f"- `{f}`" for f in s["files"]]
    return "\n".join(lines) + "\n"
