"""Gradient-safe smooth primitives with an explicit width and an exact limit.

Every non-smooth function in tolerax (ramp, dead zone, contact switch, vector norm, fractional
power at zero) goes through this module. Each primitive takes a *width* $\\varepsilon$ in the units
of its argument (metres for displacements). `width = 0` is accepted and gives the exact piecewise
function, for reference solutions; gradients are finite everywhere, including exactly at the kinks
and at zero norm.

Worst-case errors against the exact function (used in the tests):

| primitive | at the kink | tails |
|---|---|---|
| `ramp` (softplus) | $\\varepsilon\\ln 2$ at $x=0$ | $\\varepsilon e^{-|x|/\\varepsilon}$ (exponentially small) |
| `step` (logistic) | $1/2$ at $x=0$ (the exact step is discontinuous) | $e^{-|x|/\\varepsilon}$ |
| `dead_zone` | $\\varepsilon\\ln 2$ at each gap edge | $\\varepsilon e^{-d/\\varepsilon}$, $d$ distance to nearest edge |
| `norm` | $\\varepsilon$ at $v=0$ | $\\varepsilon^2/(2|v|)$ (algebraic) |

The softplus ramp was chosen over $\\tfrac12(x+\\sqrt{x^2+\\varepsilon^2})$ because its tails are
exponentially small: the algebraic tail $\\varepsilon^2/(4|x|)$ of the square-root form leaks
force across a 10 µm gap unless $\\varepsilon \\ll$ gap. The norm keeps the algebraic form because
it is only ever evaluated far from zero (at the clearance, $|e| \\approx c$) or where its value
at zero is harmless (the force direction $e/|e|_\\varepsilon$ then vanishes).
"""

import jax
import jax.numpy as jnp
from jaxtyping import Array, ArrayLike, Float


# Widths at or below this count as 0 (the exact function): below ~1e-154 the width derivative's
# x / w**2 overflows to inf (and 0 * inf = NaN in reverse mode). 1e-150 m is 140 decades below
# any physical width, so the exact function is the same number to every printed digit.
WIDTH_FLOOR = 1e-150


def _split_width(width):
    """Return (is_smooth, safe_width): safe_width is 1 where the width is 0 (at most
    `WIDTH_FLOOR`) so that the unused branch of a `jnp.where` never produces inf/NaN (which
    would poison reverse-mode)."""
    width = jnp.asarray(width)
    is_smooth = width > WIDTH_FLOOR
    return is_smooth, jnp.where(is_smooth, width, 1.0)


def ramp(x: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """Smooth $\\max(0, x)$: $\\varepsilon\\,\\mathrm{softplus}(x/\\varepsilon)$.

    **Arguments:**

    - `x`: argument (any unit).
    - `width`: smoothing width $\\varepsilon \\ge 0$, in the unit of `x`; 0 gives the exact ramp.

    **Returns:** a value $\\ge \\max(0, x)$, exceeding it by at most $\\varepsilon\\ln 2$ (at $x=0$).
    """
    x = jnp.asarray(x)
    is_smooth, w = _split_width(width)
    smooth = w * jnp.logaddexp(0.0, x / w)
    return jnp.where(is_smooth, smooth, jnp.maximum(x, 0.0))


def step(x: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """Smooth Heaviside step, the derivative of `ramp`: $\\sigma(x/\\varepsilon)$.

    `width = 0` gives the exact step with value 1/2 at $x = 0$.
    """
    x = jnp.asarray(x)
    is_smooth, w = _split_width(width)
    return jnp.where(is_smooth, jax.nn.sigmoid(x / w), jnp.heaviside(x, 0.5))


def dead_zone(g: ArrayLike, backlash: ArrayLike, width: ArrayLike) -> Float[Array, "..."]:
    """Smooth backlash dead zone $f_g(g)$.

    Exact form: $g$ for $g \\ge 0$ (drive flank in contact), 0 for $-b < g < 0$ (no contact),
    $g + b$ for $g \\le -b$ (back flank). Written as $\\mathrm{ramp}(g) - \\mathrm{ramp}(-g-b)$, so
    the smoothed function stays exactly odd about the centre of the gap $g = -b/2$.

    **Arguments:**

    - `g`: relative displacement along the line of action (m), positive = drive flank compressed.
    - `backlash`: total backlash $b \\ge 0$ (m).
    - `width`: smoothing width (m).
    """
    g = jnp.asarray(g)
    return ramp(g, width) - ramp(-g - backlash, width)


def norm(v: Float[ArrayLike, "... d"], width: ArrayLike) -> Float[Array, "..."]:
    """Gradient-safe Euclidean norm over the last axis: $\\sqrt{|v|^2 + \\varepsilon^2}$.

    At `width = 0` this is the exact norm, with gradient 0 (a subgradient) at $v = 0$ instead of
    the NaN that `jnp.linalg.norm` gives in reverse mode.
    """
    v = jnp.asarray(v)
    width = jnp.asarray(width)
    sq = jnp.sum(v * v, axis=-1) + width * width
    positive = sq > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, sq, 1.0)), 0.0)


def power(x: ArrayLike, exponent: float) -> Float[Array, "..."]:
    """$x^p$ for $x \\ge 0$ (negative `x` is treated as 0) with a finite gradient at 0.

    Avoids the `sqrt(x) * x` trap, whose reverse-mode gradient at 0 is `0 * inf = NaN`.
    `exponent` must be $\\ge 1$ for the gradient at 0 to be finite (it is then 0 or 1).
    """
    x = jnp.asarray(x)
    positive = x > 0
    safe = jnp.where(positive, x, 1.0)
    return jnp.where(positive, safe**exponent, 0.0)


def sqrt(x: ArrayLike) -> Float[Array, "..."]:
    """$\\sqrt{x}$ for $x \\ge 0$ with gradient 0 (not inf/NaN) at and below 0."""
    x = jnp.asarray(x)
    positive = x > 0
    return jnp.where(positive, jnp.sqrt(jnp.where(positive, x, 1.0)), 0.0)
