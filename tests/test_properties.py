"""Property-based tests (hypothesis) of the smooth primitives, the contact laws and the mesh
functions (MODEL.md §1-3).

`test_smooth.py` and `test_contact.py` compare these functions with the exact piecewise functions
on fixed grids and through a 1-DOF impact; here the same functions are checked for properties that
must hold for *every* input of their domain (monotonicity, Lipschitz bounds, symmetry, sign, exact
limit at width 0, finite derivatives), over random inputs spanning all magnitudes from 1e-300 to
1e3 (SI units) where the quantity is meaningful, with zero widths, zero clearances and the kinks
themselves drawn often.

Every function under test is jitted once at module level (scalar float64 arguments, so values
never retrace). Examples are derandomized so that CI is reproducible. Subnormal inputs are never
drawn: XLA on CPU flushes them to zero (FTZ/DAZ), so for them the "exact" numpy reference and the
jitted function disagree by design.
"""

import functools
import operator

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

import tolerax
from tolerax import _mesh, smooth
from tolerax._contact import CLIP_WIDTH, FORCE_FLOOR

# MODEL.md §2's hysteresis factors, transcribed independently of tolerax (one copy, in test_contact).
from test_contact import _chi


EPS = float(np.finfo(float).eps)
SETTINGS = settings(max_examples=60, deadline=None, derandomize=True)
# The contact-force properties have the largest input space (law, 8 inputs, kinks): more examples.
MORE = settings(SETTINGS, max_examples=100)


# ------------------------------------------------------------------------------------------------
# Strategies.


def _positive(lo, hi):
    """Floats in [lo, hi], spread evenly over the decades (log-uniform) and also drawn by
    hypothesis' own float strategy (which favours the bounds and simple values)."""
    log_uniform = st.floats(np.log10(lo), np.log10(hi)).map(lambda u: float(np.clip(10.0**u, lo, hi)))
    direct = st.floats(lo, hi, allow_nan=False, allow_infinity=False, allow_subnormal=False)
    return st.one_of(log_uniform, direct)


def _signed(lo, hi):
    """0, or +-[lo, hi]."""
    return st.one_of(st.just(0.0), _positive(lo, hi), _positive(lo, hi).map(operator.neg))


def _widths(lo=1e-300, hi=1e3):
    """Smoothing widths: 0 (the exact limit) drawn often, else [lo, hi]."""
    return st.one_of(st.just(0.0), _positive(lo, hi))


def _finite(tree):
    return all(np.all(np.isfinite(np.asarray(leaf))) for leaf in jax.tree_util.tree_leaves(tree))


def _f(x):
    return float(np.asarray(x))


# Arguments of the primitives: displacements from 1e-300 m to 1 km, zero included.
X = _signed(1e-300, 1e3)
WIDTH = _widths()
# Widths for which the derivative with respect to the width is asked to be finite: the ramp's
# width derivative contains x / w^2, which overflowed below w ~ 1e-154 (smooth.WIDTH_FLOOR now;
# see test_width_derivative_finite_for_tiny_widths).
WIDTH_DIFFERENTIABLE = _widths(1e-150)
BACKLASH = st.one_of(st.just(0.0), _positive(1e-300, 1e-2))


# ------------------------------------------------------------------------------------------------
# Smooth primitives, MODEL.md §1.

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
    assert _f(_ramp(lo, width)) <= _f(_ramp(hi, width)) * (1 + 4 * EPS)
    assert _f(_step(lo, width)) <= _f(_step(hi, width)) + 4 * EPS
    # Exact bracket of the smoothed ramp: max(0, x) <= ramp <= max(0, x) + eps ln 2 (softplus
    # error is largest at the kink). Round-off: fl(eps * fl(x / eps)) can sit an ulp below x.
    r = _f(_ramp(x1, width))
    exact = max(x1, 0.0)
    assert exact * (1 - 2 * EPS) <= r <= (exact + width * np.log(2.0)) * (1 + 2 * EPS)
    assert 0.0 <= _f(_step(x1, width)) <= 1.0


@SETTINGS
@given(x=X, h_rel=_signed(1e-12, 1.0), width=WIDTH)
def test_ramp_is_1_lipschitz(x, h_rel, width):
    # |d ramp/dx| = sigma(x/eps) <= 1 (and 0 or 1 at eps = 0): a step h in the deflection never
    # changes the ramp by more than |h|, whatever the width (continuity of every force built on it).
    x2 = x + h_rel * max(abs(x), width, 1e-300)
    r1, r2 = _f(_ramp(x, width)), _f(_ramp(x2, width))
    # Round-off: a few ulp of each value (softplus), plus the ulp of x2 - x.
    assert abs(r2 - r1) <= abs(x2 - x) * (1 + 2 * EPS) + 4 * EPS * (abs(r1) + abs(r2))


@SETTINGS
@given(x=X, h_rel=_signed(1e-12, 1.0), width=_positive(1e-149, 1e3))
def test_step_lipschitz_in_units_of_its_width(x, h_rel, width):
    # |d step/dx| = sigma'(x/eps)/eps <= 1/(4 eps): the switch turns on over a distance of order eps
    # and no faster (the exact step, eps = 0 or eps <= smooth.WIDTH_FLOOR = 1e-150, is
    # discontinuous and not tested here).
    x2 = x + h_rel * max(abs(x), width)
    s1, s2 = _f(_step(x, width)), _f(_step(x2, width))
    # Round-off: the logistic is correct to an ulp of 1.
    assert abs(s2 - s1) <= abs(x2 - x) / (4 * width) * (1 + 2 * EPS) + 4 * EPS


