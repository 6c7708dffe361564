"""Bad input gets a clear error before anything is traced or run (issue 5): the message names the
field, the value and what is allowed; a rejected input leaves nothing changed."""

import math

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx


NAN, INF = float("nan"), float("inf")
N_SAVE = 51  # the bench's save grid in test_bench.py and test_hard_cases.py too: one program

# (constructor, kwargs, exception, fragments the message must contain)
BAD = [
    (tx.default_stage, dict(planet_clearance=-1e-6), ValueError, ["planet_clearance", "-1e-06", ">= 0"]),
    (tx.default_stage, dict(sun_clearance=NAN), ValueError, ["sun_clearance", "nan", "finite"]),
    (tx.default_stage, dict(carrier_clearance=INF), ValueError, ["carrier_clearance", "inf", "finite"]),
    (tx.default_stage, dict(carrier_clearance=20e-3), ValueError, ["carrier_clearance", "carrier_journal_radius"]),
    (tx.default_stage, dict(backlash=-1e-5), ValueError, ["backlash", ">= 0"]),
    (tx.default_stage, dict(module=0.0), ValueError, ["module", "[5e-05, 0.05]", "ISO 54"]),
    (tx.default_stage, dict(module=1e9), ValueError, ["module", "[5e-05, 0.05]"]),
    (tx.default_stage, dict(backlash=2e-3), ValueError, ["backlash", "below the module", "0.001"]),
    (tx.default_stage, dict(density=7.85), ValueError, ["density", "[500, 25000]", "polymers"]),
    (tx.default_stage, dict(young=206.0), ValueError, ["young", "[5e+08, 1e+12]"]),
    (tx.default_stage, dict(face_width=-1e-3), ValueError, ["face_width", "> 0"]),
    (tx.default_stage, dict(pressure_angle=math.radians(95)), ValueError, ["pressure_angle", "(0, 1.5708)"]),
    (tx.default_stage, dict(contact_ratio=2.5), ValueError, ["contact_ratio", "[1, 2)"]),
    (tx.default_stage, dict(restitution=0.0), ValueError, ["restitution", "(0, 1]"]),
    (tx.default_stage, dict(smoothing_width=-1e-9), ValueError, ["smoothing_width", ">= 0"]),
    (tx.default_stage, dict(impact_memory_time=0.0), ValueError, ["impact_memory_time", "> 0"]),
    (tx.default_stage, dict(ring_teeth=81), ValueError, ["ring_teeth=81", "sun_teeth + 2*planet_teeth = 80"]),
    (tx.default_stage, dict(n_planets=5), ValueError, ["5 planets do not fit", "tip diameter"]),
    (tx.default_stage, dict(sun_teeth=20.0), ValueError, ["sun_teeth", "positive integer", "20.0"]),
    (tx.default_stage, dict(n_planets=0), ValueError, ["n_planets", "positive integer"]),
    (tx.default_stage, dict(planet_spacing="assembled"), ValueError, ["cannot be equally spaced", "33.33"]),
    (tx.default_stage, dict(planet_spacing="random"), ValueError, ["planet_spacing='random'", "unknown"]),
    (tx.default_stage, dict(sun_support="loose"), ValueError, ["sun_support='loose'", "unknown"]),
    (tx.default_stage, dict(mesh="cubic"), ValueError, ["mesh='cubic'", "unknown"]),
    (tx.default_stage, dict(backlash="100um"), TypeError, ["backlash", "'100um'", "real number"]),
    (tx.default_stage, dict(planet_clearance=1e-4 + 0j), TypeError, ["planet_clearance", "complex"]),
    (tx.default_stage, dict(backlash=np.zeros(4)), ValueError, ["Mesh.backlash", "(3,)", "(4,)"]),
    (tx.JournalBearing, dict(journal_radius=5e-3, clearance=6e-3), ValueError, ["clearance", "journal_radius"]),
    (tx.JournalBearing, dict(journal_radius=-5e-3, clearance=1e-5), ValueError, ["journal_radius", "> 0"]),
    (tx.JournalBearing, dict(journal_radius=5e-3, clearance=None), TypeError, ["clearance", "None"]),
    (tx.Mesh, dict(stiffness=-1e8), ValueError, ["Mesh.stiffness", "> 0"]),
    (tx.Mesh, dict(backlash=[1e-5, 2e-5]), ValueError, ["Mesh.backlash", "(3,)", "(2,)"]),
    (tx.Mesh, dict(kind="soft"), ValueError, ["'soft'", "unknown"]),
    (tx.Support, dict(kind="spring", stiffness=-1.0), ValueError, ["Support.stiffness", ">= 0"]),
    (tx.Support, dict(kind="clearance"), ValueError, ["JournalBearing"]),
    (tx.BaiZhao, dict(restitution=1.5), ValueError, ["BaiZhao.restitution", "(0, 1]", "1.5"]),
    (tx.Flores, dict(restitution=True), TypeError, ["Flores.restitution", "bool"]),
    (tx.AdamsImpact, dict(exponent=0.5), ValueError, ["AdamsImpact.exponent", ">= 1"]),
    (tx.AdamsImpact, dict(stiffness=NAN), ValueError, ["AdamsImpact.stiffness", "nan"]),
    (tx.SpeedServo, dict(output_rate=INF), ValueError, ["SpeedServo.output_rate", "finite"]),
    (tx.SpeedServo, dict(proportional=-0.2), ValueError, ["SpeedServo.proportional", ">= 0"]),
    (tx.TorqueDrive, dict(amplitude=1.5, frequency=-1.0), ValueError, ["TorqueDrive.frequency", ">= 0"]),
    (tx.TestBench, dict(load_mass=-8.0), ValueError, ["TestBench.load_mass", ">= 0"]),
    (tx.TestBench, dict(stage="default"), TypeError, ["TestBench.stage", "PlanetaryStage"]),
    (tx.LumpedJoint, dict(motor_inertia=0.0), ValueError, ["LumpedJoint.motor_inertia", "> 0"]),
    (tx.antenna, dict(fidelity="exact"), ValueError, ["fidelity='exact'", "unknown"]),
    (tx.PlanetaryJoint, dict(drive=1.5), TypeError, ["drive", "SpeedServo"]),
    (tx.ScanServo, dict(period=0.0), ValueError, ["ScanServo.period", "> 0"]),
    (tx.Geometry, dict(link1_centre=(0.0, 0.3)), ValueError, ["Geometry.link1_centre", "(3,)", "(2,)"]),
    (tx.Geometry, dict(reflector_centre=(0.0, NAN, 0.0)), ValueError, ["Geometry.reflector_centre", "nan"]),
    (tx.Inertias, dict(base_mass=-1500.0), ValueError, ["Inertias.base_mass", "> 0"]),
    (tx.Inertias, dict(reflector_inertia=(1.0, 1.0)), ValueError, ["Inertias.reflector_inertia", "(3,)"]),
    (tx.Mechanism, dict(base="tethered"), ValueError, ["base='tethered'", "unknown"]),
    (tx.Mechanism, dict(azimuth="planetary"), TypeError, ["Mechanism.azimuth", "Joint"]),
    (tx.antenna, dict(mode="roll"), ValueError, ["mode='roll'", "unknown"]),
    (tx.antenna, dict(drive="current"), ValueError, ["drive='current'", "unknown"]),
    (tx.antenna, dict(fidelity=("lumped",)), ValueError, ["fidelity", "pair"]),
    (tx.antenna, dict(torques=(1.5, 0.8, 0.1)), ValueError, ["torques", "pair"]),
    (tx.antenna, dict(rate=NAN), ValueError, ["SpeedServo.output_rate", "nan"]),
]


