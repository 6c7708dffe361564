"""What the commands share: the command line that reproduces a run, the machine's load, the scene file with
its overrides, and the argument types."""

import argparse
import contextlib
import copy
import decimal
import math
import os
import pathlib
import re
import shlex
import shutil
import sys
import tempfile
import textwrap

from .._defaults import JITTER_CUTOFF  # noqa: F401 (the commands take it from here)
from .._files import atomic_write
from ..eta import FAST_STAGE_COST, ROUGH_COST, human_seconds, rough_wall  # noqa: F401 (the commands take them from here)

DEFAULT_SCENE = "scan-azimuth"


def scene_jitter(args, scene_file) -> None:
    """`--jitter` and `--jitter-cutoff` from the scene's `[tolerances] jitter` and `jitter_cutoff`
    where the command line left them at their defaults (`design`, `montecarlo`: a proposal carries
    the jitter it met)."""
    tol = scene_file.data.get("tolerances", {})
    if args.jitter is None and tol.get("jitter") is not None:
        args.jitter = tol["jitter"]
        if args.jitter_cutoff == JITTER_CUTOFF:
            args.jitter_cutoff = tol.get("jitter_cutoff", JITTER_CUTOFF)


@contextlib.contextmanager
def figures_to_files():
    """A command's figures drawn on Agg (written to files, never shown) for its duration, the
    caller's backend restored after: `tolerax.cli.main([...])` called from a notebook or a script
    leaves that session's backend (inline, a window) as it was."""
    import matplotlib

    before = dict.__getitem__(matplotlib.rcParams, "backend")  # as set: the automatic choice stays unresolved
    matplotlib.use("Agg")
    try:
        yield
    finally:
        if str(before).lower() != "agg":
            import matplotlib.pyplot as plt

            plt.switch_backend(before)


def command_line(args) -> str:
    """The command line that reproduces this run."""
    return shlex.join(["tolerax", *(sys.argv[1:] if args.argv is None else args.argv)])


def versions() -> str:
    """The versions a result depends on, for a report."""
    import platform

    import diffrax
    import equinox
    import jax

    from .. import __version__

    return (f"tolerax {__version__}, jax {jax.__version__} ({jax.default_backend()}, x64 "
            f"{'on' if jax.config.jax_enable_x64 else 'off'}), diffrax {diffrax.__version__}, equinox {equinox.__version__}, "
            f"Python {platform.python_version()}")


def settings(scene_file) -> str:
    """The solver settings of a scene's `[run]`, for a report: the keys it gives, and the
    integrator its runs use and why (chosen from the scene where `[run]` names none)."""
    run = scene_file.run
    keys = ("duration", "settle", "start", "n_save", "integrator", "rtol", "atol", "pcoeff", "icoeff", "solver", "dtmax", "max_steps")
    given = ", ".join(f"{k} {run[k]}" for k in keys if run.get(k) is not None)
    return f"{given}; integrated with {scene_file.objective().integrated_with}"


def load_average() -> str:
    return "load average (1, 5, 15 min): " + ", ".join(f"{x:.2f}" for x in os.getloadavg()) + f" on {os.cpu_count()} CPUs"


def read_scene_file(parser, args, **run):
    """`args.scene` (a built-in name or a .toml path) with `--duration`/`--settle` and `run`
    overriding its `[run]` keys; `None` when the file cannot be read or is invalid (the message,
    naming the file, line, table and key, is printed)."""
    from ..io import scenefile as F

    try:
        scene_file = F.load_scene(args.scene)
        duration = scene_file.run["duration"] if args.duration is None else args.duration
        settle = scene_file.run["settle"] if args.settle is None else args.settle
        if args.duration is not None and args.settle is None and settle >= duration:
            parser.error(f"--duration {duration} s is not longer than the scene's run.settle = {settle} s: give --settle too")
        return scene_file.replace(duration=args.duration, settle=args.settle, integrator=getattr(args, "integrator", None), **run)
    except F.SceneFileError as err:
        print(f"tolerax {args.command}: {err}", file=sys.stderr)
        return None


def with_tolerances(scene_file, band_um=None, distribution=None):
    """`scene_file` with `[tolerances] band` (given in um; replaces the per-feature `bands` too)
    and `distribution` overridden where given."""
    from ..io import scenefile as F

    if band_um is None and distribution is None:
        return scene_file
    data = copy.deepcopy(scene_file.data)
    tol = data.setdefault("tolerances", {})
    if band_um is not None:
        tol["band"] = band_um * 1e-6
        tol.pop("bands", None)
    if distribution is not None:
        tol["distribution"] = distribution
    return F.SceneFile.from_data(data, scene_file.name, scene_file.source)


