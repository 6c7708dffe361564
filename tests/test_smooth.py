"""The smooth primitives of `tolerax.smooth` against the exact piecewise functions (numpy), their
documented error bounds, and their gradients (finite at every kink; equal to finite differences
where smooth)."""

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax
from tolerax import smooth


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


# ------------------------------------------------------------------------------------------
# Gradients: finite exactly at the kinks and at zero norm; equal to finite differences.


def _finite(tree):
    return all(np.all(np.isfinite(np.asarray(leaf))) for leaf in jax.tree_util.tree_leaves(tree))


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
        assert _finite(grads), name
    # Derivative values at the kink where the formula is known: softplus' = sigmoid(0) = 1/2 for
    # width > 0. At width 0 any subgradient in [0, 1] is acceptable.
    slope = float(jax.grad(smooth.ramp)(0.0, w))
    if width > 0:
        assert slope == 0.5
    else:
        assert 0.0 <= slope <= 1.0
    # Also the gradient with respect to the backlash at both kinks.
    for g in (0.0, -1e-5):
        assert _finite(jax.grad(lambda bb: smooth.dead_zone(g, bb, w))(b))


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
        assert _finite(jax.grad(bai_zhao_like, argnums=(0, 1))(jnp.asarray(0.0), jnp.asarray(c)))
    # A Hertz force law through the contact pipeline at zero penetration: finite gradients of
    # the force in all inputs, at the wall (|e| = c) and at the bearing centre (e = 0).
    bearing = tolerax.JournalBearing(journal_radius=5e-3, clearance=1e-4, length=8e-3)
    for e in (jnp.array([1e-4, 0.0]), jnp.zeros(2)):
        for width in (0.0, 1e-9):

            def force(e, e_dot, bearing):
                state = tolerax.contact_kinematics(bearing, e, e_dot, width)
                return tolerax.normal_force(tolerax.Flores(0.9), bearing, state, 0.1, width)

            grads = jax.grad(force, argnums=(0, 1, 2))(e, jnp.array([0.1, 0.0]), bearing)
            assert _finite(grads), (e, width)


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
