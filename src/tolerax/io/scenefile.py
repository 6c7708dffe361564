"""Scene files: a mechanism, its run settings, outputs and tolerances described in TOML.

A scene file describes the *builder call* (`antenna(...)` or `scan(...)`, with `default_stage`
keyword arguments for each joint's gear data), not the model's pytree: the file stays readable
and stable while the internals change. Scene files are data: nothing in them is evaluated or
imported. The schema and its checks are `tolerax.io.schema`; the results of a run are written
by `tolerax.io.results`.

- `load_scene(name_or_path)`: a built-in scene (`builtin_scenes()`) or a `.toml` file.
- `parse_scene(text)`: the same from a string.
- `save_scene(scene_file, path)` / `SceneFile.to_toml()`: write it back (comments are not kept).
- `SceneFile.build()`: the `Mechanism`; `simulate()`, `objective()`, `tolerances()` for the runs;
  `problem()`: the design problem the file states (`tolerax.io.problem`).
"""

import copy
import dataclasses
import math
import os
import pathlib
import tomllib
import warnings

import numpy as np
import tomli_w

from .._files import atomic_write
from ..design import features as _design
from ..mechanism.scene import simulate as _simulate
from ..solve import Integrator, refined
from . import checker as C, schema as S
from .checker import builtin_scenes  # noqa: F401 (the face's)
from .schema import OUTPUT_KEYS, RUN_KEYS, TOLERANCE_KEYS, SceneFileError, SceneFileNote  # noqa: F401 (SceneFileNote: the face's)
from .schema import life as _life

# ---------------------------------------------------------------------------------------------
# The description


