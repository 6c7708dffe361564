"""The persistent compilation cache (`tolerax.enable_compilation_cache`): a second process
reads every program, the solve included, from the cache and computes the same result; the off
switch."""

import os
import subprocess
import sys

SCRIPT = """
import collections, sys
from jax import monitoring
events = collections.Counter()
monitoring.register_event_listener(lambda e, **kw: events.update([e]))
import tolerax as tx
print("folder", tx.enable_compilation_cache(sys.argv[1]))
sf = tx.load_scene("scan-azimuth").replace(duration=0.05, settle=0.0)
r = sf.simulate()
print("requests", events["/jax/compilation_cache/compile_requests_use_cache"], "hits", events["/jax/compilation_cache/cache_hits"])
print("result", float(r.pointing_error[-1]).hex())
"""


def _run(folder, **env):
    env = {k: v for k, v in os.environ.items() if k != "TOLERAX_CACHE"} | env
    out = subprocess.run([sys.executable, "-c", SCRIPT, str(folder)], env=env, capture_output=True, text=True, check=True, timeout=600)
    lines = dict(line.split(" ", 1) for line in out.stdout.strip().splitlines())
    requests, _, hits = lines["requests"].split()
    return lines["folder"], int(requests), int(hits), lines["result"]


def test_a_second_process_reads_every_program_from_the_cache(tmp_path):
    folder = tmp_path / "cache"
    _, requests, hits, result = _run(folder)
    assert requests > 10 and hits < requests  # cold: the solve and the small programs around it compiled
    # The solve itself was written (it had host callbacks from diffrax's argument checks, which
    # JAX never caches: tolerax.solve traces those checks in equinox's "nan" mode).
    assert any("solve" in p.name for p in folder.iterdir()), sorted(p.name for p in folder.iterdir())[:5]
    _, requests_warm, hits_warm, result_warm = _run(folder)
    assert hits_warm == requests_warm == requests  # warm: nothing compiled
    assert result_warm == result  # bitwise the same simulation


def test_the_cache_can_be_turned_off(tmp_path):
    folder = tmp_path / "cache"
    printed, _, hits, _ = _run(folder, TOLERAX_CACHE="off")
    assert printed == "None" and hits == 0 and not folder.exists()
