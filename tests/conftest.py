import gc
import os

import jax
import pytest

# Hermetic tests: the command line's persistent compilation cache stays off here (it would
# write under ~/.cache and make a test's compile depend on an earlier run); tests/test_cache.py
# turns it on in processes of its own.
os.environ["TOLERAX_CACHE"] = "off"

jax.config.update("jax_enable_x64", True)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After each test module, drop JAX's compiled programs: an xdist worker runs ~220 tests and
    otherwise keeps every program it compiled (several GB by the end, beside notebook kernels and
    command-line subprocesses on a 24 GB machine). CI once aborted inside an XLA compile at 97 %;
    programs are rarely shared between modules, so this costs little recompilation."""
    yield
    jax.clear_caches()
    gc.collect()


@pytest.fixture(scope="module")
def life_scan():
    """The azimuth scan at planetary fidelity (its stage wears): `test_life.py`,
    `test_life_flanks.py`."""
    import tolerax as tx  # here, not at the top: the cache setting above comes first

    return tx.scan("azimuth", fidelity=("planetary", "ideal"))
