"""ISO 286 fits (`tolerax.design.fits`): limit deviations against ISO 286-2:2010 table values, the
tables against ISO 286-1's formulas (a typo check), and the choice of fits inside a designed
radial clearance zone against a brute force written here."""

import itertools
import math

import numpy as np
import pytest

from tolerax.design.cost import SIZE_STEPS, it_tolerance
from tolerax.design.fits import (
    DEFAULT_HOLES,
    DEFAULT_SHAFTS,
    IT_TABLE_UM,
    SHAFT_ES_UM,
    SHAFT_K_EI_UM,
    Fit,
    fits_covering,
    limit_deviations,
    nearest_fit,
    size_step,
    standard_tolerance,
)

# ISO 286-2:2010 limit deviations (upper, lower) in µm at a diameter (mm) of its size step.
ISO_286_2 = [
    (30.0, "H7", 21, 0), (30.0, "g6", -7, -20), (30.0, "f7", -20, -41), (30.0, "h6", 0, -13),
    (30.0, "e8", -40, -73), (30.0, "d9", -65, -117), (30.0, "k6", 15, 2), (30.0, "js6", 6.5, -6.5),
    (30.0, "js7", 10, -10),
    (50.0, "H7", 25, 0), (50.0, "g6", -9, -25), (50.0, "f7", -25, -50),
    (10.0, "H7", 15, 0), (10.0, "g6", -5, -14),
    (2.0, "f7", -6, -16), (2.0, "k6", 6, 0), (100.0, "k6", 25, 3), (100.0, "H8", 54, 0),
]


@pytest.mark.parametrize("diameter, cls, upper, lower", ISO_286_2)
def test_limit_deviations_are_iso_286_2(diameter, cls, upper, lower):
    low, high = limit_deviations(cls, diameter)
    assert 1e6 * high == pytest.approx(upper, abs=0.5) and 1e6 * low == pytest.approx(lower, abs=0.5)


def test_h7_g6_at_30_mm():
    fit = Fit("H7", "g6")
    assert [1e6 * v for v in fit.radial_clearance(30.0)] == pytest.approx([3.5, 20.5], abs=1e-9)
    assert [1e6 * v for v in fit.hole_limits(30.0)] == pytest.approx([0.0, 21.0], abs=1e-9)
    assert [1e6 * v for v in fit.shaft_limits(30.0)] == pytest.approx([-20.0, -7.0], abs=1e-9)
    assert fit.is_clearance_fit(30.0) and fit.kind(30.0) == "clearance"
    assert "3.5 to 20.5 µm" in fit.text(30.0)


def test_fit_kinds():
    """H7/h6 is a clearance fit with zero smallest clearance; H7/k6 and H7/js6 are transition fits."""
    assert Fit("H7", "h6").radial_clearance(30.0)[0] == 0.0 and Fit("H7", "h6").is_clearance_fit(30.0)
    for shaft in ("k6", "js6"):
        fit = Fit("H7", shaft)
        assert not fit.is_clearance_fit(30.0) and fit.kind(30.0) == "transition"
        assert fit.radial_clearance(30.0)[0] < 0 < fit.radial_clearance(30.0)[1]


def test_tables_follow_iso_286_1_formulas():
    """Each tabulated value is its formula rounded (typo check): IT within 3 % or 0.75 µm of `it_tolerance`
    and the deviations within 4 % or 1 µm of theirs, above the first step (ISO's first step
    departs from its formulas: IT7 10 µm for 8.7, g -2 µm for -3.0)."""
    for k, upper in enumerate(SIZE_STEPS):
        assert size_step(upper) == ((1.0 if k == 0 else SIZE_STEPS[k - 1]), upper)
        if k == 0:
            continue
        for grade, row in IT_TABLE_UM.items():
            assert row[k] == pytest.approx(1e6 * float(it_tolerance(grade, upper)), rel=0.03, abs=0.75)
            assert standard_tolerance(grade, upper) == row[k] / 1e6
        mean = math.sqrt(SIZE_STEPS[k - 1] * upper)
        for letter, (a, b) in {"d": (16, 0.44), "e": (11, 0.41), "f": (5.5, 0.41), "g": (2.5, 0.34)}.items():
            assert -SHAFT_ES_UM[letter][k] == pytest.approx(a * mean**b, rel=0.04, abs=1.0)
        assert SHAFT_K_EI_UM[k] == round(0.6 * mean ** (1 / 3))


def test_js_and_k_grade_rules():
    """js7 to js11 round an odd IT down to even (±10 µm for IT7 = 21 µm), js5/js6 keep halves;
    k has ei > 0 only for grades 4 to 7."""
    assert [1e6 * v for v in limit_deviations("js8", 30.0)] == pytest.approx([-16.0, 16.0])  # IT8 33
    assert [1e6 * v for v in limit_deviations("js5", 30.0)] == pytest.approx([-4.5, 4.5])  # IT5 9
    assert [1e6 * v for v in limit_deviations("k7", 30.0)] == pytest.approx([2.0, 23.0])
    assert [1e6 * v for v in limit_deviations("k8", 30.0)] == pytest.approx([0.0, 33.0])


