"""The one benchmark harness: compile-then-time on the public API, the environment-and-load
header, and the writer of `benchmarks/results/<name>.md`, shared by every benchmark script.

- `timed(fn, *args, repeats=)` -> `Timing`: call once (compiles), then up to `repeats` timed calls;
  `run_s` is the fastest (noise on a shared or virtual machine only ever adds time), `median_s`
  the median, `compile_s` the first call's time minus the fastest. `wall(fn, *args)`: one call,
  `(seconds, output)`, blocked until its arrays are ready; every timing in the scripts is one of
  these two.
- `fidelity_cost` / `cost_table`: the dual-axis antenna at one joint fidelity, timed with `timed`
  (`mechanism_cost.py`).
- `argument_parser(doc)` / `parse_args(parser)`: every script's options, plus `--results DIR`
  (where to write; also `$TOLERAX_BENCH_RESULTS`), so a smoke run never overwrites the committed
  results.
- `write_table(...)`: each result file gets the same head: a title, then a line with the command
  that reproduces it (`command(args)`: every option spelled out) and the environment it ran in
  (`environment()`: tolerax, jax, diffrax and Python versions, JAX platform, device count and
  kind, CPU cores and how many this process may use, the git commit and whether src/ or
  benchmarks/ had uncommitted changes, the date, the load averages at the start and at the end,
  and the command line exactly as typed), then the script's own description, its table(s) and
  notes. Scripts format their cells themselves, so each table keeps its columns and number
  formats from run to run.
"""

import argparse
import contextlib
import dataclasses
import datetime
import functools
import math
import os
import pathlib
import platform
import shlex
import statistics
import subprocess
import sys
import time
from collections.abc import Callable, Sequence
from typing import Any

import diffrax
import jax
import numpy as np

import tolerax

ENV_VAR = "TOLERAX_BENCH_RESULTS"
ROOT = pathlib.Path(__file__).resolve().parent.parent
START_LOAD = os.getloadavg()  # when the script imported the harness: the load it started under


# ---------------------------------------------------------------------------------------------
# Timing


@dataclasses.dataclass(frozen=True)
class Timing:
    """What `timed` measured: `compile_s` (the first call minus the fastest later one; negative
    or tiny: noise larger than the compilation; `nan` with no later call), `run_s` (the fastest
    later call, or the only call), `median_s` (the median of the later calls), `times` (every
    call, the compiling one first) and `output` (the last call's result)."""

    compile_s: float
    run_s: float
    median_s: float
    times: tuple[float, ...]
    output: Any


def wall(fn: Callable, *args, **kwargs) -> tuple[float, Any]:
    """`(seconds, output)` of one call `fn(*args, **kwargs)`, blocked until its arrays are ready
    (a NumPy array is returned as is: blocking on it would add a microsecond to a call that
    takes a few)."""
    start = time.perf_counter()
    out = fn(*args, **kwargs)
    if not isinstance(out, np.ndarray):
        out = jax.block_until_ready(out)
    return time.perf_counter() - start, out


def timed(
    fn: Callable, *args, repeats: int = 1, enough_s: float = math.inf, once_s: float = math.inf, **kwargs
) -> Timing:
    """Compile, then time: `fn(*args, **kwargs)` called once (compiling), then up to `repeats`
    more times, each blocked until its arrays are ready (`wall`).

    - `enough_s`: stop repeating once the fastest timed call took at least this long (the noise
      of a long call is small against it).
    - `once_s`: when the compiling call took longer than this, do not repeat it: `run_s` is that
      call's time, compilation included, and `compile_s` is `nan`.
    - `repeats=0`: one call; the same as `once_s=0`.
    """
    first, out = wall(fn, *args, **kwargs)
    times = [first]
    if first <= once_s:
        while len(times) <= repeats and (len(times) == 1 or min(times[1:]) < enough_s):
            t, out = wall(fn, *args, **kwargs)
            times.append(t)
    later = times[1:]
    if not later:
        return Timing(math.nan, first, first, tuple(times), out)
    return Timing(first - min(later), min(later), statistics.median(later), tuple(times), out)


