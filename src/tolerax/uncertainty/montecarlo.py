"""Monte Carlo over manufacturing errors: one model, many manufactured units, in chunks.

The engine evaluates a *model* on rows of sampled values, chunk by chunk, on one of three backends,
writes each finished chunk to disk as it completes, and returns every sample's outputs as an
`xarray.Dataset`. A model is any picklable, jittable, vmappable callable

    model(values: Float[Array, "n_features"]) -> dict[str, Float[Array, ""]]

returning scalar outputs and a `"success"` entry (the solver's success flag): an equinox Module with
`__call__` is the expected kind. A failed sample is kept and flagged, never averaged in.

(This module is longer than our ~500-line guide, about 370 lines of code: the backends, the
checkpoint folder and the result type all read the same run plan and chunk format, and are kept
together until the result type grows enough to stand alone.)
"""

import concurrent.futures
import dataclasses
import functools
import hashlib
import json
import multiprocessing
import os
import pathlib
import pickle
import queue
import statistics
import uuid
from collections.abc import Callable, Mapping

import cloudpickle
import equinox as eqx
import jax
import numpy as np
import xarray as xr
from jax.sharding import Mesh, PartitionSpec
from jaxtyping import PRNGKeyArray
from tqdm import tqdm  # the text bar: tqdm.auto warns in notebooks without ipywidgets
from .sampling import Tolerances, sample


BACKENDS = ("vmap", "processes", "dask")
QUANTILES = (0.5, 0.9, 0.95, 0.99)
_FORMAT = "tolerax-samples/1"


# ---------------------------------------------------------------------------------------------
# Evaluating a chunk: vmap inside, sharded over the local devices.


@eqx.filter_jit
def _vmapped(model, values):
    return jax.vmap(model)(values)


@functools.cache
def _sharded(n_devices: int):
    mesh = Mesh(np.array(jax.local_devices()[:n_devices]), ("sample",))
    spec = PartitionSpec("sample")

    @eqx.filter_jit
    def run(model, values):
        # shard_map rather than a sharded jit: each device runs its own (while-)loops, so a
        # device whose samples finish early does not step in lockstep with the others.
        return jax.shard_map(lambda v: jax.vmap(model)(v), mesh=mesh, in_specs=spec, out_specs=spec)(values)

    return run


