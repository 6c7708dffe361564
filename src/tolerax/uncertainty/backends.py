"""Monte Carlo's backends: how a chunk of units is evaluated (`evaluate`: vmapped, sharded over
local devices) and where (`"auto"`, `"vmap"`, `"processes"`, `"dask"`: `run_auto`, `run_chunks`),
for `tolerax.uncertainty.montecarlo`'s engine, which plans the chunks, keeps them on disk and
assembles the result."""

import concurrent.futures
import contextlib
import dataclasses
import functools
import hashlib
import multiprocessing
import os
import queue
import re
import sys
import time
import uuid
from collections.abc import Callable

import cloudpickle
import equinox as eqx
import jax
import numpy as np
from jax.sharding import Mesh, NamedSharding, PartitionSpec
from tqdm import tqdm

from ..cache import compilation_cache_dir, enable_compilation_cache, exported_jit

@dataclasses.dataclass(frozen=True)
class Plan:
    """Chunk k of a run is rows `span(k)` of the `n` rows `draw(start, stop)` gives (the features
    `names`); `settings` are what a resumed run must share (`monte_carlo`'s checkpoints)."""

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


WORKERS_VARIABLE = "TOLERAX_MC_WORKERS"  # at most this many worker processes beside the caller under "auto" (0: none)

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


def _tasks(payload: bytes, plan):
    """`task(k)`: the arguments that submit chunk `k` of `plan` to a worker (`_evaluate_payload`
    with the pickled model, this process's float64 setting and compilation-cache folder)."""
    x64 = bool(jax.config.read("jax_enable_x64"))
    cache_dir = compilation_cache_dir()
    return lambda k: (_evaluate_payload, payload, x64, plan.draw(*plan.span(k)), plan.chunk_size, cache_dir)


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


def _core_queue(context, cores):
    """A queue of `cores` that `_pin_worker` takes one from per worker process."""
    shared = context.Queue()
    for core in cores:
        shared.put(core)
    return shared


