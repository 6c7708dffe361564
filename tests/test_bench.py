"""The joint on its test bench: the paper's 0.98 deg/s case runs, results are physical, failures
are reported, and the command line works.

Every run saves at `N_SAVE` times, as `test_hard_cases.py` and `test_validation.py` do: the
default solver's runs of the default bench (any duration, tolerance, start) are one compiled
program, which the run's compilation cache serves to all three files; each static setting
tested here (PI coefficients, a solver, a step budget, fixed steps) compiles its own once."""

import json
import math

import diffrax
import numpy as np
import pytest

import tolerax as tx
from tolerax import cli

N_SAVE = 51  # the bench's save grid in test_hard_cases.py and test_validation.py too: one program


@pytest.fixture(scope="module")
def bench_run():
    bench = tx.TestBench()  # default joint: 100 um clearances and backlash, 0.98 deg/s
    return bench, tx.simulate(bench, 0.6, n_save=N_SAVE)


def test_bench_runs_at_paper_speed(bench_run):
    bench, res = bench_run
    assert res.success
    assert res.contact_names == ("sun", "carrier", "planet0", "planet1", "planet2")
    for series in (res.contact_force, res.sun_mesh_force, res.ring_mesh_force, res.output_angle):
        assert np.all(np.isfinite(np.asarray(series)))
    force = np.asarray(res.contact_force)
    # Contact never pulls. True by construction of `normal_force`'s clip (a ramp of the force:
    # softplus, or max(0, F) at width 0, so >= 0): this guards that clip through a whole
    # simulation, a regression test of the contact kernel as the bench uses it.
    assert force.min() >= 0.0
    # Start-up closes the backlash: the planets are driven onto their pins (they carry the
    # sun and ring tooth forces), and the carrier lags the motor by the lost motion.
    assert force[:, 2:].max() > 0.1
    q, qd, _ = res.states
    lay = bench.stage.layout
    # The PI servo, started from rest, has the output moving at the commanded rate within a
    # factor 1.5 by 0.6 s (its natural frequency is ~1 Hz; the backlash is traversed first).
    omega = float(qd[-1, lay.carrier_theta])
    assert 0.5 < omega / math.radians(0.98) < 1.5
    # Lost motion: at least the sun-mesh backlash seen at the output, less than all backlash
    # and clearances stacked up (a loose bound from geometry: (2 b + 3 c) / (r_c cos a)).
    te = -float(res.transmission_error[-1])
    r_eff = 25e-3 * math.cos(math.radians(20.0))
    assert 100e-6 / 5 / r_eff < te < (2 * 100e-6 + 3 * 100e-6) / r_eff


@pytest.fixture(scope="module")
def start_up_reference():
    """The bench's start-up (0.2 s from rest, before the planets land on their pins) at rtol
    1e-10: the reference of the controller and solver tests."""
    return tx.simulate(tx.TestBench(), 0.2, n_save=N_SAVE, integrator=tx.Integrator(rtol=1e-10, atol=1e-13))


def test_pi_step_controller_rejects_fewer_steps_same_answer(start_up_reference):
    # simulate(pcoeff, icoeff) reaches diffrax's controller: a PI controller (0.3, 0.3) on the
    # bench's start-up (0.2 s, before the planets land on their pins) rejects 68 steps where the
    # default I-controller rejects 211, and both agree with an rtol 1e-10 run to ~1e-11 rad of
    # transmission error (the error control's own scale at rtol 1e-6 over a ~3e-3 rad signal).
    bench = tx.TestBench()
    plain = tx.simulate(bench, 0.2, n_save=N_SAVE)
    pi = tx.simulate(bench, 0.2, n_save=N_SAVE, integrator=tx.Integrator(pcoeff=0.3, icoeff=0.3))
    explicit = tx.simulate(bench, 0.2, n_save=N_SAVE, integrator=tx.Integrator(pcoeff=0.0, icoeff=1.0))  # diffrax's I-controller
    assert (int(plain.num_steps), int(plain.num_rejected)) == (int(explicit.num_steps), int(explicit.num_rejected))
    ref = start_up_reference
    assert int(pi.num_rejected) < 0.5 * int(plain.num_rejected)
    for res in (plain, pi):
        te = np.abs(np.asarray(res.transmission_error) - np.asarray(ref.transmission_error)).max()
        assert te < 1e-10, te
    with pytest.raises(ValueError, match="icoeff must be .* > 0"):
        tx.simulate(bench, 1e-3, integrator=tx.Integrator(icoeff=0.0))
    with pytest.raises(ValueError, match="pcoeff must be .* >= 0"):
        tx.simulate(bench, 1e-3, integrator=tx.Integrator(pcoeff=float("nan")))