def _integrator(run: dict, budget: int | None):
    """`SceneFile.integrator` of the `[run]` settings `run` (a `tolerax.Integrator` given as
    `integrator` is refined by the settings beside it)."""
    settings = {k: run[k] for k in Integrator.FIELDS if run.get(k) is not None}
    named = run.get("integrator") or "auto"
    return refined(named, settings, where="[run] integrator", budget=None if isinstance(named, Integrator) else budget)[0] or "auto"


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
        carry line numbers. Notes on unlikely values (`SceneFileNote`) are not said again: they
        were said, at the user's own lines, when the file was read; this text is regenerated."""
        try:
            text = _dumps(data)
        except TypeError as err:
            raise SceneFileError(str(err), source) from None
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", SceneFileNote)
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
        return S.build(S.Checker(self.to_toml(), self.source), self.data["scene"])

    def replace(self, **run) -> "SceneFile":
        """This description with `[run]` keys changed (e.g. `duration=0.1`), validated again."""
        data = copy.deepcopy(self.data)
        changed = {k: v for k, v in run.items() if v is not None}
        data["run"].update(changed)
        try:
            return SceneFile.from_data(data, self.name, self.source)
        except SceneFileError as err:  # its line would be one of the regenerated text: drop it
            what = ", ".join(f"{k}={v!r}" for k, v in changed.items())
            raise SceneFileError(f"{err.message} (after setting {what})", self.source, None, err.table, err.key) from None

    def simulate(self, *, throw: bool = True, progress: bool = False):
        """`simulate(self.build(), ...)` with the `[run]` settings; the `MechanismResult`."""
        kwargs = {k: v for k, v in self.run.items() if k in ("start", "n_save") and v is not None}
        return _simulate(self.build(), self.run["duration"], throw=throw, progress=progress, integrator=self.integrator(),
                         **kwargs)

    def integrator(self, budget: int | None = None):
        """The integrator `[run]` names: the preset named (`integrator = "fast-stage"`; default
        `"auto"`, the scene's automatic choice) refined by the `Integrator` fields it sets
        (`rtol = 1e-5`), as a `tolerax.Integrator`, or `"auto"` where it names neither.
        `budget` (steps): a preset's step budget here (`PointingObjective`'s, a design unit's)."""
        return _integrator(self.run, budget)

    def objective(self, **kwargs):
        """A `PointingObjective` on this scene over the window `[settle, duration]` (s), with the
        `[run]` settings and the `[life]` (its outputs then have end-of-life twins, `_eol`);
        keyword arguments override them."""
        from ..design.objectives import OBJECTIVE_INTEGRATOR, PointingObjective

        # Every `[run]` key is an `Integrator` field or a `PointingObjective` field of the same name
        # (tests/test_scenefile.py checks it), so the whole table passes through and a new key
        # cannot be dropped here: the integrator's fields refine the preset named, on a design
        # unit's step budget, as one `Integrator`.
        opts = dict(self.run, life=self.life) | kwargs
        integrator = _integrator(opts, OBJECTIVE_INTEGRATOR.max_steps)
        opts = {k: v for k, v in opts.items() if k not in Integrator.FIELDS and k != "integrator"}
        return PointingObjective(self.build(), integrator=integrator, **opts)

    def problem(self):
        """The design problem this file states (`tolerax.io.problem`): a `ToleranceProblem` of
        `objective()` with the `[tolerances]` requirement, `require`, `jitter` and `yield`, the
        constraint `model`, the zones and the cost: what `tolerax design` on this file solves
        with no option. Give it to `tolerax.propose_design`."""
        from .problem import problem_of

        return problem_of(self)

    def solver(self):
        """The design solver `[tolerances] solver` names (default `Sequential()`), for
        `tolerax.propose_design(self.problem(), self.solver(), check=self.check())`."""
        from .problem import solver_of

        return solver_of(self)

    def check(self):
        """The Monte Carlo check of a yield design `[tolerances] check` states (default
        `Check(200)`), or `None` (`check = 0`, or no `yield`: nothing to check)."""
        from .problem import check_of, tolerance_table

        return None if tolerance_table(self).get("yield") is None else check_of(self)

    @property
    def life(self):
        """The `MissionLife` of `[life]`, or `None` without one."""
        return None if "life" not in self.data else _life(None, self.data["life"], self.build())

    def tolerances(self, scene=None):
        """The `Tolerances` of `[tolerances]` around the design of `scene` (default `build()`):
        `band` (m) for every feature, `bands` per feature, drawn `distribution`-ly."""
        scene = self.build() if scene is None else scene
        tol = self.data.get("tolerances", {})
        names = _design.design_names(scene)
        band = [tol.get("bands", {}).get(n, tol.get("band", TOLERANCE_KEYS["band"][1])) for n in names]
        return _design.tolerances_of(scene, np.asarray(band, dtype=float), tol.get("distribution", "uniform"))

    def with_tolerances(self, tolerances) -> "SceneFile":
        """This scene with the zones of `tolerances` (a `Tolerances` over some or all of its
        design features) written in: their nominals under `[design]`, their half-widths under
        `[tolerances.bands]`, their distribution. `tolerances()` of the result gives them
        back."""
        return SceneFile.from_data(self._data_with(tolerances), self.name, self.source)

    def _data_with(self, tolerances) -> dict:
        """A copy of this scene's data with the zones of `tolerances` written in (`with_tolerances`),
        not yet validated; a zone for a feature the scene lacks is refused naming it."""
        names = _design.design_names(self.build())
        unknown = [n for n in tolerances.names if n not in names]
        if unknown:
            raise ValueError(f"SceneFile.with_tolerances: {unknown} are not design features of {self.name!r}; its features: "
                             f"{', '.join(names)}.")
        data = copy.deepcopy(self.data)
        data["design"] = {**data.get("design", {}), **{n: float(v) for n, v in zip(tolerances.names, tolerances.nominal)}}
        tol = data.setdefault("tolerances", {})
        tol["bands"] = {**tol.get("bands", {}), **{n: float(b) for n, b in zip(tolerances.names, tolerances.band)}}
        tol["distribution"] = tolerances.distribution
        return data

    def with_proposal(self, report, jitter_cutoff: float | None = None) -> "SceneFile":
        """This scene with a tolerance proposal (`tolerax.propose_design`'s `DesignReport`)
        filled in: its zones (`report.tolerances`: on whole ISO grades where the report has a
        drawable design, the zones it says to draw) as the nominal clearances and backlash under
        `[design]` and the half-widths under `[tolerances.bands]`, the requirement, uniform
        manufacturing (what the design assumed), and a description with the cost and each
        zone's callout (grade, journal fit). `tolerax design` writes it as `proposal.toml`;
        `tolerax run`, `montecarlo` and `design` read it back as any scene file. The requirements
        it met go with it: the yield, the jitter (at `jitter_cutoff`, Hz: the objective's) and the
        further ones (`require`), replacing the scene's own (`tolerax montecarlo` checks them)."""
        data = self._data_with(report.tolerances)
        tol = data["tolerances"]
        for key in ("yield", "jitter", "jitter_cutoff", "require"):
            tol.pop(key, None)
        first = report.outcomes[0]
        tol["requirement"] = float(first.requirement.limit)
        if report.yield_ is not None:
            tol["yield"] = float(report.yield_)
        further = [o.requirement for o in report.outcomes[1:]]
        for r in further:
            if r.output == "pointing_jitter" and report.yield_ is not None:
                tol["jitter"] = float(r.limit)
                if jitter_cutoff is not None:
                    tol["jitter_cutoff"] = float(jitter_cutoff)
        others = {r.output: float(r.limit) for r in further if r.output != "pointing_jitter"}
        if others:
            tol["require"] = others
        what = "mean + 1 std over a few units" if report.yield_ is None else f"{report.yield_:.1%} yield"
        d = report.drawable
        cost = report.cost if d is None else d.cost
        data["title"] = f"Proposal: {self.title}"
        data["description"] = (f"Written by tolerax design from {self.source}: cost {cost:.4g} (baseline "
                               f"{report.baseline[2]:.4g}; {report.cost_unit}), {first.requirement.text()} "
                               f"({what})" + "".join(f", {o.requirement.text()}" for o in report.outcomes[1:])
                               + f"; {report.status}" + ("" if report.accepted else " (not a proposal: the best design reached)") + "."
                               + ("" if d is None else f" On whole grades, as drawn: {'; '.join(d.callouts())} (continuous optimum's "
                                  f"cost {report.cost:.4g})."))
        return SceneFile.from_data(data, "proposal", "<proposal>")

    @property
    def requirement(self) -> float | None:
        """RMS pointing requirement (arcsec) of `[tolerances]`, if given."""
        return self.data.get("tolerances", {}).get("requirement")

    def to_toml(self) -> str:
        """The description as TOML text (`parse_scene` of it gives an equal `SceneFile`)."""
        return _dumps(self.data)


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
    data = C.parse_toml(text, source)
    model = S.validate(data, text, source)
    return SceneFile(data, name, source, model)


