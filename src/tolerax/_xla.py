"""JAX's and XLA's settings tolerax asks for before JAX starts its backend (a light module: the
package's import runs it first, without importing JAX where it is not imported yet)."""

import importlib.metadata
import os
import sys

OFF = ("0", "off", "no", "false")  # values of TOLERAX_CACHE, TOLERAX_XLA_FLAGS that turn a setting off

# XLA:CPU generates fused loops with its "fusion emitters" (MLIR) by default in recent jaxlibs;
# its classic emitters compile this project's programs faster, with the same running time and
# results (`benchmarks/compile_flags.py`: the planetary solve's gradient, a Monte Carlo chunk,
# single eager operations). Compilation is most of a cold command's and of the test suite's time,
# so tolerax asks for the classic emitters when it is imported before JAX has started its
# backend. Left alone: a user's own `xla_cpu_use_fusion_emitters` in `XLA_FLAGS`,
# `TOLERAX_XLA_FLAGS=off`, a backend already started (the flags are read once), and jaxlib
# versions this was not measured on (XLA aborts the process on a flag it does not know).
FAST_COMPILE_FLAG = "--xla_cpu_use_fusion_emitters=false"
_MEASURED_JAXLIB = ((0, 8), (0, 11))  # [from, to): measured on 0.10.2


def prefer_fast_compiles() -> bool:
    """Add `FAST_COMPILE_FLAG` to `XLA_FLAGS` where that is safe (see above); `tolerax`'s import
    calls it. Returns whether the flag is in effect for this process's XLA backend."""
    flags = os.environ.get("XLA_FLAGS", "")
    if "xla_cpu_use_fusion_emitters" in flags or os.environ.get("TOLERAX_XLA_FLAGS", "").strip().lower() in OFF:
        return FAST_COMPILE_FLAG in flags.split()
    try:
        version = tuple(int(x) for x in importlib.metadata.version("jaxlib").split(".")[:2])
    except (importlib.metadata.PackageNotFoundError, ValueError):
        return False
    if _backend_started() or not _MEASURED_JAXLIB[0] <= version < _MEASURED_JAXLIB[1]:
        return False
    os.environ["XLA_FLAGS"] = f"{flags} {FAST_COMPILE_FLAG}".strip()
    return True


def _backend_started() -> bool:
    if "jax" not in sys.modules:  # not imported yet: nothing started
        return False
    from jax._src import xla_bridge

    return xla_bridge.backends_are_initialized()


def enable_x64() -> None:
    """float64 by default (`jax_enable_x64`): set in JAX's configuration where JAX is imported
    already, else in its environment variable, which JAX reads when it is imported."""
    if "jax" in sys.modules:
        sys.modules["jax"].config.update("jax_enable_x64", True)
    else:
        os.environ["JAX_ENABLE_X64"] = "1"
