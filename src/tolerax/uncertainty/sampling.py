"""Manufacturing errors: each toleranced dimension drawn within its band.

A `Tolerances` says, per feature (a clearance, a backlash, a profile-error amplitude, ...), the
nominal value, the half-width of the band a part is accepted in, and how manufactured parts spread
inside it. Draws are made in two steps, so that a design optimiser can keep one fixed set of draws
while it moves the nominal values and bands (common random numbers):

1. `unit_draws(key, n, n_features, distribution)`: standardised draws $u \\in [-1, 1]$;
2. `apply_draws(tolerances, u)`: values $\\max(\\text{nominal} + \\text{band}\\,u, \\text{lower})$ (m),
   differentiable with respect to `nominal` and `band`.

`sample` is the two in one. Sample $i$ is drawn from `jax.random.fold_in(key, i)`, so a sample's
value depends on the key and its index only, never on how many samples were drawn with it or in
what batches: the Monte Carlo engine's chunks draw exactly what one call to `sample` would.
"""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float, PRNGKeyArray
from .._validate import is_traced


DISTRIBUTIONS = ("uniform", "normal")
# "normal": sigma = band / 3, truncated at +-band, i.e. a standard normal truncated at +-3 sigma.
_SIGMAS_IN_BAND = 3.0


def _vector(name: str, value, n: int | None) -> Array:
    """`value` as a float64 vector, checked for shape (and, when concrete, for NaN)."""
    if value is None or isinstance(value, (str, bytes, bool)):
        raise TypeError(f"Tolerances.{name} must be an array of real numbers (m), got {value!r}.")
    array = jnp.asarray(value, dtype=float)
    if array.ndim != 1:
        raise ValueError(f"Tolerances.{name} must be a vector (one entry per feature), got shape {array.shape}.")
    if n is not None and array.shape != (n,):
        raise ValueError(
            f"Tolerances.{name} has shape {array.shape} but there are {n} feature names: one entry per feature."
        )
    if not is_traced(array) and np.isnan(np.asarray(array)).any():
        raise ValueError(f"Tolerances.{name} contains NaN: {np.asarray(array)}.")
    return array


