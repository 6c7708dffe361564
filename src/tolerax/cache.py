"""JAX's persistent compilation cache for tolerax: compiled programs written to disk and read
back by the next process, so that a command, a notebook kernel or a Monte Carlo worker that
simulates a scene structure already compiled skips the compilation (seconds per solve;
`benchmarks/warm_start.py` times a cold start against a warm one).

- `enable_compilation_cache(path=None)`: turn it on (the command line does, unless
  `TOLERAX_CACHE=off`); in a notebook or script, `tx.enable_compilation_cache()` before the
  first simulation.
- The location: `path`, else `$TOLERAX_CACHE_DIR`, else `~/.cache/tolerax/jax` (under
  `$XDG_CACHE_HOME` where set). Delete the folder to empty it; JAX keys each program by its
  text, the JAX/XLA versions and the device, so a stale entry is never used.
- Monte Carlo workers (`backend="processes"` or `"dask"`) use the driver's cache folder.
- `exported_jit(fn)`: a jitted function whose traced program is kept too (`jax.export`), in the
  folder's `exported/` subfolder, so that a later process skips the *tracing* of the programs
  that dominate a warm start (a design's value-and-gradient through the solve: 8 s of Python
  tracing on the design scan) as well as their compilation. See its docstring for the key.
"""

import functools
import hashlib
import importlib.metadata
import io
import os
import pathlib
import pickle
import sys
import types
import uuid

import equinox as eqx
import jax
import jax.export

from ._xla import OFF


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


# ---------------------------------------------------------------------------------------------
# Traced programs kept between processes (jax.export).

_VERSIONS = ("jax", "jaxlib", "equinox", "diffrax", "optimistix", "lineax", "optax", "numpy", "scipy", "jaxtyping", "tolerax")


@functools.cache
def _versions() -> tuple:
    out = []
    for name in _VERSIONS:
        try:
            out.append((name, importlib.metadata.version(name)))
        except importlib.metadata.PackageNotFoundError:
            out.append((name, None))
    return tuple(out)


@functools.cache
def _module_digest(name: str) -> str | None:
    """A digest of module `name`'s source file (its bytes; size and time for a compiled one), or
    `None` where it has no file (`__main__` of an interactive session, a notebook cell): code
    that cannot be fingerprinted is never served from the cache. A module of a library in the
    key's versions (JAX, equinox, diffrax, NumPy, ...) is covered by its version."""
    if name.partition(".")[0] in _VERSIONS:
        return "versioned"
    module = sys.modules.get(name)
    path = getattr(module, "__file__", None)
    if module is None or path is None or name == "__main__":
        return None
    path = pathlib.Path(path)
    try:
        if path.suffix == ".py":
            return hashlib.sha256(path.read_bytes()).hexdigest()
        stat = path.stat()
        return f"{path}:{stat.st_size}:{stat.st_mtime_ns}"
    except OSError:
        return None


@functools.cache
def _package_digest() -> str:
    """A digest of every tolerax source file: any edit to tolerax makes every key new."""
    root = pathlib.Path(__file__).parent
    digest = hashlib.sha256()
    for path in sorted(root.rglob("*.py")):
        digest.update(str(path.relative_to(root)).encode() + b"\0" + path.read_bytes())
    return digest.hexdigest()


class _Recorder(pickle.Pickler):
    """Pickles the static part of a call and records the module of every class and function it
    refers to (pickled by reference), so their source files enter the key."""

    def __init__(self, file):
        super().__init__(file, protocol=4)
        self.modules = set()

    def reducer_override(self, obj):
        if isinstance(obj, (type, types.FunctionType, types.BuiltinFunctionType)):
            self.modules.add(getattr(obj, "__module__", None) or "")
        else:
            self.modules.add(getattr(type(obj), "__module__", None) or "")
        return NotImplemented


def _key(fn, static, shapes) -> str | None:
    """The program's key: the function, the static part of its arguments (pickled, with the
    source of every module it refers to), the arrays' shapes and dtypes, float64 on or off, the
    backend, tolerax's own source and the versions of JAX and the libraries it traces through.
    `None` where something cannot be fingerprinted (then the call is an ordinary jit)."""
    buffer = io.BytesIO()
    recorder = _Recorder(buffer)
    try:
        recorder.dump((fn.__module__, fn.__qualname__, static, shapes))
    except Exception:  # an unpicklable static argument (a lambda, a local class): do not cache
        return None
    modules = sorted(recorder.modules | {fn.__module__})
    digests = [(m, _module_digest(m)) for m in modules if m and m != "builtins"]
    if any(d is None for _, d in digests):
        return None
    parts = (buffer.getvalue(), digests, _versions(), _package_digest(), bool(jax.config.read("jax_enable_x64")),
             jax.default_backend(), jax.local_device_count())
    return hashlib.sha256(pickle.dumps(parts, protocol=4)).hexdigest()


