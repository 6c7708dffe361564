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
    ABC_STEPS,
    HOLE_LETTERS,
    SHAFT_ES_ABC_UM,
    SHAFT_ES_UM,
    SHAFT_K_EI_UM,
    SLACK,
    Fit,
    fits_covering,
    limit_deviations,
    nearest_fit,
    size_step,
    standard_tolerance,
    why_no_fit,
)

# ISO 286-2:2010 limit deviations (upper, lower) in µm at a diameter (mm) of its size step.
ISO_286_2 = [
    (30.0, "H7", 21, 0), (30.0, "g6", -7, -20), (30.0, "f7", -20, -41), (30.0, "h6", 0, -13),
    (30.0, "e8", -40, -73), (30.0, "d9", -65, -117), (30.0, "k6", 15, 2), (30.0, "js6", 6.5, -6.5),
    (30.0, "js7", 10, -10),
    (50.0, "H7", 25, 0), (50.0, "g6", -9, -25), (50.0, "f7", -25, -50),
    (10.0, "H7", 15, 0), (10.0, "g6", -5, -14),
    (2.0, "f7", -6, -16), (2.0, "k6", 6, 0), (100.0, "k6", 25, 3), (100.0, "H8", 54, 0),
    # a, b, c on ISO 286's intermediate steps (30-40 and 40-50, 50-65 and 65-80, ... differ)
    (5.0, "a11", -270, -345), (15.0, "b11", -150, -260), (45.0, "c11", -130, -290), (36.0, "c9", -120, -182),
    (36.0, "c8", -120, -159), (110.0, "a9", -410, -497), (170.0, "b9", -310, -410), (210.0, "c11", -260, -550),
    (240.0, "a11", -820, -1110), (55.0, "b11", -190, -380), (70.0, "b11", -200, -390),
    (60.0, "d9", -100, -174), (150.0, "e8", -85, -148), (200.0, "f7", -50, -96), (4.0, "g6", -4, -12),
    (150.0, "h9", 0, -100),
    # holes of the shaft-basis system (EI = -es of the shaft letter)
    (36.0, "C11", 280, 120), (25.0, "D9", 117, 65), (12.0, "F7", 34, 16), (40.0, "E8", 89, 50), (30.0, "G7", 28, 7),
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
    and the list goes from the cheapest pair of grades to the dearest."""
    found = fits_covering(lower, upper, diameter)
    assert found, "the zones here are wide enough for some fit"
    for fit in found:
        low, high = fit.radial_clearance(diameter)
        assert lower - SLACK <= low <= high <= upper + SLACK
    inside = {Fit(h, s) for h, s in itertools.product(DEFAULT_HOLES, DEFAULT_SHAFTS)
              if lower - SLACK <= Fit(h, s).radial_clearance(diameter)[0]
              and Fit(h, s).radial_clearance(diameter)[1] <= upper + SLACK}
    assert set(found) == inside and len(found) == len(inside)
    # Cheapest first: the two parts' costs at 1.58x per grade tighter (IT7 = 1), written out here.
    costs = [1.5848931924611136 ** (7 - int(f.hole[1:])) + 1.5848931924611136 ** (7 - int(f.shaft.lstrip("abcdefghjks")))
             for f in found]
    assert all(a <= b + 1e-9 for a, b in itertools.pairwise(costs))
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


def test_abc_tables_are_ordered_like_the_standard():
    """A typo check of the a, b, c rows (their ISO 286-1 formulas are rounded to 10-20 µm steps,
    too coarse for a formula check): each grows with size, a below b below c below d on every
    step, and the intermediate steps refine the main ones (each main step's upper limit is one)."""
    assert set(SIZE_STEPS) <= set(ABC_STEPS)
    for letter in "abc":
        row = SHAFT_ES_ABC_UM[letter]
        assert len(row) == len(ABC_STEPS) and all(x >= y for x, y in itertools.pairwise(row))
    for k, upper in enumerate(ABC_STEPS):
        d = SHAFT_ES_UM["d"][next(j for j, u in enumerate(SIZE_STEPS) if upper <= u)]
        assert SHAFT_ES_ABC_UM["a"][k] < SHAFT_ES_ABC_UM["b"][k] < SHAFT_ES_ABC_UM["c"][k] < d


def test_the_carrier_journal_gets_a_fit():
    """The zone issue 61 found without one: a Ø36 mm carrier journal, 41-141 µm radial. H8/c8
    (60-99 µm) and H9/c9 (60-122 µm) lie inside it (ISO 286-2 at 30-40 mm: c es -120 µm, IT8 39,
    IT9 62), and the loosest fit chosen is a c fit inside the zone."""
    found = fits_covering(41e-6, 141e-6, 36.0)
    assert Fit("H8", "c8") in found and Fit("H9", "c9") in found
    assert [1e6 * v for v in Fit("H9", "c9").radial_clearance(36.0)] == pytest.approx([60.0, 122.0])
    best = nearest_fit(41e-6, 141e-6, 36.0)
    lo, hi = best.radial_clearance(36.0)
    assert best.shaft.startswith("c") and 41e-6 <= lo and hi <= 141e-6 + 1e-12
    assert why_no_fit(41e-6, 141e-6, 36.0) == ""


def test_shaft_basis_fits_mirror_the_hole_basis():
    """A-H holes with an h shaft have the clearance of H with the same letter's shaft (EI = -es),
    grades swapped: C9/h8 is H8/c9's zone; the shaft-basis search lists only X/h fits."""
    for letter in HOLE_LETTERS:
        for d in (5.0, 36.0, 130.0, 230.0):
            assert Fit(f"{letter}9", "h8").radial_clearance(d) == pytest.approx(
                Fit("H8", f"{letter.lower()}9").radial_clearance(d), abs=1e-12)
    found = fits_covering(41e-6, 141e-6, 36.0, basis="shaft")
    assert found and all(f.shaft.startswith("h") for f in found) and Fit("C9", "h9") in found
    with pytest.raises(ValueError, match="basis"):
        fits_covering(41e-6, 141e-6, 36.0, basis="both")


def test_why_no_fit_names_the_reason():
    """Each reason is checked against the candidates themselves: too narrow (no pair's zone is
    that narrow), too loose (every position's smallest clearance is below the zone), between
    positions (the zone's lower limit falls between two letters' smallest clearances)."""
    pairs = [Fit(h, s) for h, s in itertools.product(DEFAULT_HOLES, DEFAULT_SHAFTS)]
    reason = why_no_fit(41e-6, 50e-6, 36.0)
    assert reason.startswith("too narrow") and fits_covering(41e-6, 50e-6, 36.0) == []
    assert min(f.radial_clearance(36.0)[1] - f.radial_clearance(36.0)[0] for f in pairs) > 9e-6
    reason = why_no_fit(200e-6, 400e-6, 36.0)
    assert reason.startswith("too loose") and "155 µm" in reason  # a at 30-40 mm: es -310 µm
    assert max(f.radial_clearance(36.0)[0] for f in pairs) == pytest.approx(155e-6)
    # d allows 40 µm (es -80); c starts at 60 µm (es -120) and, at its finest (H6/c8: IT6 16, IT8 39), reaches 87.5
    reason = why_no_fit(41e-6, 65e-6, 36.0)
    assert reason.startswith("between positions") and "60 µm" in reason and "87.5 µm" in reason and "40 µm" in reason
    assert "c5" not in "".join(DEFAULT_SHAFTS) and "a8" not in "".join(DEFAULT_SHAFTS)  # as ISO 286-2 prints them
    # A zone that only a grade ISO 286-2 does not print fits says so (c6 at 18-30 mm: -110/-123 µm).
    reason = why_no_fit(52e-6, 68e-6, 30.0)
    assert reason.startswith("none of the grades ISO 286-2 prints") and "H6/c6 (55-68 µm" in reason
    # Within SLACK (0.05 µm): H6/f5 at 6-10 mm (6.5-14 µm) is the fit of the zone 5-13.98 µm, not 5-13.9.
    assert nearest_fit(5e-6, 13.98e-6, 8.0) == Fit("H6", "f5") and nearest_fit(5e-6, 13.9e-6, 8.0) is None
    assert fits_covering(41e-6, 65e-6, 36.0) == []
