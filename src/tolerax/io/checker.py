"""Scene-file checking that needs no simulator: `SceneFileError` (a message located at its file,
line, table and key), `SceneFileNote` (a valid but unlikely value), the lines of a TOML text's
tables and keys, the types a key accepts, and `Checker`, which the schema (`tolerax.io.schema`)
validates with; and the checks a scene file can have before the simulator is imported
(`precheck`: the file read, its TOML, its top-level tables), which the command line runs first.
Imports neither JAX nor the physics.
"""

import difflib
import importlib.resources
import os
import pathlib
import re
import tomllib
import types
import typing
import warnings


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
    if origin is list:
        (item,) = typing.get_args(ann)
        return isinstance(value, list) and all(_accepts(v, item) for v in value)
    return False


def _type_text(ann) -> str:
    origin = typing.get_origin(ann)
    if origin in (typing.Union, types.UnionType):
        return " or ".join(_type_text(a) for a in typing.get_args(ann) if a is not type(None))
    if origin is tuple:
        args = typing.get_args(ann)
        return f"a list of {len(args)} ({', '.join(_type_text(a) for a in args)})"
    if origin is list:
        return f"a list of {_type_text(typing.get_args(ann)[0]).removeprefix('a ').removeprefix('an ')}s"
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


def _suggest(word, choices) -> str:
    """`" (did you mean 'x'?)"` for the closest of `choices`, or nothing."""
    close = difflib.get_close_matches(str(word), [str(c) for c in choices], n=1, cutoff=0.6)
    return f" (did you mean {close[0]!r}?)" if close else ""


class SceneFileNote(UserWarning):
    """A value a scene file may hold but that is unlikely to be what was meant (a scan amplitude
    of a radian: degrees typed where the file wants radians); said before any work, with the
    file, line and key, and not refused."""


class Checker:
    def __init__(self, text: str, source: str):
        self.text, self.source = text, source

    def error(self, message, table: tuple[str, ...] = (), key=None):
        line = _line_of(self.text, table, key)
        return SceneFileError(message, self.source, line, ".".join(table), key)

    def note(self, message, table: tuple[str, ...] = (), key=None):
        """Say `message` about a valid but unlikely value (`SceneFileNote`), located as `error`."""
        warnings.warn(str(self.error(message, table, key)), SceneFileNote, stacklevel=2)

    def keys(self, data: dict, table: tuple[str, ...], allowed, required=()):
        for key in data:
            if key not in allowed:
                raise self.error(f"unknown key {key!r}{_suggest(key, allowed)}; allowed keys: {', '.join(allowed)}.", table, key)
        for key in required:
            if key not in data:
                raise self.error(f"missing key {key!r}.", table)

    def typed(self, data: dict, table: tuple[str, ...], key: str, ann):
        value = data[key]
        if not _accepts(value, ann):
            # A number written with its unit ("50um"): the file holds plain numbers in SI units.
            units = (" Scene files hold plain numbers, each in its key's unit (docs/scene_files.md: lengths in m, so "
                     "50 µm is 5e-05; requirements in arcsec)." if isinstance(value, str) and re.match(r"\s*[-+]?[\d.]", value)
                     and _accepts(1.0, ann) else "")
            raise self.error(f"must be {_type_text(ann)}, got {value!r} ({_toml_type(value)}).{units}", table, key)

    def wrap(self, err: Exception, table: tuple[str, ...], data: dict):
        """A builder's error, located at the key of `table` its message names first: the
        argument it is about (`default_stage(backlash=80) must be below the module`: the
        backlash, not the module it is compared with)."""
        message = str(err)
        named = [(m.start(), key) for key in data if (m := re.search(rf"\b{re.escape(key)}\b", message))]
        if named:
            return self.error(message, table, min(named)[1])
        return self.error(message, table)


# The top-level keys of a scene file and their types.
TOP_KEYS = {"title": str, "description": str, "scene": dict, "design": dict, "run": dict, "outputs": dict, "tolerances": dict,
            "life": dict}


def check_top(chk: Checker, data: dict) -> None:
    """The top level of a parsed scene file: known keys of the right types, `[scene]` and `[run]` present."""
    for key, value in data.items():
        if key not in TOP_KEYS:
            raise chk.error(f"unknown key {key!r}{_suggest(key, TOP_KEYS)}; allowed at the top level: {', '.join(TOP_KEYS)}.", (), key)
        if not _accepts(value, TOP_KEYS[key]):
            raise chk.error(f"must be {_type_text(TOP_KEYS[key])}, got {_toml_type(value)}.", (), key)
    for key in ("scene", "run"):
        if key not in data:
            raise chk.error(f"missing table [{key}].")


def builtin_scenes() -> tuple[str, ...]:
    """Names of the scene files shipped with tolerax (`load_scene(name)`)."""
    folder = importlib.resources.files("tolerax") / "scenes"
    return tuple(sorted(p.name[: -len(".toml")] for p in folder.iterdir() if p.name.endswith(".toml")))


def builtin_text(name: str) -> str:
    """The TOML text of the built-in scene `name`."""
    return (importlib.resources.files("tolerax") / "scenes" / f"{name}.toml").read_text(encoding="utf-8")


def read_scene_text(scene: str | os.PathLike) -> tuple[str, str, str]:
    """`(text, name, source)` of a built-in scene by name or a scene file by path (`load_scene`'s
    rule: a path when it names an existing file, ends in `.toml` or contains a path separator);
    `SceneFileError` where the file cannot be read or no built-in scene has the name."""
    text_arg = os.fspath(scene)
    as_path = isinstance(scene, os.PathLike) or text_arg.endswith(".toml") or os.sep in text_arg or "/" in text_arg
    if as_path or os.path.isfile(text_arg):
        path = pathlib.Path(text_arg)
        try:
            return path.read_text(encoding="utf-8"), path.stem, str(path)
        except (OSError, UnicodeDecodeError) as err:
            raise SceneFileError(f"cannot read the scene file: {err}", str(path)) from None
    names = builtin_scenes()
    if text_arg not in names:
        raise SceneFileError(f"no built-in scene {text_arg!r} and no such file{_suggest(text_arg, names)}; built-in scenes: "
                             f"{', '.join(names)}.", text_arg)
    return builtin_text(text_arg), text_arg, f"builtin:{text_arg}"


def parse_toml(text: str, source: str) -> dict:
    """`tomllib.loads(text)`, its error as a `SceneFileError` at its line."""
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as err:
        m = re.search(r"\(at line (\d+), column \d+\)", str(err))
        raise SceneFileError(f"invalid TOML: {err}", source, int(m.group(1)) if m else None) from None


def precheck(scene: str | os.PathLike) -> None:
    """What can be wrong with a scene file before the simulator is imported: it cannot be read, is
    not TOML, or has an unknown or mistyped top-level key; `SceneFileError`, as `load_scene` says it."""
    text, _, source = read_scene_text(scene)
    check_top(Checker(text, source), parse_toml(text, source))