@contextlib.contextmanager
def _threads_kept_to(cores):
    """Every thread of this process (XLA's pool among them) kept to `cores` while the block runs,
    then all of them given the calling thread's cores back (Linux; elsewhere nothing changes): a
    process whose XLA runtime spreads a solve's kernels over every core would otherwise take time
    on the cores its workers were pinned to."""
    tasks = "/proc/self/task"
    if not cores or not os.path.isdir(tasks) or not hasattr(os, "sched_setaffinity"):
        yield
        return
    before = os.sched_getaffinity(0)

    def every(mask):
        for tid in os.listdir(tasks):
            with contextlib.suppress(OSError, ValueError):
                os.sched_setaffinity(int(tid), mask)

    every(set(cores))
    try:
        yield
    finally:
        every(before)


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
    counts), less one for this process, at most one per chunk beyond the first and at most
    `$TOLERAX_MC_WORKERS` (0: none, e.g. on a shared machine); `workers` overrides the count."""
    if chunks < 2:
        return 0, "one chunk"
    if jax.default_backend() != "cpu":
        return 0, f"on {jax.default_backend()}"
    if not _spawn_safe():
        return 0, ("this script has no `if __name__ == \"__main__\":` guard, which worker processes need "
                   "(or this is a worker itself)")
    if workers is not None:
        return max(0, min(int(workers), chunks - 1)), f"workers={workers}"
    cap = os.environ.get(WORKERS_VARIABLE, "").strip()
    if cap.isdigit() and int(cap) == 0:
        return 0, f"{WORKERS_VARIABLE}=0"
    cores, idle = _idle_cores()
    if cap.isdigit():
        idle = min(idle, int(cap) + 1)
    helpers = max(0, min(idle - 1, chunks - 1))
    return helpers, f"{cores} cores, {idle} idle"


def _idle_cores(interval: float = 0.1) -> tuple[int, int]:
    """`(cores this process may use, how many of them are idle now)`: the machine's idle share over
    `interval` seconds (Linux's /proc/stat), else over the last minute (the load average), times
    the cores, rounded. This process's own use counts as idle (read from /proc/self/stat): its
    work is what the workers share (a chunk still finishing from the last run, XLA's threads)."""
    cores = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else (os.cpu_count() or 1)
    total = os.cpu_count() or cores

    def ticks():
        with open("/proc/stat") as f:
            values = [int(x) for x in f.readline().split()[1:]]
        with open("/proc/self/stat") as f:
            own = f.read().rsplit(")", 1)[1].split()  # after the command's name: fields 3 onwards
        # all, idle + iowait, this process's user + system time (the same clock ticks)
        return sum(values), values[3] + (values[4] if len(values) > 4 else 0), int(own[11]) + int(own[12])

    try:
        (all0, idle0, own0), _, (all1, idle1, own1) = ticks(), time.sleep(interval), ticks()
        elapsed = max(all1 - all0, 1)
        busy = total * (1.0 - (idle1 - idle0) / elapsed) - total * (own1 - own0) / elapsed
    except (OSError, ValueError, IndexError):
        busy = os.getloadavg()[0] if hasattr(os, "getloadavg") else 0.0
    return cores, max(0, min(cores, round(total - busy)))


def run_auto(model, plan, todo, handle, save, workers, pin_workers, progress) -> None:
    """`backend="auto"`: this process evaluates chunks as `"vmap"` does (in a thread of its own,
    so that it can hand results on while it computes) and `helper_count` worker processes, each
    on an idle core at the lowest priority (`_helper_init`), take chunks beside it, one at a time.
    Nothing waits for a worker to start: once no chunk is left to start while no worker has handed
    back a chunk yet, this process computes a chunk a worker holds itself and keeps whichever result
    comes first (the backends' outputs are bitwise alike), so a run is never slower than `"vmap"` by
    more than starting the workers. Once workers deliver, nothing is duplicated: a duplicate would
    finish after the worker's own and run on in the background. Workers that fail (a model that
    does not pickle or import there) are dropped and their chunks computed here."""
    todo = list(todo)
    helpers, why = helper_count(len(todo), workers)
    payload = None
    if helpers:
        try:
            payload = cloudpickle.dumps(model)
        except Exception as err:  # noqa: BLE001 (any pickling failure: compute here)
            helpers, why = 0, f"the model does not pickle ({type(err).__name__})"
    if not helpers:
        return run_chunks(model, plan, "vmap", todo, handle, save, None, None)
    if progress:
        tqdm.write(f"Monte Carlo: {len(todo)} chunks, computed here and in {helpers} worker process"
                   f"{'es' if helpers > 1 else ''} on idle cores ({why})")
    task = _tasks(payload, plan)
    context = multiprocessing.get_context("spawn")
    shared, mine = None, None
    if pin_workers is not False and hasattr(os, "sched_setaffinity"):
        cores = sorted(os.sched_getaffinity(0))
        if len(cores) > helpers:  # the last cores: this process keeps the others
            shared, mine = _core_queue(context, cores[-helpers:]), cores[:-helpers]
    pool = concurrent.futures.ProcessPoolExecutor(helpers, mp_context=context, initializer=_helper_init, initargs=(shared,))
    here = concurrent.futures.ThreadPoolExecutor(1, thread_name_prefix="tolerax-chunks")
    waiting = list(todo)  # chunks not started anywhere
    running = {}  # future -> (chunk, "here" or "worker")
    done = set()
    pool_ok = True
    delivered = False  # whether a worker has handed back a chunk (it has started and runs at its core's pace)

    def start_here():
        if waiting:
            k = waiting.pop(0)
        elif not delivered:  # nothing left to start and no worker has finished a chunk yet (still starting):
            # compute a chunk a worker holds (the oldest), first result kept. Once workers deliver, a
            # duplicate would finish after the worker's own and run on in the background, where it
            # takes a core from whatever comes next.
            held = [k for k, where in running.values() if where == "worker" and k not in done]
            if not held:
                return
            k = held[0]
        else:
            return
        running[here.submit(evaluate, model, plan.draw(*plan.span(k)), plan.chunk_size)] = (k, "here")

    def start_worker():
        if waiting and pool_ok:
            k = waiting.pop(0)
            running[pool.submit(*task(k))] = (k, "worker")

    with _threads_kept_to(mine):
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
                    delivered = delivered or where == "worker"
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


def evaluate_rows(model, values, unit: int, *, workers: int | None = None, pin_workers: bool | None = None
                  ) -> dict[str, np.ndarray]:
    """`jax.vmap(model)` over the rows of `values` (a model as `monte_carlo` takes: a row of
    feature values -> a dict of arrays), computed as Monte Carlo's `"auto"` backend computes its
    chunks: the rows in chunks of about `unit` (the scene's `unit_chunk()`, `default_chunk`: as
    many chunks as `unit` fits the rows, rounded, evened out), this process taking them one by one
    and a worker process on each idle core beside it (`run_auto`, `helper_count`; `workers` as
    `monte_carlo`'s). The chunking depends on `unit` and the rows alone, never on how many cores
    are idle, so the same rows give bitwise the same outputs on a busy or an idle machine. What a
    design's response surfaces and secant fits simulate."""
    values = np.asarray(values)
    n = len(values)
    chunks = max(1, round(n / max(int(unit), 1)))
    plan = Plan((), n, max(-(-n // chunks), 1), lambda start, stop: values[start:stop], {})
    parts = {}
    run_auto(model, plan, range(plan.n_chunks), parts.__setitem__, parts.__setitem__, workers, pin_workers, False)
    return {name: np.concatenate([parts[k][name] for k in range(plan.n_chunks)]) for name in parts[0]}


def run_chunks(model, plan, backend, todo, handle, save, client, workers, pin_workers=None) -> None:
    if backend == "vmap":
        for k in todo:
            handle(k, evaluate(model, plan.draw(*plan.span(k)), plan.chunk_size))
        return
    args = _tasks(cloudpickle.dumps(model), plan)
    if backend == "processes":
        context = multiprocessing.get_context("spawn")
        pinning = {}
        cores = _worker_cores(workers, pin_workers)
        if cores is not None:
            pinning = dict(initializer=_pin_worker, initargs=(_core_queue(context, cores),))
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
