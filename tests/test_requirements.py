"""Requirements as data (`tolerax.Requirement`): any number of them through one optimiser, a
new kind of requirement as one small metric class, and bad input named."""

import dataclasses

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax.design import propose as _propose
from tolerax.design.cost import IsoGrade
from tolerax.design.sequential import sequential_design
from tolerax.design.types import Design, Features, realise, robust
from tolerax.mechanism.outputs import ARCSEC

from _slsqp import slsqp_reference

UM = 1e-6
FEATURES = Features(["a", "b", "c"], [12.0, 80.0, 20.0])


def _three(x, draws, width):
    """Three metrics that weigh the features differently: a root-sum-square lost motion, a
    metric that falls as feature 0's lower limit grows, and a linear band budget."""
    v = realise(x, draws)
    rss = robust(jnp.sqrt(jnp.sum((v * jnp.array([1.0, 3.0, 2.0]) / UM) ** 2, axis=1)), "mean+kstd", k=1.0)
    other = robust(jnp.sqrt(jnp.sum((v * jnp.array([2.0, 0.3, 0.1]) / UM) ** 2, axis=1)), "mean+kstd", k=2.0) - 0.8 * x.nominal[0] / UM
    budget = jnp.dot(jnp.array([0.5, 2.0, 4.0]), x.band) / UM
    return jnp.stack([rss, other, budget])


def test_sequential_with_three_requirements_against_scipy_slsqp():
    """Three constraints through the same loop as one: the cost and design of SciPy's SLSQP
    on the same problem with all three (an independent method)."""
    draws = jnp.asarray(np.random.default_rng(0).uniform(-1.0, 1.0, (16, 3)))
    model, R = IsoGrade(factor_per_grade=2.0), np.array([80.0, 35.0, 18.0])  # all three active at the optimum
    lower = Design(jnp.full(3, 20 * UM), jnp.full(3, 1 * UM))
    upper = Design(jnp.full(3, 40 * UM), jnp.full(3, 15 * UM))
    x0 = Design(jnp.full(3, 30 * UM), jnp.full(3, 8 * UM))
    result = sequential_design(_three, FEATURES, requirement=tuple(R), lower=lower, upper=upper, draws=draws, x0=x0,
                               cost_model=model, tol=1e-6, max_iterations=60)

    reference, margins = slsqp_reference(_three, R, draws, model, FEATURES.size_mm)
    active = np.abs([float(g(jnp.asarray(reference.x))) for g in margins]) < 1e-6
    assert reference.success and np.all(active)  # a trade between all three, not one alone
    assert bool(result.converged) and np.asarray(result.objective).shape == (3,)
    np.testing.assert_allclose(result.cost, reference.fun, rtol=1e-5)
    np.testing.assert_allclose(np.r_[result.x.nominal, result.x.band] / UM, reference.x, rtol=1e-3)
    np.testing.assert_array_equal(np.asarray(result.constraint_active), active)


class PeakAfterReversal(tx.AbstractMetric):
    """The peak pointing error (arcsec) over `span` seconds after the scan reverses at `reversal` (s)."""

    name = "peak_after_reversal"
    reversal: float
    span: float

    def __call__(self, result, times, window):
        after = window & (times >= self.reversal) & (times <= self.reversal + self.span)
        return jnp.max(jnp.where(after, result.pointing_error, 0.0)) / ARCSEC


@pytest.fixture(scope="module")
def peak_pointing(scan_pointing):
    """The design layer's scan (conftest: A sin(2 pi t / 1 s), which reverses at 0.25 s) with
    the metric above added and no jitter (its simulation is the scan's own program)."""
    return dataclasses.replace(scan_pointing, metrics=(PeakAfterReversal(0.25, 0.1),), jitter_cutoff=None)


