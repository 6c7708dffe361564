"""Closed-form unit models (`tx.AbstractObjective`) for the design layer's tests: responses whose
value, slopes, scatter and quantiles are known exactly, so that the design's orchestration
(secant fits, response surfaces, Monte Carlo checks, re-solves, rescues, the noise band) is
tested in seconds through what `propose_design` accepts, with no simulation and nothing patched.

`Line` is one family: each output $k$ of a unit with design values $v$ (m) is

$$y_k = g\\Big(a_k + s_k\\cdot(v - m) + (s^w_k\\cdot(v - m))\\,w + \\kappa_k\\cdot\\max(v - v_{knee}, 0)
       + \\sigma_k z_k(v) + A_k \\sin(\\Omega \\textstyle\\sum v) + c_k (e^{t} - 1)\\Big)$$

with $g$ the identity or `exp` (`log`), $w$ the smoothing width (m, 0 where `None`), $z_k(v)$ a
standard normal drawn from the unit's own values (`noise`: the same unit gives the same draw,
different units independent ones; `seed` picks another realisation), and $t$ an uncertain input
the unit carries after its design values (a wear-rate factor's logarithm, drawn over `box`).
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import tolerax as tx
from tolerax.design.life import WEAR_FACTOR


def scan_scene():
    """The lumped azimuth scan: four design features (carrier and pin clearances, sun and ring
    backlash), whose names and sizes the closed forms borrow. Building it simulates nothing."""
    return tx.scan("azimuth", fidelity=("lumped", "ideal"))


def noise(values, seed):
    """A standard normal that is a function of the unit `values` (m) and `seed` (int): the key
    folds in a hash of the values rounded to the picometre, so units a picometre apart draw
    independently and the same unit always draws the same number, however it was computed (a
    unit realised in a vmapped batch and on its own differ in the last bits)."""
    picometres = jax.lax.stop_gradient(jnp.round(jnp.asarray(values, dtype=float) * 1e12)).astype(jnp.int64).reshape(-1)
    primes = jnp.asarray([1000003, 998244353, 754974721, 167772161, 469762049, 1004535809][: picometres.shape[0]], dtype=jnp.int64)
    digest = (jnp.sum((picometres % 1000000007) * primes) % 2147483647).astype(jnp.uint32)
    return jax.random.normal(jax.random.fold_in(jax.random.fold_in(jax.random.key(0), digest), seed), ())


class Line(tx.AbstractObjective):
    """The closed form in the module's docstring, one row of each coefficient per output."""

    scene: eqx.Module
    value: jax.Array  # (k,) a_k
    slopes: jax.Array  # (k, n) s_k, per m
    at: jax.Array  # (n,) m
    names: tuple[str, ...] = eqx.field(static=True, default=("pointing_rms",))
    log: tuple[bool, ...] | None = eqx.field(static=True, default=None)
    width_slopes: jax.Array | None = None  # (k, n), per m of value and per m of width
    kink: jax.Array | None = None  # (k, n) kappa_k
    knee: jax.Array | None = None  # (n,) m
    sigma: jax.Array | None = None  # (k,)
    seed: jax.Array = eqx.field(default_factory=lambda: jnp.asarray(0))
    rough: jax.Array | None = None  # (k,) A_k
    frequency: float = eqx.field(static=True, default=1e9)  # Omega, 1/m
    wear: jax.Array | None = None  # (k,) c_k
    box: tuple | None = None  # (middle, half-width) of t
    jitter_cutoff: float | None = eqx.field(static=True, default=None)

    def __init__(self, scene, value, slopes, at, names=("pointing_rms",), **more):
        self.scene = scene
        self.value = jnp.atleast_1d(jnp.asarray(value, dtype=float))
        self.slopes = jnp.atleast_2d(jnp.asarray(slopes, dtype=float))
        self.at = jnp.broadcast_to(jnp.asarray(at, dtype=float), self.slopes.shape[-1:])
        self.names = tuple(names)
        self.log = tuple(more.pop("log", (False,) * len(self.names)))
        for name in ("width_slopes", "kink", "knee", "sigma", "rough", "wear"):
            v = more.pop(name, None)
            setattr(self, name, None if v is None else jnp.asarray(v, dtype=float))
        self.seed = jnp.asarray(more.pop("seed", 0))
        self.frequency = float(more.pop("frequency", 1e9))
        box = more.pop("box", None)
        self.box = None if box is None else tuple(jnp.atleast_1d(jnp.asarray(b, dtype=float)) for b in box)
        self.jitter_cutoff = more.pop("jitter_cutoff", None)
        if more:
            raise TypeError(f"Line: unknown {sorted(more)}")

    @property
    def outputs(self):
        return self.names

    @property
    def uncertain_inputs(self):
        return () if self.box is None else (WEAR_FACTOR,)

    def uncertain_box(self):
        return self.box

    def __call__(self, values, smoothing_width=None):
        values = jnp.asarray(values, dtype=float)
        n = self.slopes.shape[1]
        v, t = values[:n], (values[n] if values.shape[-1] > n else None)
        d = v - self.at
        y = self.value + self.slopes @ d
        if self.width_slopes is not None and smoothing_width is not None:
            y = y + (self.width_slopes @ d) * smoothing_width
        if self.kink is not None:
            y = y + self.kink @ jnp.maximum(v - self.knee, 0.0)
        if self.sigma is not None:
            y = y + self.sigma * jnp.stack([noise(v, self.seed * 101 + k) for k in range(len(self.names))])
        if self.rough is not None:
            y = y + self.rough * jnp.sin(self.frequency * jnp.sum(v))
        if self.wear is not None and t is not None:
            y = y + self.wear * (jnp.exp(t) - 1.0)
        log = jnp.asarray(self.log)
        y = jnp.where(log, jnp.exp(jnp.where(log, y, 0.0)), y)  # exp only where taken: no inf x 0 = NaN in reverse mode
        return {name: y[k] for k, name in enumerate(self.names)} | dict(success=jnp.asarray(True))

    def exact(self, v, t=None, width=None):
        """NumPy: the outputs (k,) of units `v` (..., n) without the noise, for the tests' own
        quantiles."""
        v = np.asarray(v, dtype=float)
        y = np.asarray(self.value) + (v - np.asarray(self.at)) @ np.asarray(self.slopes).T
        if self.width_slopes is not None and width is not None:
            y = y + ((v - np.asarray(self.at)) @ np.asarray(self.width_slopes).T) * width
        if self.kink is not None:
            y = y + np.maximum(v - np.asarray(self.knee), 0.0) @ np.asarray(self.kink).T
        if self.wear is not None and t is not None:
            y = y + np.asarray(self.wear) * (np.exp(np.asarray(t))[..., None] - 1.0)
        return np.where(np.asarray(self.log), np.exp(y), y)