@SETTINGS
@given(g1=X, g2=X, backlash=BACKLASH, width=WIDTH)
def test_dead_zone_non_decreasing_and_1_lipschitz(g1, g2, backlash, width):
    # f_g(g) = ramp(g) - ramp(-g - b): slope sigma(g/eps) + sigma(-(g + b)/eps), which lies in
    # [0, 1] for b >= 0 (sigma(a) + sigma(-a - b/eps) <= sigma(a) + sigma(-a) = 1). The mesh force
    # K f_g therefore never decreases as the teeth are pushed together, and never stiffer than K.
    lo, hi = min(g1, g2), max(g1, g2)
    f_lo, f_hi = _f(_dead_zone(lo, backlash, width)), _f(_dead_zone(hi, backlash, width))
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
    f_lo, f_hi = _f(_dead_zone(g, lo, width)), _f(_dead_zone(g, hi, width))
    roundoff = 8 * EPS * (abs(g) + hi + width)
    assert f_lo <= f_hi + roundoff
    assert f_hi - f_lo <= (hi - lo) * (1 + 2 * EPS) + roundoff
    if width == 0.0 and g >= 0.0:
        assert f_lo == f_hi == g


@SETTINGS
@given(g=X, backlash=BACKLASH, width=WIDTH)
def test_dead_zone_odd_about_gap_centre(g, backlash, width):
    # MODEL.md §1: the dead zone is odd about the centre of the gap g = -b/2, i.e.
    # f_g(g) = -f_g(-g - b) (ramp(g) - ramp(-g - b) swaps its two ramps), so a gear centred in
    # its backlash feels no force and the two flanks are symmetric. Zero at mid-gap.
    mirror = -g - backlash
    total = _f(_dead_zone(g, backlash, width)) + _f(_dead_zone(mirror, backlash, width))
    # Only asymmetry: -(-g - b) - b rounds back to g to within an ulp of max(|g|, b); the ramps
    # are 1-Lipschitz, plus their own round-off.
    assert abs(total) <= 8 * EPS * (abs(g) + backlash + width)
    assert abs(_f(_dead_zone(-0.5 * backlash, backlash, width))) <= 4 * EPS * backlash
    # Exact limit: no force strictly inside the gap.
    if width == 0.0 and -backlash < g < 0.0:
        assert _f(_dead_zone(g, backlash, 0.0)) == 0.0


# The plain sqrt(sum of squares) under- and overflows outside |v| in [1e-154, 1e154]; SI lengths
# and speeds are far inside that range, so the norm is tested there.
NORM_COMPONENT = _signed(1e-150, 1e150)
NORM_WIDTH = _widths(1e-150, 1e3)


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
    n1 = _f(_norm(v1, w1))
    # sqrt(|v|^2 + eps^2) lies between max(|v|, eps) and |v| + eps (triangle inequality), so the
    # smoothed eccentricity never understates a penetration, overstates it by at most eps, and
    # stays >= eps > 0 at v = 0 (where the exact norm has no gradient). Round-off: the sum of
    # squares and the sqrt, 2 ulp.
    assert max(exact1, w1) * (1 - 4 * EPS) <= n1 <= (exact1 + w1) * (1 + 4 * EPS)
    # Exact limit: width 0 is the Euclidean norm.
    assert _f(_norm(v1, 0.0)) == pytest.approx(exact1, rel=4 * EPS, abs=0.0)
    # 1-Lipschitz in v (the gradient v / sqrt(|v|^2 + eps^2) has length <= 1) and in the width:
    # contact normals and penetrations are continuous in the positions.
    n2 = _f(_norm(v2, w1))
    assert abs(n1 - n2) <= float(np.hypot(*(v1 - v2))) * (1 + 4 * EPS) + 4 * EPS * (n1 + n2)
    n3 = _f(_norm(v1, w2))
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
        a, b = _f(fn(lo)), _f(fn(hi))
        assert 0.0 <= a <= b
        # Round-off: pow is correct to an ulp or two.
        assert b - a <= p * top ** (p - 1) * (max(hi, 0.0) - max(lo, 0.0)) * (1 + 4 * EPS) + 4 * EPS * b
        if lo <= 0.0:
            assert a == 0.0
    a, b = _f(_sqrt(lo)), _f(_sqrt(hi))
    assert 0.0 <= a <= b
    assert b - a <= np.sqrt(max(hi, 0.0) - max(lo, 0.0)) * (1 + 4 * EPS) + 4 * EPS * b


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
    # MODEL.md §1: gradients finite everywhere, in reverse and forward mode, including exactly at
    # each kink (x = 0 and, for the dead zone, g = -b and mid-gap g = -b/2; offset = 0 is drawn
    # often), at width 0, at zero backlash and at zero norm (v = (x, b) = 0), for arguments from
    # 1e-300 to 1e3 and widths from 1e-150 to 1e3. The traps: sqrt at 0, x^1.5 written as
    # sqrt(x) x, |v| at 0, and 0 * inf in the unused branch of a where.
    x = {"zero": 0.0, "-b": -backlash, "-b/2": -0.5 * backlash}[anchor] + offset
    out = _primitive_derivatives(x, width, backlash)
    for name, (value, rev, fwd) in out.items():
        assert _finite(value), (name, "value")
        assert _finite(rev), (name, "reverse")
        assert _finite(fwd), (name, "forward")


@SETTINGS
@given(x=X, width=_positive(1e-300, 1e-160))
def test_width_derivative_finite_for_tiny_widths(x, width):
    # The module promises finite gradients everywhere for any width >= 0. The width derivative of
    # eps softplus(x/eps) is softplus(a) - a sigma(a), a = x/eps, which lies in [0, ln 2] for
    # every x and eps; that of sigma(x/eps) is -a sigma'(a)/eps, at most 0.23/eps (finite for any
    # normal eps) and exactly 0 at x = 0. Nothing needs to overflow. (Found by this test: the
    # x / w**2 term overflowed below w ~ 1e-154; widths <= smooth.WIDTH_FLOOR = 1e-150 now count
    # as exact.)
    out = _primitive_derivatives(x, width, 0.0)
    assert _finite(out["ramp"][1]) and _finite(out["step"][1])