def load_scene(scene: str | os.PathLike) -> SceneFile:
    """A built-in scene by name (`builtin_scenes()`, e.g. `"scan"`) or a scene file by path.

    A string is read as a path when it names an existing file, ends in `.toml` or contains a
    path separator; otherwise as a built-in name. Raises `SceneFileError` (a `ValueError`) for a
    missing or invalid file, naming the line and key."""
    text, name, source = C.read_scene_text(scene)
    return parse_scene(text, name=name, source=source)


def builtin_titles() -> dict[str, str]:
    """`{name: title}` of the built-in scenes, read without building them."""
    return {name: tomllib.loads(C.builtin_text(name)).get("title", name) for name in builtin_scenes()}


def save_scene(scene_file: SceneFile, path: str | os.PathLike) -> pathlib.Path:
    """Write `scene_file` as TOML to `path` (comments of the original are not kept)."""
    path = pathlib.Path(path)
    atomic_write(path, scene_file.to_toml())
    return path


# The TOML writer is tomli-w's; a scene file holds tables of numbers, strings, booleans and lists.
_SCALARS = (bool, int, float, str)


def _check_toml_types(data, where: str = "") -> None:
    for key, value in data.items():
        if isinstance(value, dict):
            _check_toml_types(value, f"{where}{key}.")
            continue
        items = value if isinstance(value, (list, tuple)) else [value]
        for item in items:
            if not isinstance(item, _SCALARS):
                raise TypeError(
                    f"{where}{key}: a scene file holds numbers, strings, booleans and lists; "
                    f"got {item!r} ({type(item).__name__})."
                )


def _dumps(data: dict) -> str:
    _check_toml_types(data)
    return tomli_w.dumps(data)
