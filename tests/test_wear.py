"""Archard wear of the stage's clearances and tooth flanks (`tolerax.physics.wear`): the closed
forms, the sliding speeds against rigid rolling, integration over a run, and refused input. The
wear over a real run and the rates' derivative on one saved trajectory are in tests/test_life.py,
beside the life tests' start-up run (one solve compiled for both)."""

import types

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax import planetary as P
from tolerax.mechanism.joints import planet_spin_ratio
from tolerax.physics import wear as W


def rigid_rolling_speeds(stage, omega_c):
    """Stage speeds of the rigid train on the fixed ring: sun at i * omega_c, planets at the
    rigid-rolling spin, no translation."""
    lay = stage.layout
    u = jnp.zeros(lay.size).at[lay.carrier_theta].set(omega_c).at[lay.sun_theta].set(stage.ratio * omega_c)
    return u.at[lay.planet_theta].set(planet_spin_ratio(stage) * omega_c)


def test_contact_names_and_relative_rotations():
    stage = tx.default_stage()
    assert stage.contact_names == ("sun", "carrier", "planet0", "planet1", "planet2")
    lay = stage.layout
    u = jnp.arange(1.0, lay.size + 1.0)  # theta_s' = 1, theta_c' = 2, theta_p' = 3, 4, 5
    np.testing.assert_allclose(W.relative_angular_velocities(stage, None, u), [1.0, 2.0, 1.0, 2.0, 3.0], rtol=0, atol=0)
    # Rigid planet pins: only the sun and carrier contacts remain, in that order.
    no_pins = tx.default_stage(planet_support="rigid")
    assert no_pins.contact_names == ("sun", "carrier")
    assert W.sliding_speeds(no_pins, None, jnp.ones(no_pins.layout.size)).shape == (2,)


@pytest.mark.parametrize("omega_c", [0.05, -0.3])
def test_sliding_speeds_rigid_rolling(omega_c):
    """Closed form of the rigid train with the ring fixed: the sun turns at (1 + z_r/z_s) omega_c
    in the housing, the carrier at omega_c, each planet at -(z_r/z_p) omega_c on its pin."""
    stage = tx.default_stage()
    u = rigid_rolling_speeds(stage, omega_c)
    q = jnp.zeros(stage.layout.size)
    # The speeds are rigid rolling of the code's own model: both meshes' deflection rates vanish.
    rates = jax.jvp(lambda q_: P.deflections(stage, q_), (q,), (u,))[1]
    np.testing.assert_allclose(rates["sun_drive"], 0.0, atol=1e-15)
    np.testing.assert_allclose(rates["ring_drive"], 0.0, atol=1e-15)
    zs, zp, zr = stage.sun_teeth, stage.planet_teeth, stage.ring_teeth
    expected = np.abs(omega_c) * np.array([5e-3 * (1 + zr / zs), 15e-3, 4e-3 * zr / zp, 4e-3 * zr / zp, 4e-3 * zr / zp])
    np.testing.assert_allclose(W.sliding_speeds(stage, q, u), expected, rtol=1e-13)
    # Batched speeds: leading axes kept.
    both = jnp.stack([u, 2 * u])
    np.testing.assert_allclose(W.sliding_speeds(stage, jnp.zeros_like(both), both), np.stack([expected, 2 * expected]), rtol=1e-13)


def test_archard_closed_form():
    """Constant load F at constant relative speed omega over t: h = k F/(2 R L) * omega R * t."""
    stage = tx.default_stage()
    k, force, t, omega_c = 3e-15, 12.5, 7.0, 0.2
    u = rigid_rolling_speeds(stage, omega_c)
    q = jnp.zeros(stage.layout.size)
    model = W.ArchardWear(k, flanks=False)
    depth = W.wear_depth_rates(stage, q, u, jnp.full(5, force), model) * t
    zs, zp, zr = stage.sun_teeth, stage.planet_teeth, stage.ring_teeth
    radius = np.array([5e-3, 15e-3, 4e-3, 4e-3, 4e-3])
    omega = omega_c * np.array([1 + zr / zs, 1.0, zr / zp, zr / zp, zr / zp])
    length = 8e-3
    expected = k * force / (2 * radius * length) * omega * radius * t
    np.testing.assert_allclose(depth, expected, rtol=1e-12)
    # Per-contact rates and lengths, and a force of zero (or the never-produced negative) wears nothing.
    rates, lengths = jnp.array([1.0, 2.0, 3.0, 4.0, 5.0]) * 1e-15, jnp.array([4.0, 5.0, 6.0, 7.0, 8.0]) * 1e-3
    forces = jnp.array([force, 0.0, force, -1.0, force])
    got = W.wear_depth_rates(stage, q, u, forces, W.ArchardWear(rates, lengths, flanks=False)) * t
    want = np.asarray(rates) * np.maximum(np.asarray(forces), 0) / (2 * np.asarray(lengths)) * omega * t
    np.testing.assert_allclose(got, want, rtol=1e-12)
    assert got[1] == 0.0 and got[3] == 0.0


