"""The start-up both life test files simulate (on conftest's `life_scan`) (`test_life.py`, `test_life_flanks.py`): the
planetary azimuth scan from rest over 20 ms, where the servo closes every play and the contacts
carry load but the motion is not yet a rattle, so derivatives are those of a smooth response
(the gradient checks of tests/test_gradients.py use the same regime on the bench).

The run settings are shared (`RTOL`, `ATOL`, `WIDTH`, `VALUES`) so that the tests of a file build
the same few compiled programs and read them back from the run's compilation cache: every
distinct run setting is one more compile of a planetary solve (~10 s)."""

import tolerax as tx

HORIZON, N_SAVE = 0.02, 41
RTOL, ATOL = 1e-8, 1e-11
WIDTH = 1e-6  # m: the optimiser's continuation width at which gradients are meaningful (tests/test_gradients.py)
MOS2 = "MoS2 sputtered film, vacuum"


def life_objective(scene, life, rtol=None, atol=None, **kw):
    """The `PointingObjective` over the start-up with `life` (at `rtol`, `atol` where given: Tsit5
    on a design unit's step budget)."""
    if rtol is not None:
        kw["integrator"] = tx.Integrator(rtol=rtol, atol=atol, max_steps=400_000)
    return tx.PointingObjective(scene, duration=HORIZON, settle=0.0, start="rest", n_save=N_SAVE, life=life, **kw)
