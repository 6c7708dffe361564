import gc
import os
import shutil
import tempfile

import jax
import pytest

# One compilation cache for the whole test run, shared by pytest-xdist's workers and the
# command-line subprocesses the tests start: the controller makes a fresh folder before the
# workers start (they inherit the environment) and removes it at the end, so the run stays
# hermetic (nothing read from or left in ~/.cache) while a program one module compiled is read
# back, not compiled again, by every other module and worker. `TOLERAX_TEST_CACHE=off` runs
# without it (every process compiles its own); tests/test_cache.py sets its own folders.
_OWNER = "TOLERAX_TEST_CACHE_OWNER"
_MADE_HERE = False  # whether this process made the run's cache folder (and removes it at the end)
if os.environ.get("TOLERAX_TEST_CACHE", "").strip().lower() in ("0", "off", "no", "false"):
    os.environ["TOLERAX_CACHE"] = "off"
elif "TOLERAX_CACHE_DIR" not in os.environ or os.environ.get(_OWNER) != os.environ.get("TOLERAX_CACHE_DIR"):
    # This process is the run's first (the controller, or the only one with `-n 0`): a folder of
    # its own; workers find it in the environment with the owner mark and keep it.
    os.environ["TOLERAX_CACHE_DIR"] = os.environ[_OWNER] = tempfile.mkdtemp(prefix="tolerax-test-cache-")
    os.environ.pop("TOLERAX_CACHE", None)
    _MADE_HERE = True

jax.config.update("jax_enable_x64", True)

# Monte Carlo's "auto" backend starts no worker processes in the suite (its two processes keep both
# cores busy, and a worker spawned in a gap would take time from the other): the tests that
# exercise the workers ask for them (`workers=`).
os.environ.setdefault("TOLERAX_MC_WORKERS", "0")
import tolerax  # noqa: E402  (after the environment above: it reads the cache settings)

tolerax.enable_compilation_cache()


def pytest_configure(config):
    if os.environ.get("TOLERAX_TEST_PROFILE"):  # where the time goes: tests/_compile_profile.py
        import _compile_profile

        _compile_profile.register(config)


# The files that take longest, longest first (summed test seconds of a whole run: tests/README.md).
# pytest-xdist (`--dist loadfile --no-loadscope-reorder`, pyproject.toml) hands whole files to
# the workers in collection order, each to the first worker free; longest first keeps both of
# CI's two cores busy to the end instead of one finishing a long file alone. The notebooks come
# after test_cli.py, whose designs and studies compile programs two of them read back from the
# run's cache (tests/_notebooks.py); test_hard_cases.py before test_bench.py (the bench
# program). A stale order costs only time, never a result. Last of all: the identification
# notebook, whose programs test_identify.py and the mission-life notebook compile.
_LAST = ("test_notebooks_identify.py",)
_LONGEST_FIRST = ("test_cli.py", "test_reliability.py", "test_life.py", "test_gradients.py", "test_scenefile.py",
                  "test_notebooks.py", "test_montecarlo.py", "test_mechanism.py", "test_loaded.py", "test_hard_cases.py",
                  "test_notebooks_physics.py", "test_cache.py", "test_identify.py", "test_bench.py", "test_design_values.py",
                  "test_joint.py", "test_outcome.py", "test_design.py", "test_planetary.py", "test_contact.py",
                  "test_requirements.py", "test_extending.py", "test_jitter.py", "test_optimise.py")


def pytest_collection_modifyitems(config, items):
    rank = {name: i for i, name in enumerate(_LONGEST_FIRST)}
    last = {name: len(rank) + 1 + i for i, name in enumerate(_LAST)}  # after the files not listed
    items.sort(key=lambda item: last.get(item.path.name, rank.get(item.path.name, len(rank))))  # stable: each file's own order kept


def pytest_unconfigure(config):
    if _MADE_HERE:
        shutil.rmtree(os.environ[_OWNER], ignore_errors=True)


@pytest.fixture(autouse=True, scope="module")
def _release_compiled_programs():
    """After each test module, drop JAX's in-memory programs: an xdist worker runs ~220 tests and
    otherwise keeps every program it compiled (several GB by the end, beside notebook kernels and
    command-line subprocesses on a 24 GB machine). CI once aborted inside an XLA compile at 97 %.
    A program another module needs again is read back from the run's compilation cache above,
    not compiled again."""
    yield
    jax.clear_caches()
    gc.collect()


@pytest.fixture(scope="module")
def life_scan():
    """The azimuth scan at planetary fidelity (its stage wears): `test_life.py`,
    `test_life_flanks.py`."""
    import tolerax as tx

    return tx.scan("azimuth", fidelity=("planetary", "ideal"))


@pytest.fixture(scope="session")
def scan_pointing():
    """The design layer's real scene: the lumped azimuth scan (both flanks and the pins engage
    after its reversal at 0.25 s) over 0.6 s from a steady start, 61 saves, the jitter above 20
    Hz among its outputs. One definition for every module (test_design, test_reliability,
    test_requirements, ...), so that a program one of them compiles is read back by the others
    from the run's compilation cache."""
    import tolerax as tx

    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    return tx.PointingObjective(scene, duration=0.6, settle=0.0, start="steady", n_save=61, jitter_cutoff=20.0)


@pytest.fixture(scope="session")
def scan_unit(scan_pointing):
    """One unit of `scan_pointing`: `scan_unit(values, width=1e-6)` (m, m; `None`: the scene's own
    width) -> its outputs, one compiled program for every test that evaluates single units of
    the scan."""
    import equinox as eqx
    import jax.numpy as jnp

    run = eqx.filter_jit(lambda pointing, values, width: pointing(values, width))
    return lambda values, width=1e-6: run(scan_pointing, jnp.asarray(values, dtype=float),
                                          None if width is None else jnp.asarray(width, dtype=float))