# ------------------------------------------------------------------------------------------------
# Contact laws, MODEL.md §2.

JOURNAL_RADIUS = 5e-3  # m
LENGTH = 8e-3  # m
LAWS = ("HertzLN", "Flores", "BaiZhao", "Adams")
_E_STAR = 1.0 / (2.0 * (1.0 - 0.3**2) / 206e9)  # steel on steel, the JournalBearing default
_ADAMS = tolerax.AdamsImpact()


def _law(kind, restitution):
    if kind == "Adams":
        return _ADAMS
    return {"HertzLN": tolerax.HertzLN, "Flores": tolerax.Flores, "BaiZhao": tolerax.BaiZhao}[kind](
        restitution
    )


def _force_impl(kind, e, e_dot, impact_rate, restitution, width, clearance, rate_floor):
    bearing = tolerax.JournalBearing(JOURNAL_RADIUS, clearance, LENGTH)
    state = tolerax.contact_kinematics(bearing, e, e_dot, width)
    return tolerax.normal_force(_law(kind, restitution), bearing, state, impact_rate, width, rate_floor)


def _force_and_derivatives_impl(kind, *args):
    # Derivatives with respect to the journal position e, its velocity e_dot, the impact-rate
    # state and the bearing's clearance (a design parameter).
    fn = functools.partial(_force_impl, kind)
    argnums = (0, 1, 2, 5)
    return fn(*args), jax.grad(fn, argnums)(*args), jax.jacfwd(fn, argnums)(*args)


_force = {kind: jax.jit(functools.partial(_force_and_derivatives_impl, kind)) for kind in LAWS}
_elastic = {
    kind: jax.jit(
        lambda d, c, kind=kind: _law(kind, 0.5).elastic(tolerax.JournalBearing(JOURNAL_RADIUS, c, LENGTH), d)
    )
    for kind in LAWS
}
_kinematics = jax.jit(
    lambda e, e_dot, width, c: tolerax.contact_kinematics(
        tolerax.JournalBearing(JOURNAL_RADIUS, c, LENGTH), e, e_dot, width
    )
)
_effective_impact_rate = jax.jit(tolerax.effective_impact_rate)


def _clearances(kind):
    # The Hertz stiffness K ~ sqrt(R_a R_b / c) diverges as c -> 0 (documented: conformal contact,
    # use Bai-Zhao or Adams there); its derivative dK/dc ~ c^-1.5 overflows below c ~ 1e-155.
    # Bai-Zhao and Adams accept a zero clearance.
    # Upper end 1 mm: JournalBearing requires c < R_a (5 mm here).
    if kind in ("HertzLN", "Flores"):
        return _positive(1e-100, 1e-3)
    return st.one_of(st.just(0.0), _positive(1e-300, 1e-3))


@st.composite
def contact_cases(draw, width=WIDTH):
    """A journal at a random penetration (from -1 cm to 1 cm, magnitudes down to 1e-300 m and
    exactly 0), in a random direction, with random velocity, impact rate, restitution in (0, 1],
    smoothing width (0 included), clearance (0 included where the law allows) and rate floor."""
    kind = draw(st.sampled_from(LAWS))
    clearance = draw(_clearances(kind))
    # Half of the draws from the physical ranges (nm to 0.1 mm, mm/s to 10 m/s), so that the
    # clip of a fast separation (1 + chi rate / v- < 0) is exercised often, not only by chance.
    penetration = draw(st.one_of(_signed(1e-300, 1e-2), _signed(1e-9, 1e-4)))
    speed = st.one_of(_signed(1e-300, 1e3), _signed(1e-3, 10.0))
    angle = draw(st.floats(0.0, 2 * np.pi))
    radius = abs(clearance + penetration)
    return dict(
        kind=kind,
        e=np.array([radius * np.cos(angle), radius * np.sin(angle)]),
        e_dot=np.array([draw(speed), draw(speed)]),
        impact_rate=draw(speed),
        # Flores' chi = 8(1 - ce)/(5 ce) diverges as ce -> 0; 1e-100 keeps chi * rate finite.
        restitution=draw(st.one_of(st.just(1.0), _positive(1e-100, 1.0))),
        width=draw(width),
        clearance=clearance,
        rate_floor=draw(_positive(1e-9, 1.0)),
    )


def _call_force(case):
    args = (case[k] for k in ("e", "e_dot", "impact_rate", "restitution", "width", "clearance", "rate_floor"))
    return _force[case["kind"]](*args)


@MORE
@given(case=contact_cases())
def test_normal_force_non_negative_and_finite(case):
    # MODEL.md §2: the contact never pulls, for every law, penetration, penetration rate (a fast
    # separation makes 1 + chi rate / v- negative: the clip must act), impact rate (negative,
    # zero: the rate floor), restitution, width (0 included) and clearance (0 included).
    force, _, _ = _call_force(case)
    assert np.isfinite(_f(force))
    assert _f(force) >= 0.0


@MORE
@given(case=contact_cases())
def test_normal_force_derivatives_finite(case):
    # Reverse- and forward-mode derivatives of the force with respect to position, velocity,
    # impact rate and clearance are finite over the whole domain: at contact onset (penetration
    # exactly 0, or a few widths either side where F_el is an exponentially small tail), at
    # e = 0, at width 0, at zero clearance, for tiny and huge magnitudes. One NaN poisons the
    # gradient of a whole simulation.
    _, rev, fwd = _call_force(case)
    assert _finite(rev), rev
    assert _finite(fwd), fwd


