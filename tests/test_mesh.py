"""The gear-mesh kernels of `tolerax.mesh` (docs/model.md §3): dynamic backlash (paper eq. 2), mesh
stiffness and profile error, the equivalent mass of a gear pair, the two flank forces.

Examples against closed forms, and beside them property tests (hypothesis, strategies in
`_strategies.py`) of what must hold for *every* input: monotonicity of the backlash in the centre
distance, its derivative against an independent closed form, bounds, symmetry, signs, the exact
limit at width 0, finite derivatives. Each kernel is jitted once at module level (scalar float64
arguments, so values never retrace).
"""

import functools
import math

import jax
import jax.numpy as jnp
import numpy as np
import pytest
from hypothesis import assume, given
from hypothesis import strategies as st

from tolerax import mesh, smooth

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
)


# ------------------------------------------------------------------------------------------------
# Dynamic backlash, paper eq. 2.


def test_dynamic_backlash_small_change():
    """b_t - b_0 = +-2 dA sin(alpha0) to first order, + external, - internal (ring)."""
    a0, alpha, b0 = 25e-3, math.radians(20.0), 100e-6
    for d_a in (1e-7, -1e-7, 1e-6):
        ext = mesh.dynamic_backlash(a0 + d_a, a0, alpha, b0, internal=False)
        internal = mesh.dynamic_backlash(a0 + d_a, a0, alpha, b0, internal=True)
        expect = 2 * d_a * math.sin(alpha)
        # Second-order term ~ dA^2 / A0 * O(1): relative 1e-4 at dA = 1e-6.
        assert abs((float(ext) - b0) - expect) < 2e-4 * abs(expect)
        assert abs((float(internal) - b0) + expect) < 2e-4 * abs(expect)


def _backlash_impl(internal, centre_distance, nominal, angle, backlash, error):
    def fn(centre_distance, nominal, angle, backlash, error):
        return mesh.dynamic_backlash(centre_distance, nominal, angle, backlash, internal, error)

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
        nominal=draw(positive(1e-3, 1.0)),
        angle=float(np.deg2rad(draw(st.floats(10.0, 35.0)))),
        backlash=draw(st.one_of(st.just(0.0), positive(1e-300, 1e-3))),
        error=draw(signed(1e-300, 1e-4)),
    )


@st.composite
def centre_distances(draw, geometry):
    """A' from 1e-3 A0 to 10 A0 (far beyond any clearance), or within 1e-16..1e-3 (relative) of
    the edge of the arccos domain, on either side."""
    edge = float(geometry["nominal"] * np.cos(geometry["angle"]) / _CLIP)
    return draw(
        st.one_of(
            positive(1e-3, 10.0).map(lambda t: t * geometry["nominal"]),
            signed(1e-16, 1e-3).map(lambda s: edge * (1.0 + s)),
        )
    )


@SETTINGS
@given(geometry=mesh_geometries(), internal=st.booleans(), data=st.data())
def test_dynamic_backlash_monotone_in_centre_distance(geometry, internal, data):
    # docs/model.md §3 / paper eq. 2: moving the gears apart opens an external mesh's backlash
    # (b_t non-decreasing in A') and closes the internal ring-planet one (non-increasing).
    a1 = data.draw(centre_distances(geometry))
    a2 = data.draw(centre_distances(geometry))
    lo, hi = min(a1, a2), max(a1, a2)
    args = (geometry["nominal"], geometry["angle"], geometry["backlash"], geometry["error"])
    b_lo, b_hi = scalar(_backlash[internal](lo, *args)[0]), scalar(_backlash[internal](hi, *args)[0])
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
    assert finite(value) and finite(rev) and finite(fwd)
    c = geometry["nominal"] * np.cos(geometry["angle"])
    edge = c / _CLIP
    sign = -1.0 if internal else 1.0
    # Reverse and forward mode agree (same chain rule, products in another order): the
    # derivative is dimensionless, <= 2, so an absolute round-off of a few ulp.
    assert scalar(rev[0]) == pytest.approx(scalar(fwd[0]), rel=0.0, abs=16 * EPS)
    if a < edge * (1 - 1e-9):
        assert scalar(rev[0]) == 0.0
    elif a > edge * (1 + 1e-9):
        # sin(alpha') = sqrt((A' - C)(A' + C)) / A': A' - C is exact (Sterbenz) near the edge.
        sin_alpha = np.sqrt((a - c) * (a + c)) / a
        # AD goes through arccos'(x) = -1/sqrt(1 - x^2) and tan' - 1 = tan^2: both lose digits
        # as 1/sin^2(alpha') when alpha' -> 0 (the rounding of x = C/A' is amplified by the
        # conditioning of arccos at 1), i.e. up to ~1e-4 relative right at the edge.
        rel = 1e-12 + 16 * EPS / sin_alpha**2
        assert scalar(rev[0]) == pytest.approx(sign * 2.0 * sin_alpha, rel=rel, abs=0.0)


