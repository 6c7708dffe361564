"""Monte Carlo over manufacturing errors: one model, many manufactured units, in chunks.

The engine evaluates a *model* on rows of sampled values, chunk by chunk, on one of three backends,
writes each finished chunk to disk as it completes, and returns every sample's outputs as an
`xarray.Dataset`. A model is any picklable, jittable, vmappable callable

    model(values: Float[Array, "n_features"]) -> dict[str, Float[Array, ""]]

returning scalar outputs and a `"success"` entry (the solver's success flag): an equinox Module with
`__call__` is the expected kind. A failed sample is kept and flagged, never averaged in.

The checkpoint folder is `tolerax.uncertainty.checkpoint`; the result type, its statistics and
plots `tolerax.uncertainty.results`.
"""

import concurrent.futures
import contextlib
import dataclasses
import functools
import hashlib
import json
import multiprocessing
import os
import pickle
import queue
import re
import sys
import time
import uuid
from collections.abc import Callable, Mapping

import cloudpickle
import equinox as eqx
import jax
import numpy as np
import xarray as xr
from jax.sharding import Mesh, NamedSharding, PartitionSpec
from jaxtyping import PRNGKeyArray
from tqdm import tqdm  # the text bar: tqdm.auto warns in notebooks without ipywidgets
from ..cache import compilation_cache_dir, enable_compilation_cache, exported_jit
from .checkpoint import atomic_write, chunk_path, open_folder
from .results import MonteCarloResult
from .sampling import Tolerances, sample


BACKENDS = ("auto", "vmap", "processes", "dask")
_FORMAT = "tolerax-samples/1"


# ---------------------------------------------------------------------------------------------
# Evaluating a chunk: vmap inside, sharded over the local devices.


@exported_jit
def _vmapped(model, values):
    # Kept between processes with the compilation cache (`tolerax.cache.exported_jit`): a warm
    # driver or worker neither traces nor compiles the chunk's program.
    return jax.vmap(model)(values)


@functools.cache
def _sharded(n_devices: int):
    """The chunk's program over `n_devices` local devices, and the sharding that replicates an
    array over them."""
    mesh = Mesh(np.array(jax.local_devices()[:n_devices]), ("sample",))
    spec = PartitionSpec("sample")

    @eqx.filter_jit
    def run(model, values):
        # shard_map rather than a sharded jit: each device runs its own (while-)loops, so a
        # device whose samples finish early does not step in lockstep with the others.
        # check_vma=False: JAX's varying-manual-axes check rejects diffrax's solve inside
        # shard_map ("Primitive mul requires varying manual axes to match": a loop constant
        # multiplied by a per-device value), though every device computes its own samples with
        # no collective, which is what the check guards; JAX's message names this workaround.
        return jax.shard_map(lambda v: jax.vmap(model)(v), mesh=mesh, in_specs=spec, out_specs=spec, check_vma=False)(values)

    return run, NamedSharding(mesh, PartitionSpec())


