"""The persistent compilation cache (`tolerax.enable_compilation_cache`): a second process
reads every program, the solve included, from the cache and computes the same result; the off
switch; the traced programs kept beside it (`tolerax.cache.exported_jit`): keyed so that changed
code is never served, and equal to plain jit."""

import os
import subprocess
import sys

import numpy as np

SCRIPT = """
import collections, sys
from jax import monitoring
events = collections.Counter()
traced = collections.Counter()
monitoring.register_event_listener(lambda e, **kw: events.update([e]))
def on_duration(event, duration, **kw):
    if event.endswith("jaxpr_trace_duration"):
        traced.update([kw.get("fun_name")])
monitoring.register_event_duration_secs_listener(on_duration)
import tolerax as tx
print("folder", tx.enable_compilation_cache(sys.argv[1]))
sf = tx.load_scene("scan-azimuth").replace(duration=0.05, settle=0.0)
r = sf.simulate()
print("requests", events["/jax/compilation_cache/compile_requests_use_cache"], "hits", events["/jax/compilation_cache/cache_hits"])
print("result", float(r.pointing_error[-1]).hex())
print("traced", traced["_solve"] + traced["flat"])
"""


def _run(folder, **env):
    env = {k: v for k, v in os.environ.items() if k != "TOLERAX_CACHE"} | env
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(folder)], env=env, capture_output=True, text=True, check=True, timeout=600)
    lines = dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())
    requests, _, hits = lines["requests"].split()
    return lines["folder"], int(requests), int(hits), lines["result"], int(lines["traced"])


def test_a_second_process_reads_every_program_from_the_cache(tmp_path):
    folder = tmp_path / "cache"
    _, requests, hits, result, traced = _run(folder)
    assert requests > 10 and hits < requests  # cold: the solve and the small programs around it compiled
    assert traced == 1  # the solve, traced once (into the program kept in exported/), not again by jit
    # The solve itself was written (it had host callbacks from diffrax's argument checks, which
    # JAX never caches: tolerax.solve traces those checks in equinox's "nan" mode) ...
    assert any("solve" in p.name for p in folder.iterdir()), sorted(p.name for p in folder.iterdir())[:5]
    # ... and its traced program (tolerax.cache.exported_jit).
    assert len(list((folder / "exported").iterdir())) == 1
    _, requests_warm, hits_warm, result_warm, traced_warm = _run(folder)
    # Warm: nothing compiled (the cold process asks for a few more small programs: those
    # around the export).
    assert hits_warm == requests_warm and 10 < requests_warm <= requests
    assert traced_warm == 0  # nor traced
    assert result_warm == result  # bitwise the same simulation


def test_the_cache_can_be_turned_off(tmp_path, monkeypatch):
    """`TOLERAX_CACHE=off`: `enable_compilation_cache` returns None, makes no folder and leaves
    JAX's settings as they were (checked here in-process; a whole command run with it, writing
    nothing, in test_montecarlo_command_with_the_cache_equals_without)."""
    import jax

    import tolerax as tx

    before = (jax.config.jax_compilation_cache_dir, jax.config.jax_persistent_cache_min_compile_time_secs)
    folder = tmp_path / "cache"
    for off in ("off", "0", "no", "False"):
        monkeypatch.setenv("TOLERAX_CACHE", off)
        assert tx.enable_compilation_cache(folder) is None and not folder.exists()
        assert (jax.config.jax_compilation_cache_dir, jax.config.jax_persistent_cache_min_compile_time_secs) == before


USER_MODULE = """
import equinox as eqx

OFFSET = {offset}


class Law(eqx.Module):
    k: float = eqx.field(static=True)

    def __call__(self, x):
        return self.k * x + OFFSET


def apply(law, x):
    return law(x)
"""

