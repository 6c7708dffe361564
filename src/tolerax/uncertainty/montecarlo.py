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

import hashlib
import json
import os
import pickle
from collections.abc import Callable, Mapping

import jax
import numpy as np
import xarray as xr
from jaxtyping import PRNGKeyArray
from tqdm import tqdm  # the text bar: tqdm.auto warns in notebooks without ipywidgets

from .backends import Plan, evaluate, helper_count, run_auto, run_chunks  # noqa: F401 (evaluate, helper_count: used from here)
from .checkpoint import atomic_write, chunk_path, open_folder
from .results import MonteCarloResult
from .sampling import Tolerances, sample

BACKENDS = ("auto", "vmap", "processes", "dask")
_FORMAT = "tolerax-samples/1"


# ---------------------------------------------------------------------------------------------
# Runs: chunks, checkpoints.


def default_chunk(model) -> int:
    """The chunk size `monte_carlo` takes where none is given: on a CPU, the `unit_chunk()` of the
    model's scene where it has one (a `PointingObjective`: 10 for a full planetary stage, whose
    rattling units' step counts differ, 50 otherwise); else 64 (a GPU wants larger batches: give
    `chunk_size`)."""
    scene = getattr(model, "scene", None)
    if jax.default_backend() == "cpu" and callable(getattr(scene, "unit_chunk", None)):
        return int(scene.unit_chunk())
    return 64


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
            run_auto(model, plan, todo, handle, save, workers, pin_workers, progress)
        else:
            run_chunks(model, plan, backend, todo, handle, save, client, workers, pin_workers)
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
    chunk_size: int | None = None,
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
      for a model that does not pickle, in a script without the `if __name__ == "__main__":`
      guard, or with `TOLERAX_MC_WORKERS=0` in the environment (a number: at most that many). A speculative chunk still computing when the run ends finishes in the background.
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
    - `chunk_size`: samples per chunk (the vmap batch, the unit of work and of checkpointing);
      default `default_chunk(model)` (a scene's `unit_chunk()` on a CPU, else 64).
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
    chunk_size = default_chunk(model) if chunk_size is None else chunk_size
    check_run(tolerances, n=n, chunk_size=chunk_size)
    key = typed_key(key)
    settings = {"kind": "monte_carlo", "key": key_settings(key), "tolerances": tolerances.to_json()}
    draw = lambda start, stop: np.asarray(sample(tolerances, key, stop - start, first=start))  # noqa: E731
    plan = Plan(tolerances.names, int(n), int(chunk_size), draw, settings)
    ds = run_samples(model, plan, backend=backend, out=out, progress=progress, client=client, workers=workers,
                     callback=callback, units=units, pin_workers=pin_workers)
    return MonteCarloResult(ds, requirement=requirement)
