"""The smooth primitives of `tolerax.smooth` (docs/model.md §1) against the exact piecewise functions
(numpy), their documented error bounds, and their gradients (finite at every kink; equal to finite
differences where smooth).

Beside each group of examples on fixed grids, property tests (hypothesis, strategies in
`_strategies.py`) check the same functions for what must hold for *every* input of their domain:
monotonicity, Lipschitz bounds, symmetry, exact limit at width 0, finite derivatives.
"""

import functools

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given
from hypothesis import strategies as st

from tolerax import smooth

from _strategies import (
    BACKLASH,
    EPS,
    SETTINGS,
    WIDTH,
    WIDTH_DIFFERENTIABLE,
    X,
    finite,
    positive,
    scalar,
    signed,
    widths,
)


WIDTHS = (1e-9, 1e-6, 1e-3, 1.0)
BACKLASHES = (0.0, 1e-5, 1e-4)


def _exact_ramp(x):
    return np.maximum(x, 0.0)


def _exact_step(x):
    return np.where(x > 0, 1.0, np.where(x < 0, 0.0, 0.5))


def _exact_dead_zone(g, b):
    return np.where(g >= 0, g, np.where(g <= -b, g + b, 0.0))


def _grid(scale, backlash=0.0):
    """Points over +-5 scale around both kinks, the kinks themselves included exactly."""
    pts = np.concatenate(
        [
            np.linspace(-5.0, 5.0, 101) * scale,
            -backlash + np.linspace(-5.0, 5.0, 101) * scale,
            [0.0, -backlash, -0.5 * backlash, scale * 1e-3, -scale * 1e-3],
        ]
    )
    return np.unique(pts)


# ------------------------------------------------------------------------------------------
# Exact at width 0.


@pytest.mark.parametrize("scale", [1e-6, 1.0])
def test_exact_at_zero_width(scale):
    x = _grid(scale)
    # Exact comparisons: at width 0 each primitive must *be* the piecewise function (bitwise,
    # no arithmetic on x other than max/select).
    np.testing.assert_array_equal(np.asarray(smooth.ramp(x, 0.0)), _exact_ramp(x))
    np.testing.assert_array_equal(np.asarray(smooth.step(x, 0.0)), _exact_step(x))
    v = np.stack([x, 0.5 * x], axis=-1)
    # norm: sqrt of a sum of squares, 1 ulp-level round-off against numpy's own.
    np.testing.assert_allclose(
        np.asarray(smooth.norm(v, 0.0)), np.linalg.norm(v, axis=-1), rtol=1e-15, atol=0.0
    )
    xp = np.abs(x)
    # power/sqrt: jnp's pow and sqrt against numpy's, round-off only.
    np.testing.assert_allclose(np.asarray(smooth.power(x, 1.5)), np.where(x > 0, xp**1.5, 0.0), rtol=1e-15)
    np.testing.assert_allclose(np.asarray(smooth.power(x, 2.5)), np.where(x > 0, xp**2.5, 0.0), rtol=1e-15)
    np.testing.assert_allclose(np.asarray(smooth.sqrt(x)), np.where(x > 0, np.sqrt(xp), 0.0), rtol=1e-15)


@pytest.mark.parametrize("backlash", BACKLASHES)
def test_dead_zone_exact_at_zero_width(backlash):
    g = _grid(1e-5, backlash)
    # ramp(g) - ramp(-g - b): one subtraction, so round-off of order ulp(b) only.
    np.testing.assert_allclose(
        np.asarray(smooth.dead_zone(g, backlash, 0.0)),
        _exact_dead_zone(g, backlash),
        rtol=0.0,
        atol=4 * np.finfo(float).eps * max(backlash, 1e-5),
    )


# ------------------------------------------------------------------------------------------
# Documented error bounds (module docstring table).


