"""The end-of-life gradient through the tooth flanks' wear alone against central differences
(`tolerax.design.life`, `tolerax.physics.wear`), behind `pytest -m slow` (~190 s: 20 evaluations
of three solves at rtol 1e-10): a file of its own, so that pytest-xdist (`--dist loadfile`) runs
it beside test_life.py's slow journal gradient test instead of after it. The default run checks
the same chain in test_life.py: the flanks' rates' derivative on one trajectory
(test_window_wear_rates_derivative_on_one_trajectory) and the end-of-life derivative through the
growth along one direction (test_end_of_life_directional_derivative)."""

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest

from tolerax.design.life import MissionLife
from tolerax.physics.wear import ArchardWear

from _life_helpers import life_objective as _objective


@pytest.mark.slow
def test_flank_wear_gradient(life_scan):
    """Slow: enlarges test_life.py's test_window_wear_rates_derivative_on_one_trajectory (the
    flanks' rates on a fixed trajectory) and test_end_of_life_directional_derivative (one
    direction through the growth, the sun journal) to the flanks' end-of-life gradient through the
    solves, every feature. The end-of-life gradient through the flanks' wear alone (journals at k = 0, flanks at the
    MoS2 median): the backlash grows by k|F||w_a - w_b|/(4 z b) per mesh. Measured over
    test_life.py's start-up, the forward-mode gradient agrees with central differences at 10 and 5 nm
    to within 2e-3 for every feature (its differences are flat to that level from 40 nm down:
    the mesh forces' and rates' zero crossings do not sit on saves here)."""
    life = MissionLife.from_years(0.02, wear=ArchardWear(0.0, flank_rate=4e-15), points=2)
    pointing = _objective(life_scan, life, rtol=1e-10, atol=1e-13)
    forward = _objective(life_scan, life, rtol=1e-10, atol=1e-13, adjoint=diffrax.ForwardMode())
    width, values = 1e-6, jnp.full(5, 5e-6)
    f = eqx.filter_jit(lambda p, v: p(v, width)["pointing_rms_eol"])
    both = eqx.filter_jit(lambda p, v: p(v, width))(pointing, values)
    assert float(both["pointing_rms_eol"]) != float(both["pointing_rms"])  # the backlash grew
    ad = np.asarray(eqx.filter_jit(lambda p, v: jax.jacfwd(lambda u: p(u, width)["pointing_rms_eol"])(v))(forward, values))
    diffs = np.array([[(float(f(pointing, values.at[i].add(h))) - float(f(pointing, values.at[i].add(-h)))) / (2 * h)
                       for i in range(5)] for h in (1e-8, 5e-9)])
    print("AD", ad, "differences", diffs, sep="\n")
    np.testing.assert_array_less(np.abs(diffs - ad), 2e-3 * np.abs(diffs))