@SETTINGS
@given(case=contact_cases(width=st.just(0.0)), depth=_positive(1e-12, 1.0))
def test_no_force_out_of_contact_in_exact_limit(case, depth):
    # Exact limit (width 0): with the journal strictly inside the clearance the force is exactly
    # zero, whatever the rates, and so are all its derivatives (no spurious sensitivity of a free
    # flight to the clearance). depth >= 1e-12 of c keeps |e| < c after rounding of cos/sin.
    if case["clearance"] == 0.0:
        case["clearance"] = 1e-4  # a zero clearance has no "inside"
    direction = case["e"] / max(float(np.hypot(*case["e"])), 1e-300)
    if not np.any(direction):
        direction = np.array([1.0, 0.0])
    case["e"] = direction / np.hypot(*direction) * case["clearance"] * (1.0 - depth)
    force, rev, fwd = _call_force(case)
    assert _f(force) == 0.0
    for tree in (rev, fwd):
        assert all(np.all(np.asarray(leaf) == 0.0) for leaf in jax.tree_util.tree_leaves(tree))


@SETTINGS
@given(
    kind=st.sampled_from(LAWS),
    gap_in_widths=st.floats(5.0, 700.0),
    width_fraction=_positive(1e-9, 1.0),
    clearance=_positive(1e-6, 1e-3),
    angle=st.floats(0.0, 2 * np.pi),
    rate=_signed(1e-300, 1e3),
    restitution=_positive(1e-3, 1.0),
    rate_floor=_positive(1e-9, 1.0),
)
def test_smoothed_force_out_of_contact_decays_exponentially(
    kind, gap_in_widths, width_fraction, clearance, angle, rate, restitution, rate_floor
):
    # MODEL.md §1: the smoothing tails are exponentially small, so the force a distance d outside
    # contact is at most of order F_el(eps) e^(-d/eps) (an algebraic tail, e.g. the sqrt-form
    # ramp, leaks force across the whole clearance). Bound, term by term, with g the smoothed
    # signed gap (<= -k eps): penetration ramp(g) <= eps e^(g/eps); F_el(lambda eps) <= lambda
    # F_el(eps) for lambda <= 1 (all laws are at least linear); the contact switch <= 1; the
    # bracket |1 + chi rate / v-| <= 1 + chi |rate| / v_min; the clip adds <= CLIP_WIDTH ln 2 F_el.
    width = width_fraction * clearance / (gap_in_widths + 1.0)
    radius = clearance - (gap_in_widths + 1.0) * width  # |e|_eps <= |e| + eps: gap <= -k eps
    e = radius * np.array([np.cos(angle), np.sin(angle)])
    e_dot = rate * np.array([np.cos(angle), np.sin(angle)])
    force, _, _ = _force[kind](e, e_dot, 0.0, restitution, width, clearance, rate_floor)
    gap = _f(_kinematics(e, e_dot, width, clearance).gap_signed)
    assert gap <= -gap_in_widths * width * (1 - 1e-9)
    decay = np.exp(gap / width)
    elastic = decay * _f(_elastic[kind](width, clearance))
    if kind == "Adams":
        # F_el + D STEP(p/d_max) rate, with s^2 (3 - 2s) increasing in s on [0, 1].
        s = min(width * decay / float(_ADAMS.damping_depth), 1.0)
        damping = float(_ADAMS.damping) * s * s * (3 - 2 * s) * abs(rate)
        bound = elastic * (1 + CLIP_WIDTH * np.log(2.0)) + damping
    else:
        bound = elastic * (1 + _chi(kind, restitution) * abs(rate) / rate_floor + CLIP_WIDTH * np.log(2.0))
    # 1e-9: round-off of the exponentials (e^(g/eps) with g/eps up to 700 carries ~1e-13).
    assert _f(force) <= bound * (1 + 1e-9)


@SETTINGS
@given(
    kind=st.sampled_from(LAWS),
    d1=_signed(1e-300, 1e-2),
    d2=_signed(1e-300, 1e-2),
    data=st.data(),
)
def test_elastic_force_non_negative_and_non_decreasing(kind, d1, d2, data):
    # Every elastic law is a spring that only pushes: F_el = 0 for delta <= 0, F_el >= 0, and
    # F_el non-decreasing in the penetration (Hertz K delta^1.5, Bai-Zhao
    # L pi E*/2 delta^1.5 / sqrt(2(c + delta)) whose log-derivative 1.5/delta - 1/(2(c + delta)) > 0,
    # Adams K delta^e). A decreasing branch would be an unstable (negative-stiffness) contact.
    clearance = data.draw(_clearances(kind))
    lo, hi = min(d1, d2), max(d1, d2)
    f_lo, f_hi = _f(_elastic[kind](lo, clearance)), _f(_elastic[kind](hi, clearance))
    assert 0.0 <= f_lo
    # Round-off: the Bai-Zhao quotient delta^1.5 / sqrt(...) of two increasing functions can step
    # back by an ulp between neighbouring floats.
    assert f_lo <= f_hi * (1 + 4 * EPS)
    if lo <= 0.0:
        assert f_lo == 0.0


@MORE
@given(case=contact_cases(), r1=_positive(1e-300, 2e-2), r2=_positive(1e-300, 2e-2))
def test_normal_force_at_rest_non_decreasing_in_eccentricity(case, r1, r2):
    # With zero velocity (no damping term) the normal force grows with the journal's
    # eccentricity |e| along any direction: the smoothed penetration, the smoothed switch and
    # F_el are all non-decreasing, and so is the clipped force. Includes the FORCE_FLOOR cut-off
    # (a jump up, never down).
    direction = np.array([np.cos(1.0), np.sin(1.0)]) if not np.any(case["e"]) else case["e"]
    direction = direction / np.hypot(*direction)
    forces = []
    for r in sorted((r1, r2)):
        case.update(e=r * direction, e_dot=np.zeros(2))
        forces.append(_f(_call_force(case)[0]))
    # Round-off: the clip ramp(F, w F_el) divides two rounded products of F_el; a few ulp.
    assert forces[0] <= forces[1] * (1 + 8 * EPS)