@pytest.mark.parametrize("width", WIDTHS)
def test_ramp_error_bounds(width):
    x = _grid(width)
    err = np.asarray(smooth.ramp(x, width)) - _exact_ramp(x)
    # Upper bounds from the docstring: eps ln2 at the kink, eps exp(-|x|/eps) in the tails
    # (softplus(-a) = ln(1 + e^-a) <= e^-a). Factor 1 + 1e-12: round-off of the softplus.
    assert np.all(err >= -1e-15 * np.maximum(np.abs(x), width))  # never below max(0, x)
    assert np.all(err <= width * np.log(2.0) * (1 + 1e-12))
    assert np.all(err <= width * np.exp(-np.abs(x) / width) * (1 + 1e-12) + 1e-15 * np.abs(x))
    # The bound eps ln2 is attained at the kink.
    assert float(smooth.ramp(0.0, width)) == pytest.approx(width * np.log(2.0), rel=1e-14)


@pytest.mark.parametrize("width", WIDTHS)
def test_step_error_bounds(width):
    x = _grid(width)
    err = np.abs(np.asarray(smooth.step(x, width)) - _exact_step(x))
    # Logistic tails: sigma(-a) = 1/(1 + e^a) <= e^-a; the value 1/2 at 0 matches the exact
    # step's convention. 1e-15: round-off of the sigmoid near 1.
    assert np.all(err <= np.exp(-np.abs(x) / width) + 1e-15)
    assert float(smooth.step(0.0, width)) == 0.5


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("backlash", BACKLASHES)
def test_dead_zone_error_bounds(width, backlash):
    g = _grid(max(width, backlash), backlash)
    err = np.abs(np.asarray(smooth.dead_zone(g, backlash, width)) - _exact_dead_zone(g, backlash))
    distance = np.minimum(np.abs(g), np.abs(g + backlash))
    # eps ln2 at each edge, eps exp(-d/eps) away from both; the difference of two softplus
    # errors is bounded by the larger one. Round-off: a few ulp of the larger of |g|, b.
    roundoff = 8 * np.finfo(float).eps * (np.abs(g) + backlash + width)
    assert np.all(err <= width * np.log(2.0) + roundoff)
    assert np.all(err <= width * np.exp(-distance / width) + roundoff)


@pytest.mark.parametrize("width", WIDTHS)
def test_norm_error_bounds(width):
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(50, 2))
    directions /= np.linalg.norm(directions, axis=-1, keepdims=True)
    lengths = np.concatenate([[0.0], np.logspace(-4, 4, 49)]) * width
    v = directions * lengths[:, None]
    exact = np.linalg.norm(v, axis=-1)
    err = np.asarray(smooth.norm(v, width)) - exact
    # sqrt(|v|^2 + eps^2) - |v| lies in [0, min(eps, eps^2/(2|v|))]; 1e-15 relative round-off
    # (at |v| = 1e4 eps the error eps^2/(2|v|) is itself below round-off of |v|).
    roundoff = 4e-16 * (exact + width)
    assert np.all(err >= -roundoff)
    assert np.all(err <= width + roundoff)
    with np.errstate(divide="ignore"):
        algebraic = np.where(exact > 0, width**2 / (2 * exact), np.inf)
    assert np.all(err <= algebraic + roundoff)
    assert float(smooth.norm(np.zeros(2), width)) == width


# ------------------------------------------------------------------------------------------
# For every input (hypothesis): monotonicity, Lipschitz bounds, brackets. Each primitive is
# jitted once (scalar float64 arguments, so values never retrace).

_ramp = jax.jit(smooth.ramp)
_step = jax.jit(smooth.step)
_dead_zone = jax.jit(smooth.dead_zone)
_norm = jax.jit(smooth.norm)
_power = {p: jax.jit(functools.partial(smooth.power, exponent=p)) for p in (1.5, 2.5)}
_sqrt = jax.jit(smooth.sqrt)


