"""Input checks: every number a user gives is checked where it is given, before anything is traced
or run, and a rejected input raises with the field, the value and what is allowed.

Two layers:

- `real(owner, name, value, ...)` in constructors: type (a real number, not a string, bool,
  complex or None) and shape, then conversion to a float64 array. A wrong type or shape is a
  `TypeError`/`ValueError` naming `owner.name`.
- `Rule`s checked in each module's `__check_init__` (finite, inside its range). They run after
  every construction and again, through `check_tree`, on the scene `simulate` is given, which
  catches values set with `eqx.tree_at` (it bypasses constructors).

Values that are JAX tracers (a scene built or modified inside `jit`, `vmap` or `grad`) cannot be
inspected: their type and shape are checked, their values are not. Check concrete designs before
batching them, or read the per-sample result codes afterwards.
"""

import dataclasses
import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np


def is_traced(x) -> bool:
    return isinstance(x, jax.core.Tracer)


def _shape_text(shape) -> str:
    return "a scalar" if shape == () else f"shape {shape}"


def real(owner: str, name: str, value, unit: str, shape=(), broadcast: bool = False):
    """`value` as a float64 array, after checking that it is a real number (or array of them) of
    `shape` (or, with `broadcast`, of any shape that broadcasts to it; `shape=None`: any shape).
    Raises `TypeError` (not a real number) or `ValueError` (wrong shape) naming `owner.name`."""
    what = f"{owner}.{name}"
    if value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise TypeError(f"{what} must be a real number ({unit}), got {value!r} ({type(value).__name__}).")
    if is_traced(value) or isinstance(value, jax.Array):
        dtype, got_shape = value.dtype, value.shape
    else:
        try:
            arr = np.asarray(value)
        except Exception as err:  # ragged lists and the like
            raise TypeError(f"{what} must be a real number or array ({unit}), got {value!r}.") from err
        dtype, got_shape = arr.dtype, arr.shape
    if np.dtype(dtype).kind not in "iuf":
        raise TypeError(
            f"{what} must be real ({unit}), got {value!r} of dtype {np.dtype(dtype).name}."
        )
    if shape is not None:
        ok = got_shape == tuple(shape)
        if broadcast and not ok:
            try:
                ok = np.broadcast_shapes(got_shape, tuple(shape)) == tuple(shape)
            except ValueError:
                ok = False
        if not ok:
            allowed = _shape_text(tuple(shape)) + (" (or one that broadcasts to it)" if broadcast else "")
            raise ValueError(f"{what} must be {allowed} ({unit}), got shape {got_shape}: {value!r}.")
    return jnp.asarray(value, dtype=float)


@dataclasses.dataclass(frozen=True)
class Rule:
    """An allowed range `low < x` (or `<=`), `x < high` (or `<=`), always finite, in `unit`."""

    unit: str
    low: float | None = None
    high: float | None = None
    low_open: bool = False
    high_open: bool = False
    optional: bool = False  # None allowed (e.g. "no torsional support")

    def text(self) -> str:
        if self.low is not None and self.high is not None:
            lb, hb = ("(" if self.low_open else "["), (")" if self.high_open else "]")
            return f"finite, in {lb}{self.low:g}, {self.high:g}{hb}"
        if self.low is not None:
            return f"finite and {'>' if self.low_open else '>='} {self.low:g}"
        if self.high is not None:
            return f"finite and {'<' if self.high_open else '<='} {self.high:g}"
        return "finite"

    def violated(self, value) -> bool:
        arr = np.asarray(value, dtype=float)
        if not np.all(np.isfinite(arr)):
            return True
        if self.low is not None and np.any(arr <= self.low if self.low_open else arr < self.low):
            return True
        if self.high is not None and np.any(arr >= self.high if self.high_open else arr > self.high):
            return True
        return False