class Tolerances(eqx.Module):
    """The tolerance zones of a mechanism: per feature a nominal value and a band. The one
    zone type of tolerax: Monte Carlo draws units within it, scene files read and write it
    (`SceneFile.tolerances`, `SceneFile.with_tolerances`), the design starts from it and holds
    given features at it (`propose_design(start=..., fixed=...)`) and proposes one
    (`DesignReport.tolerances`).

    A part is in tolerance when $|x - \\text{nominal}| \\le \\text{band}$: the zone is
    $[\\text{nominal} - \\text{band}, \\text{nominal} + \\text{band}]$ (`lower_limit`,
    `upper_limit`; `from_limits` builds one from its limits). Manufactured values are spread
    over the band by `distribution`:

    - `"uniform"`: uniform on $[\\text{nominal} - \\text{band}, \\text{nominal} + \\text{band}]$;
    - `"normal"`: normal with mean `nominal` and $\\sigma = \\text{band}/3$, truncated at
      $\\pm\\text{band}$ (parts outside the band are rejected by inspection). Its variance is
      $\\sigma^2 (1 - 6\\,\\varphi(3) / (2\\Phi(3) - 1)) \\approx 0.9733\\,\\sigma^2$.

    Draws below `lower` are then clipped to it (not redrawn): a clearance or backlash cannot be
    negative, so a band reaching below zero yields a share of zero-clearance (line-to-line) parts,
    a point mass at `lower`. With `lower=None` nothing is clipped.

    **Arguments:**

    - `names`: one name per feature, e.g. `("carrier_clearance", "backlash")`. They name the
      sampled values in Monte Carlo results, so they must be distinct.
    - `nominal`: nominal values (m), shape `(n_features,)`.
    - `band`: half-widths of the bands (m), non-negative, shape `(n_features,)`; zero fixes a
      feature at its nominal value.
    - `distribution`: `"uniform"` (default) or `"normal"`.
    - `lower`: physical floor (m), a scalar or shape `(n_features,)`; default 0; `None` for none.
    """

    names: tuple[str, ...] = eqx.field(static=True)
    nominal: Float[Array, " n_features"]
    band: Float[Array, " n_features"]
    distribution: str = eqx.field(static=True)
    lower: Float[Array, " n_features"] | None

    def __init__(self, names, nominal, band, distribution: str = "uniform", lower=0.0):
        if isinstance(names, str) or not all(isinstance(name, str) for name in names):
            raise TypeError(f"Tolerances.names must be a sequence of strings, got {names!r}.")
        self.names = tuple(names)
        n = len(self.names)
        self.nominal = _vector("nominal", nominal, n)
        self.band = _vector("band", band, n)
        self.distribution = distribution
        if lower is None:
            self.lower = None
        else:
            scalar = not isinstance(lower, (str, bytes, bool)) and np.ndim(lower) == 0
            self.lower = _vector("lower", jnp.full((n,), lower, dtype=float) if scalar else lower, n)

    def __check_init__(self):
        if len(set(self.names)) != len(self.names) or not self.names:
            raise ValueError(f"Tolerances.names must be distinct and at least one, got {self.names!r}.")
        if self.distribution not in DISTRIBUTIONS:
            raise ValueError(
                f"Tolerances.distribution must be one of {DISTRIBUTIONS}, got {self.distribution!r}."
            )
        if is_traced(self.nominal) or is_traced(self.band):
            return  # values inside jit/grad cannot be inspected; shapes were checked in __init__
        band = np.asarray(self.band)
        if not np.all(np.isfinite(band)) or np.any(band < 0):
            bad = [name for name, b in zip(self.names, band) if not (np.isfinite(b) and b >= 0)]
            raise ValueError(f"Tolerances.band must be finite and non-negative (m); bad for {bad}: {band}.")
        if not np.all(np.isfinite(np.asarray(self.nominal))):
            raise ValueError(f"Tolerances.nominal must be finite (m), got {np.asarray(self.nominal)}.")
        if self.lower is not None and not is_traced(self.lower):
            below = np.asarray(self.nominal) < np.asarray(self.lower)
            if below.any():
                bad = [name for name, b in zip(self.names, below) if b]
                raise ValueError(f"Tolerances.nominal is below Tolerances.lower (the physical floor) for {bad}.")

    @classmethod
    def from_limits(cls, names, lower_limit, upper_limit, distribution: str = "uniform", lower=0.0) -> "Tolerances":
        """The zones $[\\text{lower\\_limit}, \\text{upper\\_limit}]$ (m) per feature: nominal their
        middle, band their half-width (a drawing's limits, a design's lower limit and width)."""
        lo, hi = np.asarray(lower_limit, dtype=float), np.asarray(upper_limit, dtype=float)
        if np.any(hi < lo):
            bad = [name for name, a, b in zip(names, np.broadcast_to(lo, np.shape(hi)), hi) if b < a]
            raise ValueError(f"Tolerances.from_limits: the upper limit is below the lower limit for {bad} (m): {lo}, {hi}.")
        return cls(names, 0.5 * (lo + hi), 0.5 * (hi - lo), distribution, lower)

    @property
    def n_features(self) -> int:
        return len(self.names)

    @property
    def lower_limit(self) -> Array:
        """The zones' lower limits, nominal - band (m): the smallest value a part may have."""
        return self.nominal - self.band

    @property
    def upper_limit(self) -> Array:
        """The zones' upper limits, nominal + band (m)."""
        return self.nominal + self.band

    def of(self, names) -> "Tolerances":
        """These zones in the order of `names` (a subset or a reordering), e.g. a scene's
        `design_names`; a name without a zone here is an error naming it."""
        names = tuple(names)
        missing = [name for name in names if name not in self.names]
        if missing:
            raise ValueError(f"Tolerances.of: no zone for {missing}; the zones are for {', '.join(self.names)}.")
        k = np.asarray([self.names.index(name) for name in names], dtype=int)
        lower = None if self.lower is None else self.lower[k]
        return Tolerances(names, self.nominal[k], self.band[k], self.distribution, lower)

    def joined(self, other: "Tolerances") -> "Tolerances":
        """These zones followed by `other`'s (one `Tolerances`; the same `distribution`; a
        `lower` of `None` on either side is no floor, -inf, for its features)."""
        if not isinstance(other, Tolerances):
            raise TypeError(f"Tolerances.joined: other must be a Tolerances, got {type(other).__name__}.")
        if other.distribution != self.distribution:
            raise ValueError(f"Tolerances.joined: both must have one distribution, got {self.distribution!r} and "
                             f"{other.distribution!r}.")
        floor = lambda t: jnp.full((t.n_features,), -jnp.inf) if t.lower is None else t.lower  # noqa: E731
        lower = None if self.lower is None and other.lower is None else jnp.concatenate([floor(self), floor(other)])
        return Tolerances(self.names + other.names, jnp.concatenate([self.nominal, other.nominal]),
                          jnp.concatenate([self.band, other.band]), self.distribution, lower)

    def bounds(self) -> np.ndarray:
        """The tolerance box as an array of `[low, high]` rows (m): nominal ± band, the low end
        clipped at `lower`."""
        low = np.asarray(self.lower_limit)
        if self.lower is not None:
            low = np.maximum(low, np.asarray(self.lower))
        return np.stack([low, np.asarray(self.upper_limit)], axis=1)

    def to_json(self) -> dict:
        """The tolerances as JSON-ready Python values (for manifests and dataset attributes)."""
        return {
            "names": list(self.names),
            "nominal": np.asarray(self.nominal).tolist(),
            "band": np.asarray(self.band).tolist(),
            "distribution": self.distribution,
            "lower": None if self.lower is None else np.asarray(self.lower).tolist(),
        }