# What a scene in which nothing wears needs, said where `--life` added (or completed) its [life]:
# the scene file's own key, which every command reads (`design` says its --fidelity too).
NOTHING_WEARS_FIX = (" Give a joint planetary fidelity in the scene file ([scene] fidelity, e.g. [\"planetary\", \"ideal\"]; "
                     "the built-in scan-azimuth-planetary is one).")


def with_life(scene_file, years, spread=False, *, fix=NOTHING_WEARS_FIX):
    """`scene_file` with its `[life]` lasting `years` in orbit (its other keys kept; without a
    `[life]`, the table's defaults: duty 1, sputtered MoS2 at its median rate, 2 points) and,
    with `spread`, each unit's wear rate drawn over the lubricant's band (`spread = true`): what
    `--life YEARS` (and design's `--wear-spread`) make of a scene.

    **Arguments:**

    - `scene_file`: a `tolerax.io.scenefile.SceneFile`.
    - `years`: the mission's life, years in orbit (> 0).
    - `spread`: draw each unit's wear rate over the lubricant's published band.
    - `fix`: the sentence added where nothing in the scene wears (what to do about it).

    **Returns:** the `SceneFile` with its `[life]`; `SceneFileError` where the table cannot be
    (nothing in the scene wears: no joint at planetary fidelity), naming the flags that made the
    table, not a line of the user's file."""
    from ..io import scenefile as F

    data = copy.deepcopy(scene_file.data)
    had = "life" in data
    data["life"] = {**data.get("life", {}), "years": float(years)} | ({"spread": True} if spread else {})
    try:
        return F.SceneFile.from_data(data, scene_file.name, scene_file.source)
    except F.SceneFileError as err:  # the table (or its keys) came from the flags: no line of the user's file to point at
        if err.table != "life":
            raise
        flag = f"--life {years:g}" + (" --wear-spread" if spread else "")
        what = "the [life] table that " + flag + (" completed" if had else " added")
        raise F.SceneFileError(f"{what}: {err.message}{fix if 'nothing wears' in err.message else ''}", scene_file.source, None,
                               "", None) from None


OWNER = ".tolerax-command"  # in an output folder: the command whose results it holds
# Results written before folders were marked: the files by which each command's folder is known.
_SIGNS = (("demo.md", "demo"), ("bench.png", "demo"), ("design.md", "design"), ("tradeoff.json", "tradeoff"),
          ("montecarlo.nc", "montecarlo"), ("chunks", "montecarlo"), ("timeseries.nc", "run"), ("life.md", "run"))
_STUDY = re.compile(r"^[a-z0-9_]+-(small|full)\.json$")


def out_owner(path: pathlib.Path) -> str | None:
    """The command whose results the folder `path` holds: its mark (`OWNER`), else the files it
    has (`_SIGNS`, a study's table); `None` for a folder with no results (missing, empty, or
    only the mark: a command stopped before writing)."""
    if not path.is_dir():
        return None
    entries = [e.name for e in path.iterdir() if e.name != OWNER and not e.name.endswith(".tmp")]
    if not entries:
        return None
    mark = (path / OWNER).read_text().strip() if (path / OWNER).is_file() else ""
    if mark:
        return mark
    for name, command in _SIGNS:
        if name in entries:
            return command
    return "studies" if any(_STUDY.match(e) for e in entries) else None


def check_out(parser, out, command: str, *, force: bool = False, resumes: bool = False) -> pathlib.Path:
    """The output folder `out` of `tolerax command`, checked before any work, the one contract
    of every command (exit 2 with what to type instead, nothing written or lost):

    - an existing file, not a folder: refused;
    - a folder holding another command's results (`out_owner`): refused, naming that command
      and a folder of this one's own;
    - a folder holding this command's results: kept where the command goes on from them
      (`resumes`: montecarlo's chunks, studies' `--resume`), replaced with `force` (`--force`:
      the earlier results are removed when the new ones are written, `claim_out`), else
      refused, naming `--force`;
    - a folder that cannot be created or written (read-only, a path under a file): refused with
      the system's reason, before any simulation.

    Nothing is created here (a command refused later for its scene leaves nothing behind): the
    command marks the folder as its own when its work starts (`claim_out`). Returns the path."""
    path = pathlib.Path(out)
    if path.exists() and not path.is_dir():
        parser.error(f"--out {str(out)!r} is an existing file, not a folder: name a folder (created if missing)")
    owner = out_owner(path)
    if owner is not None and owner != command:
        parser.error(f"--out {str(out)!r} holds the results of `tolerax {owner}`, which this `tolerax {command}` would overwrite "
                     f"or mix with its own: give it a folder of its own, e.g. --out {path / command}")
    if owner == command and not (resumes or force):
        parser.error(f"--out {str(out)!r} holds the results of an earlier `tolerax {command}`: --force overwrites them, or give "
                     "another --out")
    try:
        _probe(path)
    except OSError as err:
        parser.error(f"--out {str(out)!r} cannot be written ({err.strerror or err}): name a folder you can write to")
    return path