def _fake_run(stage, ts, q, u, forces, name="azimuth"):
    """The fields `wear_over_run` reads, for a mechanism whose azimuth joint is the full stage."""
    mech = tx.Mechanism(azimuth=tx.PlanetaryJoint(stage), pitch=tx.IdealJoint(), base="fixed")
    result = types.SimpleNamespace(ts=ts, states=(q, u, None), azimuth_contact=forces, azimuth_contact_names=stage.contact_names,
                                   pitch_contact=jnp.zeros((ts.shape[0], 0)), pitch_contact_names=())
    return mech, result


def test_wear_over_run_constant_series():
    """The trapezoid over a constant series is exact, on uneven saves too."""
    stage = tx.default_stage()
    k, force, omega_c = 2e-15, 30.0, 0.1
    ts = jnp.array([0.0, 0.1, 0.15, 0.4, 1.0, 1.3])
    u = jnp.tile(rigid_rolling_speeds(stage, omega_c), (ts.shape[0], 1))
    q = jnp.cumsum(u, axis=0)  # any configuration: the speeds carry the wear
    mech, result = _fake_run(stage, ts, q, u, jnp.full((ts.shape[0], 5), force))
    out = W.wear_over_run(mech, result, W.ArchardWear(k, flanks=False))
    assert list(out) == ["azimuth"] and tuple(out["azimuth"]) == stage.contact_names
    zs, zp, zr = stage.sun_teeth, stage.planet_teeth, stage.ring_teeth
    omega = omega_c * np.array([1 + zr / zs, 1.0, zr / zp, zr / zp, zr / zp])
    radius = np.array([5e-3, 15e-3, 4e-3, 4e-3, 4e-3])
    expected = k * force / (2 * radius * 8e-3) * omega * radius * 1.3
    np.testing.assert_allclose([out["azimuth"][c] for c in stage.contact_names], expected, rtol=1e-12)
    # A dict of models: only the joints named are computed.
    assert W.wear_over_run(mech, result, {"pitch": W.ArchardWear(k)}) == {}


# The stage's tooth forces and the flank rates, compiled once each (op by op they cost ~15 s of
# small compiles: the rates vmap the whole force law).
_stage_forces = eqx.filter_jit(P.stage_forces)
_flank_rates = eqx.filter_jit(W.flank_backlash_rates)


def test_flank_wear_closed_form():
    """Tooth flanks (`flank_backlash_rates`, the module docstring): at rigid rolling with the
    meshes loaded (the sun and the planets turned through the backlash), each tooth of gear g thins at
    k |F| |w_a - w_b| / (4 z_g b) per mesh it works in, with the rolling speeds' differences in
    closed form from the tooth counts: sun-planet w_c (z_r/z_s + z_r/z_p), ring-planet
    w_c (1 - z_r/z_p); each planet's sun-mesh backlash opens at t_sun + t_planet, its ring mesh's
    at t_ring + t_planet. Over a run of constant states the trapezoid gives rate x time, and the
    worn scene carries the grown backlash per planet."""
    stage = tx.default_stage()
    omega_c, k, b = 0.2, 3e-15, 10e-3
    zs, zp, zr, n = stage.sun_teeth, stage.planet_teeth, stage.ring_teeth, stage.n_planets
    lay = stage.layout
    u = rigid_rolling_speeds(stage, omega_c)
    q = jnp.zeros(lay.size).at[lay.sun_theta].set(0.03).at[lay.planet_theta].set(0.02)  # both meshes past their backlash
    v = jnp.zeros(len(stage.contact_names))
    forces = _stage_forces(stage, q, u, v)
    f_s, f_r = np.abs(np.asarray(forces.sun_mesh)), np.abs(np.asarray(forces.ring_mesh))
    assert np.all(f_s > 1.0) and np.all(f_r > 1.0)
    vol_s = k * f_s * abs(omega_c) * (zr / zs + zr / zp) / 4
    vol_r = k * f_r * abs(omega_c * (1 - zr / zp)) / 4
    t_sun, t_ring, t_planet = vol_s.sum() / (zs * b), vol_r.sum() / (zr * b), (vol_s + vol_r) / (zp * b)
    want = np.concatenate([t_sun + t_planet, t_ring + t_planet])
    model = W.ArchardWear(k)
    np.testing.assert_allclose(_flank_rates(stage, q, u, v, model), want, rtol=1e-12)
    # Batched leading axes kept; another face width and flank rate scale as 1/b and k.
    both = _flank_rates(stage, jnp.stack([q, q]), jnp.stack([u, u]), jnp.stack([v, v]),
                        W.ArchardWear(k, flank_rate=2 * k, face_width=2 * b))
    np.testing.assert_allclose(both, np.stack([want, want]), rtol=1e-12)
    assert W.wear_names(stage, model) == stage.contact_names + tuple(f"{m}_mesh{i}" for m in ("sun", "ring") for i in range(n))
    assert W.flank_names(stage, W.ArchardWear(k, flanks=False)) == ()
    assert W.flank_names(tx.default_stage(mesh="linear"), model) == ()
    # Over a run: constant states for 1.3 s.
    ts = jnp.array([0.0, 0.1, 0.15, 0.4, 1.0, 1.3])
    tile = lambda x: jnp.tile(x, (ts.shape[0], 1))  # noqa: E731
    mech = tx.Mechanism(azimuth=tx.PlanetaryJoint(stage), pitch=tx.IdealJoint(), base="fixed")
    result = types.SimpleNamespace(ts=ts, states=(tile(q), tile(u), tile(v)), azimuth_contact=jnp.zeros((ts.shape[0], 5)),
                                   azimuth_contact_names=stage.contact_names, pitch_contact=jnp.zeros((ts.shape[0], 0)),
                                   pitch_contact_names=())
    out = W.wear_over_run(mech, result, model)["azimuth"]  # eager: the entries' order is wear_names' (a compiled call sorts them)
    assert tuple(out) == W.wear_names(stage, model)
    np.testing.assert_allclose([out[f"{m}_mesh{i}"] for m in ("sun", "ring") for i in range(n)], want * 1.3, rtol=1e-12)
    # The worn scene: clearances and each planet's backlash grown.
    from tolerax.design.life import worn_scene

    growth = jnp.concatenate([jnp.arange(1.0, 6.0), jnp.arange(6.0, 12.0)]) * 1e-6
    worn = worn_scene(mech, {"azimuth": growth}).azimuth.stage
    np.testing.assert_allclose(worn.sun_mesh.backlash, stage.sun_mesh.backlash + np.array([6.0, 7.0, 8.0]) * 1e-6, rtol=1e-14)
    np.testing.assert_allclose(worn.ring_mesh.backlash, stage.ring_mesh.backlash + np.array([9.0, 10.0, 11.0]) * 1e-6, rtol=1e-14)
    np.testing.assert_allclose(worn.planet_support.bearing.clearance, stage.planet_support.bearing.clearance + np.array([3.0, 4.0, 5.0]) * 1e-6,
                               rtol=1e-14)
    with pytest.raises(ValueError, match=r"azimuth has 7 growths; its stage wears 5 contacts"):
        worn_scene(mech, {"azimuth": jnp.zeros(7)})