def _exact_normal_force(kind, delta, rate, impact_rate, ce, clearance, rate_floor):
    """MODEL.md §2 in numpy, unsmoothed: 0 out of contact; else max(0, F) with F the law.
    Returns (force, magnitude of the largest term, F_el)."""
    if delta <= 0.0:
        return 0.0, 0.0, 0.0
    if kind in ("HertzLN", "Flores"):
        rb = JOURNAL_RADIUS + clearance
        elastic = 4.0 / 3.0 * _E_STAR * np.sqrt(JOURNAL_RADIUS * rb / clearance) * delta**1.5
    elif kind == "BaiZhao":
        elastic = LENGTH * np.pi * _E_STAR / 2.0 * delta * np.sqrt(delta / (2.0 * (clearance + delta)))
    else:
        elastic = 1e7 * delta**1.5
    if elastic <= FORCE_FLOOR:  # documented: below it the contact is treated as open
        return 0.0, 0.0, elastic
    if kind == "Adams":
        s = min(delta / 1e-5, 1.0)
        damping = 100.0 * s * s * (3.0 - 2.0 * s) * rate
        return max(elastic + damping, 0.0), elastic + abs(damping), elastic
    # The documented floor on the impact rate: a softplus max(v-, v_min) of width v_min / 10.
    v_eff = rate_floor + 0.1 * rate_floor * np.logaddexp(0.0, (impact_rate - rate_floor) / (0.1 * rate_floor))
    bracket = _chi(kind, ce) * rate / v_eff
    # chi = 0.75 (1 - ce^2) [e^(2(1 - ce))] cancels as ce -> 1: its absolute round-off is
    # relative to 0.75 (1 + ce^2) [...], not to chi (and XLA fuses 1 - ce*ce into one FMA, numpy
    # rounds twice: 2e-10 relative apart at ce = 1 - 4e-10). Flores' 1 - ce is exact there.
    chi_terms = {"HertzLN": 0.75 * (1 + ce**2), "BaiZhao": 0.75 * (1 + ce**2) * np.exp(2 * (1 - ce))}
    terms = abs(rate) / v_eff * chi_terms.get(kind, abs(_chi(kind, ce)))
    return max(elastic * (1.0 + bracket), 0.0), elastic * (1.0 + abs(bracket) + terms), elastic


@MORE
@given(case=contact_cases(width=st.just(0.0)))
def test_exact_limit_is_the_exact_law(case):
    # Width 0 must give the exact piecewise law (reference solutions): compared with MODEL.md §2
    # written independently in numpy, for random penetrations, rates, impact rates, restitutions
    # and clearances. The journal moves along x so that |e| - c rounds identically in both.
    radius = float(np.hypot(*case["e"]))
    case["e"] = np.array([radius, 0.0])
    rate = float(case["e_dot"][0])
    delta = radius - case["clearance"]
    force = _f(_call_force(case)[0])
    exact, scale, elastic = _exact_normal_force(
        case["kind"],
        delta,
        rate,
        case["impact_rate"],
        case["restitution"],
        case["clearance"],
        case["rate_floor"],
    )
    # Round-off: each term (F_el, F_el chi rate / v-, the damping) is correct to a few ulp of
    # the terms it is computed from; where they cancel the error is relative to their magnitudes
    # (`scale`), not to the result. Where
    # F_el is within round-off of FORCE_FLOOR the cut-off may fall on either side.
    at_floor = abs(elastic - FORCE_FLOOR) <= 1e-12 * FORCE_FLOOR
    assert abs(force - exact) <= 32 * EPS * scale + (scale if at_floor else 0.0)


def _potential(kind, d, c):
    return _law(kind, 0.5).potential(tolerax.JournalBearing(JOURNAL_RADIUS, c, LENGTH), d)


_potential_slope = {
    kind: jax.jit(jax.grad(functools.partial(_potential, kind))) for kind in ("HertzLN", "Flores", "Adams")
}


@SETTINGS
@given(
    kind=st.sampled_from(("HertzLN", "Flores", "Adams")),
    delta=_signed(1e-300, 1e-2),
    clearance=_positive(1e-100, 1e-3),
)
def test_elastic_force_is_gradient_of_potential(kind, delta, clearance):
    # normal_force relies on F_el = dU/d delta (the smoothed model then conserves energy with
    # damping off). U is a separate closed form (K delta^2.5 / 2.5, K delta^(e+1)/(e+1)):
    # compare its AD derivative with F_el. Bai-Zhao has no closed-form potential.
    slope = _f(_potential_slope[kind](delta, clearance))
    elastic = _f(_elastic[kind](delta, clearance))
    # d/dx x^2.5 = 2.5 x^1.5 (pow and the division by 2.5 each round once).
    assert slope == pytest.approx(elastic, rel=8 * EPS, abs=0.0)



@SETTINGS
@given(ir1=_signed(1e-300, 1e3), ir2=_signed(1e-300, 1e3), floor=_positive(1e-9, 1e3))
def test_effective_impact_rate_floor(ir1, ir2, floor):
    # The restitution laws divide by the impact rate v-: it is replaced by a smooth
    # max(v-, v_min) of width v_min/10, so it is >= max(v-, v_min) > 0 (never a division by zero
    # or a sign flip of the damping), exceeds it by at most 0.1 v_min ln 2, and is non-decreasing.
    lo, hi = min(ir1, ir2), max(ir1, ir2)
    v_lo, v_hi = _f(_effective_impact_rate(lo, floor)), _f(_effective_impact_rate(hi, floor))
    target = max(lo, floor)
    # Round-off: floor + ramp(...) rounds twice, and the softplus is monotone only to an ulp
    # (see test_ramp_and_step_non_decreasing): a few ulp of the result.
    assert target * (1 - 4 * EPS) <= v_lo <= (target + 0.1 * floor * np.log(2.0)) * (1 + 4 * EPS)
    assert v_lo <= v_hi * (1 + 4 * EPS)