@pytest.mark.parametrize("make, kwargs, exc, fragments", BAD, ids=[f"{m.__name__}-{list(k)[0]}" for m, k, _, _ in BAD])
def test_bad_input_is_rejected_with_a_clear_message(make, kwargs, exc, fragments):
    with pytest.raises(exc) as info:
        make(**kwargs)
    message = str(info.value)
    for fragment in fragments:
        assert fragment in message, (fragment, message)


def test_good_edge_values_are_accepted():
    # The edges of the allowed ranges are legal: zero clearance and backlash, exact smoothing,
    # restitution 1, zero damping, the tightest fit of 4 planets, an assemblable equal spacing.
    tx.default_stage(sun_clearance=0.0, carrier_clearance=0.0, planet_clearance=0.0, backlash=0.0)
    tx.default_stage(smoothing_width=0.0, restitution=1.0, mesh_damping_ratio=0.0, contact_ratio=1.0)
    tx.default_stage(n_planets=4)  # centres 35.4 mm apart, tips 32 mm across
    tx.default_stage(sun_teeth=22, planet_teeth=29, ring_teeth=80, n_planets=3, planet_spacing="assembled")
    tx.default_stage(planet_clearance=np.full(3, 50e-6))  # one clearance per planet pin


def _leaves(tree):
    return [np.asarray(x).copy() for x in jax.tree.leaves(eqx.filter(tree, eqx.is_array))]


def test_rejected_input_changes_nothing():
    # Modules are immutable; a rejected construction or run must not change what the user has.
    stage = tx.default_stage()
    bench = tx.TestBench(stage)
    before = _leaves(bench)
    with pytest.raises(ValueError):
        tx.TestBench(stage, load_mass=-1.0)
    with pytest.raises(ValueError):
        tx.default_stage(planet_clearance=-1e-6)
    with pytest.raises(ValueError):
        tx.simulate(bench, -1.0)
    after = _leaves(bench)
    assert all(np.array_equal(a, b) for a, b in zip(before, after))
    assert float(bench.stage.planet_support.bearing.clearance) == 100e-6


