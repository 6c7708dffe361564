"""The design layer on real scenes: the design vector and its inverse, the scan scene that makes
clearances and backlash matter, pointing-error gradients against finite differences, and the
Monte Carlo engine and design proposal wired to the physics."""


import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax.design import propose as _propose
from tolerax.design import problem as _problem

import _responses as R


def _leaves(tree):
    return [np.asarray(x) for x in jax.tree.leaves(eqx.filter(tree, eqx.is_array))]


def test_design_vector_round_trip_and_names():
    mech = tx.antenna("dual", fidelity=("planetary", "lumped"))
    names = tx.design_names(mech)
    # A planetary joint reads all five; a lumped one no sun bearing (it has no sun translation).
    assert names == (
        "azimuth.sun_clearance", "azimuth.carrier_clearance", "azimuth.planet_clearance",
        "azimuth.sun_backlash", "azimuth.ring_backlash",
        "pitch.carrier_clearance", "pitch.planet_clearance", "pitch.sun_backlash", "pitch.ring_backlash",
    )
    p = jnp.arange(1.0, 10.0) * 1e-6
    changed = tx.with_design(mech, p)
    np.testing.assert_array_equal(tx.design_of(changed), p)
    np.testing.assert_array_equal(changed.azimuth.stage.sun_mesh.backlash, np.full(3, 4e-6))  # all planets alike
    back = tx.with_design(changed, tx.design_of(mech))
    assert all(np.array_equal(a, b) for a, b in zip(_leaves(back), _leaves(mech)))
    # An ideal joint has no features; a rigid support none either.
    assert tx.design_names(tx.antenna("dual", fidelity="ideal")) == ()
    stage = tx.default_stage(carrier_support="rigid", mesh="linear")
    assert tx.design_names(tx.TestBench(stage)) == ("sun_clearance", "planet_clearance")
    with pytest.raises(ValueError, match=r"shape \(9,\)"):
        tx.with_design(mech, jnp.zeros(3))


def test_distinct_planets_are_features_of_their_own(tmp_path):
    """A stage with `distinct_planets`: each planet's pin clearance and sun/ring backlash is a
    feature (`joint.feature[i]`), read and written per planet; all planets set alike give the
    shared design's simulation (the same arrays); one planet's pin made tighter changes the
    pointing (the lumped joint's lost motion is set by its tightest planet) and one made looser
    does not; the drawings weigh each planet 1/N of the shared feature; a scene file sets it."""
    from tolerax.design.features import lost_motion_weights

    shared = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    distinct = tx.scan("azimuth", fidelity=("lumped", "ideal"), azimuth_stage=tx.default_stage(distinct_planets=True))
    names = tx.design_names(distinct)
    assert names == ("azimuth.carrier_clearance", *(f"azimuth.{f}[{i}]" for f in ("planet_clearance", "sun_backlash", "ring_backlash")
                                                    for i in range(3)))
    p = jnp.arange(1.0, 11.0) * 1e-6
    changed = tx.with_design(distinct, p)
    np.testing.assert_array_equal(tx.design_of(changed), p)
    np.testing.assert_array_equal(changed.azimuth.stage.planet_support.bearing.clearance, p[1:4])
    np.testing.assert_array_equal(changed.azimuth.stage.sun_mesh.backlash, p[4:7])
    np.testing.assert_array_equal(changed.azimuth.stage.ring_mesh.backlash, p[7:10])
    w_shared, w_distinct = np.asarray(lost_motion_weights(shared)), np.asarray(lost_motion_weights(distinct))
    np.testing.assert_allclose(w_distinct, np.repeat(w_shared, [1, 3, 3, 3]) / np.array([1] + [3] * 9), rtol=1e-12)

    pointing = tx.PointingObjective(shared, duration=0.3, settle=0.0, start="steady", n_save=31)
    per_planet = eqx.tree_at(lambda o: o.scene, pointing, distinct)
    rms = eqx.filter_jit(lambda o, v: o(v, 1e-6)["pointing_rms"])
    base = np.array([100e-6, 30e-6, 50e-6, 50e-6])
    alike = np.repeat(base, [1, 3, 3, 3])
    assert float(rms(per_planet, jnp.asarray(alike))) == pytest.approx(float(rms(pointing, jnp.asarray(base))), rel=1e-12)
    tighter, looser = alike.copy(), alike.copy()
    tighter[1], looser[1] = 10e-6, 60e-6
    assert abs(float(rms(per_planet, jnp.asarray(tighter))) / float(rms(per_planet, jnp.asarray(alike))) - 1.0) > 1e-3
    assert float(rms(per_planet, jnp.asarray(looser))) == pytest.approx(float(rms(per_planet, jnp.asarray(alike))), rel=1e-9)

    # A lumped joint keeps only the tightest planet's lost motion: designing per-planet features
    # on it is warned against (benchmarks/results/design_antenna_planets.md).
    with pytest.warns(UserWarning, match="tightest planet"):
        _propose.design_problem(per_planet)
    scene_file = tmp_path / "planets.toml"
    scene_file.write_text('[scene]\nkind = "scan"\nmode = "azimuth"\nfidelity = ["lumped", "ideal"]\n\n'
                          '[scene.azimuth_stage]\ndistinct_planets = true\n\n'
                          '[design]\n"azimuth.planet_clearance[1]" = 2e-05\n\n[run]\nduration = 0.1\n')
    loaded = tx.load_scene(scene_file).build()
    assert tx.design_names(loaded) == names
    np.testing.assert_allclose(loaded.azimuth.stage.planet_support.bearing.clearance, [100e-6, 20e-6, 100e-6])
    with pytest.raises(TypeError, match="distinct_planets"):
        tx.default_stage(distinct_planets="yes")


