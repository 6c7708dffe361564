"""Pointing over a mission's life (`tolerax.design.life`, `PointingObjective(life=...)`): the
worn scene, the growth as Euler steps of the simulated window's wear, the wear over a real run
and the window's wear rates' derivative on one saved trajectory, the end-of-life derivative
against central differences, the wear rate's spread, and refused input.

Cost: the tests share a handful of compiled programs (module-level jitted functions, the same
objective settings: `_life_helpers`): the start-up's plain run of a worn scene (`startup`),
`over_life`, the objective's call with 5 and with 6 inputs, and one forward-mode derivative.
Every life objective here carries the MoS2 spread (static), so that the calls with 5 values
(factor 1) of different lives are one program."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax.design.life import WEAR_FACTOR, YEAR, MissionLife, spread_of_lubricant, window_wear_rates, worn_scene
from tolerax.mechanism.outputs import pointing_metrics
from tolerax.physics.wear import ArchardWear, wear_names, wear_over_run

from _life_helpers import ATOL, HORIZON, MOS2, N_SAVE, RTOL, WIDTH
from _life_helpers import life_objective as _objective

VALUES = jnp.full(5, 5e-6)  # m: tight, so that the start-up loads every contact
SPREAD = spread_of_lubricant(MOS2)
N_WORN = 11  # what wears in the planetary stage: 5 contacts, then 3 sun and 3 ring meshes (flank wear)

# One program each, shared by the tests (defined here, not inside a test: a lambda written in a
# test is a new function, and a new compile, at every run).
_call = eqx.filter_jit(lambda p, v: p(v))
_over_life = eqx.filter_jit(lambda p, v: p.over_life(v))
_simulate = eqx.filter_jit(lambda p, s: p.simulate_scene(s))
# The wear over a run and the window's mean rates, one program (op by op, the flanks' vmapped
# force law costs seconds of small compiles).
_wear = eqx.filter_jit(lambda s, r, life: (wear_over_run(s, r, life.wear), window_wear_rates(s, r, np.ones(N_SAVE, dtype=bool), life)))
_directional = eqx.filter_jit(lambda p, v, d: jax.jvp(lambda u: p(u, WIDTH), (v,), (d,)))


def _life(years, wear, duty=1.0, points=2):
    """A life with the MoS2 spread (the module's one life structure: see the module docstring)."""
    return MissionLife.from_years(years, duty=duty, wear=wear, points=points, spread=SPREAD)


def _plain(scene):
    return tx.PointingObjective(scene, duration=HORIZON, settle=0.0, start="rest", n_save=N_SAVE,
                               integrator=tx.Integrator(rtol=RTOL, atol=ATOL, max_steps=400_000))


@pytest.fixture(scope="module")
def startup(life_scan):
    """`(scene, run)`: the start-up at `VALUES`, the scene worn by nothing (`worn_scene` at zero
    growth: a clearance and a backlash per planet, the structure of every worn scene, so that the
    runs of `test_life_is_euler_steps_of_the_window_wear` share its program)."""
    scene = worn_scene(tx.with_design(life_scan, VALUES), {"azimuth": jnp.zeros(N_WORN)})
    return scene, _simulate(_plain(life_scan), scene)


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


def test_life_is_euler_steps_of_the_window_wear(life_scan, startup):
    """`over_life` with 2 points: the depth at each point is the last one plus the window's mean
    wear rate (`wear_over_run` over the saves, divided by the window's length, recomputed here
    from an independent run of the worn scene) times half the operating time; the outputs at
    each point are a plain run's of the scene worn that far; the end-of-life outputs are the
    last point's. A zero wear rate leaves the end of life equal to the beginning."""
    wear = ArchardWear.from_lubricant(MOS2)
    life = _life(5.0, wear, duty=0.5)
    assert float(life.operating_time) == pytest.approx(2.5 * YEAR, rel=1e-15)
    pointing = _objective(life_scan, life, rtol=RTOL, atol=ATOL)
    outputs, depths = _over_life(pointing, VALUES)
    d = np.asarray(depths["azimuth"])
    assert d.shape == (3, N_WORN) and np.all(d[0] == 0.0)  # 5 contacts, then 3 sun and 3 ring meshes (flank wear)
    plain = _plain(life_scan)
    step = float(life.operating_time) / 2
    for k in range(2):
        worn = worn_scene(tx.with_design(life_scan, VALUES), {"azimuth": jnp.asarray(d[k])})
        res = startup[1] if k == 0 else _simulate(plain, worn)  # at k = 0 nothing has worn: the start-up itself
        over_run, window_rates = _wear(worn, res, life)
        rate = np.array([float(over_run["azimuth"][c]) for c in wear_names(worn.azimuth.stage, wear)]) / HORIZON
        np.testing.assert_allclose(d[k + 1], d[k] + step * rate, rtol=1e-9, atol=1e-15)
        np.testing.assert_allclose(np.asarray(window_rates["azimuth"]), rate, rtol=1e-12)
        rms = float(pointing_metrics(res, np.asarray(res.ts) >= 0.0, 8)["pointing_rms"])
        assert float(outputs["pointing_rms"][k]) == pytest.approx(rms, rel=1e-9)
    assert np.all(d[1, 2:] > 0.0) and np.all(d[2] >= d[1])  # the pins and the flanks wore; nothing unwears
    both = _call(pointing, VALUES)
    assert float(both["pointing_rms_eol"]) == float(outputs["pointing_rms"][2]) and bool(both["success"])
    assert float(both["pointing_rms"]) == float(outputs["pointing_rms"][0])
    assert float(both["pointing_rms_eol"]) > 1.05 * float(both["pointing_rms"])  # 2.5 years of start-ups: the pins grew
    assert set(pointing.outputs) == {*plain.outputs, *(f"{o}_eol" for o in plain.outputs)}
    assert pointing.units["pointing_rms_eol"] == "arcsec"
    idle = _objective(life_scan, MissionLife(1e9, ArchardWear(0.0), points=2, spread=SPREAD), rtol=RTOL, atol=ATOL)
    still = _call(idle, VALUES)
    assert float(still["pointing_rms_eol"]) == float(still["pointing_rms"])


def test_wear_over_run_real_run(startup):
    """The start-up's run (`wear_over_run`, from tests/test_wear.py to share the run): finite,
    non-negative depths, the same as an independent trapezoid over the run's own states and
    forces (the journals: $k \\max(F, 0)|\\omega_{rel}|/(2L)$, the relative speeds read from the
    state's columns); a contact whose force is zero or negative at every save wears nothing
    (here every contact carries load, so two columns are set to 0 and -1 N); with a load on
    every contact every depth is positive."""
    scene, result = startup
    model = ArchardWear.from_lubricant(MOS2)
    stage = scene.azimuth.stage

    def depths(forces):
        out = _wear(scene, eqx.tree_at(lambda r: r.azimuth_contact, result, forces), MissionLife(1.0, model, spread=SPREAD))[0]
        assert list(out) == ["azimuth"]  # the pitch joint is ideal
        return np.array([out["azimuth"][c] for c in stage.contact_names])

    def independent(forces):
        u = np.asarray(result.states[1])[:, scene.layout.azimuth_u]
        omega = np.abs(np.stack([u[:, 0], u[:, 1], *(u[:, 2 + n] - u[:, 1] for n in range(3))], axis=1))
        rate = model.rate * np.maximum(forces, 0) * omega / (2 * 8e-3)
        return np.trapezoid(rate, np.asarray(result.ts), axis=0)

    forces = np.asarray(result.azimuth_contact)
    depth = depths(result.azimuth_contact)
    assert np.all(np.isfinite(depth)) and np.all(depth >= 0.0)
    np.testing.assert_allclose(depth, independent(forces), rtol=1e-12, atol=0)
    unloaded = forces.copy()
    unloaded[:, 1], unloaded[:, 3] = 0.0, -1.0  # no carrier force; a negative pin force (never produced) counts as none
    depth = depths(jnp.asarray(unloaded))
    assert depth[1] == 0.0 and depth[3] == 0.0 and np.all(depth[[0, 2, 4]] > 0.0)
    np.testing.assert_allclose(depth, independent(unloaded), rtol=1e-12, atol=0)
    loaded = jnp.full_like(result.azimuth_contact, 5.0)
    depth = depths(loaded)
    assert np.all(depth > 0.0)
    np.testing.assert_allclose(depth, independent(np.asarray(loaded)), rtol=1e-12)


_rates_jvp = eqx.filter_jit(lambda f, x, dx: jax.jvp(f, (x,), (dx,)))


def test_window_wear_rates_derivative_on_one_trajectory(life_scan, startup):
    """The window's wear rates (`window_wear_rates`: the journals and the flanks, what the life's
    growth differentiates through) as a function of one saved trajectory (the start-up's states,
    contact forces) and of the design (the backlash enters the flanks' tooth forces), along one
    random direction: the forward-mode derivative against central differences.

    The rates sum $|\\omega_{rel}|$, $|w_a - w_b|$, $|F|$ and $\\max(F, 0)$ over the saves, which
    have a kink where a saved value crosses zero: in the start-up the pins' and meshes' relative
    speeds change sign many times, some within 1e-4 of their peak at a save (through a solve
    their differences converge only as O(h): test_end_of_life_gradient_against_finite_differences).
    With the trajectory fixed the steps can be 1e-7 of each quantity's own scale, far from every
    kink (the contact forces move in proportion to themselves and keep their sign; save 0, the
    rest start, is not moved), and the differences are exact to rounding (~1e-9): at two steps
    10x apart they agree to 1e-7, which shows no kink was crossed, and the derivative is within
    1e-6 of them (measured 1e-9). A rate that loses its dependence on the states, forces or
    backlash (a `stop_gradient`) fails here."""
    scene, result = startup
    life = MissionLife(1.0, ArchardWear.from_lubricant(MOS2))
    window = np.ones(N_SAVE, dtype=bool)
    lay = scene.layout
    cols = (lay.azimuth_q, lay.azimuth_u, lay.azimuth_v)

    def rates(x):
        *states, forces, design = x
        full = tuple(s.at[:, c].set(x_) for s, c, x_ in zip(result.states, cols, states))
        run = eqx.tree_at(lambda r: (r.states, r.azimuth_contact), result, (full, forces))
        worn = worn_scene(tx.with_design(life_scan, design), {"azimuth": jnp.zeros(N_WORN)})
        return window_wear_rates(worn, run, window, life)["azimuth"]

    x = (*(s[:, c] for s, c in zip(result.states, cols)), result.azimuth_contact, VALUES)
    keys = jax.random.split(jax.random.key(0), len(x))
    # Each array's perturbation on its own scale (per column: angles, translations, speeds), the
    # contact forces in proportion to themselves (one that is 0, an open contact, stays 0).
    # Save 0 is the rest start, the same for every design: not perturbed (its speeds are exactly
    # 0, where the derivative of |x| that JAX takes is one-sided and a central difference is not).
    dx = tuple(jax.random.normal(k, a.shape) * (jnp.abs(a) if i == 3 else jnp.max(jnp.abs(a), axis=0))
               for i, (k, a) in enumerate(zip(keys, x)))
    dx = (*(d.at[0].set(0.0) for d in dx[:3]), *dx[3:])
    rates0, ad = _rates_jvp(rates, x, dx)
    assert rates0.shape == (N_WORN,) and np.all(np.asarray(rates0)[2:] > 0.0)  # the pins and the flanks wear

    def central(h):
        plus = _rates_jvp(rates, jax.tree.map(lambda a, b: a + h * b, x, dx), dx)[0]
        minus = _rates_jvp(rates, jax.tree.map(lambda a, b: a - h * b, x, dx), dx)[0]
        return np.asarray((plus - minus) / (2 * h))

    fd, fd_small = central(1e-7), central(1e-8)
    print("AD", ad, "differences", fd, fd_small, sep="\n")
    np.testing.assert_allclose(fd_small, fd, rtol=1e-7, atol=1e-7 * np.max(np.abs(fd)))
    np.testing.assert_allclose(ad, fd, rtol=1e-6, atol=1e-6 * np.max(np.abs(fd)))


def test_end_of_life_directional_derivative(life_scan, startup):
    """The forward-mode derivative of the end-of-life RMS pointing error along one random
    direction of the five as-built features, through the growth (the wear rates' own dependence
    on the clearances included, two Euler points), against a central difference at 5 nm, over
    the first 10 ms of the start-up (a forward-mode life costs three solves with tangents:
    half the horizon, half the cost).

    Where the comparison means something: only the sun journal wears (MoS2's rate on it, the
    others at 0 and no flank wear, 5 years). The sun turns one way through the whole start-up
    (asserted below on the as-built run), so its sliding speed summed over the saves has no kink
    and the response is smooth at the steps' scale. The tolerance 1e-3 (the slow variant's): the
    forward-mode derivative is that of the adaptive solve's discretisation at rtol 1e-8, which
    differs from the response's by up to 1.5e-4 (measured over 20 ms, where the differences at
    20, 10, 5 and 2.5 nm agree to 5e-5; at rtol 1e-10 derivative and differences agree to
    1.3e-6); over these 10 ms it is within 7e-5. The growth's share of the derivative (end of
    life against beginning of life) is 23 %, asserted above 5 %: a wrong derivative of the rates
    or of the worn scene fails here.

    The pins and the flanks, whose speeds cross zero at saves (their differences through a solve
    converge only as O(h)), are checked where that does not matter: their rates' derivative on one
    trajectory (test_window_wear_rates_derivative_on_one_trajectory); their end-of-life gradients
    per feature in the slow variants test_end_of_life_gradient_against_finite_differences and
    tests/test_life_flanks.py::test_flank_wear_gradient, which this test stands for by default."""
    scene, result = startup
    sun = np.asarray(result.states[1])[1:, scene.layout.azimuth_u][:, scene.azimuth.stage.layout.sun_theta]
    assert np.all(sun > 0.0) or np.all(sun < 0.0)
    k = ArchardWear.from_lubricant(MOS2).rate
    life = _life(5.0, ArchardWear(jnp.array([k, 0.0, 0.0, 0.0, 0.0]), flanks=False))
    forward = tx.PointingObjective(life_scan, duration=HORIZON / 2, settle=0.0, start="rest", n_save=(N_SAVE + 1) // 2,
                                   integrator=tx.Integrator(rtol=RTOL, atol=ATOL, max_steps=400_000), life=life, adjoint=diffrax.ForwardMode())
    direction = jax.random.normal(jax.random.key(1), (5,))
    direction = direction / jnp.linalg.norm(direction)
    out, tangent = _directional(forward, VALUES, direction)
    assert bool(out["success"])
    h = 5e-9
    plus, minus = (float(_directional(forward, VALUES + s * h * direction, direction)[0]["pointing_rms_eol"]) for s in (1, -1))
    fd, ad = (plus - minus) / (2 * h), float(tangent["pointing_rms_eol"])
    print("AD", ad, "difference", fd, "beginning of life", float(tangent["pointing_rms"]))
    assert abs(ad - float(tangent["pointing_rms"])) > 5e-2 * abs(ad)  # the growth's part of the derivative
    assert abs(ad - fd) < 1e-3 * abs(fd)


@pytest.mark.slow
def test_end_of_life_gradient_against_finite_differences(life_scan):
    """Slow: enlarges test_end_of_life_directional_derivative (one direction, the sun journal) to
    every feature, every journal wearing and four steps. The forward-mode gradient of the end-of-life RMS pointing error with respect to the
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
    same life with the rates doubled (given 5 values, i.e. at factor 1). Monte Carlo draws the
    factor with the zones (`spread_tolerances`, joined to them): inside [ln low, ln high], one
    more named input."""
    wear = ArchardWear.from_lubricant(MOS2)
    spread = spread_of_lubricant(MOS2)
    assert spread == pytest.approx((0.25, 2.5), rel=1e-12)  # 1e-6 and 1e-5 against the median 4e-6 mm^3/(N m)
    life = MissionLife.from_years(0.5, wear=wear, points=2, spread=spread)
    pointing = _objective(life_scan, life, rtol=RTOL, atol=ATOL)
    assert pointing.uncertain_inputs == (WEAR_FACTOR,)
    # The doubled rates with 5 values: at factor 1, so this is also the check that a unit without
    # the factor is at the median rate (with the spread, the module's one 5-value program).
    doubled = _objective(life_scan, _life(0.5, ArchardWear(2 * float(wear.rate))), rtol=RTOL, atol=ATOL)
    values = VALUES
    got, want, median = _call(pointing, jnp.append(values, np.log(2.0))), _call(doubled, values), _call(pointing, values)
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
