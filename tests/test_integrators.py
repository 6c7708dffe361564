"""SRK53, the explicit Runge-Kutta method fitted to the full planetary stage's lightly damped fast
modes (`tolerax.solve.SRK53`): its order (conditions and observed), its stability polynomial
and region (the claim that it is stable where Bosh3 is not, checked by integrating a damped mode
with diffrax at fixed steps), and its error estimate."""

import diffrax
import jax.numpy as jnp
import numpy as np
import pytest

from tolerax.solve import SOLVERS, SRK53, solver_named


def _tableau(solver):
    """(A, b) over the stages that a step pays for (the FSAL stage left out), and b_error."""
    tab = solver.tableau
    s = len(tab.b_sol) - 1
    a = np.zeros((s, s))
    for i, row in enumerate(tab.a_lower[: s - 1]):
        a[i + 1, : len(row)] = row
    return a, np.asarray(tab.b_sol[:s]), np.asarray(tab.b_error)


def test_order_conditions_and_stability_polynomial():
    a, b, _ = _tableau(SRK53())
    c = a.sum(1)
    assert np.allclose(c, np.r_[0.0, SRK53.tableau.c[:4]], rtol=0, atol=1e-15)  # c = A 1
    # 3rd order: the four conditions, to rounding.
    assert abs(b.sum() - 1) < 1e-14 and abs(b @ c - 1 / 2) < 1e-14
    assert abs(b @ c**2 - 1 / 3) < 1e-14 and abs(b @ a @ c - 1 / 6) < 1e-14
    # Not 4th order: g4 = b A^2 c is the documented 0.029692, not 1/24; the other 4th-order terms vanish.
    assert b @ a @ a @ c == pytest.approx(0.029692474797, abs=1e-10)
    assert b @ a @ a @ a @ c == pytest.approx(0.005773972463, abs=1e-10)
    assert abs(b @ c**3 - 1 / 4) < 1e-8 and abs(b @ (c * (a @ c)) - 1 / 8) < 1e-8 and abs(b @ a @ c**2 - 1 / 12) < 1e-8
    # The stability polynomial from the tableau, R(z) = 1 + z b (I - zA)^-1 1, against its coefficients.
    g = [1, 1, 1 / 2, 1 / 6, b @ a @ a @ c, b @ a @ a @ a @ c]
    for z in (0.3 + 2j, -1.5 + 3.1j, -0.2 + 4.0j):
        r = 1 + z * b @ np.linalg.solve(np.eye(5) - z * a, np.ones(5))
        assert abs(r - np.polyval(g[::-1], z)) < 1e-12


def test_error_estimate_is_second_order_and_scaled_like_bosh3():
    """b_error sums to 0 and is orthogonal to c (an O(h^3) estimate), and its leading term on
    y' = lambda y is Bosh3's, -z^3/48: a tolerance means about the same for both."""
    tab = SRK53.tableau
    a6 = np.zeros((6, 6))
    for i, row in enumerate(tab.a_lower):
        a6[i + 1, : len(row)] = row
    c6, be = a6.sum(1), np.asarray(tab.b_error)
    assert abs(be.sum()) < 1e-14 and abs(be @ c6) < 1e-14
    bosh = diffrax.Bosh3.tableau
    a4 = np.zeros((4, 4))
    for i, row in enumerate(bosh.a_lower):
        a4[i + 1, : len(row)] = row
    assert be @ a6 @ c6 == pytest.approx(-1 / 48, rel=1e-12)
    assert np.asarray(bosh.b_error) @ a4 @ a4.sum(1) == pytest.approx(-1 / 48, rel=1e-12)


def _forced(t, y, args):
    return jnp.array([y[1], -jnp.sin(y[0]) - 0.1 * y[1] * y[0] ** 2 + jnp.cos(t)])