def test_values_set_with_tree_at_are_checked_before_running():
    # eqx.tree_at bypasses constructors; simulate checks the scene again, before
    # tracing anything.
    bench = tx.TestBench()
    bad = eqx.tree_at(lambda b: b.stage.planet_support.bearing.clearance, bench, jnp.asarray(-1e-6))
    with pytest.raises(ValueError, match=r"JournalBearing.clearance must be finite and >= 0 \(m\), got -1e-06"):
        tx.simulate(bad, 1e-3)
    mech = tx.antenna("azimuth", fidelity="ideal")
    bad = eqx.tree_at(lambda m: m.inertias.reflector_mass, mech, jnp.asarray(NAN))
    with pytest.raises(ValueError, match="Inertias.reflector_mass"):
        tx.simulate(bad, 1e-3)


def test_run_arguments_are_checked():
    bench = tx.TestBench()
    q, qd, v = bench.initial_state()
    with pytest.raises(ValueError, match=r"y0\[0\] must have shape \(15,\)"):
        tx.simulate(bench, 1e-3, y0=(q[:-1], qd, v))
    with pytest.raises(ValueError, match="structure"):
        tx.simulate(bench, 1e-3, y0=(q, qd))
    with pytest.raises(ValueError, match="solver 'rk45' is unknown"):
        tx.simulate(bench, 1e-3, integrator=tx.Integrator(solver="rk45"))
    with pytest.raises(TypeError, match="diffrax solver"):
        tx.simulate(bench, 1e-3, integrator=tx.Integrator(solver=object()))
    # A stage is not a scene: it needs a bench or a mechanism around it.
    with pytest.raises(TypeError, match="TestBench or a Mechanism"):
        tx.simulate(tx.default_stage(), 1e-3)
    for name, value in (("rtol", -1e-6), ("atol", NAN), ("dtmax", 0.0), ("dtmin", INF)):
        with pytest.raises(ValueError, match=name):
            tx.simulate(bench, 1e-3, integrator=tx.Integrator(**{name: value}))
    with pytest.raises(ValueError, match="dtmin < dt0 <= dtmax"):
        tx.simulate(bench, 1e-3, integrator=tx.Integrator(dt0=1e-2))


def test_step_size_collapse_is_reported():
    # From rest the servo closes the backlash and the planets land on their pins at ~0.23 s; the
    # first impact needs steps below 4 us. With dtmin = 4 us the run must end there with
    # dt_min_reached and the time it reached, not a silently coarse result.
    # N_SAVE saves (every 5 ms): the bench's one forward program, shared with test_bench.py and
    # test_hard_cases.py (dtmin and dt0 are values in it).
    bench = tx.TestBench()
    res = tx.simulate(bench, 0.25, n_save=N_SAVE, throw=False, integrator=tx.Integrator(dt0=2e-5, dtmin=4e-6))
    assert not res.success
    assert res.result == diffrax.RESULTS.dt_min_reached
    t = float(res.t_reached)
    # Independently: the same run with the default dtmin succeeds, and its first saved contact
    # force comes within one save interval (5 ms) after t.
    ref = tx.simulate(bench, 0.25, n_save=N_SAVE, throw=False, integrator=tx.Integrator(dt0=2e-5))
    assert ref.success
    touching = np.asarray(ref.ts)[np.asarray(ref.contact_force).max(axis=1) > 0]
    assert t < touching[0] <= t + 0.005, (t, touching[:3])
    (line,) = res.failures()
    assert "dt_min_reached" in line and f"t = {t:.6g} s of 0.25 s" in line and "smoothing_width" in line
    with pytest.raises(tx.SimulationError, match="dt_min_reached"):
        tx.simulate(bench, 0.25, n_save=N_SAVE, integrator=tx.Integrator(dt0=2e-5, dtmin=4e-6))


def test_the_face_exports_what_the_docs_call():
    """`tolerax.__all__` holds every public name the package exports (no private one, each
    resolves) and every `tx.NAME` the README, docs/ and the notebooks call (a dotted path into a
    subpackage, `tx.design.propose...`, is a path, not a face name)."""
    import pathlib
    import re
    import types

    root = pathlib.Path(__file__).resolve().parents[1]
    assert tx.__all__ == sorted(set(tx.__all__)) and not any(n.startswith("_") for n in tx.__all__)
    for name in tx.__all__:
        assert hasattr(tx, name), name
    texts = [root / "README.md", *sorted((root / "docs").glob("*.md")), *sorted((root / "notebooks").glob("*.ipynb"))]
    called = {(m, path.name) for path in texts for m in re.findall(r"\btx\.([A-Za-z_][A-Za-z0-9_]*)", path.read_text())}
    missing = sorted((name, where) for name, where in called
                     if name not in tx.__all__ and not isinstance(getattr(tx, name, None), types.ModuleType))
    assert not missing, f"called as tx.NAME but not exported: {missing}"