USER_SCRIPT = """
import collections, sys
import jax, jax.numpy as jnp
from jax import monitoring
traced = collections.Counter()
monitoring.register_event_duration_secs_listener(
    lambda e, d, **kw: traced.update([kw.get("fun_name")]) if e.endswith("jaxpr_trace_duration") else None)
import tolerax as tx
from tolerax.cache import exported_jit
import userlaw
tx.enable_compilation_cache(sys.argv[1])
apply = exported_jit(userlaw.apply)
x = jnp.arange(3.0)
print("two", apply(userlaw.Law(2.0), x).tolist())
print("three", apply(userlaw.Law(3.0), x).tolist())
def here(law, x):  # defined in __main__: no source file to fingerprint, so never kept
    return 2 * law(x)
print("here", exported_jit(here)(userlaw.Law(2.0), x).tolist())
print("traced", traced["flat"])
"""


def _user_run(tmp_path, offset):
    (tmp_path / "userlaw.py").write_text(USER_MODULE.format(offset=offset))
    env = {k: v for k, v in os.environ.items() if k != "TOLERAX_CACHE"}
    env["PYTHONPATH"] = os.pathsep.join([str(tmp_path), *sys.path])
    out = subprocess.run([sys.executable, "-c", USER_SCRIPT, str(tmp_path / "cache")], env=env, capture_output=True,
                         text=True, check=True, timeout=300)
    lines = dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())
    kept = sorted(p.name for p in (tmp_path / "cache" / "exported").iterdir())
    return lines["two"], lines["three"], lines["here"], int(lines["traced"]), kept


def test_kept_programs_are_keyed_by_static_values_and_the_source_of_the_code_they_trace(tmp_path):
    """`exported_jit`'s programs kept between processes: one per static value (the law's `k`),
    read back without tracing, and never served to code that changed since: the same names
    with another module constant compute the new values (the module's source is in the key)."""
    two, three, here, traced, kept = _user_run(tmp_path, 1.0)
    assert (two, three, here) == ("[1.0, 3.0, 5.0]", "[1.0, 4.0, 7.0]", "[2.0, 6.0, 10.0]")
    assert traced == 2 and len(kept) == 2  # one program per static value; none for __main__'s function
    again = _user_run(tmp_path, 1.0)
    assert again[:3] == (two, three, here) and again[3] == 0 and again[4] == kept  # read back, not traced
    two, three, here, traced, kept_after_edit = _user_run(tmp_path, 10.0)
    assert (two, three, here) == ("[10.0, 12.0, 14.0]", "[10.0, 13.0, 16.0]", "[20.0, 24.0, 28.0]")
    assert traced == 2 and len(kept_after_edit) == 4


def test_montecarlo_command_with_the_cache_equals_without(tmp_path):
    """The command line's default path (cache on: the chunk's program exported, kept, read back)
    against the cache off (plain jit): the same units and outputs, bitwise, cold and warm."""
    import xarray as xr

    argv = [sys.executable, "-m", "tolerax.cli.main", "montecarlo", "scan-azimuth", "--n", "4", "--chunk", "2",
            "--duration", "0.05", "--settle", "0"]
    env = {k: v for k, v in os.environ.items() if k != "TOLERAX_CACHE"} | {"TOLERAX_CACHE_DIR": str(tmp_path / "cache")}
    runs = {}
    for name, extra in (("off", {"TOLERAX_CACHE": "off"}), ("cold", {}), ("warm", {})):
        subprocess.run([*argv, "--out", str(tmp_path / name)], env=env | extra, check=True, capture_output=True, timeout=600)
        runs[name] = xr.load_dataset(tmp_path / name / "montecarlo.nc")
        if name == "off":  # the off switch: the whole command wrote nothing where the cache would be
            assert not (tmp_path / "cache").exists()
    assert len(list((tmp_path / "cache" / "exported").iterdir())) >= 1
    for name in ("cold", "warm"):
        for var in runs["off"].variables:
            np.testing.assert_array_equal(runs[name][var].values, runs["off"][var].values)
