"""Gear mesh with backlash, docs/model.md §3.

A mesh between gears $i, j$ has a deflection $g$ along the line of action (m, positive = drive
flank compressed) and a total backlash $b_t$ (m). The force is carried by two unilateral flanks:
the drive flank with deflection $g$ and the back flank with deflection $h = g + b_t$, so that the
exact dead zone is $f_g = \\max(0, g) - \\max(0, -h)$. With dynamic backlash, $\\partial h/\\partial q$
is the *mirrored* line of action (the radial part of $\\partial b_t/\\partial q$ flips the sign of the
radial projection), which is why the two flanks are kept apart rather than lumped into $f_g$.
"""

import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float
from . import smooth as _smooth


def involute(angle: ArrayLike) -> Array:
    """$\\mathrm{inv}\\,\\alpha = \\tan\\alpha - \\alpha$."""
    return jnp.tan(angle) - angle


def dynamic_backlash(
    centre_distance: ArrayLike,
    nominal_distance: ArrayLike,
    pressure_angle: ArrayLike,
    backlash: ArrayLike,
    internal: bool,
    profile_error: ArrayLike = 0.0,
) -> Float[Array, "..."]:
    """Total backlash $b_t$ (m) of a mesh whose centres moved to distance $A'$ (paper eq. 2).

    $b_t = b_0 \\pm 2A_0\\cos\\alpha_0[\\mathrm{inv}\\,\\alpha' - \\mathrm{inv}\\,\\alpha_0] + e(t)$,
    $\\alpha' = \\arccos(A_0\\cos\\alpha_0/A')$; $+$ for an external mesh (moving the gears apart
    opens the backlash), $-$ for the internal ring–planet mesh (moving the planet out towards the
    ring closes it). For small $\\Delta A = A' - A_0$: $b_t - b_0 \\approx \\pm 2\\Delta A\\sin\\alpha_0$.
    The arccos argument is clipped to $[-1, 1 - 10^{-12}]$: that edge is reached only when the
    centres approach by $A_0(1-\\cos\\alpha_0)$ (1.5 mm on the default joint), far beyond any
    clearance; there the gradient stays finite.

    **Arguments:**

    - `centre_distance`: $A'$ (m), from the displaced centres.
    - `nominal_distance`: $A_0$ (m).
    - `pressure_angle`: $\\alpha_0$ (rad).
    - `backlash`: $b_0$ (m).
    - `internal`: True for the ring–planet mesh (static).
    - `profile_error`: $e(t)$ (m), added as in the paper's eq. 2.
    """
    cos0 = nominal_distance * jnp.cos(pressure_angle)
    # Below A' = A0 cos a0 the argument is clipped anyway: evaluating there at A0 cos a0 keeps
    # b_t continuous and its gradient 0 down to A' = 0 (no overflow of cos0 / A'**2).
    safe_distance = jnp.maximum(centre_distance, cos0)
    argument = jnp.clip(cos0 / safe_distance, -1.0, 1.0 - 1e-12)
    change = 2.0 * cos0 * (involute(jnp.arccos(argument)) - involute(pressure_angle))
    sign = -1.0 if internal else 1.0
    return backlash + sign * change + profile_error


def mesh_stiffness(mean_stiffness: ArrayLike, contact_ratio: ArrayLike, phase: ArrayLike) -> Array:
    """Time-varying mesh stiffness $K_t = k_m[1 + (\\varepsilon_c - 1)\\cos\\phi]$ (N/m).

    $\\phi$ is the mesh phase ($z(\\theta_i - \\theta_j)$ plus an offset), which for a constant
    speed equals $\\omega_m t + \\varphi$. Requires $\\varepsilon_c < 2$ for $K_t > 0$.
    """
    return mean_stiffness * (1.0 + (contact_ratio - 1.0) * jnp.cos(phase))


def profile_error(amplitude: ArrayLike, phase: ArrayLike, phase_offset: ArrayLike) -> Array:
    """Tooth profile (transmission) error $e = E_e\\sin(\\phi + \\varphi_e)$ (m)."""
    return amplitude * jnp.sin(phase + phase_offset)


def equivalent_mass(inertia_i: ArrayLike, radius_i: ArrayLike, inertia_j, radius_j) -> Array:
    """$\\bar m = I_iI_j/(I_i r_j^2 + I_j r_i^2)$ (kg), base radii $r$; $I_j = \\infty$ (fixed
    ring) is accepted and gives $I_i/r_i^2$. (The paper's flattened eq. 8 swaps the pairing.)"""
    inertia_j = jnp.asarray(inertia_j, dtype=float)
    fixed = jnp.isinf(inertia_j)
    safe_j = jnp.where(fixed, 1.0, inertia_j)
    pair = inertia_i * safe_j / (inertia_i * radius_j**2 + safe_j * radius_i**2)
    return jnp.where(fixed, inertia_i / radius_i**2, pair)


def flank_forces(
    drive: ArrayLike,
    drive_rate: ArrayLike,
    back: ArrayLike,
    back_rate: ArrayLike,
    stiffness: ArrayLike,
    damping: ArrayLike,
    width: ArrayLike,
) -> tuple[Array, Array]:
    """Restoring forces (N) on the drive flank ($g$) and back flank ($h = g + b_t$).

    Drive: $K\\,\\mathrm{ramp}(g) + D\\,H(g)\\dot g$ (acts while $g > 0$); back:
    $-K\\,\\mathrm{ramp}(-h) + D\\,H(-h)\\dot h$ (acts while $h < 0$). Their sum along a common
    line of action is $K_t f_g + D_t\\,\\tfrac{d}{dt}f_g$, docs/model.md §3, with the damping on only
    while a flank is in contact. Sign: a positive force opposes growth of its deflection.
    """
    f_drive = stiffness * _smooth.ramp(drive, width) + damping * _smooth.step(drive, width) * drive_rate
    f_back = -stiffness * _smooth.ramp(-back, width) + damping * _smooth.step(-back, width) * back_rate
    return f_drive, f_back