def test_parse_round_trip_and_refusals():
    for text in ("H7/g6", "H8/f7", "H6/js5", "H9/d9", "H11/k11"):
        assert str(Fit.parse(text)) == text and Fit.parse(text) == Fit(*text.split("/"))
    assert Fit.parse(" H7 / g6 ") == Fit("H7", "g6")
    for bad, message in [("X7/g6", "hole position 'X'"), ("H7", "hole class '/' shaft class"),
                         ("H7/q6", "shaft position 'q'"), ("g6/H7", "swapped"), ("H12/g6", "grade 12"),
                         ("H7/g6/h6", "'/'"), ("H/g6", "position letter and a grade"), ("", "'/'")]:
        with pytest.raises(ValueError, match=message):
            Fit.parse(bad)
    with pytest.raises(ValueError, match="shaft position 'G'"):
        Fit("H7", "G6")
    with pytest.raises(ValueError, match="hole class '/' shaft class"):
        Fit.parse(None)


@pytest.mark.parametrize("bad", [0.5, 0.03, 0.0, -30.0, 500.5, 1000.0, math.nan, math.inf, "30", None, True,
                                 np.array([30.0, 40.0])])
def test_sizes_outside_the_tables_are_refused(bad):
    with pytest.raises(ValueError, match="diameter_mm"):
        Fit("H7", "g6").radial_clearance(bad)
    with pytest.raises(ValueError, match="diameter_mm"):
        fits_covering(1e-6, 30e-6, bad)


def test_size_step_edges():
    """"Over ... up to and including": 18 mm is in 10-18, 18.001 mm in 18-30; 1 and 500 mm included."""
    assert size_step(18.0) == (10.0, 18.0) and size_step(18.001) == (18.0, 30.0)
    assert size_step(1.0) == (1.0, 3.0) and size_step(500.0) == (400.0, 500.0)
    assert "in m" in _message(lambda: size_step(0.03))


def _message(call) -> str:
    with pytest.raises(ValueError) as info:
        call()
    return str(info.value)


@pytest.mark.parametrize("diameter, lower, upper", [(30.0, 5e-6, 40e-6), (10.0, 2e-6, 25e-6), (50.0, 0.0, 30e-6),
                                                     (30.0, -10e-6, 20e-6), (120.0, 20e-6, 120e-6)])
def test_fits_covering_against_brute_force(diameter, lower, upper):
    """Every listed fit lies inside the zone, every fit of the candidates that does is listed,
    and the list goes from the widest zone to the narrowest."""
    found = fits_covering(lower, upper, diameter)
    assert found, "the zones here are wide enough for some fit"
    for fit in found:
        low, high = fit.radial_clearance(diameter)
        assert lower - 1e-12 <= low <= high <= upper + 1e-12
    inside = {Fit(h, s) for h, s in itertools.product(DEFAULT_HOLES, DEFAULT_SHAFTS)
              if lower - 1e-12 <= Fit(h, s).radial_clearance(diameter)[0]
              and Fit(h, s).radial_clearance(diameter)[1] <= upper + 1e-12}
    assert set(found) == inside and len(found) == len(inside)
    widths = [f.radial_clearance(diameter)[1] - f.radial_clearance(diameter)[0] for f in found]
    assert all(a >= b - 1e-15 for a, b in itertools.pairwise(widths))
    assert nearest_fit(lower, upper, diameter) == found[0]
    if lower >= 0:
        assert all(f.is_clearance_fit(diameter) for f in found)


def test_fits_covering_exact_limits_and_too_narrow_zones():
    """H7/g6's own zone at 30 mm holds H7/g6 (limits met exactly count), and a zone narrower
    than the narrowest fit (H6/x5: (13 + 9)/2 = 11 µm wide) holds none."""
    assert Fit("H7", "g6") in fits_covering(3.5e-6, 20.5e-6, 30.0)
    assert fits_covering(3.5e-6, 20.5e-6, 30.0, holes="H7", shafts=["g6"]) == [Fit("H7", "g6")]
    # Equal widths (27 µm): equal margins (3 µm to the upper limit), so the coarser hole first.
    assert fits_covering(5e-6, 40e-6, 30.0)[:2] == [Fit("H8", "f7"), Fit("H7", "f8")]
    assert fits_covering(5e-6, 15e-6, 30.0) == [] and nearest_fit(5e-6, 15e-6, 30.0) is None
    assert fits_covering(-1e-6, 1e-6, 30.0) == []


def test_fits_covering_refuses_bad_arguments():
    for args, message in [((20e-6, 5e-6, 30.0), "above upper_limit"), ((5.0, 40.0, 30.0), "in m"),
                          ((math.nan, 40e-6, 30.0), "finite"), (("5e-6", 40e-6, 30.0), "real number")]:
        with pytest.raises(ValueError, match=message):
            fits_covering(*args)
    with pytest.raises(ValueError, match="swapped"):
        fits_covering(5e-6, 40e-6, 30.0, holes=("g6",))
    with pytest.raises(ValueError, match="empty"):
        fits_covering(5e-6, 40e-6, 30.0, shafts=())