def test_solver_by_name_same_run_and_bosh3_within_its_tolerance(start_up_reference):
    # simulate(solver="Bosh3") is diffrax.Bosh3(); unknown names are refused with the list. On the
    # bench's start-up (0.2 s) Bosh3 at rtol 1e-4 agrees with an rtol 1e-10 Tsit5 run to 1.0e-9 rad
    # of transmission error (measured; Tsit5 at rtol 1e-6: 8e-12). The bound, 1e-8 rad, is 30x
    # below rtol times the ~3.4e-3 rad signal (3.4e-7): a check of the solver, not of rtol.
    bench = tx.TestBench()
    named = tx.simulate(bench, 0.2, n_save=N_SAVE, integrator=tx.Integrator(solver="Bosh3", rtol=1e-4, atol=1e-7))
    given = tx.simulate(bench, 0.2, n_save=N_SAVE, integrator=tx.Integrator(solver=diffrax.Bosh3(), rtol=1e-4, atol=1e-7))
    assert int(named.num_steps) == int(given.num_steps)
    np.testing.assert_array_equal(np.asarray(named.transmission_error), np.asarray(given.transmission_error))
    # The same settings as one value (`tx.Integrator`): the same run, bitwise (one program).
    held = tx.simulate(bench, 0.2, n_save=N_SAVE, integrator=tx.Integrator("Bosh3", rtol=1e-4, atol=1e-7))
    np.testing.assert_array_equal(np.asarray(held.transmission_error), np.asarray(named.transmission_error))
    # The settings one by one (deprecated for a release): the same run, with a warning naming the value.
    with pytest.warns(DeprecationWarning, match=r"pass integrator=tolerax.solve.ACCURATE.replace\(solver='Bosh3', rtol=0.0001"):
        legacy = tx.simulate(bench, 0.2, n_save=N_SAVE, solver="Bosh3", rtol=1e-4, atol=1e-7)
    np.testing.assert_array_equal(np.asarray(legacy.transmission_error), np.asarray(named.transmission_error))
    assert legacy.integrated_with == held.integrated_with
    with pytest.raises(ValueError, match="give rtol in the integrator"):
        tx.simulate(bench, 0.2, integrator=tx.Integrator("Bosh3"), rtol=1e-4)
    ref = start_up_reference
    te = np.abs(np.asarray(named.transmission_error) - np.asarray(ref.transmission_error)).max()
    assert te < 1e-8, te
    # SRK53 (tolerax's own tableau, fitted to the planetary stage's damped modes) by name, on the
    # same scene and bound: measured 8.2e-10 rad (Bosh3 1.4e-9), in 797 steps (Bosh3 926).
    srk = tx.simulate(bench, 0.2, n_save=N_SAVE, integrator=tx.Integrator(solver="SRK53", rtol=1e-4, atol=1e-7))
    te = np.abs(np.asarray(srk.transmission_error) - np.asarray(ref.transmission_error)).max()
    assert te < 1e-8, te
    with pytest.raises(ValueError, match=r"solver 'RK4' is unknown; use one of \['Bosh3', 'Dopri5', 'Dopri8', 'SRK53', 'Tsit5'\]"):
        tx.simulate(bench, 1e-3, integrator=tx.Integrator(solver="RK4"))
    with pytest.raises(TypeError, match="solver must be a name"):
        tx.simulate(bench, 1e-3, integrator=tx.Integrator(solver=3))


