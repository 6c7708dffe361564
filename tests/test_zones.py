"""One tolerance-zone type (`tolerax.Tolerances`) shared by the design, Monte Carlo, scene files
and reports: its limits, its round trip through a scene file, the design started from and holding
zones, and a proposal's zones."""

import numpy as np
import pytest

import tolerax as tx
from tolerax.design import problem as _problem

NAMES = ("azimuth.carrier_clearance", "azimuth.planet_clearance", "azimuth.sun_backlash", "azimuth.ring_backlash")


def test_limits_and_order():
    """A zone's limits are nominal -+ band; built from limits it has them back; `of` reorders
    and refuses a name it has no zone for."""
    zones = tx.Tolerances.from_limits(NAMES, [10e-6, 20e-6, 30e-6, 40e-6], [30e-6, 24e-6, 30e-6, 60e-6])
    np.testing.assert_allclose(zones.nominal, [20e-6, 22e-6, 30e-6, 50e-6])
    np.testing.assert_allclose(zones.band, [10e-6, 2e-6, 0.0, 10e-6], atol=1e-18)
    np.testing.assert_allclose(zones.lower_limit, [10e-6, 20e-6, 30e-6, 40e-6])
    np.testing.assert_allclose(zones.upper_limit, [30e-6, 24e-6, 30e-6, 60e-6])
    np.testing.assert_allclose(zones.bounds(), np.stack([zones.lower_limit, zones.upper_limit], axis=1))
    back = zones.of(NAMES[::-1])
    assert back.names == NAMES[::-1]
    np.testing.assert_allclose(back.nominal, np.asarray(zones.nominal)[::-1])
    with pytest.raises(ValueError, match="no zone for"):
        zones.of(["pitch.backlash"])
    with pytest.raises(ValueError, match="upper limit is below"):
        tx.Tolerances.from_limits(NAMES[:1], [20e-6], [10e-6])
    # The optimiser's variables as zones: from a lower limit, or from a middle.
    x = tx.Design(np.array([5e-6, 6e-6]), np.array([1e-6, 2e-6]))
    np.testing.assert_allclose(x.tolerances(NAMES[:2], from_lower_limit=True).lower_limit, [5e-6, 6e-6])
    np.testing.assert_allclose(x.tolerances(NAMES[:2], from_lower_limit=False).nominal, [5e-6, 6e-6])


def test_scene_file_round_trip():
    """Zones written into a scene file come back from it (nominals under [design], bands under
    [tolerances.bands]); a zone for a feature the scene lacks is refused naming it."""
    sf = tx.load_scene("scan-azimuth")
    zones = tx.Tolerances(NAMES, [61e-6, 72e-6, 83e-6, 94e-6], [3e-6, 4e-6, 5e-6, 6e-6], "normal")
    back = sf.with_tolerances(zones).tolerances()
    assert back.names == NAMES and back.distribution == "normal"
    np.testing.assert_allclose(back.nominal, zones.nominal, rtol=1e-12)
    np.testing.assert_allclose(back.band, zones.band, rtol=1e-12)
    # A subset leaves the others at the scene's own zones.
    part = sf.with_tolerances(zones.of(NAMES[:1])).tolerances()
    np.testing.assert_allclose(part.nominal, [61e-6, *np.asarray(sf.tolerances().nominal)[1:]], rtol=1e-12)
    with pytest.raises(ValueError, match="not design features"):
        sf.with_tolerances(tx.Tolerances(["pitch.sun_clearance"], [1e-4], [1e-5]))


def test_design_starts_from_and_holds_zones():
    """`design_problem(start=zones)` starts each feature at its zone (lower limit nominal - band,
    at least the functional minimum): the same problem as a scalar band where the zones are
    the scene's design +- that band; a `Tolerances` given as `fixed` holds its features at
    its zones; a starting band outside the band range is refused naming the feature."""
    sf = tx.load_scene("scan-azimuth")
    pointing = sf.objective(duration=0.3, settle=0.0)
    scalar = _problem.design_problem(pointing, band=10e-6)
    zoned = _problem.design_problem(pointing, start=tx.tolerances_of(pointing.scene, 10e-6))
    for a, b in ((scalar.x0, zoned.x0), (scalar.lower, zoned.lower), (scalar.upper, zoned.upper)):
        np.testing.assert_allclose(a.nominal, b.nominal, rtol=1e-12)
        np.testing.assert_allclose(a.band, b.band, rtol=1e-12)
    start = tx.Tolerances(NAMES[::-1], [80e-6, 70e-6, 60e-6, 50e-6], [4e-6, 3e-6, 2e-6, 20e-6])  # any order
    problem = _problem.design_problem(pointing, start=start, min_clearance=5e-6)
    np.testing.assert_allclose(problem.x0.band, [20e-6, 2e-6, 3e-6, 4e-6])
    np.testing.assert_allclose(problem.x0.nominal, [30e-6, 58e-6, 67e-6, 76e-6])  # the lower limits
    np.testing.assert_allclose(problem.upper.nominal, problem.x0.nominal)  # no wider than it started
    held = tx.Tolerances(NAMES[2:3], [40e-6], [15e-6])
    fixed = _problem.design_problem(pointing, start=start, fixed=held)
    for box in (fixed.lower, fixed.upper, fixed.x0):
        np.testing.assert_allclose([box.nominal[2], box.band[2]], [25e-6, 15e-6])
    # Names: held at the starting zone.
    by_name = _problem.design_problem(pointing, start=start, fixed=[NAMES[0]])
    np.testing.assert_allclose([by_name.lower.nominal[0], by_name.upper.band[0]], [30e-6, 20e-6])
    wide = tx.Tolerances(NAMES, np.full(4, 100e-6), [10e-6, 60e-6, 10e-6, 10e-6])
    with pytest.raises(ValueError, match="azimuth.planet_clearance"):
        _problem.design_problem(pointing, start=wide)
    _problem.design_problem(pointing, start=wide, fixed=[NAMES[1]])  # a given feature may be outside it
    with pytest.raises(ValueError, match="no zone for"):
        _problem.design_problem(pointing, start=start.of(NAMES[:2]))