# ---------------------------------------------------------------------------------------------
# Options, environment, result files


def cli(argv: Sequence[str], out, cache, quiet_stderr: bool = True, command: Callable | None = None) -> float:
    """Wall time (s) of `tolerax ARGV --out OUT` in a fresh Python process whose compilation
    cache is the folder `cache` (the `TOLERAX_CACHE_DIR` a user would set; never off), its
    output discarded: a command as a user starts it, cold or warm. `command` (optional): the
    process's whole command line from `[*ARGV, "--out", OUT]` (another tolerax's command line,
    a Python call), instead of `python -m tolerax.cli.main ...`."""
    env = dict(os.environ, TOLERAX_CACHE_DIR=str(cache))
    env.pop("TOLERAX_CACHE", None)
    argv = [*argv, "--out", str(out)]
    start = time.perf_counter()
    subprocess.run([sys.executable, "-m", "tolerax.cli.main", *argv] if command is None else command(argv), env=env, check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL if quiet_stderr else None)
    return time.perf_counter() - start


def child_result(code: str, argv: Sequence[str], env: dict) -> dict:
    """Run `python -c CODE ARGV` in a fresh process with the environment `env` and return the JSON
    of its last line starting `RESULT ` (a workload measured where nothing compiled before it)."""
    import json

    done = subprocess.run([sys.executable, "-c", code, *argv], env=env, capture_output=True, text=True)
    line = [x for x in done.stdout.splitlines() if x.startswith("RESULT ")]
    if done.returncode or not line:
        raise RuntimeError(f"{' '.join(argv)} exited {done.returncode}:\n{done.stderr[-3000:]}")
    return json.loads(line[-1][len("RESULT "):])


def interleaved_best(rounds: int, works: Sequence[str], configs: Sequence[str], run: Callable, parts: Sequence[str]) -> dict:
    """`{(work, config): result}` of `run(work, config)` (a dict of seconds under `parts`, `None`
    where not measured, and anything else), over `rounds` rounds interleaving the configurations,
    keeping per part the fastest (these machines are noisy); each run printed as it ends."""
    best = {}
    for _ in range(rounds):
        for work in works:
            for config in configs:
                r = run(work, config)
                print(work, config, {k: r[k] for k in parts}, flush=True)
                keep = best.setdefault((work, config), r)
                for k in parts:
                    if r[k] is not None and r[k] < keep[k]:
                        keep[k] = r[k]
    return best


