"""The start-up both life test files simulate (on conftest's `life_scan`) (`test_life.py`, `test_life_flanks.py`): the
planetary azimuth scan from rest over 20 ms, where the servo closes every play and the contacts
carry load but the motion is not yet a rattle, so derivatives are those of a smooth response
(the gradient checks of tests/test_gradients.py use the same regime on the bench)."""

import tolerax as tx

HORIZON, N_SAVE = 0.02, 41


def life_objective(scene, life, **kw):
    """The `PointingObjective` over the start-up with `life`."""
    return tx.PointingObjective(scene, duration=HORIZON, settle=0.0, start="rest", n_save=N_SAVE, life=life, **kw)
