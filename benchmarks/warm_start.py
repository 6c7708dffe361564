"""Cold against warm start of the command line (issue 32, item 2): each command run twice in
fresh processes, first with an empty persistent compilation cache, then with the cache the
first run wrote (`tolerax.enable_compilation_cache`, on by default in the command line).

    python benchmarks/warm_start.py [--commands demo design montecarlo montecarlo-processes] [--results DIR]

Commands (each into its own output folder; the cache in a temporary folder via
`TOLERAX_CACHE_DIR`):

- `demo`: `tolerax demo` (the dual scan over 1 s, then a short proposal on the azimuth scan);
- `design`: `tolerax design scan-azimuth --requirement 1000 --yield 0.99 --secant-units 9 --check 0 --outer 3 --allow-unconverged` (a short run: the timing, not the answer);
- `montecarlo`: `tolerax montecarlo scan-azimuth --n 16 --chunk 8` (vmap in the command's process);
- `montecarlo-processes`: the same with `--backend processes` (two spawned workers, which
  use the driver's cache folder).

Wall time of the whole process (imports, tracing, compilation, the run); the ratio warm/cold
is the figure (these machines are noisy: read ratios in one run).
"""

import pathlib
import tempfile

import harness

COMMANDS = {
    "demo": ["demo"],
    "design": ["design", "scan-azimuth", "--requirement", "1000", "--yield", "0.99", "--secant-units", "9", "--check", "0", "--outer", "3",
               "--allow-unconverged"],
    "montecarlo": ["montecarlo", "scan-azimuth", "--n", "16", "--chunk", "8"],
    "montecarlo-processes": ["montecarlo", "scan-azimuth", "--n", "16", "--chunk", "8", "--backend", "processes"],
}


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--commands", nargs="+", default=list(COMMANDS), choices=list(COMMANDS))
    args = harness.parse_args(parser)
    rows = []
    with tempfile.TemporaryDirectory(prefix="tolerax-warm-") as tmp:
        for name in args.commands:
            cache = pathlib.Path(tmp) / f"cache-{name}"
            cold = harness.cli(COMMANDS[name], pathlib.Path(tmp) / f"{name}-cold", cache)
            warm = harness.cli(COMMANDS[name], pathlib.Path(tmp) / f"{name}-warm", cache)
            entries = sum(1 for _ in cache.rglob("*") if _.is_file())
            size = sum(p.stat().st_size for p in cache.rglob("*") if p.is_file()) / 1e6
            rows.append((name, "`tolerax " + " ".join(COMMANDS[name]) + "`", f"{cold:.1f}", f"{warm:.1f}", f"{warm / cold:.2f}",
                         f"{entries} ({size:.1f} MB)"))
            print(rows[-1], flush=True)
    harness.write_table(
        "warm_start", "Cold against warm start of the command line (persistent compilation cache)", harness.command(args),
        ["command", "command line", "cold (s)", "warm (s)", "warm / cold", "cache entries (size)"], rows,
        about="Each command run twice in fresh processes into new output folders: cold with an empty cache folder, warm with "
              "the cache the cold run wrote. Whole-process wall time (imports, tracing, compilation, run).",
    )


if __name__ == "__main__":
    main()