def test_observed_order_three_on_a_nonlinear_oscillator():
    """Fixed steps halved: the error falls 8x (3rd order), and below Bosh3's at the same steps
    (three of its four 4th-order error terms are zero)."""
    y0 = jnp.array([1.0, 0.0])
    ref = diffrax.diffeqsolve(diffrax.ODETerm(_forced), diffrax.Dopri8(), 0.0, 5.0, 1e-3, y0,
                              stepsize_controller=diffrax.PIDController(rtol=1e-13, atol=1e-13), max_steps=100_000).ys[-1]
    err = {}
    for name, solver in (("SRK53", SRK53()), ("Bosh3", diffrax.Bosh3())):
        # The step as an array: one compiled program per solver serves the three steps.
        err[name] = np.array([float(jnp.max(jnp.abs(diffrax.diffeqsolve(diffrax.ODETerm(_forced), solver, 0.0, 5.0, jnp.asarray(h), y0).ys[-1] - ref)))
                              for h in (0.05, 0.025, 0.0125)])
    ratios = err["SRK53"][:-1] / err["SRK53"][1:]
    assert np.all((ratios > 7.0) & (ratios < 9.0)), ratios
    assert np.all(err["SRK53"] < err["Bosh3"])


def _damped_mode(t, y, args):
    omega, zeta = args
    return jnp.array([y[1], -(omega**2) * y[0] - 2 * zeta * omega * y[1]])


@pytest.mark.parametrize("zeta", [0.04, 0.06, 0.1])
def test_stable_where_bosh3_is_not_on_a_damped_mode(zeta):
    """A mode of 16 kHz at `zeta` of critical damping, integrated with fixed steps h = 3.9/omega
    (inside SRK53's region on these rays, twice Bosh3's limit there): SRK53 decays, Bosh3 grows."""
    omega = 2 * np.pi * 16e3
    y0, h = jnp.array([1e-6, 0.0]), 3.9 / omega
    end = {}
    for name, solver in (("SRK53", SRK53()), ("Bosh3", diffrax.Bosh3())):
        # The mode's constants and the steps as arrays: one compiled program per solver for every zeta.
        y = diffrax.diffeqsolve(diffrax.ODETerm(_damped_mode), solver, 0.0, jnp.asarray(2000 * h), jnp.asarray(h), y0,
                                args=jnp.array([omega, zeta]), max_steps=4000).ys[-1]
        end[name] = float(jnp.abs(y[0]))
    assert end["SRK53"] < 1e-6  # decayed (the exact solution's is ~1e-6 * exp(-zeta * 7800))
    assert not end["Bosh3"] < 1e-3  # grown (or overflowed to inf/nan)


def test_adaptive_solve_and_names():
    """Under diffrax's PID controller it meets a tight tolerance on an oscillator with a known
    solution; `solver_named("SRK53")` gives it, as scene files and `simulate` name it."""
    assert isinstance(solver_named("SRK53"), SRK53) and SOLVERS["SRK53"] is SRK53
    f = lambda t, y, args: jnp.array([y[1], -y[0]])  # noqa: E731
    sol = diffrax.diffeqsolve(diffrax.ODETerm(f), SRK53(), 0.0, 10.0, 0.1, jnp.array([1.0, 0.0]),
                              stepsize_controller=diffrax.PIDController(rtol=1e-9, atol=1e-12), max_steps=100_000)
    assert abs(float(sol.ys[-1][0]) - np.cos(10.0)) < 1e-7
    assert bool(jnp.all(jnp.isfinite(sol.ys)))