def argument_parser(doc: str | None) -> argparse.ArgumentParser:
    """A script's parser: its docstring as the help text, and `--results DIR`."""
    parser = argparse.ArgumentParser(description=doc, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument(
        "--results", type=pathlib.Path, metavar="DIR",
        help=f"write the result files to DIR (default: ${ENV_VAR} where set, else benchmarks/results)",
    )
    return parser


def parse_args(parser: argparse.ArgumentParser, argv: Sequence[str] | None = None) -> argparse.Namespace:
    """`parser.parse_args(argv)`, with `--results DIR` made the results folder."""
    args = parser.parse_args(argv)
    if getattr(args, "results", None) is not None:
        os.environ[ENV_VAR] = str(args.results)
    return args


def results_dir() -> pathlib.Path:
    """`benchmarks/results/`, or `--results` / `$TOLERAX_BENCH_RESULTS` where set (created if
    missing)."""
    out = pathlib.Path(os.environ.get(ENV_VAR) or pathlib.Path(__file__).parent / "results")
    out.mkdir(parents=True, exist_ok=True)
    return out


def command(args=None) -> str:
    """The command line that reproduces this run: `python benchmarks/<script>` with every option
    of the parsed `args` spelled out (defaults included, so the file records what ran even if a
    default changes later; `--results`, where the files went, left out); the raw command line
    where `args` is None."""
    head = ["python", f"benchmarks/{pathlib.Path(sys.argv[0]).name}"]
    if args is None:
        return shlex.join(head + sys.argv[1:])
    words = []
    for dest, value in vars(args).items():
        option = "--" + dest.rstrip("_").replace("_", "-")  # dest `yield_` (a keyword) is option `--yield`
        if dest == "results" or value is None or value is False:
            continue
        if value is True:
            words.append(option)
        elif isinstance(value, (list, tuple)):
            words += [option, *map(str, value)]
        else:
            words += [option, str(value)]
    return shlex.join(head + words)


def load(averages: Sequence[float] | None = None) -> str:
    """Load averages (1/5/15 min), now or the given ones, as `1.2/0.9/0.8`."""
    return "/".join(f"{x:.1f}" for x in (os.getloadavg() if averages is None else averages))


def _git(*words: str) -> str | None:
    try:
        out = subprocess.run(["git", *words], capture_output=True, text=True, check=True, cwd=ROOT)
    except (OSError, subprocess.CalledProcessError):
        return None
    return out.stdout.strip()


def commit() -> str:
    """The short commit, with `+ uncommitted changes` where src/ or benchmarks/ (results aside)
    differ from it."""
    head = _git("rev-parse", "--short", "HEAD")
    if head is None:
        return "unknown commit"
    dirty = _git("status", "--porcelain", "--", "src", "benchmarks", ":(exclude)benchmarks/results")
    return f"commit {head}" + (" + uncommitted changes" if dirty else "")


def environment() -> str:
    """Versions, platform, commit, date, load and the command line as typed, for the head line."""
    devices = jax.devices()
    usable = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else os.cpu_count()
    typed = shlex.join([pathlib.Path(sys.executable).name] + sys.argv)
    kind = devices[0].device_kind
    return (
        f"tolerax {tolerax.__version__}, jax {jax.__version__}, diffrax {diffrax.__version__}, "
        f"Python {platform.python_version()}, {devices[0].platform} x{len(devices)}"
        f"{'' if kind == devices[0].platform else f' ({kind})'}, "
        f"{os.cpu_count()} CPU cores ({usable} usable); {commit()}, {datetime.date.today().isoformat()}; "
        f"load average {load(START_LOAD)} at the start, {load()} at the end; run as `{typed}`"
    )


def markdown_table(columns: Sequence[str], rows: Sequence[Sequence[str]]) -> list[str]:
    """Lines of a Markdown table; cells are used as given (format numbers before), with `|`
    escaped."""
    cell = lambda x: str(x).replace("|", "\\|")  # noqa: E731
    lines = ["| " + " | ".join(map(cell, columns)) + " |", "|" + "---|" * len(columns)]
    for row in rows:
        if len(row) != len(columns):
            raise ValueError(f"a row has {len(row)} cells for {len(columns)} columns: {row!r}")
        lines.append("| " + " | ".join(map(cell, row)) + " |")
    return lines


@dataclasses.dataclass(frozen=True)
class Section:
    """A further table after the main one: an optional `## heading`, the table, notes."""

    heading: str | None
    columns: Sequence[str]
    rows: Sequence[Sequence[str]]
    notes: Sequence[str] = ()


def write_table(
    name: str,
    title: str,
    command: str,
    columns: Sequence[str],
    rows: Sequence[Sequence[str]],
    *,
    about: str = "",
    intro: Sequence[str] = (),
    notes: Sequence[str] = (),
    sections: Sequence[Section] = (),
    env: str | None = None,
) -> pathlib.Path:
    """Write `results/<name>.md` and print it; returns its path.

    - `title`: the `#` heading. `command`: how to reproduce it (see `command`).
    - `about`: text after the head line (scene, settings). `intro`: paragraphs before the table.
    - `columns`, `rows`: the main table, cells already formatted as strings.
    - `notes`: paragraphs after it. `sections`: further tables (`Section`), in order.
    - `env`: the head line's environment where it is not this process's (a table rendered again
      from a saved run: the environment that run recorded); default `environment()`.
    """
    head = f"`{command}` ({env or environment()})."
    lines = [f"# {title}", "", head + (f" {about}" if about else ""), ""]
    for paragraph in intro:
        lines += [paragraph, ""]
    lines += markdown_table(columns, rows) + [""]
    for paragraph in notes:
        lines += [paragraph, ""]
    for section in sections:
        if section.heading:
            lines += [f"## {section.heading}", ""]
        lines += markdown_table(section.columns, section.rows) + [""]
        for paragraph in section.notes:
            lines += [paragraph, ""]
    path = results_dir() / f"{name}.md"
    text = "\n".join(lines).rstrip("\n") + "\n"
    path.write_text(text)
    print(text, flush=True)
    return path


# ---------------------------------------------------------------------------------------------
# Cost per joint fidelity of the dual-axis antenna (mechanism_cost.py)

COLUMNS = (
    "fidelity", "DOFs (u)", "contacts", "compile (s)", "wall s per simulated s", "median wall s per simulated s", "x {base}",
    "accepted steps per simulated s", "rejected", "pointing RMS (arcsec)",
)


def fidelity_cost(
    fidelity: str,
    duration: float,
    *,
    n_save: int = 51,
    label: str | None = None,
    repeats: int = 1,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    pid: tuple[float, float] = (0.0, 1.0),
    **options,
) -> dict:
    """Compile and run time of `antenna("dual", fidelity=fidelity, **options)` (free base, 0.98
    deg/s on both joints, 100 um clearances and backlash) over `duration` (s) from a steady start.
    `label` names the row (default: the fidelity); `options` go to `antenna` (for example
    `mass_scaling=100.0` with `"planetary-scaled"`); `rtol`, `atol` are the solver's tolerances
    (Tsit5) and `pid` its step-size controller's `(pcoeff, icoeff)` (`simulate`).

    The scene is solved `1 + repeats` times (`timed`).

    **Returns:** a dict: `fidelity`, `dofs` (velocity coordinates), `contacts` (clearance contacts),
    `compile_s`, `per_sim_s` (wall s per simulated s, the fastest of the repeats),
    `median_per_sim_s` (the median of the repeats), `steps_per_sim_s` (accepted steps per
    simulated s), `rejected` (rejected steps), `pointing_rms_arcsec` (over the whole run).
    """
    mech = tolerax.antenna("dual", fidelity=fidelity, **options)
    t = timed(
        tolerax.simulate, mech, duration, repeats=repeats, n_save=n_save, start="steady", rtol=rtol, atol=atol,
        pcoeff=pid[0], icoeff=pid[1],
    )
    res, lay = t.output, mech.layout
    return dict(
        fidelity=fidelity if label is None else label,
        dofs=int(lay.size_u),
        contacts=int(lay.size_v),
        compile_s=t.compile_s,
        per_sim_s=t.run_s / duration,
        median_per_sim_s=t.median_s / duration,
        steps_per_sim_s=int(res.num_steps) / duration,
        rejected=int(res.num_rejected),
        pointing_rms_arcsec=float((res.pointing_error**2).mean() ** 0.5) / tolerax.ARCSEC,
    )


def cost_table(rows: list[dict]) -> tuple[list[str], list[tuple[str, ...]]]:
    """Column names and formatted cells of `fidelity_cost` rows; the ratio column is relative to
    the first row."""
    base = rows[0]
    columns = [c.format(base=base["fidelity"]) for c in COLUMNS]
    cells = [
        (
            r["fidelity"], str(r["dofs"]), str(r["contacts"]), f"{r['compile_s']:.1f}", f"{r['per_sim_s']:.2f}",
            f"{r['median_per_sim_s']:.2f}", f"{r['per_sim_s'] / base['per_sim_s']:.1f}", f"{r['steps_per_sim_s']:.0f}", str(r["rejected"]),
            f"{r['pointing_rms_arcsec']:.1f}",
        )
        for r in rows
    ]
    return columns, cells


@functools.cache
def _forward_jacobian_joint():
    """`tx.PlanetaryJoint` whose stage forces take the deflections' Jacobian by forward-mode
    autodiff (`stage_forces(projection="forward")`): the joint as it was before the closed form
    (another class, so another compiled program and cache key)."""
    import tolerax as tx
    from tolerax.physics import planetary

    class ForwardJacobianPlanetaryJoint(tx.PlanetaryJoint):
        def forces(self, qj, uj, vj, t):
            f = planetary.stage_forces(self.stage, qj, uj, vj, projection="forward")
            return f.generalised + self.drive_forces(qj, uj, t), f.contact

    return ForwardJacobianPlanetaryJoint


def with_forward_jacobian(mech):
    """`mech` with each `tx.PlanetaryJoint` computing its deflections' Jacobian by forward mode,
    as before the closed form (the benchmarks' before-and-after of it)."""
    import tolerax as tx

    def swap(j):
        if type(j) is not tx.PlanetaryJoint:
            return j
        return _forward_jacobian_joint()(j.stage, j.drive, j.motor_inertia, j.drag_torque)

    return tx.Mechanism(swap(mech.azimuth), swap(mech.pitch), mech.geometry, mech.inertias, mech.base, mass_solve=mech.mass_solve)


@functools.cache
def tolerax_at(rev: str):
    """The tolerax package as it was at git revision `rev` (this checkout's history), imported
    beside today's as a module of its own, `tolerax_at_<commit>`: `git archive` of `src/tolerax`
    into a temporary folder with the package's name in its own source replaced. A benchmark then
    times an earlier program against today's in the same process and the same run, the scene
    built by that module's `antenna` and solved by its `simulate` (`rattle_window.py`'s `:@REV`
    rows, `rhs_floor.py --against REV`). Raises where `rev` is not a commit of this checkout.
    Cached by `rev`; the folder stays while the process runs (the package reads its submodules
    and scene files from it) and is removed at exit."""
    import atexit
    import importlib
    import io
    import re
    import shutil
    import tarfile
    import tempfile

    sha = _git("rev-parse", "--short", f"{rev}^{{commit}}")
    if sha is None:
        raise ValueError(f"{rev!r} is not a git revision of {ROOT}: name a commit of this checkout (git log --oneline)")
    name = f"tolerax_at_{sha}"
    if name in sys.modules:
        return sys.modules[name]
    folder = pathlib.Path(tempfile.mkdtemp(prefix=f"{name}_"))
    atexit.register(shutil.rmtree, folder, ignore_errors=True)
    archive = subprocess.run(["git", "archive", sha, "src/tolerax"], capture_output=True, check=True, cwd=ROOT).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    package = folder / "src" / "tolerax"
    for path in package.rglob("*"):
        if path.is_file() and path.suffix == ".py":
            path.write_text(re.sub(r"\btolerax\b", name, path.read_text()))
    package.rename(folder / name)
    sys.path.insert(0, str(folder))
    try:
        return importlib.import_module(name)
    finally:
        sys.path.remove(str(folder))


EIGEN_THREADS = {"xla_cpu_multi_thread_eigen": True}
"""The XLA option `tolerax.solve.CPU_COMPILER_OPTIONS` turned off: Eigen's products split over the CPU's threads."""


@contextlib.contextmanager
def eigen_threads():
    """`tolerax.simulate` on a CPU compiled with Eigen's products over the CPU's threads (XLA's
    default, and tolerax's before `CPU_COMPILER_OPTIONS` turned it off): the same traced program,
    compiled with other options (JAX's compilation cache keys on them)."""
    import tolerax.solve as solve
    from tolerax.cache import exported_jit

    saved = solve._solve_cpu
    solve._solve_cpu = exported_jit(solve._solve, compiler_options={**solve.CPU_COMPILER_OPTIONS, **EIGEN_THREADS})
    try:
        yield
    finally:
        solve._solve_cpu = saved


def with_mass_solve(mech, mass_solve: str):
    """`mech` (a `tolerax.Mechanism`) with another `mass_solve` (`"blocks"` or `"whole"`): a static
    field, so a new `Mechanism` (the benchmarks' before-and-after of the block solve)."""
    import tolerax as tx

    return tx.Mechanism(mech.azimuth, mech.pitch, mech.geometry, mech.inertias, mech.base, mass_solve=mass_solve)