@SETTINGS
@given(case=contact_cases(width=_widths(1e-150, 1e-2)))
def test_contact_kinematics_bounds(case):
    # Penetration = ramp(|e|_eps - c) >= max(0, gap), exactly max(0, gap) at width 0; the
    # smoothed eccentricity |e|_eps is in [|e|, |e| + eps]; the normal has length <= 1 (exactly
    # 1 at width 0 away from e = 0); |rate| = |n . e_dot| <= |e_dot| (Cauchy-Schwarz), so the
    # smoothing never invents a penetration speed.
    e, e_dot, width, c = case["e"], case["e_dot"], case["width"], case["clearance"]
    state = _kinematics(e, e_dot, width, c)
    pen, gap, rate = _f(state.penetration), _f(state.gap_signed), _f(state.rate)
    normal = np.asarray(state.normal)
    ecc = float(np.hypot(*e))
    # Round-off: ulps of |e| and c in the subtraction |e|_eps - c; and |e|^2 underflows to 0
    # below |e| ~ 1.5e-154 (1e-154 m: irrelevant, but drawn).
    roundoff = 4 * EPS * (ecc + c + width) + 2e-154
    assert pen >= 0.0
    assert pen >= gap - roundoff
    assert ecc - c - roundoff <= gap <= ecc + width - c + roundoff
    length = float(np.hypot(*normal))
    assert length <= 1 + 4 * EPS
    assert abs(rate) <= float(np.hypot(*e_dot)) * (1 + 8 * EPS)
    if width == 0.0:
        assert pen == max(gap, 0.0)
        if ecc > 1e-150:  # (not where |e|^2 underflows: there n = 0, harmlessly)
            assert length == pytest.approx(1.0, abs=4 * EPS)


# ------------------------------------------------------------------------------------------------
# Gear mesh, MODEL.md §3.


def _backlash_impl(internal, centre_distance, nominal, angle, backlash, error):
    def fn(centre_distance, nominal, angle, backlash, error):
        return _mesh.dynamic_backlash(centre_distance, nominal, angle, backlash, internal, error)

    args = (centre_distance, nominal, angle, backlash, error)
    argnums = (0, 1, 2, 3)
    return fn(*args), jax.grad(fn, argnums)(*args), jax.jacfwd(fn, argnums)(*args)


_backlash = {internal: jax.jit(functools.partial(_backlash_impl, internal)) for internal in (False, True)}
# The arccos argument is clipped at 1 - 1e-12: below A' = A0 cos(alpha0) / (1 - 1e-12) the
# backlash is frozen at its edge value.
_CLIP = 1.0 - 1e-12


@st.composite
def mesh_geometries(draw):
    """A0 from 1 mm to 1 m, pressure angle 10-35 deg, b0 up to 1 mm, profile error up to 0.1 mm."""
    return dict(
        nominal=draw(_positive(1e-3, 1.0)),
        angle=float(np.deg2rad(draw(st.floats(10.0, 35.0)))),
        backlash=draw(st.one_of(st.just(0.0), _positive(1e-300, 1e-3))),
        error=draw(_signed(1e-300, 1e-4)),
    )


@st.composite
def centre_distances(draw, geometry):
    """A' from 1e-3 A0 to 10 A0 (far beyond any clearance), or within 1e-16..1e-3 (relative) of
    the edge of the arccos domain, on either side."""
    edge = float(geometry["nominal"] * np.cos(geometry["angle"]) / _CLIP)
    return draw(
        st.one_of(
            _positive(1e-3, 10.0).map(lambda t: t * geometry["nominal"]),
            _signed(1e-16, 1e-3).map(lambda s: edge * (1.0 + s)),
        )
    )


@SETTINGS
@given(geometry=mesh_geometries(), internal=st.booleans(), data=st.data())
def test_dynamic_backlash_monotone_in_centre_distance(geometry, internal, data):
    # MODEL.md §3 / paper eq. 2: moving the gears apart opens an external mesh's backlash
    # (b_t non-decreasing in A') and closes the internal ring-planet one (non-increasing).
    a1 = data.draw(centre_distances(geometry))
    a2 = data.draw(centre_distances(geometry))
    lo, hi = min(a1, a2), max(a1, a2)
    args = (geometry["nominal"], geometry["angle"], geometry["backlash"], geometry["error"])
    b_lo, b_hi = _f(_backlash[internal](lo, *args)[0]), _f(_backlash[internal](hi, *args)[0])
    # Round-off: 2 A0 cos(alpha0) [inv(alpha') - inv(alpha0)] subtracts two involutes, each a
    # difference tan - alpha of magnitude <= tan(alpha') + alpha'; a few ulp of those.
    alpha_max = np.arccos(min(geometry["nominal"] * np.cos(geometry["angle"]) / hi, _CLIP))
    roundoff = 16 * EPS * (
        geometry["nominal"] * (np.tan(alpha_max) + alpha_max) + geometry["backlash"] + abs(geometry["error"])
    )
    if internal:
        assert b_hi <= b_lo + roundoff
    else:
        assert b_lo <= b_hi + roundoff