def _one_draw(key, n_features: int, distribution: str):
    if distribution == "uniform":
        return jax.random.uniform(key, (n_features,), minval=-1.0, maxval=1.0)
    z = jax.random.truncated_normal(key, -_SIGMAS_IN_BAND, _SIGMAS_IN_BAND, (n_features,))
    return jnp.clip(z / _SIGMAS_IN_BAND, -1.0, 1.0)


@eqx.filter_jit
def _unit_draws(key, first, n: int, n_features: int, distribution: str):
    index = first + jnp.arange(n, dtype=jnp.uint32)
    keys = jax.vmap(jax.random.fold_in, in_axes=(None, 0))(key, index)
    return jax.vmap(lambda k: _one_draw(k, n_features, distribution))(keys)


def unit_draws(
    key: PRNGKeyArray, n: int, n_features: int, distribution: str = "uniform", *, first: int = 0
) -> Float[Array, "n n_features"]:
    """Standardised manufacturing errors $u \\in [-1, 1]$ (fractions of the band).

    Sample $i$ (counted from `first`) comes from `jax.random.fold_in(key, first + i)`: drawing
    samples 0-99 at once or as 0-49 and 50-99 gives the same numbers.

    **Arguments:**

    - `key`: a JAX PRNG key (`jax.random.key` or the raw `jax.random.PRNGKey`).
    - `n`: number of samples.
    - `n_features`: number of toleranced features.
    - `distribution`: `"uniform"` (uniform on $[-1, 1]$) or `"normal"` (standard normal truncated
      at $\\pm 3$, divided by 3).
    - `first`: index of the first sample (keyword only).

    **Returns:**

    An array of shape `(n, n_features)`.
    """
    if distribution not in DISTRIBUTIONS:
        raise ValueError(f"distribution must be one of {DISTRIBUTIONS}, got {distribution!r}.")
    if int(n) < 0 or int(n_features) < 1:
        raise ValueError(f"n must be >= 0 and n_features >= 1, got n={n!r}, n_features={n_features!r}.")
    return _unit_draws(key, jnp.asarray(first, dtype=jnp.uint32), int(n), int(n_features), distribution)


def apply_draws(tolerances: Tolerances, u: Float[Array, "n n_features"]) -> Float[Array, "n n_features"]:
    """Map standardised draws to manufactured values: $\\max(\\text{nominal} + \\text{band}\\,u,
    \\text{lower})$ (m).

    Differentiable with respect to `tolerances.nominal` and `tolerances.band` (the derivative is
    zero for a draw clipped at `lower`), so a robust design objective can keep `u` fixed.

    **Arguments:**

    - `tolerances`: the `Tolerances`.
    - `u`: standardised draws from `unit_draws`, shape `(n, n_features)` (or `(n_features,)`).

    **Returns:**

    Values (m), same shape as `u`.
    """
    if u.shape[-1] != tolerances.n_features:
        raise ValueError(
            f"u has {u.shape[-1]} features in its last axis but the tolerances have {tolerances.n_features}."
        )
    return manufactured(tolerances.nominal, tolerances.band, u, tolerances.lower)


def manufactured(nominal, band, u, lower=None):
    """$\\max(\\text{nominal} + \\text{band}\\,u, \\text{lower})$ (m; no floor when `lower` is
    `None`): the one map from standardised draws to manufactured values."""
    values = nominal + band * u
    return values if lower is None else jnp.maximum(values, lower)


def sample(tolerances: Tolerances, key: PRNGKeyArray, n: int, *, first: int = 0) -> Float[Array, "n n_features"]:
    """Draw `n` manufactured units within `tolerances`: `apply_draws(tolerances, unit_draws(...))`.

    **Arguments:**

    - `tolerances`: the `Tolerances`.
    - `key`: a JAX PRNG key; the same key gives the same values.
    - `n`: number of samples.
    - `first`: index of the first sample (keyword only): `sample(t, key, 50, first=50)` is rows
      50-99 of `sample(t, key, 100)`.

    **Returns:**

    Values (m), shape `(n, n_features)`.
    """
    u = unit_draws(key, n, tolerances.n_features, tolerances.distribution, first=first)
    return apply_draws(tolerances, u)
