"""Backlash as the gear drawings carry it (`tolerax.design.backlash`): the normal backlash of two
gears' tooth-thickness allowances against the involute's own base-circle tooth thickness, and
the allowances a stage's zones get: each mesh's backlash inside its zone, the rounding's loss
bounded, the planet's one tooth thickness shared by both meshes."""

import math

import pytest
from hypothesis import given, settings, strategies as st

from tolerax.design.backlash import Allowances, backlash_range, callout_text, stage_allowances

UM = 1e-6
ALPHA = math.radians(20.0)


def _inv(a):
    return math.tan(a) - a


def _base_thickness(module, teeth, thickness, alpha, internal=False):
    """The tooth's arc thickness on the base circle from its thickness `thickness` on the reference
    circle (the involute: s_b = r_b (s / r +- 2 inv alpha), + for an external tooth, - for an
    internal gear's tooth, whose flanks curve the other way)."""
    r = module * teeth / 2
    rb = r * math.cos(alpha)
    return rb * (thickness / r + (-2 if internal else 2) * _inv(alpha))


@pytest.mark.parametrize("internal", [False, True])
def test_normal_backlash_is_the_base_circle_gap_of_the_involutes(internal):
    """Thinning two teeth by their allowances opens a gap along the line of action (the base
    circle's tangent) equal to the sum of their base-circle thickness losses: the involute's
    base thickness, computed here from its own formula, agrees with -(E1 + E2) cos(alpha)."""
    m, z1, z2 = 1.5e-3, 24, 60 if not internal else 96
    s = math.pi * m / 2
    e1, e2 = Allowances("sun", -12 * UM, -30 * UM), Allowances("ring" if internal else "planet", -7 * UM, -19 * UM)
    for pick in ("upper", "lower"):
        d1 = _base_thickness(m, z1, s, ALPHA) - _base_thickness(m, z1, s + getattr(e1, pick), ALPHA)
        d2 = (_base_thickness(m, z2, s, ALPHA, internal) - _base_thickness(m, z2, s + getattr(e2, pick), ALPHA, internal))
        gap = d1 + d2
        expected = backlash_range(e1, e2, ALPHA)[0 if pick == "upper" else 1]
        assert gap == pytest.approx(expected, rel=1e-12)


zones = st.tuples(st.floats(0.0, 200.0), st.floats(5.0, 150.0)).map(lambda t: (t[0] * UM, (t[0] + t[1]) * UM))


@settings(max_examples=60, deadline=None)
@given(sun=zones, ring=zones, a_sun=st.floats(14.5, 25.0), a_ring=st.floats(14.5, 25.0))
def test_stage_allowances_put_each_mesh_inside_its_zone(sun, ring, a_sun, a_ring):
    """Both meshes' backlash from the gears' whole-µm allowances lies inside their zones and
    misses each edge by at most 2 µm of thinning (one µm of rounding per gear); the planet's
    allowances are the same in both meshes; every allowance is <= 0 and upper >= lower."""
    angles = math.radians(a_sun), math.radians(a_ring)
    sun_g, planet, ring_g = stage_allowances(sun, ring, *angles)
    assert [a.gear for a in (sun_g, planet, ring_g)] == ["sun", "planet", "ring"]
    for mesh, zone, angle in ((sun_g, sun, angles[0]), (ring_g, ring, angles[1])):
        lo, hi = backlash_range(mesh, planet, angle)
        assert zone[0] - 1e-12 <= lo <= hi <= zone[1] + 1e-12
        assert lo - zone[0] <= 2 * UM * math.cos(angle) + 1e-12 and zone[1] - hi <= 2 * UM * math.cos(angle) + 1e-12
    for a in (sun_g, planet, ring_g):
        assert a.upper <= 0 and a.lower <= a.upper
        assert round(a.upper / UM) == pytest.approx(a.upper / UM) and round(a.lower / UM) == pytest.approx(a.lower / UM)


def test_one_mesh_alone_and_refusals():
    """A stage with one designed backlash gives its two gears allowances; a zone too narrow for
    whole micrometres, a negative or reversed zone, and no zone at all are refused with the reason."""
    got = stage_allowances(None, (30 * UM, 80 * UM))
    assert [a.gear for a in got] == ["planet", "ring"]
    text = callout_text("ring", got, ALPHA)
    assert text.startswith("jn ") and "ring " in text and "planet " in text and "tooth thickness" in text
    for args, match in [(((10 * UM, 10.5 * UM),), "too narrow"), (((-1 * UM, 10 * UM),), "0 <= smallest"),
                        (((20 * UM, 10 * UM),), "0 <= smallest"), ((None, None), "give the sun")]:
        with pytest.raises(ValueError, match=match):
            stage_allowances(*args)
