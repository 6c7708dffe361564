"""JAX's persistent compilation cache for tolerax: compiled programs written to disk and read
back by the next process, so that a command, a notebook kernel or a Monte Carlo worker that
simulates a scene structure already compiled skips the compilation (seconds per solve;
`benchmarks/results/warm_start.md`).

- `enable_compilation_cache(path=None)`: turn it on (the command line does, unless
  `TOLERAX_CACHE=off`); in a notebook or script, `tx.enable_compilation_cache()` before the
  first simulation.
- The location: `path`, else `$TOLERAX_CACHE_DIR`, else `~/.cache/tolerax/jax` (under
  `$XDG_CACHE_HOME` where set). Delete the folder to empty it; JAX keys each program by its
  text, the JAX/XLA versions and the device, so a stale entry is never used.
- Monte Carlo workers (`backend="processes"` or `"dask"`) use the driver's cache folder.
"""

import os
import pathlib

import jax

OFF = ("0", "off", "no", "false")


def default_cache_dir() -> pathlib.Path:
    """`$TOLERAX_CACHE_DIR`, else `$XDG_CACHE_HOME/tolerax/jax`, else `~/.cache/tolerax/jax`."""
    if os.environ.get("TOLERAX_CACHE_DIR"):
        return pathlib.Path(os.environ["TOLERAX_CACHE_DIR"]).expanduser()
    return pathlib.Path(os.environ.get("XDG_CACHE_HOME") or "~/.cache").expanduser() / "tolerax" / "jax"


def enable_compilation_cache(path: str | os.PathLike | None = None) -> pathlib.Path | None:
    """Write compiled programs to `path` (default `default_cache_dir()`) and read them back in
    later processes; every program is cached, the small ones around a solve too (they are a
    hundred or so: together seconds). Returns the folder, or `None` where `TOLERAX_CACHE` is
    `off` (or `0`, `no`, `false`), which turns the cache off."""
    if os.environ.get("TOLERAX_CACHE", "").strip().lower() in OFF:
        return None
    folder = pathlib.Path(path).expanduser() if path is not None else default_cache_dir()
    folder.mkdir(parents=True, exist_ok=True)
    jax.config.update("jax_compilation_cache_dir", str(folder))
    jax.config.update("jax_persistent_cache_min_compile_time_secs", 0.0)
    jax.config.update("jax_persistent_cache_min_entry_size_bytes", 0)
    return folder


def compilation_cache_dir() -> str | None:
    """The folder of JAX's persistent compilation cache in this process, or `None`."""
    return jax.config.jax_compilation_cache_dir or None