def test_a_new_requirement_kind_is_one_metric_class(peak_pointing):
    """A requirement on the peak pointing error after a reversal, at a yield, beside the RMS one:
    the metric is the class above and nothing else changes. Its value is the peak of the
    simulated error over the saves after the reversal (by NumPy on the same run); it is one of
    the objective's outputs, with its unit; its forward-mode derivative through the simulation
    (what the design's linearised quantile is built from) equals central differences along a
    random direction (measured 1e-8 relative; the step 10 nm does not move the argmax save). The design and its report on two
    such requirements, one of them named by the metric: on a closed-form unit with the same
    outputs (tests/_responses.py), where both linearised quantiles are known: the design meets
    both, each equal to the problem's objective evaluated again; the Monte Carlo check covers
    the metric; the report names it."""
    values = tx.design_of(peak_pointing.scene)
    run = peak_pointing.run(values, 1e-6)  # the optimiser's width: `outputs` and `at_middle` below are one program
    ts, error = np.asarray(run.ts), np.asarray(run.pointing_error) / ARCSEC
    after = (ts >= 0.25) & (ts <= 0.35)
    outputs = peak_pointing(values, 1e-6)
    assert float(outputs["peak_after_reversal"]) == pytest.approx(error[after].max(), rel=1e-12)
    assert "peak_after_reversal" in peak_pointing.outputs and peak_pointing.units["peak_after_reversal"] == "arcsec"
    # Differentiable through the simulation (what the design's linearised quantile needs): its
    # forward-mode derivative along a random direction of the features is finite and equals a
    # central difference along it (one tangent; the quantile itself is the closed-form design
    # below, and tests/test_reliability.py's on the scan).
    forward = peak_pointing.forward_mode()
    direction = jnp.asarray(np.random.default_rng(2).normal(size=values.shape))
    peak, slope = eqx.filter_jit(lambda v, d: jax.jvp(lambda u: forward(u, 1e-6)["peak_after_reversal"], (v,), (d,)))(values, direction)
    assert float(peak) == pytest.approx(float(outputs["peak_after_reversal"]), rel=1e-9)
    h = 1e-8 / float(jnp.linalg.norm(direction))  # m along the unit direction
    difference = (float(peak_pointing(values + h * direction, 1e-6)["peak_after_reversal"])
                  - float(peak_pointing(values - h * direction, 1e-6)["peak_after_reversal"])) / (2 * h)
    print(f"\n  peak slope {float(slope):.6e}, difference {difference:.6e}, relative {float(slope) / difference - 1:.1e}")
    assert np.isfinite(float(slope)) and float(slope) == pytest.approx(difference, rel=1e-4)

    import _responses as R

    scene = peak_pointing.scene
    line = R.Line(scene, [900.0, 1500.0], [0.5 * np.asarray(tx.lost_motion_weights(scene)), [2e6, 3e6, 1e6, 4e6]], 100e-6,
                  names=("pointing_rms", "peak_after_reversal"))
    closed = _propose.design_problem(line, yield_=0.9, output=("pointing_rms", "peak_after_reversal"))
    quantiles = lambda x: np.asarray(closed.value(x, 1e-6))  # noqa: E731
    baseline = quantiles(closed.x0)
    requirements = [tx.Requirement("pointing_rms", 0.9 * baseline[0]), tx.Requirement("peak_after_reversal", 0.8 * baseline[1])]
    report = tx.propose_design(tx.ToleranceProblem(line, requirements, tx.Yield(0.9)), tx.Sequential(widths=(1e-6,), max_gradients=12),
                               check=tx.Check(units=6, rounds=1))
    assert [o.requirement.output for o in report.outcomes] == ["pointing_rms", "peak_after_reversal"]
    np.testing.assert_allclose([o.baseline for o in report.outcomes], baseline, rtol=1e-12)
    np.testing.assert_allclose(quantiles(report.result.x), [o.objective for o in report.outcomes], rtol=1e-12)
    assert all(o.met for o in report.outcomes) and report.cost < report.baseline[2]
    check = report.outcomes[1].checks[-1]
    assert check.n == 6 and check.requirement == pytest.approx(0.8 * baseline[1])
    text = report.table()
    assert "Peak after reversal: 90.0% quantile (linearised)" in text and "d peak after reversal / d nominal" in text


def test_bad_requirements_are_named(peak_pointing):
    with pytest.raises(ValueError, match="limit must be finite and > 0"):
        tx.Requirement("pointing_rms", -1.0)
    with pytest.raises(ValueError, match="tol must be in"):
        tx.Requirement("pointing_rms", 100.0, tol=2.0)
    with pytest.raises(ValueError, match="each on its own output"):
        tx.propose_design(tx.ToleranceProblem(peak_pointing, [tx.Requirement("pointing_rms", 1.0), tx.Requirement("pointing_rms", 2.0)]))
    with pytest.raises(ValueError, match="does not compute 'pointing_jitter'.*jitter_cutoff"):
        tx.propose_design(tx.ToleranceProblem(peak_pointing, [tx.Requirement("pointing_jitter", 1.0)], tx.Yield(0.9)))
    with pytest.raises(ValueError, match="does not compute 'pointing_peek'"):
        tx.propose_design(tx.ToleranceProblem(peak_pointing, tx.Requirement("pointing_peek", 1.0)))
    with pytest.raises(ValueError, match="metrics must be AbstractMetric"):
        tx.PointingObjective(peak_pointing.scene, duration=0.6, settle=0.0, metrics=(PeakAfterReversal(0.25, 0.1),) * 2)