@SETTINGS
@given(x1=X, x2=X, width=WIDTH)
def test_ramp_and_step_non_decreasing(x1, x2, width):
    # ramp = softplus and step = logistic have slopes sigma(x/eps) >= 0 and sigma'(x/eps)/eps >= 0.
    # A non-monotone ramp would make a penetration force pull back somewhere; a non-monotone
    # switch would switch a contact off deeper in contact. Round-off: the float implementations
    # are monotone only to within an ulp (softplus = max(0, a) + log1p(exp(-|a|)) adds an
    # increasing and a decreasing term; dense scans of neighbouring floats show 1-ulp steps back,
    # for the logistic too), so 2 ulp of the larger value are allowed.
    lo, hi = min(x1, x2), max(x1, x2)
    assert scalar(_ramp(lo, width)) <= scalar(_ramp(hi, width)) * (1 + 4 * EPS)
    assert scalar(_step(lo, width)) <= scalar(_step(hi, width)) + 4 * EPS
    # Exact bracket of the smoothed ramp: max(0, x) <= ramp <= max(0, x) + eps ln 2 (softplus
    # error is largest at the kink). Round-off: fl(eps * fl(x / eps)) can sit an ulp below x.
    r = scalar(_ramp(x1, width))
    exact = max(x1, 0.0)
    assert exact * (1 - 2 * EPS) <= r <= (exact + width * np.log(2.0)) * (1 + 2 * EPS)
    assert 0.0 <= scalar(_step(x1, width)) <= 1.0


@SETTINGS
@given(x=X, h_rel=signed(1e-12, 1.0), width=WIDTH)
def test_ramp_is_1_lipschitz(x, h_rel, width):
    # |d ramp/dx| = sigma(x/eps) <= 1 (and 0 or 1 at eps = 0): a step h in the deflection never
    # changes the ramp by more than |h|, whatever the width (continuity of every force built on it).
    x2 = x + h_rel * max(abs(x), width, 1e-300)
    r1, r2 = scalar(_ramp(x, width)), scalar(_ramp(x2, width))
    # Round-off: a few ulp of each value (softplus), plus the ulp of x2 - x.
    assert abs(r2 - r1) <= abs(x2 - x) * (1 + 2 * EPS) + 4 * EPS * (abs(r1) + abs(r2))


@SETTINGS
@given(x=X, h_rel=signed(1e-12, 1.0), width=positive(1e-149, 1e3))
def test_step_lipschitz_in_units_of_its_width(x, h_rel, width):
    # |d step/dx| = sigma'(x/eps)/eps <= 1/(4 eps): the switch turns on over a distance of order eps
    # and no faster (the exact step, eps = 0 or eps <= smooth.WIDTH_FLOOR = 1e-150, is
    # discontinuous and not tested here).
    x2 = x + h_rel * max(abs(x), width)
    s1, s2 = scalar(_step(x, width)), scalar(_step(x2, width))
    # Round-off: the logistic is correct to an ulp of 1.
    assert abs(s2 - s1) <= abs(x2 - x) / (4 * width) * (1 + 2 * EPS) + 4 * EPS


@SETTINGS
@given(g1=X, g2=X, backlash=BACKLASH, width=WIDTH)
def test_dead_zone_non_decreasing_and_1_lipschitz(g1, g2, backlash, width):
    # f_g(g) = ramp(g) - ramp(-g - b): slope sigma(g/eps) + sigma(-(g + b)/eps), which lies in
    # [0, 1] for b >= 0 (sigma(a) + sigma(-a - b/eps) <= sigma(a) + sigma(-a) = 1). The mesh force
    # K f_g therefore never decreases as the teeth are pushed together, and never stiffer than K.
    lo, hi = min(g1, g2), max(g1, g2)
    f_lo, f_hi = scalar(_dead_zone(lo, backlash, width)), scalar(_dead_zone(hi, backlash, width))
    # Round-off: f_g is a difference of two ramps, each of magnitude <= |g| + b + eps ln 2, and
    # -g - b is rounded; a few ulp of those magnitudes.
    roundoff = 8 * EPS * (abs(lo) + abs(hi) + backlash + width)
    assert f_lo <= f_hi + roundoff
    assert f_hi - f_lo <= (hi - lo) * (1 + 2 * EPS) + roundoff


