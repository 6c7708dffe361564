"""Test models for `test_montecarlo.py`, at module level so that worker processes (spawned
processes, Dask workers, the sharding subprocess) import them by reference."""

import functools
import os
import sys
import time

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


class Linear(eqx.Module):
    """$y = a \\cdot x$ (plus `offset`), always successful."""

    a: jax.Array
    offset: float = 0.0

    def __call__(self, x):
        return {"y": jnp.dot(self.a, x) + self.offset, "success": jnp.array(True)}


class Nonlinear(eqx.Module):
    """A smooth nonlinear function with an integer output, for comparing backends bit for bit."""

    def __call__(self, x):
        y = jnp.sin(1e4 * x[0]) * jnp.exp(-1e3 * x[1]) + jnp.sum(x**2)
        return {"y": y, "steps": jnp.int32(jnp.floor(1e5 * x[0])), "success": jnp.array(True)}


class FailAbove(eqx.Module):
    """`Linear`, except that a sample with `x[0] > threshold` fails with NaN outputs (as a solver
    failure does)."""

    a: jax.Array
    threshold: float

    def __call__(self, x):
        ok = x[0] <= self.threshold
        return {"y": jnp.where(ok, jnp.dot(self.a, x), jnp.nan), "success": ok}


class Ishigami(eqx.Module):
    """$\\sin x_1 + a \\sin^2 x_2 + b x_3^4 \\sin x_1$ on $[-\\pi, \\pi]^3$ (Ishigami & Homma, 1990)."""

    a: float = 7.0
    b: float = 0.1

    def __call__(self, x):
        y = jnp.sin(x[0]) + self.a * jnp.sin(x[1]) ** 2 + self.b * x[2] ** 4 * jnp.sin(x[0])
        return {"y": y, "success": jnp.array(True)}


class Affinity(eqx.Module):
    """Where the evaluating process runs: its process id, how many cores it may use and the first
    of them, read when the process traces the model (so, per worker, at its first chunk).
    `run` (static) names the run: a program traced in one run is kept in the test run's
    compilation cache (`tolerax.cache.exported_jit`), so two runs that must trace afresh (pinned,
    free) need different names."""

    run: str = eqx.field(static=True, default="")

    def __call__(self, x):
        cores = sorted(os.sched_getaffinity(0))
        constant = lambda v: jnp.asarray(float(v)) + 0.0 * x[0]  # noqa: E731
        return {"pid": constant(os.getpid()), "n_cores": constant(len(cores)), "first_core": constant(cores[0]),
                "success": jnp.array(True)}


_CALLS = 0


def _die_once(x, marker):
    """Count the chunks this process evaluated; at its second, kill the process (once per test:
    `marker` records that it happened)."""
    global _CALLS
    _CALLS += 1
    if _CALLS >= 2 and not os.path.exists(marker):
        with open(marker, "w"):
            pass
        sys.stderr.flush()
        os._exit(1)
    return np.asarray(x)


class DieOnce(eqx.Module):
    """`Linear`, but the worker process evaluating it dies at its second chunk, once."""

    a: jax.Array
    marker: str = eqx.field(static=True)

    def __call__(self, x):
        y = jnp.dot(self.a, x)
        shape = jax.ShapeDtypeStruct(y.shape, y.dtype)
        y = jax.pure_callback(functools.partial(_die_once, marker=self.marker), shape, y, vmap_method="broadcast_all")
        return {"y": y, "success": jnp.array(True)}


def _sleep_then_pid(x, seconds):
    time.sleep(seconds)
    return np.full(np.shape(x), float(os.getpid())), np.full(np.shape(x), float(os.nice(0)))


class Slow(eqx.Module):
    """`sum(x)`, and the id and scheduling priority (nice value) of the process that evaluated the
    unit, after sleeping `seconds` per chunk (one host callback per chunk): a model slow enough
    that a worker process has started before the run ends."""

    seconds: float = eqx.field(static=True, default=1.0)

    def __call__(self, x):
        y = jnp.sum(x)
        shape = jax.ShapeDtypeStruct(y.shape, y.dtype)
        pid, nice = jax.pure_callback(functools.partial(_sleep_then_pid, seconds=self.seconds), (shape, shape), y,
                                      vmap_method="broadcast_all")
        return {"y": y, "pid": pid, "nice": nice, "success": jnp.array(True)}