def _probe(path: pathlib.Path) -> None:
    """Raise `OSError` where the folder `path` cannot be written, or, where it does not exist
    yet, created: a file made and removed in it, or a folder in its nearest existing parent."""
    if path.is_dir():
        with tempfile.NamedTemporaryFile(dir=path, prefix=".tolerax-probe-"):
            return
    parent = path.absolute()
    while not parent.exists():
        parent = parent.parent
    if not parent.is_dir():
        raise NotADirectoryError(20, "a parent of it is a file, not a folder", str(parent))
    os.rmdir(tempfile.mkdtemp(dir=parent, prefix=".tolerax-probe-"))


def claim_out(out, command: str, *, fresh: bool = False) -> None:
    """Mark the folder `out` as holding `tolerax command`'s results (`out_owner` reads it).
    With `fresh` (`--force`), first remove what an earlier `tolerax command` left there (its
    results are replaced, not mixed with the new ones: an earlier `best_reached.toml` beside a
    new `proposal.toml`, an earlier verification's chunks); a folder holding another command's
    results is never emptied."""
    path = pathlib.Path(out)
    if fresh and out_owner(path) == command:
        for entry in path.iterdir():
            shutil.rmtree(entry) if entry.is_dir() and not entry.is_symlink() else entry.unlink()
    path.mkdir(parents=True, exist_ok=True)
    atomic_write(path / OWNER, command + "\n")


def check_clipping(parser, tolerances, allow: bool):
    """Refuse (exit 2) bands that reach below zero unless `allow`: units drawn there are
    clipped to 0 um (line-to-line parts), almost always a slip in the band's unit (um)."""
    import numpy as np

    low = np.asarray(tolerances.nominal) - np.asarray(tolerances.band)
    below = [f"{name} ({n * 1e6:.3g} - {b * 1e6:.3g} um)" for name, n, b, lo in
             zip(tolerances.names, np.asarray(tolerances.nominal), np.asarray(tolerances.band), low) if lo < 0]
    if below and not allow:
        parser.error("the band reaches below zero for " + ", ".join(below) + ": units drawn there would be clipped to 0 um "
                     "(line-to-line parts). Narrow the band (--band is a half-width in um) or pass --allow-clip to accept them")


def has_features(scene_file, command) -> bool:
    from ..design.features import design_names

    if design_names(scene_file.build()):
        return True
    print(f"tolerax {command}: scene {scene_file.name!r} models no clearance or backlash (ideal joints only): "
          "nothing to tolerance.", file=sys.stderr)
    return False


# ---------------------------------------------------------------------------------------------
# demo


POWER_OF_METRE = {"m": 0, "mm": -3, "um": -6, "µm": -6, "μm": -6, "nm": -9}  # 10^k m
_LENGTH = re.compile(r"^\s*([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)\s*([a-zµμ]*)\s*$")


def length_in(unit: str):
    """An argparse type for a length whose bare number is in `unit` ("m" or "um"), and which
    also takes a unit suffix (`10um`, `0.01mm`, `1e-5m`, `100nm`), returned in `unit`: the
    command line takes some lengths in um and others in m, and a suffix makes either unambiguous."""

    def parse(text):
        match = _LENGTH.match(str(text))
        if match is None or match.group(2) not in ("", *POWER_OF_METRE):
            raise argparse.ArgumentTypeError(f"must be a length: a number in {unit}, or with a unit such as 10um, 0.01mm, "
                                             f"1e-5m, got {text!r}")
        if not match.group(2):
            return float(match.group(1))
        # Decimal: 0.01mm is exactly 10 um, not 10.000000000000002.
        return float(decimal.Decimal(match.group(1)).scaleb(POWER_OF_METRE[match.group(2)] - POWER_OF_METRE[unit]))

    return parse


def positive(text):
    value = float(text)
    if not (math.isfinite(value) and value > 0):
        raise argparse.ArgumentTypeError(f"must be a positive number, got {text!r}")
    return value


def positive_length(unit: str):
    """`length_in(unit)`, positive."""
    parse = length_in(unit)

    def check(text):
        value = parse(text)
        if not (math.isfinite(value) and value > 0):
            raise argparse.ArgumentTypeError(f"must be a positive length, got {text!r}")
        return value

    return check