@SETTINGS
@given(g=X, b1=BACKLASH, b2=BACKLASH, width=WIDTH)
def test_dead_zone_non_decreasing_in_backlash(g, b1, b2, width):
    # d f_g / db = sigma(-(g + b)/eps) in [0, 1]: more backlash delays the back-flank contact, so
    # the (negative) back-flank part only weakens, at most one-for-one, and the drive flank
    # (g >= 0) is unaffected in the exact limit.
    lo, hi = min(b1, b2), max(b1, b2)
    f_lo, f_hi = scalar(_dead_zone(g, lo, width)), scalar(_dead_zone(g, hi, width))
    roundoff = 8 * EPS * (abs(g) + hi + width)
    assert f_lo <= f_hi + roundoff
    assert f_hi - f_lo <= (hi - lo) * (1 + 2 * EPS) + roundoff
    if width == 0.0 and g >= 0.0:
        assert f_lo == f_hi == g



# The plain sqrt(sum of squares) under- and overflows outside |v| in [1e-154, 1e154]; SI lengths
# and speeds are far inside that range, so the norm is tested there.
NORM_COMPONENT = signed(1e-150, 1e150)
NORM_WIDTH = widths(1e-150, 1e3)


@SETTINGS
@given(
    v1=st.tuples(NORM_COMPONENT, NORM_COMPONENT),
    v2=st.tuples(NORM_COMPONENT, NORM_COMPONENT),
    w1=NORM_WIDTH,
    w2=NORM_WIDTH,
)
def test_norm_bounds_exact_limit_and_lipschitz(v1, v2, w1, w2):
    v1, v2 = np.array(v1), np.array(v2)
    exact1 = float(np.hypot(*v1))
    n1 = scalar(_norm(v1, w1))
    # sqrt(|v|^2 + eps^2) lies between max(|v|, eps) and |v| + eps (triangle inequality), so the
    # smoothed eccentricity never understates a penetration, overstates it by at most eps, and
    # stays >= eps > 0 at v = 0 (where the exact norm has no gradient). Round-off: the sum of
    # squares and the sqrt, 2 ulp.
    assert max(exact1, w1) * (1 - 4 * EPS) <= n1 <= (exact1 + w1) * (1 + 4 * EPS)
    # Exact limit: width 0 is the Euclidean norm.
    assert scalar(_norm(v1, 0.0)) == pytest.approx(exact1, rel=4 * EPS, abs=0.0)
    # 1-Lipschitz in v (the gradient v / sqrt(|v|^2 + eps^2) has length <= 1) and in the width:
    # contact normals and penetrations are continuous in the positions.
    n2 = scalar(_norm(v2, w1))
    assert abs(n1 - n2) <= float(np.hypot(*(v1 - v2))) * (1 + 4 * EPS) + 4 * EPS * (n1 + n2)
    n3 = scalar(_norm(v1, w2))
    assert abs(n1 - n3) <= abs(w1 - w2) * (1 + 4 * EPS) + 4 * EPS * (n1 + n3)


@SETTINGS
@given(x1=X, x2=X)
def test_power_and_sqrt_monotone_and_continuous(x1, x2):
    # x^p (p >= 1, the Hertz exponents 1.5 and 2.5) and sqrt: zero for x <= 0, non-decreasing,
    # Lipschitz with constant p X^(p-1) on [0, X], and sqrt Hoelder-1/2: |sqrt a - sqrt b| <=
    # sqrt|a - b| (no jump at contact onset).
    lo, hi = min(x1, x2), max(x1, x2)
    top = max(hi, 0.0)
    for p, fn in _power.items():
        a, b = scalar(fn(lo)), scalar(fn(hi))
        assert 0.0 <= a <= b
        # Round-off: pow is correct to an ulp or two.
        assert b - a <= p * top ** (p - 1) * (max(hi, 0.0) - max(lo, 0.0)) * (1 + 4 * EPS) + 4 * EPS * b
        if lo <= 0.0:
            assert a == 0.0
    a, b = scalar(_sqrt(lo)), scalar(_sqrt(hi))
    assert 0.0 <= a <= b
    assert b - a <= np.sqrt(max(hi, 0.0) - max(lo, 0.0)) * (1 + 4 * EPS) + 4 * EPS * b