def evaluate(model, values: np.ndarray, size: int | None = None) -> dict[str, np.ndarray]:
    """`jax.vmap(model)` over the rows of `values`, sharded over all local devices when there are
    several. The rows are padded (by repeating the last) to `size` and to a multiple of the device
    count, so every chunk of a run has one shape and compiles once; the padding is dropped."""
    n = len(values)
    n_devices = jax.local_device_count()
    size = max(size or n, n)
    size = -(-size // n_devices) * n_devices
    padded = np.concatenate([values, np.repeat(values[-1:], size - n, axis=0)])
    run = _vmapped if n_devices == 1 else _sharded(n_devices)
    out = jax.device_get(run(model, padded))
    return {name: np.asarray(x)[:n] for name, x in out.items()}


_MODELS: dict[str, object] = {}  # per worker process: unpickle (and so compile) each model once


def _evaluate_payload(payload: bytes, x64: bool, values: np.ndarray, size: int) -> dict[str, np.ndarray]:
    """Worker entry point (processes, Dask). The model travels pickled and is unpickled here after
    float64 is set as in the driver, so its arrays keep their dtype."""
    jax.config.update("jax_enable_x64", x64)
    digest = hashlib.sha256(payload).hexdigest()
    if digest not in _MODELS:
        _MODELS[digest] = cloudpickle.loads(payload)
    return evaluate(_MODELS[digest], values, size)


def _pin_worker(cores) -> None:
    """Initializer of a `backend="processes"` worker: run on one core of its own, taken from the
    shared queue `cores`, before JAX starts (its CPU client sizes its thread pool to the process's
    cores). One solve's right-hand side is hundreds of microsecond kernels, which XLA's runtime
    hands between threads at a loss: a planetary solve pinned to one core ran 0.87x the time of
    one free (benchmarks/results/pinning.md), and two free workers on two cores contend for both."""
    try:
        core = cores.get(timeout=10.0)
    except queue.Empty:  # more workers than cores were queued: run free
        return
    os.sched_setaffinity(0, {core})


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
class _Plan:
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


def _check_outputs(model, plan: _Plan) -> None:
    dtype = jax.dtypes.canonicalize_dtype(np.float64)
    spec = jax.eval_shape(model, jax.ShapeDtypeStruct((len(plan.names),), dtype))
    if not isinstance(spec, dict) or "success" not in spec:
        raise TypeError(f"The model must return a dict of scalar outputs with a 'success' entry, got {spec!r}.")
    for name, leaf in spec.items():
        if not isinstance(name, str) or getattr(leaf, "shape", None) != ():
            raise TypeError(f"Model output {name!r} must be a scalar array under a string name, got {leaf!r}.")
        if name == "sample" or name in plan.names:
            raise ValueError(f"Model output {name!r} clashes with a feature name or 'sample'; rename it.")


def _chunk_path(out: pathlib.Path, k: int) -> pathlib.Path:
    return out / f"chunk-{k:05d}.nc"


def _open_folder(out, settings: dict) -> tuple[pathlib.Path, dict[int, xr.Dataset]]:
    """Create `out` with its manifest, or check that the manifest there matches; load the chunks
    already finished there."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    manifest = out / "manifest.json"
    settings = json.loads(json.dumps(settings))  # as it reads back (tuples become lists)
    if manifest.exists():
        previous = json.loads(manifest.read_text())
        if previous != settings:
            raise ValueError(
                f"{out} holds a run with other settings ({'; '.join(_differences(previous, settings))}). "
                "Resume with the same arguments, or give another `out` folder."
            )
    else:
        if any(out.glob("chunk-*.nc")):
            raise ValueError(f"{out} holds chunk files but no manifest.json; give an empty or new `out` folder.")
        _atomic(manifest, lambda tmp: tmp.write_text(json.dumps(settings, indent=1)))
    for stale in out.glob("*.tmp"):
        stale.unlink()  # written by a run killed mid-write: never renamed, so never counted
    done = {}
    for path in sorted(out.glob("chunk-*.nc")):
        done[int(path.stem.split("-")[1])] = xr.load_dataset(path, engine="h5netcdf")
    return out, done


def _differences(there: dict, now: dict, prefix: str = "") -> list[str]:
    lines = []
    for key in sorted(there.keys() | now.keys()):
        old, new = there.get(key), now.get(key)
        if isinstance(old, dict) and isinstance(new, dict):
            lines += _differences(old, new, f"{prefix}{key}.")
        elif old != new:
            lines.append(f"{prefix}{key}: {old!r} there, {new!r} now")
    return lines


def _atomic(path: pathlib.Path, write: Callable[[pathlib.Path], object]) -> None:
    tmp = path.with_name(f"{path.name}.{uuid.uuid4().hex[:8]}.tmp")
    write(tmp)
    os.replace(tmp, path)  # atomic: a chunk file exists whole or not at all


def _chunk_dataset(plan: _Plan, k: int, values: np.ndarray, outputs: dict[str, np.ndarray]) -> xr.Dataset:
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


def _run_chunks(model, plan: _Plan, backend, todo, handle, save, client, workers, pin_workers=None) -> None:
    if backend == "vmap":
        for k in todo:
            handle(k, evaluate(model, plan.draw(*plan.span(k)), plan.chunk_size))
        return
    payload = cloudpickle.dumps(model)
    x64 = bool(jax.config.read("jax_enable_x64"))
    args = lambda k: (_evaluate_payload, payload, x64, plan.draw(*plan.span(k)), plan.chunk_size)  # noqa: E731
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
    model, plan: _Plan, *, backend, out, progress, client, workers, callback, units: Mapping[str, str] | None,
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
    folder, chunks = (None, {}) if out is None else _open_folder(out, settings)
    for k, ds in chunks.items():
        if k >= plan.n_chunks or not np.array_equal(ds["sample"].values, np.arange(*plan.span(k))):
            raise ValueError(f"{_chunk_path(folder, k)} does not hold the samples of chunk {k}; is `out` shared?")
    bar = tqdm(total=plan.n_chunks, initial=len(chunks), disable=not progress, unit="chunk", desc="Monte Carlo")

    def save(k: int, outputs: dict[str, np.ndarray]) -> None:
        ds = _chunk_dataset(plan, k, plan.draw(*plan.span(k)), outputs)
        if folder is not None:
            _atomic(_chunk_path(folder, k), lambda tmp: ds.to_netcdf(tmp, engine="h5netcdf"))
        chunks[k] = ds
        bar.update()

    def handle(k: int, outputs: dict[str, np.ndarray]) -> None:
        save(k, outputs)
        if callback is not None:
            callback(k, chunks[k])

    todo = [k for k in range(plan.n_chunks) if k not in chunks]
    try:
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


def _typed_key(key) -> PRNGKeyArray:
    if not isinstance(key, jax.Array):
        raise TypeError(f"key must be a JAX PRNG key such as jax.random.key(0), got {key!r}.")
    return key if jax.dtypes.issubdtype(key.dtype, jax.dtypes.prng_key) else jax.random.wrap_key_data(key)


def key_settings(key) -> dict:
    key = _typed_key(key)
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
    backend: str = "vmap",
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

    Sample $i$ has the values `sample(tolerances, key, n)[i]` (drawn from `(key, i)` alone), so a
    run's *inputs* do not depend on the backend, the chunk size or on interruptions, and its
    outputs are bitwise identical across backends and resumptions at the same chunk size. The
    chunk size itself changes a solver's outputs at rounding level, which an adaptive solve may
    amplify (a vmapped batch is one program that rounds differently; measured on the scan scene:
    up to 1.3e-5 relative, benchmarks/results/monte_carlo_throughput.md); a resumed run keeps
    the chunk size of its manifest.

    **Backends** (each runs the samples in chunks of `chunk_size`, with a tqdm bar over chunks):

    - `"vmap"`: in this process, `jax.vmap(model)` over each chunk, jit-compiled once; with
      several local devices (GPUs, or `XLA_FLAGS=--xla_force_host_platform_device_count=N` on a
      CPU), each chunk is split over them with `jax.shard_map`. On GPUs take large chunks. On CPUs
      a vmapped adaptive solve steps until its slowest sample is done: on the lumped scan chunks
      of 16 ran 4x faster than one at a time, on the planetary one (whose samples differ more in
      cost) batching gained 1.1x (benchmarks/results/monte_carlo_throughput.md). For thousands of
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
    twice. Different settings (n, chunk size, key, tolerances, or a differently pickled model)
    are refused.

    **Arguments:**

    - `model`: `model(values) -> dict` of scalar outputs with a `"success"` entry (see the module
      docstring). For `"processes"`/`"dask"` it must pickle (with cloudpickle) and its class or
      function must be importable on the workers: define it at module level in a package, not in
      a notebook cell or `__main__`, unless it is plain cloudpickle-able code.
    - `tolerances`: the `Tolerances` to draw from.
    - `n`: number of samples.
    - `key`: JAX PRNG key.
    - `backend`: `"vmap"`, `"processes"` or `"dask"`.
    - `chunk_size`: samples per chunk (the vmap batch, the unit of work and of checkpointing).
    - `out`: folder for checkpoints, or `None` to keep the run in memory only.
    - `progress`: show a progress bar.
    - `client`: Dask client or scheduler address (for `backend="dask"`).
    - `workers`: processes for `backend="processes"` (default: CPU count).
    - `pin_workers`: for `backend="processes"`, run each worker on one core of its own
      (`os.sched_setaffinity`, Linux): `None` (default) does so on a CPU backend when there are
      at least as many cores as workers, `True` insists (an error otherwise), `False` leaves the
      workers free. XLA's runtime spreads one solve's small kernels over every core it may use,
      at a loss (`benchmarks/results/pinning.md`): pinned, two workers' calls took 0.80-0.88x
      the time of free ones with samples of a second or more, but a pinned worker also
      compiles on its one core, so for many very short samples `False` starts faster
      (`benchmarks/results/monte_carlo_pinning.md`).
    - `requirement`: default requirement of `MonteCarloResult.summary` (output units).
    - `units`: units of the outputs, e.g. `{"pointing_error": "arcsec"}` (features are in m).
    - `callback`: called as `callback(k, chunk_dataset)` in the driver after chunk `k` is saved.

    **Returns:**

    A `MonteCarloResult`: every sample's outputs, success flag and sampled values.
    """
    check_run(tolerances, n=n, chunk_size=chunk_size)
    key = _typed_key(key)
    settings = {"kind": "monte_carlo", "key": key_settings(key), "tolerances": tolerances.to_json()}
    draw = lambda start, stop: np.asarray(sample(tolerances, key, stop - start, first=start))  # noqa: E731
    plan = _Plan(tolerances.names, int(n), int(chunk_size), draw, settings)
    ds = run_samples(model, plan, backend=backend, out=out, progress=progress, client=client, workers=workers,
                     callback=callback, units=units, pin_workers=pin_workers)
    return MonteCarloResult(ds, requirement=requirement)


# ---------------------------------------------------------------------------------------------
# Results and statistics.


def wilson_interval(successes, trials, confidence: float = 0.95) -> tuple[np.ndarray, np.ndarray]:
    """Wilson score interval for a proportion: with $\\hat p = k/n$ and $z$ the normal quantile,
    $(\\hat p + z^2/2n \\pm z\\sqrt{\\hat p(1-\\hat p)/n + z^2/4n^2}) / (1 + z^2/n)$. Unlike the
    normal approximation it stays inside [0, 1] and is not empty at $\\hat p \\in \\{0, 1\\}$."""
    z = statistics.NormalDist().inv_cdf(0.5 + confidence / 2)
    k, n = np.asarray(successes, dtype=float), np.asarray(trials, dtype=float)
    p = k / n
    centre = (p + z**2 / (2 * n)) / (1 + z**2 / n)
    half = z / (1 + z**2 / n) * np.sqrt(p * (1 - p) / n + z**2 / (4 * n**2))
    return np.clip(centre - half, 0.0, 1.0), np.clip(centre + half, 0.0, 1.0)


class MonteCarloResult:
    """Every sample of a Monte Carlo run, as `dataset`: an `xarray.Dataset` along `sample` with one
    variable per model output, `success`, and the sampled values as coordinates named by feature
    (m); `dataset.attrs["settings"]` is the run's manifest (JSON).

    Statistics use the samples whose `success` is true and whose output is finite; the others
    are counted (`n_failed`, `n_nonfinite`), never averaged in.
    """

    def __init__(self, dataset: xr.Dataset, requirement: float | Mapping[str, float] | None = None):
        self.dataset = dataset
        self.requirement = requirement

    @property
    def features(self) -> tuple[str, ...]:
        return tuple(json.loads(self.dataset.attrs["settings"])["names"])

    @property
    def outputs(self) -> tuple[str, ...]:
        return tuple(name for name in self.dataset.data_vars if name != "success")

    @property
    def success(self) -> np.ndarray:
        return self.dataset["success"].values

    def save(self, path: str | os.PathLike) -> None:
        """Write the dataset to netCDF (h5netcdf), atomically."""
        path = pathlib.Path(path)
        _atomic(path, lambda tmp: self.dataset.to_netcdf(tmp, engine="h5netcdf"))

    @classmethod
    def load(cls, path: str | os.PathLike, requirement=None) -> "MonteCarloResult":
        """Read a result written by `save`."""
        return cls(xr.load_dataset(path, engine="h5netcdf"), requirement)

    def _used(self, output: str) -> tuple[np.ndarray, np.ndarray]:
        if output not in self.outputs:
            raise ValueError(f"Unknown output {output!r}; the outputs are {self.outputs}.")
        y = self.dataset[output].values
        used = self.success & np.isfinite(y)
        if not used.any():
            raise ValueError(f"No successful sample with a finite {output!r} ({(~self.success).sum()} failed).")
        return y, used

    def summary(self, requirement: float | Mapping[str, float] | None = None, confidence: float = 0.95) -> dict:
        """Statistics per output over the successful samples.

        **Arguments:**

        - `requirement`: a threshold (output units) for every output, or a mapping output ->
          threshold; default the run's `requirement`.
        - `confidence`: level of the yield's Wilson score interval.

        **Returns:**

        `{output: {...}}` with `n_samples`, `n_failed` (solver failures), `n_nonfinite`
        (successful but non-finite output), `n_used`, `mean`, `std` (ddof 1), `min`, `max`,
        `q50`, `q90`, `q95`, `q99`, and with a requirement `requirement`, `yield` (fraction of the
        used samples with output <= requirement) and `yield_low`, `yield_high`.
        """
        requirement = self.requirement if requirement is None else requirement
        table = {}
        for output in self.outputs:
            y, used = self._used(output)
            values = y[used].astype(float)
            row = dict(
                n_samples=y.size, n_failed=int((~self.success).sum()),
                n_nonfinite=int((self.success & ~np.isfinite(y)).sum()), n_used=int(used.sum()),
                mean=float(values.mean()), std=float(values.std(ddof=1)) if values.size > 1 else 0.0,
                min=float(values.min()), max=float(values.max()),
            )
            row |= {f"q{round(100 * q)}": float(np.quantile(values, q)) for q in QUANTILES}
            limit = requirement.get(output) if isinstance(requirement, Mapping) else requirement
            if limit is not None:
                passed = int((values <= limit).sum())
                low, high = wilson_interval(passed, values.size, confidence)
                row |= {"requirement": float(limit), "yield": passed / values.size,
                        "yield_low": float(low), "yield_high": float(high)}
            table[output] = row
        return table

    def report(self, requirement=None) -> str:
        """The summary as readable lines."""
        lines = []
        for output, row in self.summary(requirement).items():
            text = (f"{output}: {row['n_used']} of {row['n_samples']} samples used ({row['n_failed']} failed, "
                    f"{row['n_nonfinite']} non-finite); mean {row['mean']:.6g}, std {row['std']:.6g}, "
                    f"q50/q90/q95/q99 {row['q50']:.6g}/{row['q90']:.6g}/{row['q95']:.6g}/{row['q99']:.6g}")
            if "yield" in row:
                text += (f"; yield at <= {row['requirement']:.6g}: {row['yield']:.4f} "
                         f"[{row['yield_low']:.4f}, {row['yield_high']:.4f}]")
            lines.append(text)
        return "\n".join(lines)

    def drivers(self, output: str) -> dict[str, float]:
        """Spearman rank correlation of `output` with each feature over the used samples (0 for a
        feature that does not vary), strongest first."""
        y, used = self._used(output)
        rank = lambda x: np.argsort(np.argsort(x, kind="stable"), kind="stable").astype(float)  # noqa: E731
        ry = rank(y[used])
        result = {}
        for name in self.features:
            rx = rank(self.dataset[name].values[used])
            spread = rx.std() * ry.std()
            result[name] = float(np.mean((rx - rx.mean()) * (ry - ry.mean())) / spread) if spread > 0 else 0.0
        return dict(sorted(result.items(), key=lambda item: -abs(item[1])))

    def _label(self, name: str, units: Mapping[str, str] | None) -> str:
        unit = (units or {}).get(name, self.dataset[name].attrs.get("units"))
        return f"{name} ({unit})" if unit else name

    @staticmethod
    def _axes(ax):
        import matplotlib.pyplot as plt

        return plt.subplots()[1] if ax is None else ax

    def plot_histogram(self, output: str, *, requirement=None, units=None, bins: int = 50, ax=None):
        """Histogram of `output` over the used samples, with the requirement as a vertical line."""
        ax = self._axes(ax)
        y, used = self._used(output)
        ax.hist(y[used], bins=bins)
        requirement = self.requirement if requirement is None else requirement
        limit = requirement.get(output) if isinstance(requirement, Mapping) else requirement
        if limit is not None:
            ax.axvline(limit, color="k", linestyle="--", label="requirement")
            ax.legend()
        ax.set_xlabel(self._label(output, units))
        ax.set_ylabel("samples")
        ax.set_title(f"{used.sum()} of {y.size} samples ({(~self.success).sum()} failed)")
        return ax

    def plot_yield_curve(self, output: str, *, units=None, confidence: float = 0.95, ax=None):
        """Yield (fraction of used samples with output <= requirement) against the requirement,
        with its Wilson score band."""
        ax = self._axes(ax)
        y, used = self._used(output)
        values = np.sort(y[used])
        passed = np.arange(1, values.size + 1)
        low, high = wilson_interval(passed, values.size, confidence)
        ax.step(values, passed / values.size, where="post", label="yield")
        ax.fill_between(values, low, high, step="post", alpha=0.3, label=f"{confidence:.0%} interval")
        ax.set_xlabel("requirement on " + self._label(output, units))
        ax.set_ylabel("yield")
        ax.legend()
        return ax

    def plot_scatter(self, output: str, *, driver: str | None = None, units=None, ax=None):
        """`output` against `driver` (default: the feature with the strongest rank correlation);
        the failed samples' driver values are marked along the bottom."""
        ax = self._axes(ax)
        y, used = self._used(output)
        driver = driver or next(iter(self.drivers(output)))
        x = self.dataset[driver].values
        ax.plot(x[used], y[used], ".", alpha=0.5, label="samples")
        failed = ~self.success
        if failed.any():
            ax.plot(x[failed], np.full(failed.sum(), y[used].min()), "x", color="red", label="failed")
        ax.set_xlabel(self._label(driver, units))
        ax.set_ylabel(self._label(output, units))
        ax.legend()
        return ax
