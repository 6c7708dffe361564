"""Defaults several layers share, in one place (a light module: the command line imports it
before JAX)."""

JITTER_CUTOFF = 20.0  # Hz: the usual start of a pointing budget's stability band: `--jitter-cutoff`'s default
# (design, montecarlo), a scene file's `[tolerances] jitter_cutoff`'s, and the band `tolerax run` reports
# The design solvers by their names on the command line (`--solver`) and in a scene file
# (`[tolerances] solver`): the classes of `tolerax.design.solvers` they build.
DESIGN_SOLVERS = {"sequential": "Sequential", "augmented-lagrangian": "AugmentedLagrangian", "slsqp": "SLSQP"}