# ------------------------------------------------------------------------------------------
# Symmetry of the dead zone.


@pytest.mark.parametrize("width", (0.0,) + WIDTHS[:3])
@pytest.mark.parametrize("backlash", BACKLASHES)
def test_dead_zone_odd_about_gap_centre(width, backlash):
    centre = -0.5 * backlash
    offsets = np.concatenate([[0.0], np.linspace(-3, 3, 61) * max(backlash, width, 1e-6)])
    up = np.asarray(smooth.dead_zone(centre + offsets, backlash, width))
    down = np.asarray(smooth.dead_zone(centre - offsets, backlash, width))
    # Odd by construction (ramp(c + s) - ramp(c - s) with c = -b/2 swaps the two ramps); the
    # only asymmetry is round-off in forming centre +- offset. Zero force at mid-gap.
    scale = 8 * np.finfo(float).eps * (np.abs(offsets) + backlash + width)
    np.testing.assert_array_less(np.abs(up + down), scale + 1e-300)
    assert abs(float(smooth.dead_zone(centre, backlash, width))) <= 4 * np.finfo(float).eps * backlash


@SETTINGS
@given(g=X, backlash=BACKLASH, width=WIDTH)
def test_dead_zone_odd_about_gap_centre_for_any_input(g, backlash, width):
    # docs/model.md §1: the dead zone is odd about the centre of the gap g = -b/2, i.e.
    # f_g(g) = -f_g(-g - b) (ramp(g) - ramp(-g - b) swaps its two ramps), so a gear centred in
    # its backlash feels no force and the two flanks are symmetric. Zero at mid-gap.
    mirror = -g - backlash
    total = scalar(_dead_zone(g, backlash, width)) + scalar(_dead_zone(mirror, backlash, width))
    # Only asymmetry: -(-g - b) - b rounds back to g to within an ulp of max(|g|, b); the ramps
    # are 1-Lipschitz, plus their own round-off.
    assert abs(total) <= 8 * EPS * (abs(g) + backlash + width)
    assert abs(scalar(_dead_zone(-0.5 * backlash, backlash, width))) <= 4 * EPS * backlash
    # Exact limit: no force strictly inside the gap.
    if width == 0.0 and -backlash < g < 0.0:
        assert scalar(_dead_zone(g, backlash, 0.0)) == 0.0



# ------------------------------------------------------------------------------------------
# Gradients: finite exactly at the kinks and at zero norm; equal to finite differences.


@pytest.mark.parametrize("width", [0.0, 1e-9, 1e-3])
def test_gradients_finite_at_kinks(width):
    w = jnp.asarray(width)
    b = jnp.asarray(1e-5)
    cases = {
        "ramp(0)": lambda x, w: smooth.ramp(x, w),
        "step(0)": lambda x, w: smooth.step(x, w),
        "dead_zone(g=0)": lambda x, w: smooth.dead_zone(x, b, w),
        "dead_zone(g=-b)": lambda x, w: smooth.dead_zone(x - b, b, w),
        "dead_zone(b=0, g=0)": lambda x, w: smooth.dead_zone(x, 0.0, w),
    }
    for name, fn in cases.items():
        grads = jax.grad(fn, argnums=(0, 1))(jnp.asarray(0.0), w)
        assert finite(grads), name
    # Derivative values at the kink where the formula is known: softplus' = sigmoid(0) = 1/2 for
    # width > 0. At width 0 any subgradient in [0, 1] is acceptable.
    slope = float(jax.grad(smooth.ramp)(0.0, w))
    if width > 0:
        assert slope == 0.5
    else:
        assert 0.0 <= slope <= 1.0
    # Also the gradient with respect to the backlash at both kinks.
    for g in (0.0, -1e-5):
        assert finite(jax.grad(lambda bb: smooth.dead_zone(g, bb, w))(b))