@SETTINGS
@given(geometry=mesh_geometries(), internal=st.booleans(), data=st.data())
def test_dynamic_backlash_derivative(geometry, internal, data):
    # Differentiating eq. 2 with cos(alpha') = C/A', C = A0 cos(alpha0): d inv/d alpha = tan^2,
    # d alpha'/dA' = C / (A'^2 sin alpha'), so db_t/dA' = +-2C tan^2(alpha') C/(A'^2 sin alpha')
    # = +-2 sin(alpha'): an independent closed form for the AD derivative. In the clipped region
    # (A' below the arccos edge) b_t is constant: derivative exactly 0. All derivatives (w.r.t.
    # A', A0, alpha0, b0), reverse and forward, finite, near the edge included.
    a = data.draw(centre_distances(geometry))
    args = (geometry["nominal"], geometry["angle"], geometry["backlash"], geometry["error"])
    value, rev, fwd = _backlash[internal](a, *args)
    assert _finite(value) and _finite(rev) and _finite(fwd)
    c = geometry["nominal"] * np.cos(geometry["angle"])
    edge = c / _CLIP
    sign = -1.0 if internal else 1.0
    # Reverse and forward mode agree (same chain rule, products in another order): the
    # derivative is dimensionless, <= 2, so an absolute round-off of a few ulp.
    assert _f(rev[0]) == pytest.approx(_f(fwd[0]), rel=0.0, abs=16 * EPS)
    if a < edge * (1 - 1e-9):
        assert _f(rev[0]) == 0.0
    elif a > edge * (1 + 1e-9):
        # sin(alpha') = sqrt((A' - C)(A' + C)) / A': A' - C is exact (Sterbenz) near the edge.
        sin_alpha = np.sqrt((a - c) * (a + c)) / a
        # AD goes through arccos'(x) = -1/sqrt(1 - x^2) and tan' - 1 = tan^2: both lose digits
        # as 1/sin^2(alpha') when alpha' -> 0 (the rounding of x = C/A' is amplified by the
        # conditioning of arccos at 1), i.e. up to ~1e-4 relative right at the edge.
        rel = 1e-12 + 16 * EPS / sin_alpha**2
        assert _f(rev[0]) == pytest.approx(sign * 2.0 * sin_alpha, rel=rel, abs=0.0)


@SETTINGS
@given(geometry=mesh_geometries(), change=_signed(1e-300, 1e-2))
def test_dynamic_backlash_small_change(geometry, change):
    # MODEL.md §3 small-change check: b_t - b0 - e = +-2 dA sin(alpha0) + O(dA^2), with the
    # remainder bounded by (dA^2 / 2) max b_t'' and b_t'' = 2 cos^2(alpha') / (A' sin(alpha'))
    # largest at the smallest A'. The internal and external formulas differ only by the sign of
    # the centre-distance term: b_ext + b_int = 2 (b0 + e).
    a0, angle = geometry["nominal"], geometry["angle"]
    a = a0 * (1.0 + change)
    args = (a0, angle, geometry["backlash"], geometry["error"])
    ext, internal = _f(_backlash[False](a, *args)[0]), _f(_backlash[True](a, *args)[0])
    base = geometry["backlash"] + geometry["error"]
    delta_a = a - a0
    a_min = min(a, a0)
    cos_min = a0 * np.cos(angle) / a_min
    sin_min = np.sqrt(1.0 - cos_min**2)
    remainder = 0.5 * delta_a**2 * 2.0 * cos_min**2 / (a_min * sin_min)
    # Round-off: the involute difference carries a few ulp of A0 (tan(alpha) + alpha), amplified
    # through arccos by 1/sin(alpha0) (the rounding of A0 cos(alpha0) / A').
    roundoff = 64 * EPS * (a0 * (1 + 1 / np.sin(angle)) + geometry["backlash"] + abs(geometry["error"]))
    assert abs(ext - base - 2.0 * delta_a * np.sin(angle)) <= remainder + roundoff
    assert abs(internal - base + 2.0 * delta_a * np.sin(angle)) <= remainder + roundoff
    assert abs(ext + internal - 2.0 * base) <= roundoff


@SETTINGS
@given(geometry=mesh_geometries(), internal=st.booleans(), a=_positive(1e-300, 1e-160))
def test_dynamic_backlash_gradient_finite_as_centres_coincide(geometry, internal, a):
    # The clip promises a finite gradient beyond the arccos edge; it is 0 there (b_t frozen),
    # and the value stays the edge value as A' -> 0. (Found by this test: cos0 / A'**2
    # overflowed to NaN below A' ~ 1e-154 m, and A' = 0 jumped back to b0.)
    args = (geometry["nominal"], geometry["angle"], geometry["backlash"], geometry["error"])
    value, rev, fwd = _backlash[internal](a, *args)
    assert _finite(rev) and _finite(fwd)
    edge, _, _ = _backlash[internal](geometry["nominal"] * np.cos(geometry["angle"]), *args)
    zero, _, _ = _backlash[internal](0.0, *args)
    assert _f(value) == _f(edge) == _f(zero)


_mesh_stiffness = jax.jit(_mesh.mesh_stiffness)
_profile_error = jax.jit(_mesh.profile_error)


@SETTINGS
@given(
    mean=_positive(1e-300, 1e300),
    contact_ratio=st.floats(1.0, 2.0),
    phase=st.floats(-1e4, 1e4),
    amplitude=_signed(1e-300, 1e-3),
    offset=st.floats(-10.0, 10.0),
)
def test_mesh_stiffness_and_profile_error_bounds(mean, contact_ratio, phase, amplitude, offset):
    # K_t = k_m [1 + (eps_c - 1) cos(phi)] swings between k_m (2 - eps_c) (one tooth pair) and
    # k_m eps_c (two pairs): positive for eps_c < 2, and its average over a mesh period is k_m
    # (antipodal phases sum to 2 k_m). The profile error E sin(phi + phi_e) is bounded by |E|.
    k = _f(_mesh_stiffness(mean, contact_ratio, phase))
    # Round-off: 2-3 roundings of products of magnitude k_m eps_c.
    tol = 4 * EPS * mean * contact_ratio
    assert mean * (2.0 - contact_ratio) - tol <= k <= mean * contact_ratio + tol
    if contact_ratio < 2.0 - 1e-12:
        assert k > 0.0
    opposite = _f(_mesh_stiffness(mean, contact_ratio, phase + np.pi))
    # phi + pi rounds by ulp(phi) ~ 2e-12 at |phi| = 1e4, moving cos by as much.
    assert k + opposite == pytest.approx(2.0 * mean, rel=8 * EPS * (2 + abs(phase)), abs=0.0)
    assert abs(_f(_profile_error(amplitude, phase, offset))) <= abs(amplitude)


_equivalent_mass = jax.jit(_mesh.equivalent_mass)


