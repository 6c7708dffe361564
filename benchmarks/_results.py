"""The one writer of `benchmarks/results/<name>.md`, shared by every benchmark script.

Each file gets the same head: a title, then a line with the command that reproduces it and the
environment it ran in (tolerax, jax and diffrax versions, JAX platform and device count, CPU
cores), then the script's own description, its table(s) and notes. Scripts format their cells
themselves, so each table keeps its columns and number formats from run to run.

Set `TOLERAX_BENCH_RESULTS=DIR` to write somewhere else than `benchmarks/results/` (a smoke
run that must not overwrite the committed results).
"""

import dataclasses
import os
import pathlib
import shlex
import sys
from collections.abc import Sequence

import diffrax
import jax

import tolerax

ENV_VAR = "TOLERAX_BENCH_RESULTS"


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


def environment() -> str:
    """Versions and platform, for the head line."""
    devices = jax.devices()
    return (
        f"tolerax {tolerax.__version__}, jax {jax.__version__}, diffrax {diffrax.__version__}, "
        f"{devices[0].platform} x{len(devices)}, {os.cpu_count()} CPU cores"
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