FINITE = lambda unit: Rule(unit)  # noqa: E731
POSITIVE = lambda unit: Rule(unit, low=0.0, low_open=True)  # noqa: E731
NONNEGATIVE = lambda unit: Rule(unit, low=0.0)  # noqa: E731
# Ranges that more than one constructor checks (default_stage and the module it builds):
PRESSURE_ANGLE = Rule("rad", low=0.0, high=math.pi / 2, low_open=True, high_open=True)
# K_t = k_m [1 + (eps_c - 1) cos phi] stays positive only for eps_c < 2.
CONTACT_RATIO = Rule("contact ratio", low=1.0, high=2.0, high_open=True)
# c_e = 0 (perfectly plastic) is outside every law's range: Flores' chi = 8(1-c_e)/(5 c_e)
# diverges, and the others are fitted for c_e well above 0.
RESTITUTION = Rule("coefficient of restitution", low=0.0, high=1.0, low_open=True)


def positive_integer(what: str, value) -> None:
    """`value` must be a positive Python or NumPy integer (not a bool or a float): tooth and
    planet counts, which set the structure."""
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value < 1:
        raise ValueError(f"{what} must be a positive integer, got {value!r}.")


def check(obj, /, **rules: Rule) -> None:
    """Check fields of `obj` (a module) against their rules (concrete values only); `ValueError` naming
    the field, the value and the allowed range."""
    owner = type(obj).__name__
    for name, rule in rules.items():
        value = getattr(obj, name)
        if value is None:
            if rule.optional:
                continue
            raise ValueError(f"{owner}.{name} must be given ({rule.unit}), got None.")
        if is_traced(value):
            continue
        if rule.violated(value):
            raise ValueError(f"{owner}.{name} must be {rule.text()} ({rule.unit}), got {_show(value)}.")


def concrete(*values) -> bool:
    """True when none of `values` is traced (so a cross-field check can be decided)."""
    return not any(is_traced(v) for v in jax.tree.leaves(values))


def _show(value) -> str:
    arr = np.asarray(value)
    if arr.ndim == 0:
        return repr(float(arr))
    return np.array2string(arr, precision=6)


def check_tree(tree) -> None:
    """Run `__check_init__` of every equinox module in `tree` (the scene a solver is given):
    catches values set with `eqx.tree_at`, which bypasses constructors."""
    for node in _modules(tree):
        for cls in type(node).__mro__:
            hook = cls.__dict__.get("__check_init__")
            if hook is not None:
                hook(node)


def _modules(tree):
    out = []

    def visit(x):
        if isinstance(x, eqx.Module):
            out.append(x)
            for f in dataclasses.fields(x):
                visit(getattr(x, f.name, None))
        elif isinstance(x, (list, tuple)):
            for y in x:
                visit(y)
        elif isinstance(x, dict):
            for y in x.values():
                visit(y)

    visit(tree)
    return out


def state_like(y0, reference, what: str = "y0") -> None:
    """`y0` must have the structure and shapes of `reference` (the scene's `initial_state()`)."""
    ref_leaves, ref_def = jax.tree.flatten(reference)
    try:
        leaves, tdef = jax.tree.flatten(y0)
    except Exception as err:  # pragma: no cover - jax flattens anything
        raise TypeError(f"{what} must be a tuple of arrays like the scene's initial_state().") from err
    if tdef != ref_def:
        raise ValueError(
            f"{what} must have the structure of the scene's initial_state(), {ref_def}; got {tdef}."
        )
    for k, (a, b) in enumerate(zip(leaves, ref_leaves)):
        if jnp.shape(a) != jnp.shape(b):
            raise ValueError(
                f"{what}[{k}] must have shape {jnp.shape(b)} (this scene's coordinates), got {jnp.shape(a)}."
            )
        kind = np.dtype(a.dtype if hasattr(a, "dtype") else np.asarray(a).dtype).kind
        if kind not in "iuf":
            raise TypeError(f"{what}[{k}] must be real, got dtype {np.dtype(a.dtype).name}.")
        if not is_traced(a) and not np.all(np.isfinite(np.asarray(a))):
            raise ValueError(f"{what}[{k}] contains NaN or inf: {np.asarray(a)}.")

