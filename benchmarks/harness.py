"""The one benchmark harness: compile-then-time on the public API, the environment-and-load
header, and the writer of `benchmarks/results/<name>.md`, shared by every benchmark script.

- `timed(fn, *args, repeats=)`: call once (compiles), then `repeats` timed calls; the fastest is
  the run time (noise on a shared or virtual machine only ever adds time), the first call's time
  minus it the compile time.
- `fidelity_cost` / `cost_table`: the dual-axis antenna at one joint fidelity, timed with `timed`
  (`mechanism_cost.py`).
- `write_table(...)`: each result file gets the same head: a title, then a line with the command
  that reproduces it (`command(args)`: every option spelled out) and the environment it ran in
  (`environment()`: tolerax, jax and diffrax versions, JAX platform and device count, CPU cores,
  the git commit, the date and the load average), then the script's own description, its
  table(s) and notes. Scripts format their cells themselves, so each table keeps its columns and
  number formats from run to run.

Set `TOLERAX_BENCH_RESULTS=DIR` to write somewhere else than `benchmarks/results/` (a smoke run
that must not overwrite the committed results).
"""

import dataclasses
import datetime
import os
import pathlib
import shlex
import subprocess
import sys
import time
from collections.abc import Callable, Sequence

import diffrax
import jax

import tolerax

ENV_VAR = "TOLERAX_BENCH_RESULTS"


def timed(fn: Callable, *args, repeats: int = 1, **kwargs):
    """`(compile_s, run_s, output)`: `fn(*args, **kwargs)` called once (compiling), then
    `repeats` more times, each blocked until its arrays are ready; `run_s` is the fastest of the
    later calls, `compile_s` the first call's time minus it. With `repeats=0` the one call's time
    is `run_s` (compilation included) and `compile_s` is 0."""
    times, out = [], None
    for _ in range(1 + repeats):
        start = time.perf_counter()
        out = jax.block_until_ready(fn(*args, **kwargs))
        times.append(time.perf_counter() - start)
    if repeats == 0:
        return 0.0, times[0], out
    run = min(times[1:])
    return max(times[0] - run, 0.0), run, out

@dataclasses.dataclass(frozen=True)
class Section:
    """A further table after the main one: an optional `## heading`, the table, notes."""

    heading: str | None
    columns: Sequence[str]
    rows: Sequence[Sequence[str]]
    notes: Sequence[str] = ()


def results_dir() -> pathlib.Path:
    """`benchmarks/results/`, or `$TOLERAX_BENCH_RESULTS` where set (created if missing)."""
    out = pathlib.Path(os.environ.get(ENV_VAR) or pathlib.Path(__file__).parent / "results")
    out.mkdir(parents=True, exist_ok=True)
    return out


def command(args=None) -> str:
    """The command line that reproduces this run: `python benchmarks/<script>` with every option
    of the parsed `args` spelled out (defaults included, so the file records what ran even if a
    default changes later); the raw command line where `args` is None."""
    head = ["python", f"benchmarks/{pathlib.Path(sys.argv[0]).name}"]
    if args is None:
        return shlex.join(head + sys.argv[1:])
    words = []
    for dest, value in vars(args).items():
        option = "--" + dest.replace("_", "-")
        if value is None or value is False:
            continue
        if value is True:
            words.append(option)
        elif isinstance(value, (list, tuple)):
            words += [option, *map(str, value)]
        else:
            words += [option, str(value)]
    return shlex.join(head + words)


def _commit() -> str:
    try:
        out = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True, check=True,
                             cwd=pathlib.Path(__file__).parent)
        return out.stdout.strip()
    except (OSError, subprocess.CalledProcessError):
        return "unknown"


def environment() -> str:
    """Versions, platform, commit, date and load, for the head line."""
    devices = jax.devices()
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    return (
        f"tolerax {tolerax.__version__}, jax {jax.__version__}, diffrax {diffrax.__version__}, "
        f"{devices[0].platform} x{len(devices)}, {os.cpu_count()} CPU cores; commit {_commit()}, "
        f"{datetime.date.today().isoformat()}, load average {load} at the end"
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
) -> pathlib.Path:
    """Write `results/<name>.md` and print it; returns its path.

    - `title`: the `#` heading. `command`: how to reproduce it (see `command`).
    - `about`: text after the head line (scene, settings). `intro`: paragraphs before the table.
    - `columns`, `rows`: the main table, cells already formatted as strings.
    - `notes`: paragraphs after it. `sections`: further tables (`Section`), in order.
    """
    head = f"`{command}` ({environment()})."
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
    "fidelity", "DOFs (u)", "contacts", "compile (s)", "wall s per simulated s", "x {base}",
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
    `compile_s`, `per_sim_s` (wall s per simulated s), `steps_per_sim_s` (accepted steps per
    simulated s), `rejected` (rejected steps), `pointing_rms_arcsec` (over the whole run).
    """
    mech = tolerax.antenna("dual", fidelity=fidelity, **options)
    compile_s, run, res = timed(
        tolerax.simulate, mech, duration, repeats=repeats, n_save=n_save, start="steady", rtol=rtol, atol=atol,
        pcoeff=pid[0], icoeff=pid[1],
    )
    lay = mech.layout
    return dict(
        fidelity=fidelity if label is None else label,
        dofs=int(lay.size_u),
        contacts=int(lay.size_v),
        compile_s=compile_s,
        per_sim_s=run / duration,
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
            f"{r['per_sim_s'] / base['per_sim_s']:.1f}", f"{r['steps_per_sim_s']:.0f}", str(r["rejected"]),
            f"{r['pointing_rms_arcsec']:.1f}",
        )
        for r in rows
    ]
    return columns, cells