@pytest.mark.parametrize("width", [0.0, 1e-9])
def test_norm_gradient_at_zero(width):
    v = jnp.zeros(2)
    grad_v, grad_w = jax.grad(smooth.norm, argnums=(0, 1))(v, jnp.asarray(width))
    # At v = 0 the gradient in v is 0 (the subgradient; sqrt(|v|^2 + eps^2) is even in v).
    np.testing.assert_array_equal(np.asarray(grad_v), np.zeros(2))
    # d/d eps sqrt(eps^2) = 1 for eps > 0; at eps = 0 any finite value (0 by the safe branch).
    if width > 0:
        assert float(grad_w) == pytest.approx(1.0, rel=1e-15)
    else:
        assert np.isfinite(float(grad_w))
    # Forward mode too (used by `rate_derivative`).
    _, tangent = jax.jvp(lambda v: smooth.norm(v, width), (v,), (jnp.ones(2),))
    assert np.isfinite(float(tangent))
    # Second derivative (Hessian) at 0 is finite at width > 0 (1/eps on the diagonal) and at
    # least not NaN at width 0.
    hess = jax.hessian(smooth.norm)(v, jnp.asarray(width))
    if width > 0:
        np.testing.assert_allclose(np.asarray(hess), np.eye(2) / width, rtol=1e-12)
    else:
        assert not np.any(np.isnan(np.asarray(hess)))


def test_power_and_sqrt_gradients_at_zero():
    # The traps: sqrt(x) * x and jnp.sqrt at 0 give inf/NaN in reverse mode.
    assert float(jax.grad(smooth.power)(0.0, 1.5)) == 0.0
    assert float(jax.grad(smooth.power)(0.0, 2.5)) == 0.0
    assert float(jax.grad(smooth.sqrt)(0.0)) == 0.0
    assert float(jax.grad(smooth.sqrt)(-1.0)) == 0.0
    assert float(jax.grad(smooth.power)(-1.0, 1.5)) == 0.0
    # Bai-Zhao-like composite d^1.5 / sqrt(2(c + d)) at d = 0, with c > 0 and c = 0 (where the
    # naive form is 0/0): built from the safe pieces, all gradients finite.
    def bai_zhao_like(d, c):
        denom = 2.0 * (c + d)
        return jnp.where(denom > 0, smooth.power(d, 1.5) / smooth.sqrt(jnp.where(denom > 0, denom, 1.0)), 0.0)

    for c in (1e-4, 0.0):
        assert finite(jax.grad(bai_zhao_like, argnums=(0, 1))(jnp.asarray(0.0), jnp.asarray(c)))
    # (The same primitives inside the contact pipeline: test_contact.py::
    # test_force_gradients_finite_at_wall_and_centre.)


def _primitive_derivatives_impl(x, width, backlash):
    v = jnp.stack([x, backlash])
    fns = {
        "ramp": (smooth.ramp, (x, width), (0, 1)),
        "step": (smooth.step, (x, width), (0, 1)),
        "dead_zone": (smooth.dead_zone, (x, backlash, width), (0, 1, 2)),
        "norm": (smooth.norm, (v, width), (0, 1)),
        "power1.5": (lambda x: smooth.power(x, 1.5), (x,), (0,)),
        "power2.5": (lambda x: smooth.power(x, 2.5), (x,), (0,)),
        "sqrt": (smooth.sqrt, (x,), (0,)),
    }
    return {
        name: (fn(*args), jax.grad(fn, argnums)(*args), jax.jacfwd(fn, argnums)(*args))
        for name, (fn, args, argnums) in fns.items()
    }


_primitive_derivatives = jax.jit(_primitive_derivatives_impl)