@SETTINGS
@given(
    inertia_i=_positive(1e-30, 1e30),
    inertia_j=_positive(1e-30, 1e30),
    radius_i=_positive(1e-6, 1e2),
    radius_j=_positive(1e-6, 1e2),
)
def test_equivalent_mass_is_a_half_harmonic_mean(inertia_i, inertia_j, radius_i, radius_j):
    # m = I_i I_j / (I_i r_j^2 + I_j r_i^2) = 1 / (1/m_i + 1/m_j), m_k = I_k / r_k^2: two masses
    # in series along the line of action. So min(m_i, m_j)/2 <= m <= min(m_i, m_j), symmetric in
    # (i, j), increasing in I_j and equal to m_i for a fixed ring (I_j = inf).
    m = _f(_equivalent_mass(inertia_i, radius_i, inertia_j, radius_j))
    m_i, m_j = inertia_i / radius_i**2, inertia_j / radius_j**2
    small = min(m_i, m_j)
    # Round-off: a few roundings of products and one quotient.
    assert small / 2 * (1 - 8 * EPS) <= m <= small * (1 + 8 * EPS)
    swapped = _f(_equivalent_mass(inertia_j, radius_j, inertia_i, radius_i))
    assert swapped == pytest.approx(m, rel=8 * EPS, abs=0.0)
    fixed = _f(_equivalent_mass(inertia_i, radius_i, np.inf, radius_j))
    assert fixed == pytest.approx(m_i, rel=4 * EPS, abs=0.0)
    assert m <= fixed * (1 + 8 * EPS)


_flank_forces = jax.jit(_mesh.flank_forces)


def _flank_derivatives_impl(*args):
    return jax.grad(lambda *a: sum(_mesh.flank_forces(*a)), argnums=tuple(range(7)))(*args), jax.jacfwd(
        _mesh.flank_forces, argnums=tuple(range(7))
    )(*args)


_flank_derivatives = jax.jit(_flank_derivatives_impl)
STIFFNESS = _positive(1e-3, 1e12)  # N/m
DAMPING = _positive(1e-3, 1e6)  # N s/m
RATE = _signed(1e-300, 1e3)  # m/s


@SETTINGS
@given(
    # b >= 1e-280 so that g = -fraction b stays a normal float (subnormals are flushed to 0).
    backlash=_positive(1e-280, 1e-3),
    fraction=st.floats(1e-12, 1.0 - 1e-12),
    drive_rate=RATE,
    back_rate=RATE,
    stiffness=STIFFNESS,
    damping=DAMPING,
)
def test_flank_forces_zero_inside_backlash_in_exact_limit(
    backlash, fraction, drive_rate, back_rate, stiffness, damping
):
    # Exact limit: with -b < g < 0 neither flank touches (g < 0, h = g + b > 0), so both forces,
    # elastic and damping, are exactly zero whatever the rates.
    drive = -fraction * backlash
    back = drive + backlash
    if not (drive < 0.0 < back):  # the fraction rounded onto an edge (b tiny)
        return
    f_drive, f_back = _flank_forces(drive, drive_rate, back, back_rate, stiffness, damping, 0.0)
    assert _f(f_drive) == 0.0
    assert _f(f_back) == 0.0


@SETTINGS
@given(
    drive=_signed(1e-300, 1e-2),
    back=_signed(1e-300, 1e-2),
    drive_rate=RATE,
    back_rate=RATE,
    stiffness=STIFFNESS,
    damping=DAMPING,
    width=WIDTH_DIFFERENTIABLE,
)
def test_flank_force_signs_and_exact_contact(drive, back, drive_rate, back_rate, stiffness, damping, width):
    # Sign convention (a positive force opposes growth of its deflection): the drive flank's
    # elastic force K ramp(g) >= 0, the back flank's -K ramp(-h) <= 0, for any width. In the
    # exact limit a flank in contact is the linear spring-damper K g + D g_dot (drive, g > 0) and
    # K h + D h_dot (back, h < 0). Derivatives finite everywhere, kinks included.
    f_drive, f_back = _flank_forces(drive, drive_rate, back, back_rate, stiffness, 0.0, width)
    assert _f(f_drive) >= 0.0
    assert _f(f_back) <= 0.0
    forces = _flank_forces(drive, drive_rate, back, back_rate, stiffness, damping, 0.0)
    f_drive, f_back = (_f(f) for f in forces)
    if drive > 0.0:
        expected = stiffness * drive + damping * drive_rate
        # Round-off: two products and a sum, relative to the larger term.
        assert abs(f_drive - expected) <= 4 * EPS * (stiffness * drive + damping * abs(drive_rate))
    elif drive < 0.0:
        assert f_drive == 0.0
    if back < 0.0:
        expected = stiffness * back + damping * back_rate
        assert abs(f_back - expected) <= 4 * EPS * (stiffness * abs(back) + damping * abs(back_rate))
    elif back > 0.0:
        assert f_back == 0.0
    rev, fwd = _flank_derivatives(drive, drive_rate, back, back_rate, stiffness, damping, width)
    assert _finite(rev) and _finite(fwd)


@SETTINGS
@given(drive=X, backlash=BACKLASH, stiffness=STIFFNESS, width=WIDTH)
def test_flank_forces_sum_to_dead_zone(drive, backlash, stiffness, width):
    # MODEL.md §3: on a common line of action (h = g + b) the two flanks together are the mesh
    # force K f_g(g) of the dead zone (damping off).
    f_drive, f_back = _flank_forces(drive, 0.0, drive + backlash, 0.0, stiffness, 0.0, width)
    total = _f(f_drive) + _f(f_back)
    expected = stiffness * _f(_dead_zone(drive, backlash, width))
    # Round-off: K multiplies each ramp separately (one rounding each) before the sum.
    assert abs(total - expected) <= 4 * EPS * stiffness * (abs(drive) + backlash + width)
