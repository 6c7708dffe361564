"""Drawable tolerances (`tolerax.design.drawable`): whole ISO 286 grades next to a continuous
design, against a brute-force search written here on a linear stack-up."""

import itertools
import math

import numpy as np
import pytest

from tolerax.design.cost import IsoGrade, grade_of, it_tolerance
from tolerax.design.drawable import round_to_grades, width_of_grade

SIZES = np.array([30.0, 8.0, 40.0, 120.0])  # mm


def test_whole_grade_widths_are_iso_286():
    """IT5-IT11 are ISO 286-1's standard tolerances (IT7 at 18-30 mm: 21 um); beyond, the R5
    progression, within 1 % of ISO's rounded IT12 (160 i) and IT13 (250 i)."""
    assert float(width_of_grade(7, 25.0)) == pytest.approx(float(it_tolerance(7, 25.0)), rel=1e-12)
    assert 1e6 * float(width_of_grade(7, 25.0)) == pytest.approx(21.0, abs=0.5)
    for g, multiple in ((12, 160), (13, 250)):
        assert float(width_of_grade(g, 25.0)) / float(it_tolerance(11, 25.0)) == pytest.approx(multiple / 100, rel=0.01)
    for g in range(3, 14):  # the inverse of grade_of at whole grades
        assert float(grade_of(width_of_grade(g, 25.0), 25.0)) == pytest.approx(g, abs=1e-9)


def _brute(lower, band, grade, f0, limit, slopes, cost):
    best = None
    choices = [sorted({math.floor(g), math.ceil(g)}) for g in grade]
    for pick in itertools.product(*choices):
        b = np.array([0.5 * float(width_of_grade(g, s)) for g, s in zip(pick, SIZES)])
        f = f0 + slopes @ (b - band)
        if np.all(f <= limit) and (best is None or np.sum(cost(b)) < best[0]):
            best = (float(np.sum(cost(b))), pick)
    return best


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_rounding_is_the_cheapest_whole_grade_design_meeting_the_linear_model(seed):
    """Random continuous designs on a linear stack-up of two outputs: the drawable design takes
    each feature to the whole grade just below or above its own, meets both linearised
    requirements, costs what its zones cost, and is the brute force's cheapest."""
    rng = np.random.default_rng(seed)
    grade = rng.uniform(6.2, 9.8, 4)
    band = 0.5 * np.asarray(width_of_grade(7, SIZES)) * 1.5848931924611136 ** (grade - 7)
    grade = np.asarray(grade_of(2 * band, SIZES))
    lower = np.full(4, 5e-6)
    slopes = rng.uniform(1e6, 2e7, (2, 4))  # arcsec per m of half-width
    f0 = np.array([700.0, 650.0])
    limit = f0 + rng.uniform(0.0, 60.0, 2)  # a little slack for the rounding to use
    model = IsoGrade()
    cost = lambda b: np.asarray(model(2 * np.asarray(b), SIZES))  # noqa: E731 (per feature)
    d = round_to_grades(["a", "b", "c", "d"], SIZES, lower, band, grade, f0, limit, slopes, cost)
    assert np.all((d.grades == np.floor(grade)) | (d.grades == np.ceil(grade)))
    np.testing.assert_allclose(d.band, [0.5 * float(width_of_grade(int(g), s)) for g, s in zip(d.grades, SIZES)], rtol=1e-12)
    np.testing.assert_allclose(d.nominal - d.band, lower, rtol=1e-12)  # the lower limits kept
    np.testing.assert_allclose(d.objective, f0 + slopes @ (d.band - band), rtol=1e-12)
    assert d.met and d.cost == pytest.approx(np.sum(cost(d.band)), rel=1e-12)
    assert d.rounding_cost == pytest.approx(d.cost - np.sum(cost(band)), rel=1e-12)
    best = _brute(lower, band, grade, f0, limit, slopes, cost)
    assert best is not None and d.cost == pytest.approx(best[0], rel=1e-12) and tuple(d.grades.astype(int)) == best[1]


def test_fixed_features_and_band_range_are_kept():
    """A given feature keeps its zone; a feature with no whole grade inside the band range keeps
    its continuous one; both are named as kept, and the table says so."""
    grade = np.array([7.4, 8.5, 6.6, 9.3])
    band = 0.5 * np.asarray(width_of_grade(7, SIZES)) * 1.5848931924611136 ** (grade - 7)
    grade = np.asarray(grade_of(2 * band, SIZES))
    narrow = (band * 0.99, band * 1.01)  # the second feature's band may not move at all
    lo, hi = np.zeros(4), np.full(4, 1.0)
    lo[1], hi[1] = narrow[0][1], narrow[1][1]
    cost = lambda b: np.asarray(IsoGrade()(2 * np.asarray(b), SIZES))  # noqa: E731
    d = round_to_grades(["a", "b", "c", "d"], SIZES, np.full(4, 5e-6), band, grade, [500.0], [1e9], np.ones((1, 4)), cost,
                        band_range=(lo, hi), fixed=("d",))
    assert d.kept == ("b", "d")
    np.testing.assert_allclose(d.band[[1, 3]], band[[1, 3]], rtol=1e-12)
    assert np.all(d.grades[[0, 2]] == np.ceil(grade[[0, 2]]))  # no requirement binds: the looser grade, cheaper
    assert "(kept)" in d.table() and "IT8" in d.table()