def test_lubricant_table():
    for name, lub in W.LUBRICANTS.items():
        assert 0.0 < lub.low <= lub.median <= lub.high < 1e-12, name  # m^3/(N m): tables give mm^3/(N m) x 1e-9
        assert lub.source
    model = W.ArchardWear.from_lubricant("PFPE grease (Braycote-type), vacuum", "high", length=5e-3)
    assert float(model.rate) == W.LUBRICANTS["PFPE grease (Braycote-type), vacuum"].high
    assert float(model.length) == 5e-3


def test_bad_input_refused():
    stage = tx.default_stage()
    q = u = jnp.zeros(stage.layout.size)
    with pytest.raises(ValueError, match=r"ArchardWear.rate must be finite and >= 0"):
        W.ArchardWear(-1e-15)
    with pytest.raises(ValueError, match=r"ArchardWear.length must be finite and > 0"):
        W.ArchardWear(1e-15, length=-8e-3)
    with pytest.raises(ValueError, match=r"ArchardWear.length must be finite and > 0"):
        W.ArchardWear(1e-15, length=jnp.array([8e-3, 0.0, 8e-3, 8e-3, 8e-3]))
    with pytest.raises(TypeError, match=r"ArchardWear.rate must be a real number"):
        W.ArchardWear("MoS2")
    with pytest.raises(ValueError, match=r"Unknown lubricant 'grease'; known: \["):
        W.ArchardWear.from_lubricant("grease")
    with pytest.raises(ValueError, match=r"estimate='mean' is unknown"):
        W.ArchardWear.from_lubricant("MoS2 sputtered film, vacuum", "mean")
    with pytest.raises(ValueError, match=r"rate has 3 values for the stage's 5 contacts"):
        W.wear_depth_rates(stage, q, u, jnp.zeros(5), W.ArchardWear(jnp.ones(3) * 1e-15, flanks=False))
    with pytest.raises(ValueError, match=r"with one rate per contact, give the flanks' own flank_rate"):
        W.ArchardWear(jnp.ones(5) * 1e-15)
    with pytest.raises(ValueError, match=r"ArchardWear.face_width must be finite and > 0"):
        W.ArchardWear(1e-15, face_width=0.0)
    with pytest.raises(ValueError, match=r"forces must end in one column per contact, 5"):
        W.wear_depth_rates(stage, q, u, jnp.zeros(4), W.ArchardWear(1e-15))
    with pytest.raises(ValueError, match=r"Lubricant rates must satisfy low <= median <= high"):
        W.Lubricant(median=1e-15, low=2e-15, high=3e-15, source="x")
    ts = jnp.array([0.0, 0.1, jnp.inf])
    mech, result = _fake_run(stage, ts, jnp.zeros((3, stage.layout.size)), jnp.zeros((3, stage.layout.size)), jnp.zeros((3, 5)))
    with pytest.raises(ValueError, match=r"non-finite save times"):
        W.wear_over_run(mech, result, W.ArchardWear(1e-15, flanks=False))
