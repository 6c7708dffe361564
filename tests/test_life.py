"""Pointing over a mission's life (`tolerax.design.life`, `PointingObjective(life=...)`): the
worn scene, the growth as Euler steps of the simulated window's wear, the end-of-life gradient
against central differences, and refused input."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax.design.life import YEAR, MissionLife, window_wear_rates, worn_scene
from tolerax.mechanism.outputs import pointing_metrics
from tolerax.physics.wear import ArchardWear, wear_names, wear_over_run

from _life_helpers import HORIZON, N_SAVE
from _life_helpers import life_objective as _objective

MOS2 = "MoS2 sputtered film, vacuum"


def test_worn_scene_grows_each_contact(life_scan):
    """Each clearance grows by its own contact's depth (sun, carrier, then one per planet pin:
    the pins' clearance becomes one value per planet); the backlash and a joint left out of
    `depth` keep their values."""
    stage = life_scan.azimuth.stage
    assert stage.contact_names == ("sun", "carrier", "planet0", "planet1", "planet2")
    depth = jnp.array([1.0, 2.0, 3.0, 4.0, 5.0]) * 1e-6
    worn = worn_scene(life_scan, {"azimuth": depth}).azimuth.stage
    c = {name: np.asarray(getattr(stage, f"{name}_support").bearing.clearance) for name in ("sun", "carrier", "planet")}
    assert float(worn.sun_support.bearing.clearance) == pytest.approx(c["sun"] + 1e-6, rel=1e-15)
    assert float(worn.carrier_support.bearing.clearance) == pytest.approx(c["carrier"] + 2e-6, rel=1e-15)
    np.testing.assert_allclose(worn.planet_support.bearing.clearance, c["planet"] + np.array([3e-6, 4e-6, 5e-6]), rtol=1e-15)
    np.testing.assert_array_equal(worn.sun_mesh.backlash, stage.sun_mesh.backlash)
    assert worn_scene(life_scan, {}) is life_scan


def test_life_is_euler_steps_of_the_window_wear(life_scan):
    """`over_life` with 2 points: the depth at each point is the last one plus the window's mean
    wear rate (`wear_over_run` over the saves, divided by the window's length, recomputed here
    from an independent run of the worn scene) times half the operating time; the outputs at
    each point are a plain run's of the scene worn that far; the end-of-life outputs are the
    last point's. A zero wear rate leaves the end of life equal to the beginning."""
    wear = ArchardWear.from_lubricant(MOS2)
    life = MissionLife.from_years(5.0, duty=0.5, wear=wear, points=2)
    assert float(life.operating_time) == pytest.approx(2.5 * YEAR, rel=1e-15)
    pointing = _objective(life_scan, life, rtol=1e-8, atol=1e-11)
    values = jnp.full(5, 5e-6)  # m: tight, so that the start-up loads every contact
    outputs, depths = eqx.filter_jit(lambda p, v: p.over_life(v))(pointing, values)
    d = np.asarray(depths["azimuth"])
    assert d.shape == (3, 11) and np.all(d[0] == 0.0)  # 5 contacts, then 3 sun and 3 ring meshes (flank wear)
    window = np.ones(N_SAVE, dtype=bool)
    plain = tx.PointingObjective(life_scan, duration=HORIZON, settle=0.0, start="rest", n_save=N_SAVE, rtol=1e-8, atol=1e-11)
    step = float(life.operating_time) / 2
    for k in range(2):
        worn = worn_scene(tx.with_design(life_scan, values), {"azimuth": jnp.asarray(d[k])})
        res = eqx.filter_jit(lambda p, s: p.simulate_scene(s))(plain, worn)
        by_contact = wear_over_run(worn, res, wear)["azimuth"]
        rate = np.array([float(by_contact[c]) for c in wear_names(worn.azimuth.stage, wear)]) / HORIZON
        np.testing.assert_allclose(d[k + 1], d[k] + step * rate, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(np.asarray(window_wear_rates(worn, res, window, life)["azimuth"]), rate, rtol=1e-12)
        rms = float(pointing_metrics(res, np.asarray(res.ts) >= 0.0, 8)["pointing_rms"])
        assert float(outputs["pointing_rms"][k]) == pytest.approx(rms, rel=1e-9)
    assert np.all(d[1, 2:] > 0.0) and np.all(d[2] >= d[1])  # the pins and the flanks wore; nothing unwears
    both = eqx.filter_jit(lambda p, v: p(v))(pointing, values)
    assert float(both["pointing_rms_eol"]) == float(outputs["pointing_rms"][2]) and bool(both["success"])
    assert float(both["pointing_rms"]) == float(outputs["pointing_rms"][0])
    assert float(both["pointing_rms_eol"]) > 1.05 * float(both["pointing_rms"])  # 2.5 years of start-ups: the pins grew
    assert set(pointing.outputs) == {*plain.outputs, *(f"{o}_eol" for o in plain.outputs)}
    assert pointing.units["pointing_rms_eol"] == "arcsec"
    idle = _objective(life_scan, MissionLife(1e9, ArchardWear(0.0), points=1), rtol=1e-8, atol=1e-11)
    still = eqx.filter_jit(lambda p, v: p(v))(idle, values)
    assert float(still["pointing_rms_eol"]) == float(still["pointing_rms"])


def test_end_of_life_gradient_against_finite_differences(life_scan):
    """The forward-mode gradient of the end-of-life RMS pointing error with respect to the
    as-built clearances and backlash, through the growth (the wear rates' own dependence on the
    clearances included), against central differences at 40, 20, 10 and 5 nm.

    The sun and carrier bearings: within 1e-3 of the differences extrapolated
    (Richardson, as tests/test_gradients.py does on the bench), whose last two agree to 1e-3.
    The planet pins: in the start-up the planets turn through zero relative to their pins, and
    the sliding speed $R|\\omega_{rel}|$ summed over the saves has a kink wherever a save sits at
    that crossing; their differences converge to the gradient only as O(h) (measured: the error
    halves with h). There the error must shrink with every halving of h and be within 5 % at
    5 nm. A week of start-ups (0.02 years of MoS2 wear: the pins grow by 0.3-0.6 um). The
    journals only (`flanks=False`): the flanks' wear rate has |F| and |w_a - w_b| of the meshes,
    both crossing zero in a start-up (test_flank_wear_gradient checks that part)."""
    life = MissionLife.from_years(0.02, wear=ArchardWear.from_lubricant(MOS2, flanks=False), points=2)
    pointing = _objective(life_scan, life, rtol=1e-10, atol=1e-13)
    forward = _objective(life_scan, life, rtol=1e-10, atol=1e-13, adjoint=diffrax.ForwardMode())
    width, values = 1e-6, jnp.full(5, 5e-6)
    f = eqx.filter_jit(lambda p, v: p(v, width)["pointing_rms_eol"])
    ad = np.asarray(eqx.filter_jit(lambda p, v: jax.jacfwd(lambda u: p(u, width)["pointing_rms_eol"])(v))(forward, values))
    diffs = np.array([[(float(f(pointing, values.at[i].add(h))) - float(f(pointing, values.at[i].add(-h)))) / (2 * h)
                       for i in range(5)] for h in (4e-8, 2e-8, 1e-8, 5e-9)])
    extrapolated = (4 * diffs[1:] - diffs[:-1]) / 3
    print("AD", ad, "differences", diffs, "extrapolated", extrapolated, sep="\n")
    # Where the extrapolations from 40-20-10 and 20-10-5 nm agree to 1e-3 the response is smooth
    # at that scale (the bearings' clearances here): the gradient within 1e-3 of them.
    smooth = np.abs(extrapolated[-1] - extrapolated[-2]) < 1e-3 * np.abs(extrapolated[-1])
    assert smooth.sum() >= 2
    np.testing.assert_array_less(np.abs(ad - extrapolated[-1])[smooth], 1e-3 * np.abs(extrapolated[-1])[smooth])
    # Elsewhere (the pins and the backlash) the kinks: the differences approach the gradient as h halves.
    errors = np.abs(diffs - ad)[:, ~smooth]
    assert np.all(np.diff(errors, axis=0) < 0.0) and np.all(errors[-1] < 0.05 * np.abs(ad[~smooth]))


def test_wear_rate_spread_per_unit(life_scan):
    """`MissionLife(spread=(low, high))`: a unit's inputs carry the logarithm of a factor on every
    wear rate after its design values; the end of life with factor 2 is the end of life of the
    same life with the rates doubled. Monte Carlo draws the factor with the zones
    (`spread_tolerances`, joined to them): inside [ln low, ln high], one more named input."""
    from tolerax.design.life import WEAR_FACTOR, spread_of_lubricant

    wear = ArchardWear.from_lubricant(MOS2)
    spread = spread_of_lubricant(MOS2)
    assert spread == pytest.approx((0.25, 2.5), rel=1e-12)  # 1e-6 and 1e-5 against the median 4e-6 mm^3/(N m)
    life = MissionLife.from_years(0.5, wear=wear, points=1, spread=spread)
    pointing = _objective(life_scan, life)
    assert pointing.uncertain_inputs == (WEAR_FACTOR,)
    doubled = _objective(life_scan, MissionLife.from_years(0.5, wear=ArchardWear(2 * float(wear.rate)), points=1))
    values = jnp.full(5, 5e-6)
    run = eqx.filter_jit(lambda p, v: p(v))
    got, want, median = run(pointing, jnp.append(values, np.log(2.0))), run(doubled, values), run(pointing, values)
    assert float(got["pointing_rms_eol"]) == pytest.approx(float(want["pointing_rms_eol"]), rel=1e-12)
    assert float(got["pointing_rms_eol"]) != float(median["pointing_rms_eol"])  # without the factor: the median rate
    assert float(got["pointing_rms"]) == float(median["pointing_rms"])  # as built: no wear yet
    with pytest.raises(ValueError, match=r"a unit has 7 values; the scene has 5 design features .* or 6 \(with life.log_wear_factor\)"):
        pointing(jnp.zeros(7))
    zones = tx.Tolerances(tx.design_names(life_scan), values, jnp.full(5, 1e-6)).joined(life.spread_tolerances())
    assert zones.names[-1] == WEAR_FACTOR and zones.lower is not None and float(zones.lower[-1]) == -np.inf
    draws = np.asarray(tx.sample(zones, jax.random.key(0), 2000))
    assert np.all(draws[:, -1] >= np.log(0.25) - 1e-12) and np.all(draws[:, -1] <= np.log(2.5) + 1e-12)
    assert np.ptp(draws[:, -1]) > 0.9 * np.log(10.0)  # spread over the band (log-uniform)
    assert np.all(draws[:, :5] >= 4e-6 - 1e-18)
    with pytest.raises(ValueError, match=r"spread must be \(low, high\) with 0 < low <= high"):
        MissionLife(1.0, wear, spread=(2.0, 1.0))
    with pytest.raises(ValueError, match=r"this life has no spread"):
        MissionLife(1.0, wear).spread_tolerances()
    with pytest.raises(ValueError, match=r"one distribution"):
        zones.joined(life.spread_tolerances("normal"))


def test_life_refused_input(life_scan):
    wear = ArchardWear.from_lubricant(MOS2)
    with pytest.raises(ValueError, match="operating_time"):
        MissionLife(-1.0, wear)
    with pytest.raises(ValueError, match="points must be an integer >= 1"):
        MissionLife(1.0, wear, points=0)
    with pytest.raises(TypeError, match="ArchardWear"):
        MissionLife(1.0, "MoS2")
    with pytest.raises(TypeError, match="joint names to ArchardWear"):
        MissionLife(1.0, {"azimuth": 3e-15})
    with pytest.raises(ValueError, match="duty"):
        MissionLife.from_years(10, duty=2.0, wear=wear)
    with pytest.raises(ValueError, match="period"):
        MissionLife.from_cycles(1e6, 0.0, wear=wear)
    lumped = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    with pytest.raises(ValueError, match="wears nothing"):
        _objective(lumped, MissionLife(1.0, wear)).over_life(tx.design_of(lumped))
    with pytest.raises(ValueError, match="needs a life"):
        _objective(life_scan, None).over_life(tx.design_of(life_scan))