def test_greedy_beyond_sixteen_features_meets_the_model():
    """With 18 features the search is greedy: it still meets the linear model and costs no more
    than every feature at its tighter grade."""
    rng = np.random.default_rng(5)
    n = 18
    sizes = rng.uniform(5.0, 100.0, n)
    grade = rng.uniform(6.1, 9.9, n)
    band = 0.5 * np.asarray(width_of_grade(7, sizes)) * 1.5848931924611136 ** (grade - 7)
    grade = np.asarray(grade_of(2 * band, sizes))
    slopes = rng.uniform(1e6, 1e7, (1, n))
    limit = np.array([1000.0 + 40.0])
    cost = lambda b: np.asarray(IsoGrade()(2 * np.asarray(b), sizes))  # noqa: E731
    d = round_to_grades([f"f{k}" for k in range(n)], sizes, np.full(n, 5e-6), band, grade, [1000.0], limit, slopes, cost)
    tight = 0.5 * np.array([float(width_of_grade(math.floor(g), s)) for g, s in zip(grade, sizes)])
    assert d.met and d.cost <= np.sum(cost(tight)) * (1 + 1e-12) and np.any(d.grades > np.floor(grade))


def test_journal_clearances_get_the_loosest_iso_286_fit_inside_their_zone():
    """A journal's drawable zone names the loosest ISO 286 hole-basis fit inside it: at Ø30 mm
    the zone 3.5-20.5 um is exactly H7/g6's (ISO 286-2: H7 +21/0, g6 -7/-20 -> radial
    (0 + 7)/2 to (21 + 20)/2), and nothing looser fits in it; a zone narrower than any fit
    gets none; a backlash gets no fit; the drawable design's table carries them."""
    from tolerax.design.drawable import journal_fits
    from tolerax.design.fits import Fit, fits_covering

    got = journal_fits(["carrier_clearance", "sun_backlash", "planet_clearance"], [30.0, 30.0, 10.0],
                       [3.5e-6, 5e-6, 10e-6], [20.5e-6, 50e-6, 10.5e-6])
    first = fits_covering(3.5e-6, 20.5e-6, 30.0)[0]
    assert got[0].startswith(f"{first} (") and Fit("H7", "g6") in fits_covering(3.5e-6, 20.5e-6, 30.0)
    lo, hi = first.radial_clearance(30.0)
    assert 3.5e-6 - 1e-12 <= lo and hi <= 20.5e-6 + 1e-12 and hi - lo >= 17e-6 - 1e-12  # as wide as H7/g6's zone
    assert got[1] == "" and got[2].startswith("none inside the zone: too narrow")
    grade = np.array([7.4, 8.5])
    band = 0.5 * np.asarray(width_of_grade(7, SIZES[:2])) * 1.5848931924611136 ** (grade - 7)
    cost = lambda b: np.asarray(IsoGrade()(2 * np.asarray(b), SIZES[:2]))  # noqa: E731
    d = round_to_grades(["carrier_clearance", "ring_backlash"], SIZES[:2], np.full(2, 20e-6), band,
                        np.asarray(grade_of(2 * band, SIZES[:2])), [500.0], [1e9], np.ones((1, 2)), cost)
    assert len(d.fits) == 2 and d.fits[1] == "" and "ISO 286 fit" in d.table()


def test_backlash_zones_are_drawn_as_tooth_thickness_allowances():
    """With the meshes' pressure angles, a stage's sun and ring backlash are called out together
    as sun, planet and ring tooth-thickness allowances (the planet's the same in both), each
    mesh's normal backlash inside its zone; a clearance keeps its fit; without angles, nothing."""
    import re

    from tolerax.design.drawable import journal_fits

    names = ["az.sun_backlash", "az.ring_backlash", "az.planet_clearance"]
    lo, hi, alpha = [20e-6, 30e-6, 5e-6], [45e-6, 80e-6, 30e-6], math.radians(20.0)
    got = journal_fits(names, [40.0, 120.0, 12.0], lo, hi, [alpha] * 3)
    planet = {re.search(r"planet (\S+)", t).group(1) for t in got[:2]}
    assert len(planet) == 1 and got[2].startswith("H")
    for text, a, b in zip(got[:2], lo, hi):
        jn = [float(v) for v in re.match(r"jn ([\d.]+)–([\d.]+) µm", text).groups()]
        assert a * 1e6 - 0.05 <= jn[0] <= jn[1] <= b * 1e6 + 0.05
    assert journal_fits(names, [40.0, 120.0, 12.0], lo, hi)[:2] == ("", "")