@pytest.mark.slow
def test_scan_gradients_against_finite_differences(scan_pointing, scan_unit):
    """Enlarges tests/test_gradients.py::test_lumped_scan_directional_derivative_at_contact_onset
    (reverse and forward mode against differences and each other, 0.3 s) and
    tests/test_reliability.py::test_yield_objective_gradient_on_the_scan (the forward-mode
    gradient on this scan, its backlash derivatives against the lever): the whole 0.6 s scan at
    the design's own tolerance, both modes. Through one reversal (0.25 s) with the back flank engaging after it: the reverse-mode
    gradient of the RMS pointing error matches central differences along a random direction,
    and the forward-mode one matches it. At the 1 um smoothing width of the optimiser's
    continuation the objective is nearly smooth at finite-difference scale:
    benchmarks/results/archive/gradient_horizon.md measured |AD - FD| / |FD| = 7.1e-4 on this
    scene (per feature), with the differences at 10 nm and 100 nm steps themselves differing by
    4.9e-4; the tolerance, 2e-3, is about three times that noise. (At the default 1 nm width the
    same comparison differs by 6 %: the output bearing's impacts make the objective rough at
    that scale.)"""
    p0 = tx.design_of(scan_pointing.scene)
    width = jnp.asarray(1e-6)
    ad = np.asarray(eqx.filter_jit(jax.grad(lambda p, w: scan_pointing(p, w)["pointing_rms"]))(p0, width))
    h, d = 1e-8, np.random.default_rng(2).normal(size=4)
    d /= np.linalg.norm(d)
    fd = (float(scan_unit(p0 + h * d)["pointing_rms"]) - float(scan_unit(p0 - h * d)["pointing_rms"])) / (2 * h)
    assert abs(ad @ d - fd) < 2e-3 * np.linalg.norm(ad)
    # Lost motion per metre of backlash seen at the output: 1 / lever (rad/m); the RMS over the
    # run sees a fraction of it, and the pin play enters both flanks with cos a_s + cos a_r.
    lever = float(tx.lumped_mesh(scan_pointing.scene.azimuth.stage, 2e-4).lever)
    per_backlash = 1.0 / lever / tx.ARCSEC
    assert 0.1 * per_backlash < ad[2] < per_backlash
    assert ad[2] == pytest.approx(ad[3], rel=1e-9)  # sun and ring backlash add in the lumped mesh
    # The optimiser's gradient (`RobustPointing(adjoint=None)`: tangents carried through
    # the solve by `diffrax.ForwardMode`, the Jacobian handed to reverse mode by a custom VJP) is
    # the same derivative of the same discrete solve by another route, so it agrees far better
    # than the differences above. Not to the last bit: tangents pushed forward and adjoints
    # pulled back through ~3000 steps of a contact problem round differently. Measured here
    # |fwd - rev| / |rev| = 8e-8 (2.6e-6 on the small carrier component alone); at rtol 1e-8 over
    # 0.4 s, 3e-11. Bound 1e-6: 2000x tighter than the finite-difference check.
    unit = eqx.filter_jit(jax.grad(lambda p, w: _problem._unit_output_forward(p, scan_pointing, "pointing_rms", w)))
    forward = np.asarray(unit(p0, width))
    assert np.linalg.norm(forward - ad) < 1e-6 * np.linalg.norm(ad)