@SETTINGS
@given(geometry=mesh_geometries(), change=signed(1e-300, 1e-2))
def test_dynamic_backlash_small_change_for_any_geometry(geometry, change):
    # docs/model.md §3 small-change check: b_t - b0 - e = +-2 dA sin(alpha0) + O(dA^2), with the
    # remainder bounded by (dA^2 / 2) max b_t'' and b_t'' = 2 cos^2(alpha') / (A' sin(alpha'))
    # largest at the smallest A'. The internal and external formulas differ only by the sign of
    # the centre-distance term: b_ext + b_int = 2 (b0 + e).
    a0, angle = geometry["nominal"], geometry["angle"]
    a = a0 * (1.0 + change)
    args = (a0, angle, geometry["backlash"], geometry["error"])
    ext, internal = scalar(_backlash[False](a, *args)[0]), scalar(_backlash[True](a, *args)[0])
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
@given(geometry=mesh_geometries(), internal=st.booleans(), a=positive(1e-300, 1e-160))
def test_dynamic_backlash_gradient_finite_as_centres_coincide(geometry, internal, a):
    # The clip promises a finite gradient beyond the arccos edge; it is 0 there (b_t frozen),
    # and the value stays the edge value as A' -> 0. (Found by this test: cos0 / A'**2
    # overflowed to NaN below A' ~ 1e-154 m, and A' = 0 jumped back to b0.)
    args = (geometry["nominal"], geometry["angle"], geometry["backlash"], geometry["error"])
    value, rev, fwd = _backlash[internal](a, *args)
    assert finite(rev) and finite(fwd)
    edge, _, _ = _backlash[internal](geometry["nominal"] * np.cos(geometry["angle"]), *args)
    zero, _, _ = _backlash[internal](0.0, *args)
    assert scalar(value) == scalar(edge) == scalar(zero)


# ------------------------------------------------------------------------------------------------
# Mesh stiffness and profile error.


_mesh_stiffness = jax.jit(mesh.mesh_stiffness)
_profile_error = jax.jit(mesh.profile_error)


@SETTINGS
@given(
    mean=positive(1e-300, 1e300),
    contact_ratio=st.floats(1.0, 2.0),
    phase=st.floats(-1e4, 1e4),
    amplitude=signed(1e-300, 1e-3),
    offset=st.floats(-10.0, 10.0),
)
def test_mesh_stiffness_and_profile_error_bounds(mean, contact_ratio, phase, amplitude, offset):
    # K_t = k_m [1 + (eps_c - 1) cos(phi)] swings between k_m (2 - eps_c) (one tooth pair) and
    # k_m eps_c (two pairs): positive for eps_c < 2, and its average over a mesh period is k_m
    # (antipodal phases sum to 2 k_m). The profile error E sin(phi + phi_e) is bounded by |E|.
    k = scalar(_mesh_stiffness(mean, contact_ratio, phase))
    # Round-off: 2-3 roundings of products of magnitude k_m eps_c.
    tol = 4 * EPS * mean * contact_ratio
    assert mean * (2.0 - contact_ratio) - tol <= k <= mean * contact_ratio + tol
    if contact_ratio < 2.0 - 1e-12:
        assert k > 0.0
    opposite = scalar(_mesh_stiffness(mean, contact_ratio, phase + np.pi))
    # phi + pi rounds by ulp(phi) ~ 2e-12 at |phi| = 1e4, moving cos by as much.
    assert k + opposite == pytest.approx(2.0 * mean, rel=8 * EPS * (2 + abs(phase)), abs=0.0)
    assert abs(scalar(_profile_error(amplitude, phase, offset))) <= abs(amplitude)


# ------------------------------------------------------------------------------------------------
# Equivalent mass of a gear pair on its line of action.