def _exported_dir() -> pathlib.Path | None:
    folder = compilation_cache_dir()
    return None if folder is None else pathlib.Path(folder) / "exported"


def exported_jit(fn, *, compiler_options: dict | None = None):
    """`eqx.filter_jit(fn)`, whose traced program is also kept on disk where the compilation
    cache is on (`enable_compilation_cache`): the first call of a structure traces `fn` once
    into a `jax.export.Exported` and writes it (with the structure of its output) to
    `exported/<key>` in the cache folder; a later process with the same key reads it back
    instead of tracing, and JAX's compilation cache serves its compiled code. Every call runs the
    exported program (cold or warm alike, so a warm process computes bitwise what the cold one
    did).

    The key (`_key`) covers what the trace depends on: the function, the static part of the
    arguments (pickled: every non-array field of the scene and objective, the Python numbers)
    with the source files of the modules of every class and function in it, the shapes and
    dtypes of the array arguments, float64, the backend and device count, a digest of
    tolerax's source and the versions of JAX, equinox, diffrax, optimistix, lineax, optax,
    NumPy, SciPy and jaxtyping. The files are pickles, read back only from the cache folder this
    process was given (as JAX's own cache).
    Where something cannot be fingerprinted (an unpicklable argument, code defined in
    `__main__` or a notebook cell) or exported, the call is an ordinary `eqx.filter_jit`.

    `compiler_options`: XLA options of the compiled program (`jax.jit`'s), on both paths. Call it
    on concrete arrays only (at the top level, not inside `jit`, `vmap` or `grad`): an exported
    program is not differentiated or batched here."""
    jitted = eqx.filter_jit(fn, compiler_options=compiler_options)
    programs = {}  # key -> (the jitted exported program, its output structure), or False: this process

    @functools.wraps(fn)
    def call(*args):
        folder = _exported_dir()
        if folder is None:
            return jitted(*args)
        dynamic, static = eqx.partition(args, eqx.is_array)
        leaves, treedef = jax.tree.flatten(dynamic)
        shapes = [(tuple(x.shape), str(x.dtype)) for x in leaves]
        key = _key(fn, (static, treedef), shapes)
        if key is None:
            return jitted(*args)
        if key not in programs:
            program = _load(folder / key)
            program = _export(fn, static, treedef, leaves, folder / key) if program is None else program
            if program is not False:
                exported, skeleton = program

                def run(*xs, exported=exported):
                    return exported.call(*xs)

                run.__name__ = run.__qualname__ = f"{fn.__name__}_exported"  # compiled as jit_<fn>_exported
                program = jax.jit(run, compiler_options=compiler_options), jax.tree.structure(skeleton)
            programs[key] = program
        program = programs[key]
        if program is False:  # could not be exported (here or in an earlier process): jit as usual
            return jitted(*args)
        run, out_tree = program
        return jax.tree.unflatten(out_tree, run(*leaves))

    return call


def _load(path: pathlib.Path):
    """The program kept at `path`: `(Exported, output skeleton)`, `False` where an earlier process
    could not export it, `None` where there is none (or the file is unreadable: trace again)."""
    try:
        blob = pickle.loads(path.read_bytes())
        if blob.get("failed"):
            return False
        return jax.export.deserialize(bytearray(blob["exported"])), blob["skeleton"]
    except Exception:  # absent, truncated or foreign
        return None


def _export(fn, static, treedef, leaves, path: pathlib.Path):
    skeleton = []

    def flat(*xs):
        out = fn(*eqx.combine(jax.tree.unflatten(treedef, list(xs)), static))
        out_leaves, out_tree = jax.tree.flatten(out)
        skeleton.append(jax.tree.unflatten(out_tree, list(range(len(out_leaves)))))
        return out_leaves

    try:
        exported = jax.export.export(jax.jit(flat))(*[jax.ShapeDtypeStruct(x.shape, x.dtype) for x in leaves])
        blob = pickle.dumps(dict(exported=bytes(exported.serialize()), skeleton=skeleton[-1]), protocol=4)
        program = exported, skeleton[-1]
    except Exception:  # a host callback (a progress meter), a custom call jax.export refuses: plain jit, here and later
        blob, program = pickle.dumps(dict(failed=True), protocol=4), False
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        tmp = path.with_name(f".{path.name}.{uuid.uuid4().hex}")
        tmp.write_bytes(blob)
        os.replace(tmp, path)
    except OSError:  # a read-only cache folder: keep it for this process only
        pass
    return program