def evaluate(model, values: np.ndarray, size: int | None = None) -> dict[str, np.ndarray]:
    """`jax.vmap(model)` over the rows of `values`, sharded over all local devices when there are
    several. The rows are padded (by repeating the last) to `size` and to a multiple of the device
    count, so every chunk of a run has one shape and compiles once; the padding is dropped."""
    n = len(values)
    n_devices = jax.local_device_count()
    size = max(size or n, n)
    size = -(-size // n_devices) * n_devices
    padded = np.concatenate([values, np.repeat(values[-1:], size - n, axis=0)])
    if n_devices == 1:
        out = _vmapped(model, padded)
    else:
        run, replicated = _sharded(n_devices)
        # The model's arrays go to every device: one committed to a single device (a user's
        # `jax.device_put`) would otherwise clash with the mesh ("incompatible devices").
        arrays, rest = eqx.partition(model, eqx.is_array)
        try:
            out = run(eqx.combine(jax.device_put(arrays, replicated), rest), padded)
        except Exception as err:
            raise RuntimeError(
                f"monte_carlo: the model failed when its chunk was split over the {n_devices} local devices "
                f"(jax.shard_map): {type(err).__name__}: {err}\nThe units are independent, so one device computes "
                "them too (to the solver's error): make one device visible before starting Python "
                "(CUDA_VISIBLE_DEVICES=0 on GPUs; on a CPU, no --xla_force_host_platform_device_count in XLA_FLAGS), "
                "or run each chunk in a worker of its own (backend='processes' or 'dask' with one device per worker)."
            ) from err
    out = jax.device_get(out)
    return {name: np.asarray(x)[:n] for name, x in out.items()}


_MODELS: dict[str, object] = {}  # per worker process: unpickle (and so compile) each model once


def _evaluate_payload(payload: bytes, x64: bool, values: np.ndarray, size: int, cache_dir: str | None = None) -> dict[str, np.ndarray]:
    """Worker entry point (processes, Dask). The model travels pickled and is unpickled here after
    float64 is set as in the driver, so its arrays keep their dtype; the worker uses the driver's
    persistent compilation cache folder (`tolerax.enable_compilation_cache`) where it has one."""
    jax.config.update("jax_enable_x64", x64)
    if cache_dir is not None and not jax.config.jax_compilation_cache_dir:
        try:
            enable_compilation_cache(cache_dir)
        except OSError:  # a Dask worker on another machine where that folder cannot be made: compile
            pass
    digest = hashlib.sha256(payload).hexdigest()
    if digest not in _MODELS:
        _MODELS[digest] = cloudpickle.loads(payload)
    return evaluate(_MODELS[digest], values, size)


def _pin_worker(cores) -> None:
    """Initializer of a `backend="processes"` worker: run on one core of its own, taken from the
    shared queue `cores`, before JAX starts (its CPU client sizes its thread pool to the process's
    cores). One solve's right-hand side is hundreds of microsecond kernels, which XLA's runtime
    hands between threads at a loss (a solve pinned to one core runs faster and steadier),
    and two free workers on two cores contend for both."""
    try:
        core = cores.get(timeout=10.0)
    except queue.Empty:  # more workers than cores were queued: run free
        return
    os.sched_setaffinity(0, {core})


def _helper_init(cores) -> None:
    """Initializer of a `backend="auto"` worker: the lowest scheduling priority (it takes only
    time no other work wants: the calling process, or another program started meanwhile, keeps
    its cores), then pinned as `_pin_worker` does where `cores` is a queue of cores."""
    with contextlib.suppress(OSError, AttributeError):
        os.nice(19)
    if cores is not None:
        _pin_worker(cores)


def _worker_cores(workers: int | None, pin: bool | None) -> list[int] | None:
    """The cores to pin `backend="processes"` workers to, one each, or None to leave them free:
    `pin=None` pins on a CPU backend when there are at least as many cores as workers."""
    if pin is False or not hasattr(os, "sched_setaffinity"):
        return None
    cores = sorted(os.sched_getaffinity(0))
    n = len(cores) if workers is None else int(workers)  # the pool's default is one per core
    if n > len(cores):
        if pin:
            raise ValueError(f"pin_workers=True needs a core per worker: {n} workers, {len(cores)} cores available.")
        return None
    if pin is None and jax.default_backend() != "cpu":  # a GPU's workers: leave the host free
        return None
    return cores[:n]


# ---------------------------------------------------------------------------------------------
# Runs: chunks, checkpoints, backends.


@dataclasses.dataclass(frozen=True)
class Plan:
    names: tuple[str, ...]
    n: int
    chunk_size: int
    draw: Callable[[int, int], np.ndarray]  # (start, stop) -> values, shape (stop - start, n_features)
    settings: dict  # JSON-ready; a resumed run must have the same

    @property
    def n_chunks(self) -> int:
        return -(-self.n // self.chunk_size)

    def span(self, k: int) -> tuple[int, int]:
        return k * self.chunk_size, min((k + 1) * self.chunk_size, self.n)


def _fingerprint(model) -> str | None:
    try:  # plain pickle: deterministic for module-level classes/functions and arrays
        return hashlib.sha256(pickle.dumps(model)).hexdigest()
    except Exception:
        return None


def _check_outputs(model, plan: Plan) -> None:
    dtype = jax.dtypes.canonicalize_dtype(np.float64)
    spec = jax.eval_shape(model, jax.ShapeDtypeStruct((len(plan.names),), dtype))
    if not isinstance(spec, dict) or "success" not in spec:
        raise TypeError(f"The model must return a dict of scalar outputs with a 'success' entry, got {spec!r}.")
    for name, leaf in spec.items():
        if not isinstance(name, str) or getattr(leaf, "shape", None) != ():
            raise TypeError(f"Model output {name!r} must be a scalar array under a string name, got {leaf!r}.")
        if name == "sample" or name in plan.names:
            raise ValueError(f"Model output {name!r} clashes with a feature name or 'sample'; rename it.")


def _chunk_dataset(plan: Plan, k: int, values: np.ndarray, outputs: dict[str, np.ndarray]) -> xr.Dataset:
    start, stop = plan.span(k)
    coords = {"sample": np.arange(start, stop)}
    coords |= {name: ("sample", values[:, j]) for j, name in enumerate(plan.names)}
    data = {name: ("sample", x) for name, x in sorted(outputs.items())}
    data["success"] = ("sample", np.asarray(outputs["success"]).astype(bool))
    return xr.Dataset(data, coords=coords)


def _finished_ok(future) -> bool:
    if isinstance(future, concurrent.futures.Future):
        return future.done() and not future.cancelled() and future.exception() is None
    return future.status == "finished"  # dask.distributed.Future


def _farm(futures: dict, as_completed, cancel, handle, save) -> None:
    """Hand each finished chunk to `handle` as it completes. On any error (a failed chunk, a
    broken pool, KeyboardInterrupt) the chunks that finished meanwhile are saved too (`save`: no
    callback), the rest cancelled, and the error raised."""
    pending = futures  # popped as handled, so that Dask can release the results
    try:
        for future in as_completed(list(futures)):
            k = pending.pop(future)
            handle(k, future.result())
    except BaseException:
        try:
            for future in [f for f in pending if _finished_ok(f)]:
                save(pending.pop(future), future.result())
        finally:
            cancel(list(pending))
        raise


def _spawn_safe() -> bool:
    """Whether worker processes can be started here with the spawn method: not inside a worker
    itself, and the main module either none (a notebook, `python -c`) or a file that guards its
    work with `if __name__ == "__main__":` (a spawned worker imports the main file again; without
    the guard it would run the script's Monte Carlo once more, then fail)."""
    if multiprocessing.parent_process() is not None:
        return False
    path = getattr(sys.modules.get("__main__"), "__file__", None)
    if path is None:
        return True
    try:
        with open(path, encoding="utf-8", errors="replace") as f:
            return re.search(r"__name__\s*==\s*['\"]__main__['\"]", f.read()) is not None
    except OSError:
        return False


def helper_count(chunks: int, workers: int | None = None) -> tuple[int, str]:
    """`(helpers, why)`: how many worker processes `backend="auto"` adds beside this one for a run
    of `chunks` chunks, and why in words. Helpers where the JAX backend is the CPU, the run has
    two chunks or more, this session can start workers (`_spawn_safe`) and cores are idle:
    the idle cores this process may use (`_idle_cores`: work already running on the others
    counts), less one for this process, at most one per chunk beyond the first; `workers`
    overrides the count."""
    if chunks < 2:
        return 0, "one chunk"
    if jax.default_backend() != "cpu":
        return 0, f"on {jax.default_backend()}"
    if not _spawn_safe():
        return 0, ("this script has no `if __name__ == \"__main__\":` guard, which worker processes need "
                   "(or this is a worker itself)")
    if workers is not None:
        return max(0, min(int(workers), chunks - 1)), f"workers={workers}"
    cores, idle = _idle_cores()
    helpers = max(0, min(idle - 1, chunks - 1))
    return helpers, f"{cores} cores, {idle} idle"


def _idle_cores(interval: float = 0.1) -> tuple[int, int]:
    """`(cores this process may use, how many of them are idle now)`: the machine's idle share over
    `interval` seconds (Linux's /proc/stat), else over the last minute (the load average), times
    the cores, rounded."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    total = os.cpu_count() or cores

    def ticks():
        with open("/proc/stat") as f:
            values = [int(x) for x in f.readline().split()[1:]]
        return sum(values), values[3] + (values[4] if len(values) > 4 else 0)  # all, idle + iowait

    try:
        (all0, idle0), _, (all1, idle1) = ticks(), time.sleep(interval), ticks()
        busy = total * (1.0 - (idle1 - idle0) / max(all1 - all0, 1))
    except (OSError, ValueError, IndexError):
        busy = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
    return cores, max(0, min(cores, round(total - busy)))


def _run_auto(model, plan: Plan, todo, handle, save, workers, pin_workers, progress) -> None:
    """`backend="auto"`: this process evaluates chunks as `"vmap"` does (in a thread of its own,
    so that it can hand results on while it computes) and `helper_count` worker processes, each
    on an idle core at the lowest priority (`_helper_init`), take chunks beside it, one at a time. Nothing waits for a worker: once no
    chunk is left to start, this process computes a chunk a worker still holds itself and keeps
    whichever result comes first (the backends' outputs are bitwise alike), so a run is never
    slower than `"vmap"` by more than starting the workers, and a short run never waits for a
    worker to start. Workers that fail (a model that does not pickle or import there) are dropped
    and their chunks computed here."""
    todo = list(todo)
    helpers, why = helper_count(len(todo), workers)
    payload = None
    if helpers:
        try:
            payload = cloudpickle.dumps(model)
        except Exception as err:  # noqa: BLE001 (any pickling failure: compute here)
            helpers, why = 0, f"the model does not pickle ({type(err).__name__})"
    if not helpers:
        return _run_chunks(model, plan, "vmap", todo, handle, save, None, None)
    if progress:
        tqdm.write(f"Monte Carlo: {len(todo)} chunks, computed here and in {helpers} worker process"
                   f"{'es' if helpers > 1 else ''} on idle cores ({why})")
    x64 = bool(jax.config.read("jax_enable_x64"))
    cache_dir = compilation_cache_dir()
    context = multiprocessing.get_context("spawn")
    shared = None
    if pin_workers is not False and hasattr(os, "sched_setaffinity"):
        cores = sorted(os.sched_getaffinity(0))
        if len(cores) > helpers:  # the last cores: this process keeps the others
            shared = context.Queue()
            for core in cores[-helpers:]:
                shared.put(core)
    pool = concurrent.futures.ProcessPoolExecutor(helpers, mp_context=context, initializer=_helper_init, initargs=(shared,))
    here = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="tolerax-chunks")
    waiting = list(todo)  # chunks not started anywhere
    running = {}  # future -> (chunk, "here" or "worker")
    done = set()
    pool_ok = True

    def start_here():
        if waiting:
            k = waiting.pop(0)
        else:  # nothing left to start: compute a chunk a worker holds (the oldest), first result kept
            held = [k for k, where in running.values() if where == "worker" and k not in done]
            if not held:
                return
            k = held[0]
        running[here.submit(evaluate, model, plan.draw(*plan.span(k)), plan.chunk_size)] = (k, "here")

    def start_worker():
        if waiting and pool_ok:
            k = waiting.pop(0)
            args = (_evaluate_payload, payload, x64, plan.draw(*plan.span(k)), plan.chunk_size, cache_dir)
            running[pool.submit(*args)] = (k, "worker")

    try:
        start_here()
        for _ in range(helpers):
            start_worker()
        while len(done) < len(todo):
            finished, _ = concurrent.futures.wait(list(running), return_when=concurrent.futures.FIRST_COMPLETED)
            for future in finished:
                k, where = running.pop(future)
                if where == "worker" and future.exception() is not None:
                    if pool_ok and progress:
                        tqdm.write(f"Monte Carlo: a worker process failed ({type(future.exception()).__name__}: "
                                   f"{future.exception()}); its chunks are computed here")
                    pool_ok = False
                    if k not in done and k not in [c for c, _ in running.values()]:
                        waiting.insert(0, k)
                    continue
                outputs = future.result()  # an error here (this process) is the model's: raised
                if k not in done:
                    done.add(k)
                    handle(k, outputs)
                if where == "here":
                    start_here()
                else:
                    start_worker()
            if not any(where == "here" for _, where in running.values()):
                start_here()  # a failed worker's chunk, or the last ones
    except BaseException:
        for future, (k, _) in list(running.items()):
            if k not in done and _finished_ok(future):
                done.add(k)
                save(k, future.result())
        raise
    finally:
        processes = list((getattr(pool, "_processes", None) or {}).values())  # gone after shutdown
        pool.shutdown(wait=False, cancel_futures=True)
        for process in processes:  # a worker may still compute a chunk already kept from here
            with contextlib.suppress(Exception):
                process.terminate()
        here.shutdown(wait=False, cancel_futures=True)


def _run_chunks(model, plan: Plan, backend, todo, handle, save, client, workers, pin_workers=None) -> None:
    if backend == "vmap":
        for k in todo:
            handle(k, evaluate(model, plan.draw(*plan.span(k)), plan.chunk_size))
        return
    payload = cloudpickle.dumps(model)
    x64 = bool(jax.config.read("jax_enable_x64"))
    cache_dir = compilation_cache_dir()
    args = lambda k: (_evaluate_payload, payload, x64, plan.draw(*plan.span(k)), plan.chunk_size, cache_dir)  # noqa: E731
    if backend == "processes":
        context = multiprocessing.get_context("spawn")
        pinning = {}
        cores = _worker_cores(workers, pin_workers)
        if cores is not None:
            shared = context.Queue()
            for core in cores:
                shared.put(core)
            pinning = dict(initializer=_pin_worker, initargs=(shared,))
        pool = concurrent.futures.ProcessPoolExecutor(workers, mp_context=context, **pinning)
        finished = False
        try:
            futures = {pool.submit(*args(k)): k for k in todo}
            _farm(futures, concurrent.futures.as_completed, lambda fs: [f.cancel() for f in fs], handle, save)
            finished = True
        finally:  # after an error, do not wait for the chunks still running: they are lost anyway
            pool.shutdown(wait=finished, cancel_futures=True)
        return
    import distributed

    own = isinstance(client, str)
    client = distributed.Client(client) if own else client
    try:
        token = uuid.uuid4().hex[:12]
        futures = {client.submit(*args(k), key=f"tolerax-chunk-{token}-{k:05d}"): k for k in todo}
        _farm(futures, distributed.as_completed, client.cancel, handle, save)
    finally:
        if own:
            client.close()


def run_samples(
    model, plan: Plan, *, backend, out, progress, client, workers, callback, units: Mapping[str, str] | None,
    pin_workers: bool | None = None,
) -> xr.Dataset:
    """Evaluate `model` on every chunk of `plan` not already finished in `out`; return all samples."""
    if backend not in BACKENDS:
        raise ValueError(f"backend must be one of {BACKENDS}, got {backend!r}.")
    if backend == "dask" and client is None:
        raise ValueError("backend='dask' needs client= (a dask.distributed.Client or a scheduler address).")
    if workers is not None and (int(workers) != workers or workers < 1):
        raise ValueError(f"workers must be a positive integer, got {workers!r}.")
    _check_outputs(model, plan)
    settings = dict(plan.settings, format=_FORMAT, names=list(plan.names), n=plan.n, chunk_size=plan.chunk_size)
    settings["model_sha256"] = _fingerprint(model)
    grow = settings.get("kind") == "monte_carlo"  # sample i depends on (key, i) alone: a run can grow
    folder, chunks = (None, {}) if out is None else open_folder(out, settings, grow=grow)
    for k, ds in list(chunks.items()):
        samples, span = ds["sample"].values, np.arange(*plan.span(k))
        if grow and k < plan.n_chunks and 0 < samples.size < span.size and np.array_equal(samples, span[: samples.size]):
            # The short last chunk of a run being extended: its samples begin this chunk, but a
            # batch of another size rounds otherwise; run the whole chunk again.
            chunk_path(folder, k).unlink()
            del chunks[k]
        elif k >= plan.n_chunks or not np.array_equal(samples, span):
            raise ValueError(f"{chunk_path(folder, k)} does not hold the samples of chunk {k}; is `out` shared?")
    bar = tqdm(total=plan.n_chunks, initial=len(chunks), disable=not progress, unit="chunk", desc="Monte Carlo")

    def save(k: int, outputs: dict[str, np.ndarray]) -> None:
        ds = _chunk_dataset(plan, k, plan.draw(*plan.span(k)), outputs)
        if folder is not None:
            atomic_write(chunk_path(folder, k), lambda tmp: ds.to_netcdf(tmp, engine="h5netcdf"))
        chunks[k] = ds
        bar.update()

    def handle(k: int, outputs: dict[str, np.ndarray]) -> None:
        save(k, outputs)
        if callback is not None:
            callback(k, chunks[k])

    todo = [k for k in range(plan.n_chunks) if k not in chunks]
    try:
        if backend == "auto":
            _run_auto(model, plan, todo, handle, save, workers, pin_workers, progress)
        else:
            _run_chunks(model, plan, backend, todo, handle, save, client, workers, pin_workers)
    except BaseException as err:
        if folder is not None and hasattr(err, "add_note"):  # Python >= 3.11
            err.add_note(
                f"tolerax: {len(chunks)} of {plan.n_chunks} chunks are saved in {folder}; "
                "run again with the same arguments to resume."
            )
        raise
    finally:
        bar.close()
    ds = xr.concat([chunks[k] for k in range(plan.n_chunks)], dim="sample", coords="minimal", compat="override",
                   join="exact", data_vars="all")
    for name in plan.names:
        ds[name].attrs["units"] = "m"
    for name, unit in (units or {}).items():
        if name in ds.variables:
            ds[name].attrs["units"] = unit
    ds.attrs["settings"] = json.dumps(settings)
    return ds


def typed_key(key) -> PRNGKeyArray:
    if not isinstance(key, jax.Array):
        raise TypeError(f"key must be a JAX PRNG key such as jax.random.key(0), got {key!r}.")
    return key if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) else jax.random.wrap_key_data(key)


def key_settings(key) -> dict:
    key = typed_key(key)
    return {"impl": str(jax.random.key_impl(key)), "data": np.asarray(jax.random.key_data(key)).tolist()}


def check_run(tolerances, **counts: int) -> None:
    if not isinstance(tolerances, Tolerances):
        raise TypeError(f"tolerances must be a tolerax Tolerances, got {type(tolerances).__name__}.")
    for name, value in counts.items():
        if not isinstance(value, (int, np.integer)) or isinstance(value, bool) or value < 1:
            raise ValueError(f"{name} must be a positive integer, got {value!r}.")


def monte_carlo(
    model,
    tolerances: Tolerances,
    n: int,
    key: PRNGKeyArray,
    *,
    backend: str = "auto",
    chunk_size: int = 64,
    out: str | os.PathLike | None = None,
    progress: bool = True,
    client=None,
    workers: int | None = None,
    pin_workers: bool | None = None,
    requirement: float | Mapping[str, float] | None = None,
    units: Mapping[str, str] | None = None,
    callback: Callable[[int, xr.Dataset], object] | None = None,
) -> "MonteCarloResult":
    """Evaluate `model` on `n` manufactured units drawn within `tolerances`.

    **Same key, same result.** Sample $i$ has the values `sample(tolerances, key, n)[i]` (drawn
    from `(key, i)` alone), so a run's *inputs* do not depend on the backend, the chunk size,
    interruptions or extensions. Its *outputs* are bitwise identical across backends, resumptions
    and extensions at the same chunk size on one device. Across chunk sizes (and device counts)
    they agree to the size of the solver's own error, not bitwise: a vmapped batch of another
    size is another program that rounds otherwise, and in an adaptive solve a rounding-level
    difference can flip one step's accept/reject decision, after which the two runs take
    different step sequences and differ by the integration error; where the response is chaotic
    (rattling joints at loose tolerances) that difference can exceed the error against a tighter
    solve (`benchmarks/monte_carlo_throughput.py` sets the difference beside the solver's own
    error, per scene). A resumed or extended run keeps the chunk size of its manifest.

    **Backends** (each runs the samples in chunks of `chunk_size`, with a tqdm bar over chunks):

    - `"auto"` (the default): `"vmap"` in this process, and beside it, where the CPU has idle
      cores and the run two chunks or more, worker processes that take chunks too (`"processes"`'
      evaluation, one per idle core, pinned, at the lowest scheduling priority so that they take
      only time nothing else wants; `helper_count` says how many and why). Once no chunk
      is left to start, this process also computes the chunk a worker still holds and keeps the
      first result, so a short run never waits for a worker to start; the outputs are bitwise
      those of `"vmap"`. No workers (plain `"vmap"`) on a GPU, with one chunk, on a busy machine,
      for a model that does not pickle, or in a script without the `if __name__ == "__main__":`
      guard. A speculative chunk still computing when the run ends finishes in the background.
    - `"vmap"`: in this process, `jax.vmap(model)` over each chunk, jit-compiled once; with
      several local devices (GPUs, or `XLA_FLAGS=--xla_force_host_platform_device_count=N` on a
      CPU), each chunk is split over them with `jax.shard_map` (the model's arrays replicated on
      every device; a model that fails there raises an error that says how to run it on one
      device). On GPUs take large chunks. On CPUs
      a vmapped adaptive solve steps until its slowest sample is done, so batching gains most
      where samples cost alike. For thousands of
      samples on a many-core machine `"processes"` wins once its start-up (one compile per
      worker) is paid.
    - `"processes"`: chunks farmed to `workers` processes of this machine
      (`concurrent.futures.ProcessPoolExecutor`, spawn start; default one per CPU core), each
      running `"vmap"`'s evaluation, each pinned to a core of its own on a CPU (`pin_workers`).
      A script calling it needs the `if __name__ == "__main__":` guard.
    - `"dask"`: chunks as tasks on a Dask cluster; `client` is a `dask.distributed.Client` or a
      scheduler address. On several machines: start `dask-scheduler` on one, `dask-worker
      tcp://SCHEDULER:8786 --nworkers 1 --nthreads 1` on each (or let `dask_jobqueue`'s
      `SLURMCluster` / `PBSCluster` submit them), with tolerax installed and the model's module
      importable on every worker, and pass `client="tcp://SCHEDULER:8786"`. A lost worker's
      chunks are rerun by the scheduler on another. Samples are independent, so multi-host
      accelerators need no collective: run one Dask worker per host and each shards its chunks
      over its own `jax.local_devices()`; if the hosts are started as one multi-controller JAX job
      (`jax.distributed.initialize()` in each worker, e.g. from a `WorkerPlugin`), the same holds,
      as the engine only ever uses the local devices.

    **Checkpoints.** With `out` a folder, a `manifest.json` of the settings is written first, and
    each chunk `k` as `chunk-0000k.nc` (netCDF, written to a temporary file then renamed) when it
    completes. Calling again with the same arguments loads the finished chunks and runs only the
    others: after Ctrl-C, a broken process pool or a lost node, nothing finished is lost or run
    twice. Calling again with a **larger `n`** and otherwise the same arguments **extends** the
    run (when its yield interval is too wide): the finished full chunks are kept, bitwise the
    ones a run at the larger `n` would compute (sample $i$ depends on `(key, i)` alone, and a
    chunk's batch is the same), the short last chunk of the smaller run is run again whole, and
    the new chunks are added. Other changes (a smaller n, chunk size, key, tolerances, or a
    differently pickled model) are refused.

    **Arguments:**

    - `model`: `model(values) -> dict` of scalar outputs with a `"success"` entry (see the module
      docstring). For `"processes"`/`"dask"` it must pickle (with cloudpickle) and its class or
      function must be importable on the workers: define it at module level in a package, not in
      a notebook cell or `__main__`, unless it is plain cloudpickle-able code.
    - `tolerances`: the `Tolerances` to draw from.
    - `n`: number of samples.
    - `key`: JAX PRNG key.
    - `backend`: `"auto"`, `"vmap"`, `"processes"` or `"dask"`.
    - `chunk_size`: samples per chunk (the vmap batch, the unit of work and of checkpointing).
    - `out`: folder for checkpoints, or `None` to keep the run in memory only.
    - `progress`: show a progress bar.
    - `client`: Dask client or scheduler address (for `backend="dask"`).
    - `workers`: processes for `backend="processes"` (default: CPU count); for `"auto"`, the
      worker processes beside this one (default: one per idle core).
    - `pin_workers`: for `backend="processes"`, run each worker on one core of its own
      (`os.sched_setaffinity`, Linux): `None` (default) does so on a CPU backend when there are
      at least as many cores as workers, `True` insists (an error otherwise), `False` leaves the
      workers free. XLA's runtime spreads one solve's small kernels over every core it may use,
      at a loss: pinned workers are faster with samples of a second or more, but a pinned
      worker also compiles on its one core, so for many very short samples `False` starts
      faster.
    - `requirement`: default requirement of `MonteCarloResult.summary` (output units).
    - `units`: units of the outputs, e.g. `{"pointing_error": "arcsec"}` (features are in m).
    - `callback`: called as `callback(k, chunk_dataset)` in the driver after chunk `k` is saved.

    **Returns:**

    A `MonteCarloResult`: every sample's outputs, success flag and sampled values.
    """
    check_run(tolerances, n=n, chunk_size=chunk_size)
    key = typed_key(key)
    settings = {"kind": "monte_carlo", "key": key_settings(key), "tolerances": tolerances.to_json()}
    draw = lambda start, stop: np.asarray(sample(tolerances, key, stop - start, first=start))  # noqa: E731
    plan = Plan(tolerances.names, int(n), int(chunk_size), draw, settings)
    ds = run_samples(model, plan, backend=backend, out=out, progress=progress, client=client, workers=workers,
                     callback=callback, units=units, pin_workers=pin_workers)
    return MonteCarloResult(ds, requirement=requirement)