def test_equivalent_mass_pairing():
    # m = I_i I_j / (I_i r_j^2 + I_j r_i^2); for two equal discs it is I/(2 r^2).
    assert np.isclose(float(mesh.equivalent_mass(2.0, 0.5, 2.0, 0.5)), 2.0 / (2 * 0.25))
    # Fixed ring (infinite inertia): I_p / r_p^2.
    assert np.isclose(float(mesh.equivalent_mass(3.0, 0.1, jnp.inf, 2.0)), 3.0 / 0.01)


_equivalent_mass = jax.jit(mesh.equivalent_mass)


@SETTINGS
@given(
    inertia_i=positive(1e-30, 1e30),
    inertia_j=positive(1e-30, 1e30),
    radius_i=positive(1e-6, 1e2),
    radius_j=positive(1e-6, 1e2),
)
def test_equivalent_mass_is_a_half_harmonic_mean(inertia_i, inertia_j, radius_i, radius_j):
    # m = I_i I_j / (I_i r_j^2 + I_j r_i^2) = 1 / (1/m_i + 1/m_j), m_k = I_k / r_k^2: two masses
    # in series along the line of action. So min(m_i, m_j)/2 <= m <= min(m_i, m_j), symmetric in
    # (i, j), increasing in I_j and equal to m_i for a fixed ring (I_j = inf).
    m = scalar(_equivalent_mass(inertia_i, radius_i, inertia_j, radius_j))
    m_i, m_j = inertia_i / radius_i**2, inertia_j / radius_j**2
    small = min(m_i, m_j)
    # Round-off: a few roundings of products and one quotient.
    assert small / 2 * (1 - 8 * EPS) <= m <= small * (1 + 8 * EPS)
    swapped = scalar(_equivalent_mass(inertia_j, radius_j, inertia_i, radius_i))
    assert swapped == pytest.approx(m, rel=8 * EPS, abs=0.0)
    fixed = scalar(_equivalent_mass(inertia_i, radius_i, np.inf, radius_j))
    assert fixed == pytest.approx(m_i, rel=4 * EPS, abs=0.0)
    assert m <= fixed * (1 + 8 * EPS)


# ------------------------------------------------------------------------------------------------
# Flank forces.

# The dead zone of `tolerax.smooth`: the reference for the sum of the two flanks.
_dead_zone = jax.jit(smooth.dead_zone)
_flank_forces = jax.jit(mesh.flank_forces)


def _flank_derivatives_impl(*args):
    return jax.grad(lambda *a: sum(mesh.flank_forces(*a)), argnums=tuple(range(7)))(*args), jax.jacfwd(
        mesh.flank_forces, argnums=tuple(range(7))
    )(*args)


_flank_derivatives = jax.jit(_flank_derivatives_impl)
STIFFNESS = positive(1e-3, 1e12)  # N/m
DAMPING = positive(1e-3, 1e6)  # N s/m
RATE = signed(1e-300, 1e3)  # m/s


@SETTINGS
@given(
    # b >= 1e-280 so that g = -fraction b stays a normal float (subnormals are flushed to 0).
    backlash=positive(1e-280, 1e-3),
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
    assume(drive < 0.0 < back)  # not where the fraction rounded onto an edge (b tiny)
    f_drive, f_back = _flank_forces(drive, drive_rate, back, back_rate, stiffness, damping, 0.0)
    assert scalar(f_drive) == 0.0
    assert scalar(f_back) == 0.0


@SETTINGS
@given(
    drive=signed(1e-300, 1e-2),
    back=signed(1e-300, 1e-2),
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
    assert scalar(f_drive) >= 0.0
    assert scalar(f_back) <= 0.0
    forces = _flank_forces(drive, drive_rate, back, back_rate, stiffness, damping, 0.0)
    f_drive, f_back = (scalar(f) for f in forces)
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
    assert finite(rev) and finite(fwd)


@SETTINGS
@given(drive=X, backlash=BACKLASH, stiffness=STIFFNESS, width=WIDTH)
def test_flank_forces_sum_to_dead_zone(drive, backlash, stiffness, width):
    # docs/model.md §3: on a common line of action (h = g + b) the two flanks together are the mesh
    # force K f_g(g) of the dead zone (damping off).
    f_drive, f_back = _flank_forces(drive, 0.0, drive + backlash, 0.0, stiffness, 0.0, width)
    total = scalar(f_drive) + scalar(f_back)
    expected = stiffness * scalar(_dead_zone(drive, backlash, width))
    # Round-off: K multiplies each ramp separately (one rounding each) before the sum.
    assert abs(total - expected) <= 4 * EPS * stiffness * (abs(drive) + backlash + width)