def test_the_run_settings_are_one_value():
    """`Integrator`: the solver, the controller and the steps' limits as one value, which a
    `PointingObjective` holds (settings given one by one replace its fields; read back as
    attributes) and a scene file's `[run]` names; bad settings are named. (`simulate` taking
    it, bitwise the settings given one by one: test_bench.py's solver-by-name test.)"""
    import dataclasses

    import tolerax as tx

    settings = dict(solver="Bosh3", rtol=1e-5, atol=1e-8, pcoeff=0.3, icoeff=0.3)
    integrator = tx.Integrator(**settings)
    objective = tx.load_scene("scan-azimuth").replace(**settings).objective()
    assert objective.integrator == integrator.replace(max_steps=objective.max_steps) and objective.rtol == 1e-5
    held = tx.PointingObjective(objective.scene, 0.6, 0.3, integrator=integrator.replace(rtol=1e-4))
    assert held.integrator == integrator.replace(rtol=1e-4) and held.solver == "Bosh3"
    # The settings one by one (deprecated for a release) still refine the integrator, with a
    # warning that writes the value to pass.
    with pytest.warns(DeprecationWarning, match=r"PointingObjective\(rtol=0.0001\) is deprecated: pass integrator=integrator.replace"):
        assert tx.PointingObjective(objective.scene, 0.6, 0.3, integrator=integrator, rtol=1e-4).integrator == held.integrator
    with pytest.warns(DeprecationWarning, match=r"integrator=tolerax.solve.ACCURATE.replace\(max_steps=400000, rtol=0.0001\)"):
        alone = tx.PointingObjective(objective.scene, 0.6, 0.3, rtol=1e-4)
    assert alone.integrator == tx.solve.ACCURATE.replace(max_steps=400_000, rtol=1e-4)
    assert dataclasses.replace(held, n_save=11).integrator == held.integrator
    assert tx.PointingObjective(objective.scene, 0.6, 0.3).max_steps == 400_000  # a design unit's budget
    with pytest.raises(ValueError, match="Integrator: rtol must be a positive finite number"):
        tx.Integrator(rtol=-1.0)
    with pytest.raises(ValueError, match="PointingObjective: solver 'Euler' is unknown"):
        tx.PointingObjective(objective.scene, 0.6, 0.3, solver="Euler")  # refused before any warning
    with pytest.raises(TypeError, match="unknown setting"):
        integrator.replace(rtool=1e-3)