def test_monte_carlo_on_a_scene_equals_direct_evaluation(scan_pointing, scan_unit):
    """The Monte Carlo engine on the physics: each sample's outputs equal a direct evaluation of
    the objective at that sample's values (a second path through the same model)."""
    pointing = scan_pointing
    tolerances = tx.tolerances_of(pointing.scene, band=20e-6)
    res = tx.monte_carlo(pointing, tolerances, 3, jax.random.key(1), chunk_size=3, progress=False, requirement=2000.0)
    ds = res.dataset
    assert int(ds["success"].sum()) == 3
    values = np.stack([ds[name].values for name in tolerances.names], axis=1)
    np.testing.assert_array_equal(values, np.asarray(tx.sample(tolerances, jax.random.key(1), 3)))
    direct = float(scan_unit(values[1], None)["pointing_rms"])
    # A vmapped chunk is one program that rounds differently from the single evaluation, and
    # the adaptive solve amplifies rounding through the impacts: measured up to 1.3e-5 relative
    # between chunk sizes (benchmarks/results/monte_carlo_throughput.md), 3e-7 here. A wrong
    # sample (another unit's values) would differ by percent.
    assert float(ds["pointing_rms"].values[1]) == pytest.approx(direct, rel=1e-4)
    summary = res.summary()["pointing_rms"]
    assert summary["n_used"] == 3 and 0.0 <= summary["yield"] <= 1.0


class _Spy(eqx.Module):
    def __call__(self, x, draws, width):
        return x


def test_design_problem_is_the_set_of_buildable_fits():
    """The optimiser's box is on (lower limit, band): the zone [l, l + 2b] never reaches below
    the functional minimum clearance, whatever the band; bad settings are named."""
    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    pointing = tx.PointingObjective(scene, duration=0.3, settle=0.0)
    problem = _propose.design_problem(pointing, band=10e-6, min_clearance=[5e-6, 5e-6, 95e-6, 5e-6])
    np.testing.assert_allclose(problem.x0.nominal, [90e-6, 90e-6, 95e-6, 90e-6])  # 100 um - band, or the minimum
    np.testing.assert_allclose(problem.lower.nominal, [5e-6, 5e-6, 95e-6, 5e-6])
    np.testing.assert_allclose(problem.upper.band, np.full(4, 50e-6))
    x = _propose.FromLowerLimit(_Spy())(tx.Design(jnp.full(4, 5e-6), jnp.full(4, 3e-6)), None, None)
    np.testing.assert_allclose(x.nominal, np.full(4, 8e-6))  # nominal = l + b
    np.testing.assert_allclose(x.nominal - x.band, np.full(4, 5e-6))
    with pytest.raises(ValueError, match="min_clearance"):
        _propose.design_problem(pointing, min_clearance=-1e-6)
    with pytest.raises(ValueError, match="band_range"):
        _propose.design_problem(pointing, band=60e-6)
    # Fixed features: the zone given (nominal +- its band, here 100 +- 70 um, outside the band
    # range) is the whole box of that feature, its start included.
    given = _propose.design_problem(pointing, band=10e-6, fixed={"azimuth.sun_backlash": 70e-6})
    for box in (given.lower, given.upper, given.x0):
        np.testing.assert_allclose([box.nominal[2], box.band[2]], [30e-6, 70e-6])
    np.testing.assert_allclose(np.asarray(given.upper.band)[[0, 1, 3]], np.full(3, 50e-6))  # the others designed as before
    by_name = _propose.design_problem(pointing, band=10e-6, fixed=["azimuth.sun_backlash"])
    np.testing.assert_allclose([by_name.lower.band[2], by_name.upper.band[2]], [10e-6, 10e-6])
    with pytest.raises(ValueError, match="not a design feature"):
        _propose.design_problem(pointing, fixed=["azimuth.sun_clearance"])  # lumped joints have none
    with pytest.raises(ValueError, match="half-width > 0"):
        _propose.design_problem(pointing, fixed={"azimuth.sun_backlash": 0.0})
    # The robust statistic's k is untouched by a fixed feature (mean + k std).
    assert _propose.design_problem(pointing, k=2.0, fixed=["azimuth.ring_backlash"]).objective.objective.k == 2.0


