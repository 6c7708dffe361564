"""Where the suite's time goes: per test, its wall time and the seconds JAX spent tracing,
lowering and compiling programs in it (`jax.monitoring`'s duration events), and reading compiled
programs back from the run's cache. Turned on by `TOLERAX_TEST_PROFILE=FOLDER` (tests/conftest.py
registers it): each process writes `FOLDER/profile-<pid>.jsonl`, a line per test.

    TOLERAX_TEST_PROFILE=/tmp/prof pytest --durations=0
    python tests/_compile_profile.py /tmp/prof          # a table by file, then the slowest tests

Each row also keeps, under `programs`, the programs that took over 0.5 s of the test's tracing,
lowering or compiling ("name|trace", "name|lower", "name|compile" -> s): which programs a
test pays for, and which are compiled in more than one test.

Programs compiled in a subprocess (the command-line tests' `tolerax ...`, notebook kernels) are
not seen: their tests count as run time. A test's own events only: one that reads a program
another compiled shows the read, not the compile.
"""

import collections
import json
import os
import pathlib
import sys
import time

import pytest

_EVENTS = (("jaxpr_trace", "trace"), ("jaxpr_to_mlir", "lower"), ("backend_compile", "compile"),
           ("compilation_cache/cache_retrieval", "cache_read"))
_now = collections.Counter()
_programs = collections.Counter()  # (program name, what) -> seconds, for the test running now
_rows = []


def _listener(event, duration_secs=None, fun_name=None, **_):
    for key, name in _EVENTS:
        if key in event and duration_secs is not None:
            _now[name] += duration_secs
            if fun_name and name != "cache_read":
                _programs[f"{fun_name.removeprefix('jit(').removesuffix(')')}|{name}"] += duration_secs


def register(config) -> None:
    """Start recording (from conftest's `pytest_configure`)."""
    import jax

    jax.monitoring.register_event_duration_secs_listener(_listener)
    config.pluginmanager.register(sys.modules[__name__], "tolerax-compile-profile")


@pytest.hookimpl(hookwrapper=True, tryfirst=True)
def pytest_runtest_protocol(item, nextitem):
    _now.clear()
    _programs.clear()
    start = time.perf_counter()
    yield
    # The programs over 0.5 s of the test's tracing, lowering or compiling: "name|what" -> s.
    programs = {k: round(v, 2) for k, v in _programs.items() if v > 0.5}
    _rows.append(dict(test=item.nodeid, wall=time.perf_counter() - start, **_now, programs=programs))


def pytest_sessionfinish(session):
    folder = os.environ.get("TOLERAX_TEST_PROFILE")
    if folder and _rows:
        path = pathlib.Path(folder)
        path.mkdir(parents=True, exist_ok=True)
        with open(path / f"profile-{os.getpid()}.jsonl", "w") as f:
            for row in _rows:
                f.write(json.dumps(row) + "\n")


def table(folder) -> str:
    """The recorded tests of `folder` as Markdown: seconds by file (wall, and of it tracing,
    lowering, compiling), then the 40 slowest tests."""
    rows = [json.loads(line) for p in sorted(pathlib.Path(folder).glob("profile-*.jsonl")) for line in open(p)]
    keys = ("wall", "trace", "lower", "compile", "cache_read")
    files = collections.defaultdict(collections.Counter)
    for r in rows:
        files[r["test"].split("::")[0]].update({k: r.get(k, 0.0) for k in keys} | {"tests": 1})
    total = sum((c for c in files.values()), collections.Counter())
    out = ["| file | tests | wall (s) | trace | lower | compile | cache read | compile share |", "|---|---:|---:|---:|---:|---:|---:|---:|"]
    for name, c in sorted(files.items(), key=lambda kv: -kv[1]["wall"]) + [("**all**", total)]:
        share = (c["trace"] + c["lower"] + c["compile"]) / c["wall"] if c["wall"] else 0.0
        out.append(f"| {name} | {c['tests']} | {c['wall']:.1f} | {c['trace']:.1f} | {c['lower']:.1f} | {c['compile']:.1f} | "
                   f"{c['cache_read']:.1f} | {share:.0%} |")
    out += ["", "| slowest tests | wall (s) | trace + lower + compile (s) |", "|---|---:|---:|"]
    for r in sorted(rows, key=lambda r: -r["wall"])[:40]:
        out.append(f"| `{r['test']}` | {r['wall']:.1f} | {r.get('trace', 0) + r.get('lower', 0) + r.get('compile', 0):.1f} |")
    return "\n".join(out)


if __name__ == "__main__":
    print(table(sys.argv[1]))