def test_failure_is_reported_not_hidden():
    bench = tx.TestBench()
    res = tx.simulate(bench, 0.05, n_save=N_SAVE, throw=False, integrator=tx.Integrator(max_steps=50))
    assert not res.success
    assert res.result == diffrax.RESULTS.max_steps_reached
    # t_reached is where the solver stopped: the same 50-step budget reaches it (the step
    # sequence is the same up to there), and does not reach 20 % further.
    t = float(res.t_reached)
    assert 0 < t < 0.05
    assert tx.simulate(bench, t, n_save=N_SAVE, throw=False, integrator=tx.Integrator(max_steps=50)).success
    assert not tx.simulate(bench, 1.2 * t, n_save=N_SAVE, throw=False, integrator=tx.Integrator(max_steps=50)).success
    (line,) = res.failures()
    assert "max_steps_reached" in line and f"t = {t:.6g} s of 0.05 s" in line and "max_steps" in line
    with pytest.raises(tx.SimulationError, match=r"failed \(max_steps_reached\) at t = "):
        tx.simulate(bench, 0.05, n_save=N_SAVE, integrator=tx.Integrator(max_steps=50))


def test_fixed_step_beyond_stability_is_a_failure_not_nan():
    # The paper's fixed 1e-4 s step is ~3x beyond Tsit5's stability limit for the ~18 kHz
    # sun/mesh mode (benchmarks/results/archive/bench_profile.md): the states blow up to NaN while
    # diffrax, taking constant steps, has no error estimate to refuse them. That must come back
    # as a failure, not as numbers.
    bench = tx.TestBench()
    res = tx.simulate(bench, 0.02, n_save=N_SAVE, throw=False, integrator=tx.Integrator(fixed_step=1e-4))
    assert not res.success
    assert res.result == diffrax.RESULTS.nonfinite
    with pytest.raises(tx.SimulationError, match="smaller step"):
        tx.simulate(bench, 0.02, n_save=N_SAVE, integrator=tx.Integrator(fixed_step=1e-4))
    # Inside the limit the fixed step agrees with the adaptive solution (no contact yet in the
    # first 20 ms from rest, so both are smooth; 5th-order steps of 20 us: error far below 1e-9).
    fixed = tx.simulate(bench, 0.02, n_save=N_SAVE, integrator=tx.Integrator(fixed_step=2e-5))
    adaptive = tx.simulate(bench, 0.02, n_save=N_SAVE, integrator=tx.Integrator(rtol=1e-10, atol=1e-13))
    assert fixed.success and int(fixed.num_steps) == 1000
    np.testing.assert_allclose(np.asarray(fixed.output_angle), np.asarray(adaptive.output_angle), rtol=0, atol=1e-9)
    with pytest.raises(ValueError, match="fixed_step"):
        tx.simulate(bench, 0.02, integrator=tx.Integrator(fixed_step=-1e-4))


def test_bad_duration_rejected():
    with pytest.raises(ValueError, match="duration"):
        tx.simulate(tx.TestBench(), float("nan"))
    with pytest.raises(ValueError, match="start"):
        tx.simulate(tx.TestBench(), 0.01, start="moving")


def test_cli_demo_bench(tmp_path, capsys):
    # 0.05 s: the demo saves every millisecond, so N_SAVE saves: the shared program.
    code = cli.main(["demo", "--bench", "--duration", "0.05", "--out", str(tmp_path)])
    assert code == 0
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["result"] == "successful"
    assert (tmp_path / "bench.png").stat().st_size > 10_000
    with pytest.raises(SystemExit):
        cli.main(["demo", "--bench", "--clearance", "-5"])
    assert "--clearance must be" in capsys.readouterr().err