def _lost_motion_line():
    """A closed-form unit (tests/_responses.py) on the scan's features: an RMS pointing error
    that is the drawings' lost motion (their weights, halved) about 1000 arcsec at 100 um."""
    scene = R.scan_scene()
    return R.Line(scene, 1000.0, 0.5 * np.asarray(tx.lost_motion_weights(scene)), 100e-6)


def test_propose_design_meets_a_loose_requirement_cheaper():
    """The augmented Lagrangian with a tiny budget, on a closed-form unit: with a requirement
    well above the baseline's error, the proposal may loosen every band, so it must cost less
    than the baseline and still meet the requirement (re-evaluated independently); the report's
    plain-words paragraph, sensitivities and lost-motion split."""
    scan_pointing = _lost_motion_line()
    baseline = float(scan_pointing(tx.design_of(scan_pointing.scene))["pointing_rms"])
    report = tx.propose_design(tx.ToleranceProblem(scan_pointing, 1.5 * baseline, tx.MeanPlusKStd(units=2)),
                               tx.AugmentedLagrangian(widths=(1e-6,), max_outer=2, inner_steps=3))
    assert report.cost < report.baseline[2]
    assert np.all(report.band >= report.baseline[1] - 1e-12)
    first = report.outcomes[0]
    assert first.objective <= 1.5 * baseline * 1.02
    assert report.names == tx.design_names(scan_pointing.scene)
    assert "IT" in report.table()
    # The plain-words paragraph first: every zone as a callout, what it meets, the cost against
    # the baseline, the most sensitive feature (the largest |d objective / d nominal|).
    plain = report.plain()
    assert plain in report.table().split("\n\n")[:2] and all(f"{name} " in plain for name in report.names)
    # Every solver's design is drawn on whole grades: the paragraph costs the drawing.
    assert report.drawable is not None and f"{report.drawable.cost:.3g} (" in plain
    assert f"{first.requirement.limit:g} arcsec" in plain
    top = report.names[int(np.argmax(np.abs(np.asarray(first.sensitivity.nominal))))]
    assert f"most sensitive to {top} " in plain and plain.startswith(("Put on the drawing", "The best design reached"))
    # The drawings' weights beside the simulated sensitivities: the scene's own geometry.
    np.testing.assert_allclose(report.lost_motion, tx.lost_motion_weights(scan_pointing.scene))
    assert "simulated / drawings" in report.table()
    # The split of the objective's variation over the zones into lost motion and dynamics:
    # sensitivities that are the drawings' weights scaled are all lost motion; adding a part
    # orthogonal to them in the zones' metric (sum b^2 w r = 0) moves its share to dynamics.
    import dataclasses

    w, b = np.array([0.0, 8.25e6, 4.39e6, 4.39e6]), np.array([50e-6, 10e-6, 15e-6, 18e-6])
    def with_slopes(report, s):  # the report with its first requirement's sensitivities replaced
        return dataclasses.replace(report, outcomes=(dataclasses.replace(report.outcomes[0], sensitivity=s),))

    scaled = with_slopes(dataclasses.replace(report, lost_motion=w, band=b), tx.Design(0.7 * w, np.zeros(4)))
    np.testing.assert_allclose(scaled.split, (1.0, 0.0, 0.7), atol=1e-12)
    r = np.array([2e4, 1e6, -1e6, 0.0])
    r = r - w * np.sum(b**2 * w * r) / np.sum(b**2 * w**2)  # orthogonal to w in the zones' metric
    mixed = with_slopes(scaled, tx.Design(0.7 * w + r, np.zeros(4)))
    lost = np.sum(b**2 * (0.7 * w) ** 2) / np.sum(b**2 * (0.7 * w + r) ** 2)
    np.testing.assert_allclose(mixed.split, (lost, 1 - lost, 0.7), rtol=1e-10)
    assert 0.0 < lost < 1.0 and "is lost motion" in report.table()