def band_um(text):
    """A tolerance half-width in µm (or with a unit suffix, `length_in`): non-negative, and 0 or
    at least 0.01 µm (a bare number below that is a length given in metres, e.g. 1e-5 for 10 µm)."""
    value = length_in("um")(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a non-negative length, got {text!r}")
    if 0 < value < 0.01:
        raise argparse.ArgumentTypeError(f"is a half-width in um: {text} um is {value * 1e3:g} nm, below any manufacturing band; "
                                         f"for {value * 1e6:g} um give {value * 1e6:g} (or {value * 1e6:g}um)")
    return value


def non_negative(text):
    value = float(text)
    if not (math.isfinite(value) and value >= 0):
        raise argparse.ArgumentTypeError(f"must be a non-negative number, got {text!r}")
    return value


def count(minimum):
    def count(text):
        value = int(text)
        if value < minimum:
            raise argparse.ArgumentTypeError(f"must be an integer >= {minimum}, got {text!r}")
        return value

    count.__name__ = f"integer >= {minimum}"  # argparse names it in "invalid ... value"
    return count


def out_options(parser, command: str, default: str | None = None):
    """`--out` (default `./tolerax-out/COMMAND`: each command its own folder, `check_out`) and
    `--force` (montecarlo, which resumes from its folder by default: start afresh)."""
    default_text = default or f"./tolerax-out/{command}"
    parser.add_argument("--out", default=None if default else f"tolerax-out/{command}",
                        help=f"output folder (default {default_text}); a folder holding another command's results is refused"
                        + ("; rerun into it to resume" if command == "montecarlo" else ""))
    if command == "montecarlo":
        parser.add_argument("--force", action="store_true",
                            help="start afresh: remove an earlier `tolerax montecarlo` run's results and finished chunks in --out "
                            "(default: resume from them, or extend them to a larger --n)")
    else:
        parser.add_argument("--force", action="store_true",
                            help="overwrite the results of an earlier `tolerax " + command + "` in --out (refused otherwise)")


# The integrators a run names (tolerax.solve.NAMED_INTEGRATORS' names, and "auto"), written out:
# the parser is built without importing the simulator (tests/test_cli.py holds them equal).
INTEGRATOR_NAMES = ("auto", "accurate", "fast-stage")


def integrator_option(parser):
    parser.add_argument("--integrator", choices=INTEGRATOR_NAMES, default=None,
                        help="override run.integrator: 'auto' (chosen from the scene), or a preset by name "
                        "(tolerax.solve.NAMED_INTEGRATORS; 'fast-stage': SRK53 at rtol 1e-4 for a full planetary stage, faster, "
                        "its outputs read less closely), which the scene's other [run] settings refine")


def scene_options(parser, what, command: str):
    parser.add_argument("scene", nargs="?", default=DEFAULT_SCENE,
                        help=f"built-in scene name (`tolerax run --list`) or path to a .toml scene file (default {DEFAULT_SCENE}); "
                        f"its [run] settings set the {what} horizon and window, its [tolerances] the bands and requirement")
    parser.add_argument("--duration", type=positive, default=None, help="override run.duration (simulated time per unit), s")
    parser.add_argument("--settle", type=non_negative, default=None, help="override run.settle (start of the pointing window), s")
    integrator_option(parser)
    parser.add_argument("--quiet", action="store_true",
                        help="no progress while it runs (the time estimate, phase lines and progress bars); the results "
                        "and errors are still printed")
    out_options(parser, command)


def wrap(text: str) -> str:
    """`text` wrapped to the terminal's width as argparse wraps its options (capped at 100 columns
    on a wide terminal): for a parser with `RawDescriptionHelpFormatter`, which does not wrap its
    own paragraphs."""
    return textwrap.fill(text, max(40, min(100, shutil.get_terminal_size().columns - 2)))


EPILOG = ("Exit codes: 0 done, 2 bad input (the message names the scene file's key and line; an output folder refused before "
          "any work: another command's, an earlier run's without --force, or not writable), 3 a simulation failed.")
# montecarlo: an earlier run in its folder is resumed, not refused.
MONTECARLO_EPILOG = EPILOG.replace("an earlier run's without --force, or not writable", "or not writable; an earlier run's "
                                   "is resumed, or extended to a larger --n, and --force starts afresh")
assert MONTECARLO_EPILOG != EPILOG
# design and tradeoff: also 4, the answer is not a proposal.
DESIGN_EPILOG = EPILOG[:-1] + (", 4 the answer is not a proposal (not converged, infeasible, noise-limited, or its Monte Carlo "
                               "check missed: the report says why first; --allow-unconverged writes it as proposal.toml and exits 0).")


def scene_and_settings(scene_file, *lines) -> list[str]:
    """A report's closing sections: the scene file, then its solver settings, the versions and `lines`."""
    return ["## Scene", "", "```toml", scene_file.to_toml().rstrip(), "```", "",
            "## Settings and versions", "", f"- solver (`[run]`): {settings(scene_file)}", f"- {versions()}", *lines, ""]
