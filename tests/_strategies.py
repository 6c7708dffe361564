"""Hypothesis strategies and settings shared by the property tests of `test_smooth.py`,
`test_contact.py` and `test_mesh.py`.

Those tests check the kernels for properties that must hold for *every* input of their domain
(monotonicity, Lipschitz bounds, symmetry, sign, exact limit at width 0, finite derivatives), over
random inputs spanning all magnitudes from 1e-300 to 1e3 (SI units) where the quantity is
meaningful, with zero widths, zero clearances and the kinks themselves drawn often.

Every function under test is jitted once at module level (scalar float64 arguments, so values
never retrace). Examples are derandomized so that CI is reproducible. Subnormal inputs are never
drawn: XLA on CPU flushes them to zero (FTZ/DAZ), so for them the "exact" numpy reference and the
jitted function disagree by design.
"""

import operator

import jax
import numpy as np
from hypothesis import settings
from hypothesis import strategies as st


EPS = float(np.finfo(float).eps)
SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)


def positive(lo, hi):
    """Floats in [lo, hi], spread evenly over the decades (log-uniform) and also drawn by
    hypothesis' own float strategy (which favours the bounds and simple values)."""
    log_uniform = st.floats(np.log10(lo), np.log10(hi)).map(lambda u: float(np.clip(10.0**u, lo, hi)))
    direct = st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False)
    return st.one_of(log_uniform, direct)


def signed(lo, hi):
    """0, or +-[lo, hi]."""
    return st.one_of(st.just(0.0), positive(lo, hi), positive(lo, hi).map(operator.neg))


def widths(lo=1e-300, hi=1e3):
    """Smoothing widths: 0 (the exact limit) drawn often, else [lo, hi]."""
    return st.one_of(st.just(0.0), positive(lo, hi))


def finite(tree):
    """Whether every leaf of a pytree of arrays is finite."""
    return all(np.all(np.isfinite(np.asarray(leaf))) for leaf in jax.tree_util.tree_leaves(tree))


def scalar(x):
    """A 0-d array (or number) as a Python float."""
    return float(np.asarray(x))


# Arguments of the primitives: displacements from 1e-300 m to 1 km, zero included.
X = signed(1e-300, 1e3)
WIDTH = widths()
# Widths for which the derivative with respect to the width is asked to be finite: the ramp's
# width derivative contains x / w^2, which overflowed below w ~ 1e-154 (smooth.WIDTH_FLOOR now;
# see test_smooth.py::test_width_derivative_finite_for_tiny_widths).
WIDTH_DIFFERENTIABLE = widths(1e-150)
BACKLASH = st.one_of(st.just(0.0), positive(1e-300, 1e-2))