def test_sequential_proposal_lands_on_the_requirement():
    """The sequential method (one smoothing width, two units, mean + 1 std), on a closed-form
    unit: a requirement half the baseline's error binds, and the method stops on it (within its
    1 % tolerance), converged, in a few gradients; the objective at the proposal, evaluated
    again independently of the optimiser, is the one reported; the proposal's zones go into a
    scene file and come back. (The same path on the real scan, with the gradient through the
    simulation: the command line's demo and design tests; the yield design on it:
    test_reliability.py::test_yield_proposal_binds_its_quantile.)"""
    scan_pointing = _lost_motion_line()
    problem = _propose.design_problem(scan_pointing, n_draws=2)
    baseline = float(eqx.filter_jit(problem.objective)(problem.x0, problem.draws, 1e-6))
    requirement = 0.5 * baseline
    report = tx.propose_design(tx.ToleranceProblem(scan_pointing, requirement, tx.MeanPlusKStd(units=2)),
                               tx.Sequential(widths=(1e-6,), max_gradients=12))
    first = report.outcomes[0]
    assert bool(report.result.converged) and first.constraint_active
    assert abs(first.objective / requirement - 1.0) <= 0.01
    assert int(np.asarray(report.result.history.steps)[-1]) <= 12
    again = float(eqx.filter_jit(problem.objective)(report.result.x, problem.draws, 1e-6))
    np.testing.assert_allclose(again, first.objective, rtol=1e-9)
    # The proposal's zones (`Tolerances`): lower limits the optimiser's, and a scene file
    # written with them reads them back (what `tolerax design` writes as proposal.toml).
    zones = report.tolerances
    np.testing.assert_allclose(zones.lower_limit, report.result.x.nominal, rtol=1e-12)
    assert zones.names == report.names
    back = tx.load_scene("scan-azimuth").with_proposal(report).tolerances()
    np.testing.assert_allclose(back.nominal, zones.nominal, rtol=1e-12)
    np.testing.assert_allclose(back.band, zones.band, rtol=1e-12)
    # The former signature: the same design for one release, with a DeprecationWarning naming
    # what replaces it (tolerax.design.legacy); an unknown method is refused.
    with pytest.warns(DeprecationWarning, match="ToleranceProblem"):
        former = tx.propose_design(scan_pointing, requirement=requirement, n_draws=2, max_outer=12, widths=(1e-6,), method="sequential")
    assert former.cost == report.cost and np.array_equal(former.band, report.band)
    with pytest.warns(DeprecationWarning), pytest.raises(ValueError, match="method"):
        tx.propose_design(scan_pointing, requirement=requirement, method="newton")
    with pytest.raises(TypeError, match="solver=, check=, progress= and callback="):
        tx.propose_design(tx.ToleranceProblem(scan_pointing, requirement), widths=(1e-6,))