@SETTINGS
@given(
    offset=X,
    anchor=st.sampled_from(["zero", "-b", "-b/2"]),
    width=WIDTH_DIFFERENTIABLE,
    backlash=BACKLASH,
)
def test_primitive_derivatives_finite(offset, anchor, width, backlash):
    # docs/model.md §1: gradients finite everywhere, in reverse and forward mode, including exactly at
    # each kink (x = 0 and, for the dead zone, g = -b and mid-gap g = -b/2; offset = 0 is drawn
    # often), at width 0, at zero backlash and at zero norm (v = (x, b) = 0), for arguments from
    # 1e-300 to 1e3 and widths from 1e-150 to 1e3. The traps: sqrt at 0, x^1.5 written as
    # sqrt(x) x, |v| at 0, and 0 * inf in the unused branch of a where.
    x = {"zero": 0.0, "-b": -backlash, "-b/2": -0.5 * backlash}[anchor] + offset
    out = _primitive_derivatives(x, width, backlash)
    for name, (value, rev, fwd) in out.items():
        assert finite(value), (name, "value")
        assert finite(rev), (name, "reverse")
        assert finite(fwd), (name, "forward")


@SETTINGS
@given(x=X, width=positive(1e-300, 1e-160))
def test_width_derivative_finite_for_tiny_widths(x, width):
    # The module promises finite gradients everywhere for any width >= 0. The width derivative of
    # eps softplus(x/eps) is softplus(a) - a sigma(a), a = x/eps, which lies in [0, ln 2] for
    # every x and eps; that of sigma(x/eps) is -a sigma'(a)/eps, at most 0.23/eps (finite for any
    # normal eps) and exactly 0 at x = 0. Nothing needs to overflow. (Found by this test: the
    # x / w**2 term overflowed below w ~ 1e-154; widths <= smooth.WIDTH_FLOOR = 1e-150 now count
    # as exact.)
    out = _primitive_derivatives(x, width, 0.0)
    assert finite(out["ramp"][1]) and finite(out["step"][1])



def _central_difference(fn, x, h):
    return (fn(x + h) - fn(x - h)) / (2 * h)


@pytest.mark.parametrize(
    "name, fn, points, scale",
    [
        ("ramp", lambda x: smooth.ramp(x, 1e-6), [-2e-6, -3e-7, 0.0, 4e-7, 3e-6], 1e-6),
        ("step", lambda x: smooth.step(x, 1e-6), [-2e-6, -3e-7, 0.0, 4e-7, 3e-6], 1e-6),
        ("dead_zone", lambda x: smooth.dead_zone(x, 1e-5, 1e-6), [-1.2e-5, -1e-5, -5e-6, 0.0, 2e-6], 1e-6),
        ("power1.5", lambda x: smooth.power(x, 1.5), [1e-6, 0.3, 2.0], None),
        ("sqrt", lambda x: smooth.sqrt(x), [1e-6, 0.3, 2.0], None),
    ],
)
def test_gradient_matches_finite_differences(name, fn, points, scale):
    for x in points:
        # Step: 1e-4 of the local length scale (the width, or x itself for the powers). Central
        # differences: truncation h^2 f'''/6 ~ 2e-9 relative, round-off eps * f / h ~ 1e-12;
        # tolerance 1e-7 relative to the derivative's scale.
        length = scale if scale is not None else x
        h = 1e-4 * length
        ad = float(jax.grad(fn)(jnp.asarray(x)))
        fd = float(_central_difference(fn, jnp.asarray(x), h))
        typical = abs(float(_central_difference(fn, jnp.asarray(x), length)))
        assert ad == pytest.approx(fd, rel=1e-7, abs=1e-7 * typical), (name, x)


@pytest.mark.parametrize("width", [1e-9, 1e-3])
def test_norm_gradient_matches_finite_differences(width):
    rng = np.random.default_rng(1)
    for _ in range(5):
        v = rng.normal(size=2) * width * 3
        ad = np.asarray(jax.grad(smooth.norm)(jnp.asarray(v), width))
        h = 1e-4 * width
        fd = np.array(
            [
                (smooth.norm(v + h * e_i, width) - smooth.norm(v - h * e_i, width)) / (2 * h)
                for e_i in np.eye(2)
            ]
        )
        # Same reasoning as above: second-order truncation with h = 1e-4 eps; the gradient is
        # a unit-ish vector (|grad| <= 1), so an absolute 1e-7 is relative to that.
        np.testing.assert_allclose(ad, fd, rtol=0.0, atol=1e-7)