def test_the_integrator_is_chosen_from_the_scene_unless_one_is_named():
    """With no run setting, `simulate`, a `PointingObjective` (what Monte Carlo and design run)
    and a scene file without `[run]` settings get `scene.automatic_integrator()`, and the result
    and the objective say which and why. Every scene gets `ACCURATE` (Tsit5 at rtol 1e-6): on a
    full planetary joint the faster `FAST_STAGE` (SRK53 at rtol 1e-4) was measured outside its
    errors (benchmarks/auto_integrator.py), and the reason says so and names it. A setting given
    replaces ACCURATE's; an `Integrator` is taken as it is; a failure names the integrator."""
    import math

    import tolerax as tx
    from tolerax.solve import ACCURATE, FAST_STAGE

    full = tx.antenna("azimuth", fidelity=("planetary", "ideal"), base="fixed")
    lumped = tx.antenna("azimuth", fidelity="lumped")
    chosen, why = full.automatic_integrator()
    assert chosen == ACCURATE and "azimuth joint" in why and "FAST_STAGE" in why and "auto_integrator.py" in why
    assert lumped.automatic_integrator()[0] == ACCURATE and tx.TestBench().automatic_integrator()[0] == ACCURATE
    assert (FAST_STAGE.solver, FAST_STAGE.rtol, FAST_STAGE.pcoeff, FAST_STAGE.icoeff) == ("SRK53", 1e-4, 0.2, 0.2)
    # The objective of Monte Carlo and design: the same choice with its step budget, said in words.
    objective = tx.PointingObjective(full, 0.1, 0.0)
    assert objective.integrator == ACCURATE.replace(max_steps=400_000)
    assert objective.integrated_with.startswith("Tsit5, rtol 1e-06") and "chosen automatically" in objective.integrated_with
    fast = tx.PointingObjective(full, 0.1, 0.0, integrator=FAST_STAGE)
    assert fast.integrator == FAST_STAGE and fast.integrated_with.endswith("as asked")
    import dataclasses  # a copy keeps the reason where the integrator is the same, says it again where not

    assert dataclasses.replace(objective, n_save=11).integrated_with == objective.integrated_with
    assert dataclasses.replace(objective, integrator=FAST_STAGE).integrated_with == fast.integrated_with
    with pytest.warns(DeprecationWarning):  # a setting given one by one refines ACCURATE, not the automatic choice
        assert tx.PointingObjective(full, 0.1, 0.0, rtol=1e-5).integrator == ACCURATE.replace(rtol=1e-5, max_steps=400_000)
    # A scene file whose [run] names no setting gets it too; one that names them keeps them.
    named = tx.load_scene("scan-azimuth-planetary")
    assert named.objective().solver == "Bosh3"  # its [run] names Bosh3
    data = {**named.data, "run": {k: v for k, v in named.data["run"].items() if k not in tx.Integrator.FIELDS}}
    bare = type(named).from_data(data, "bare", "test").objective()
    assert bare.integrator == ACCURATE.replace(max_steps=400_000) and "FAST_STAGE" in bare.integrated_with
    # simulate: the chosen one, said in the result; settings given replace ACCURATE's. (The runs
    # are the bench's shared programs, test_bench.py's and test_hard_cases.py's: 51 saves.)
    from tolerax.mechanism.scene import choose_integrator

    res = tx.simulate(tx.TestBench(), 0.002, n_save=51)
    assert res.integrated_with.startswith("Tsit5, rtol 1e-06") and "chosen automatically" in res.integrated_with
    assert "Integrated with Tsit5" in res.report()
    # Settings one by one (simulate's deprecated keywords) still refine the preset, with a
    # warning that names the one value to pass instead.
    with pytest.warns(DeprecationWarning, match=r"integrator=tolerax.solve.ACCURATE.replace\(rtol=1e-05\)"):
        asked, why = choose_integrator(lumped, "auto", dict(rtol=1e-5, solver=None))
    assert asked == ACCURATE.replace(rtol=1e-5) and why == "Tsit5, rtol 1e-05, atol 1e-09, I-controller: as asked"
    # A preset by name (simulate, the objective, a scene file's [run] integrator, --integrator),
    # refined by the settings given beside it; an unknown name refused with the names there are.
    assert choose_integrator(full, "fast-stage", {}) == (FAST_STAGE, FAST_STAGE.said())
    with pytest.warns(DeprecationWarning, match=r"NAMED_INTEGRATORS\['fast-stage'\].replace\(rtol=1e-05\)"):
        assert choose_integrator(full, "fast-stage", dict(rtol=1e-5))[0] == FAST_STAGE.replace(rtol=1e-5)
    with pytest.raises(TypeError, match="unexpected keyword argument.*rtoll.*integrator=tolerax.Integrator"):
        choose_integrator(full, "auto", dict(rtoll=1e-5))
    assert choose_integrator(full, "accurate", {})[0] == ACCURATE
    with pytest.raises(ValueError, match="simulate: 'fast' is not an integrator's name; use 'auto' .*'fast-stage'"):
        tx.simulate(lumped, 0.01, integrator="fast")
    with pytest.raises(TypeError, match="integrator must be 'auto', a name in tolerax.solve.NAMED_INTEGRATORS"):
        tx.simulate(lumped, 0.01, integrator=3)
    assert tx.PointingObjective(full, 0.1, 0.0, integrator="fast-stage").integrator == FAST_STAGE.replace(max_steps=400_000)
    assert tx.PointingObjective(full, 0.1, 0.0, integrator="auto").integrator == objective.integrator
    staged = type(named).from_data({**data, "run": {**data["run"], "integrator": "fast-stage", "rtol": 1e-5}}, "staged", "test")
    assert staged.objective().integrator == FAST_STAGE.replace(rtol=1e-5, max_steps=400_000)
    with pytest.raises(tx.SceneFileError, match=r"\[run\] integrator: integrator 'quick' is unknown; use 'auto'"):
        named.replace(integrator="quick")
    with pytest.raises(ValueError, match="give rtol in the integrator"):
        choose_integrator(lumped, FAST_STAGE, dict(rtol=1e-5))
    with pytest.raises(tx.SimulationError, match="It was integrated with Tsit5.*as asked"):
        tx.simulate(tx.TestBench(), 0.05, n_save=51, integrator=tx.Integrator(max_steps=50))
    assert not math.isnan(float(res.output_angle[-1]))
