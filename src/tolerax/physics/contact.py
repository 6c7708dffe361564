"""Contact force in a radial clearance (journal in bearing), docs/model.md §2.

Geometry: journal radius $R_a$, bearing radius $R_b = R_a + c$ (radial clearance $c$), axial length
$L$. With the journal-centre displacement $e$ relative to the bearing centre (a 2-vector), the
penetration is $\\delta = |e| - c$, the normal $n = e/|e|$ and the penetration rate
$\\dot\\delta = n\\cdot\\dot e$.

Every law has the form $F = F_{el}(\\delta)\\,[1 + \\hat\\chi\\,\\dot\\delta/\\dot\\delta^-]$ (the Adams
law is $F_{el} + \\mathrm{STEP}\\cdot D\\dot\\delta$), clipped smoothly at $F \\ge 0$ so that contact
never pulls. $\\dot\\delta^-$ is the penetration rate at which *this* impact began; it is carried as
one extra state per contact (see `impact_rate_derivative`), so that the restitution is right for
any impact speed, not only for a reference speed.

Composite modulus: $1/E^* = (1-\\nu_a^2)/E_a + (1-\\nu_b^2)/E_b$ (the paper's
$\\sigma = (1+\\nu^2)/(\\pi E)$ is a flattening error for $\\sigma = (1-\\nu^2)/(\\pi E)$, and
$1/(\\sigma_a+\\sigma_b) = \\pi E^*$).
"""

import abc

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, ArrayLike, Float
from . import smooth as _smooth
from .. import _validate as V


def composite_modulus(
    young_a: ArrayLike, poisson_a: ArrayLike, young_b: ArrayLike, poisson_b: ArrayLike
) -> Float[Array, ""]:
    """$E^*$ (Pa) from $1/E^* = (1-\\nu_a^2)/E_a + (1-\\nu_b^2)/E_b$."""
    return 1.0 / ((1.0 - poisson_a**2) / young_a + (1.0 - poisson_b**2) / young_b)


class JournalBearing(eqx.Module):
    """Geometry and material of one radial clearance.

    **Arguments:**

    - `journal_radius`: $R_a$ (m).
    - `clearance`: radial clearance $c = R_b - R_a$ (m).
    - `length`: axial contact length $L$ (m).
    - `modulus`: composite modulus $E^*$ (Pa); steel on steel by default.
    """

    journal_radius: Float[Array, ""]
    clearance: Float[Array, ""]
    length: Float[Array, ""]
    modulus: Float[Array, ""]

    def __init__(self, journal_radius, clearance, length=8e-3, modulus=None):
        if modulus is None:
            modulus = composite_modulus(206e9, 0.3, 206e9, 0.3)
        # Any shape (one bearing, or one per planet pin), as long as they broadcast together.
        self.journal_radius = V.real("JournalBearing", "journal_radius", journal_radius, "m", shape=None)
        self.clearance = V.real("JournalBearing", "clearance", clearance, "m", shape=None)
        self.length = V.real("JournalBearing", "length", length, "m", shape=None)
        self.modulus = V.real("JournalBearing", "modulus", modulus, "Pa", shape=None)

    def __check_init__(self):
        V.check(
            self,
            journal_radius=V.POSITIVE("m"),
            clearance=V.NONNEGATIVE("m"),
            length=V.POSITIVE("m"),
            modulus=V.POSITIVE("Pa"),
        )
        shapes = [jnp.shape(x) for x in (self.journal_radius, self.clearance, self.length, self.modulus)]
        try:
            np.broadcast_shapes(*shapes)
        except ValueError:
            raise ValueError(
                f"JournalBearing fields must broadcast together (one value, or one per planet), got "
                f"shapes journal_radius {shapes[0]}, clearance {shapes[1]}, length {shapes[2]}, modulus {shapes[3]}."
            ) from None
        if V.concrete(self.clearance, self.journal_radius) and not np.all(
            np.asarray(self.clearance) < np.asarray(self.journal_radius)
        ):
            raise ValueError(
                f"JournalBearing.clearance must be smaller than journal_radius (m): a clearance of "
                f"{np.asarray(self.clearance)} m around a {np.asarray(self.journal_radius)} m journal "
                f"is not a bearing (clearances are µm, journals mm)."
            )

    def hertz_stiffness(self) -> Float[Array, ""]:
        """$K = \\tfrac43 E^* \\sqrt{R_a R_b/(R_b - R_a)}$ (N/m^1.5). Diverges as $c \\to 0$
        (conformal contact): use `BaiZhao` or `AdamsImpact` for near-zero clearances."""
        ra = self.journal_radius
        rb = ra + self.clearance
        return 4.0 / 3.0 * self.modulus * _smooth.sqrt(ra * rb / self.clearance)


class AbstractContactLaw(eqx.Module):
    """A normal-force law $F(\\delta, \\dot\\delta, \\dot\\delta^-)$ for a radial clearance."""

    @abc.abstractmethod
    def elastic(self, bearing: JournalBearing, penetration: Array) -> Array:
        """$F_{el}(\\delta)$ (N) for $\\delta \\ge 0$ (m)."""

    @abc.abstractmethod
    def damped(
        self,
        bearing: JournalBearing,
        penetration: Array,
        rate: Array,
        impact_rate: Array,
        elastic: Array,
    ) -> Array:
        """Unclipped total normal force (N), given $F_{el}$ already evaluated."""

    def potential(self, bearing: JournalBearing, penetration: Array) -> Array:
        """Elastic energy $\\int_0^\\delta F_{el}$ (J), where a closed form exists."""
        raise NotImplementedError(f"{type(self).__name__} has no closed-form potential")


class _AbstractRestitutionLaw(AbstractContactLaw):
    """$F = F_{el}[1 + \\hat\\chi(c_e)\\,\\dot\\delta/\\dot\\delta^-]$."""

    restitution: Float[Array, ""]

    def __init__(self, restitution=0.9):
        self.restitution = V.real(type(self).__name__, "restitution", restitution, "-", shape=None)

    def __check_init__(self):
        V.check(self, restitution=V.RESTITUTION)

    @abc.abstractmethod
    def chi(self) -> Array:
        """Dimensionless hysteresis factor $\\hat\\chi$."""

    def damped(self, bearing, penetration, rate, impact_rate, elastic):
        return elastic * (1.0 + self.chi() * rate / impact_rate)


class _AbstractHertzLaw(_AbstractRestitutionLaw):
    """Hertzian elastic force $F_{el} = K\\delta^{1.5}$ with a restitution-based hysteresis
    factor $\\hat\\chi$ left to the final law."""

    def elastic(self, bearing, penetration):
        return bearing.hertz_stiffness() * _smooth.power(penetration, 1.5)

    def potential(self, bearing, penetration):
        return bearing.hertz_stiffness() * _smooth.power(penetration, 2.5) / 2.5


class HertzLN(_AbstractHertzLaw):
    """Lankarani–Nikravesh (1990): $F_{el} = K\\delta^{1.5}$, $\\hat\\chi = 3(1-c_e^2)/4$.

    Only accurate for $c_e \\to 1$: at $c_e = 0.5$ its effective restitution is well above nominal.
    """

    def chi(self):
        return 0.75 * (1.0 - self.restitution**2)


class Flores(_AbstractHertzLaw):
    """Flores et al. (2011): $F_{el} = K\\delta^{1.5}$, $\\hat\\chi = 8(1-c_e)/(5c_e)$.

    Effective restitution close to nominal over $c_e \\in [0.3, 0.95]$.
    """

    def chi(self):
        return 8.0 * (1.0 - self.restitution) / (5.0 * self.restitution)


class BaiZhao(_AbstractRestitutionLaw):
    """The reference paper's hybrid law (Bai & Zhao), with consistent units.

    $F_{el} = L\\,\\tfrac{\\pi E^*}{2}\\,\\delta\\sqrt{\\delta/(2(\\Delta R + \\delta))}$, $\\Delta R = c$,
    i.e. the per-unit-length Liu force times the axial length $L$;
    $\\hat\\chi = \\tfrac34(1-c_e^2)e^{2(1-c_e)}$.

    The paper's eq. (16) $K_n$ is the slope $dF/d\\delta$ of the per-unit-length Liu force; its
    eq. (19) then writes $K_n\\delta^{1.5}$, which is not a force (units). We use the force itself.
    """

    def chi(self):
        ce = self.restitution
        return 0.75 * (1.0 - ce**2) * jnp.exp(2.0 * (1.0 - ce))

    def elastic(self, bearing, penetration):
        d = jnp.maximum(penetration, 0.0)
        # d * sqrt(d / (2 (c + d))) written as d^1.5 / sqrt(2 (c + d)) with safe pieces: finite
        # gradient at d = 0 even for zero clearance (where it tends to d / sqrt(2)).
        denom = 2.0 * (bearing.clearance + d)
        safe = jnp.where(denom > 0, denom, 1.0)
        ratio = jnp.where(denom > 0, _smooth.power(d, 1.5) / jnp.sqrt(safe), 0.0)
        return bearing.length * 0.5 * jnp.pi * bearing.modulus * ratio


class AdamsImpact(AbstractContactLaw):
    """MSC Adams `IMPACT`-style law (the paper's Table 2 runs).

    $F = K\\delta^{e} + \\mathrm{STEP}(\\delta, 0, 0, d_{max}, D)\\,\\dot\\delta$, with the cubic
    Adams STEP ramping the damping in over a penetration $d_{max}$. The paper gives
    $K = 10^7$ N/m (units N/m^e), $D = 100$ N s/m and not $d_{max}$; we take $d_{max} = 10$ µm.
    This law is not restitution-based: its effective restitution depends on impact speed.
    """

    stiffness: Float[Array, ""]
    exponent: float = eqx.field(static=True)
    damping: Float[Array, ""]
    damping_depth: Float[Array, ""]

    def __init__(self, stiffness=1e7, exponent=1.5, damping=100.0, damping_depth=1e-5):
        self.stiffness = V.real("AdamsImpact", "stiffness", stiffness, "N/m^exponent")
        self.exponent = float(V.real("AdamsImpact", "exponent", exponent, "-"))
        self.damping = V.real("AdamsImpact", "damping", damping, "N s/m")
        self.damping_depth = V.real("AdamsImpact", "damping_depth", damping_depth, "m")

    def __check_init__(self):
        V.check(
            self,
            stiffness=V.POSITIVE("N/m^exponent"),
            # exponent >= 1: a force growing slower than linearly has an infinite stiffness at
            # contact onset (Adams itself requires e >= 1).
            exponent=V.Rule("-", low=1.0),
            damping=V.NONNEGATIVE("N s/m"),
            damping_depth=V.POSITIVE("m"),
        )

    def elastic(self, bearing, penetration):
        return self.stiffness * _smooth.power(penetration, self.exponent)

    def potential(self, bearing, penetration):
        return self.stiffness * _smooth.power(penetration, self.exponent + 1) / (self.exponent + 1)

    def damped(self, bearing, penetration, rate, impact_rate, elastic):
        s = jnp.clip(penetration / self.damping_depth, 0.0, 1.0)
        return elastic + self.damping * s * s * (3.0 - 2.0 * s) * rate


class ContactState(eqx.Module):
    """Kinematics of one clearance at an instant (all smoothed with the same width).

    - `penetration`: $\\delta_+ = \\mathrm{ramp}(|e|_\\varepsilon - c)$ (m), $\\ge 0$.
    - `gap_signed`: $|e|_\\varepsilon - c$ (m), negative while separated.
    - `normal`: $n = e/|e|_\\varepsilon$ (zero at $e = 0$).
    - `rate`: $\\dot\\delta = n\\cdot\\dot e$ (m/s).
    """

    penetration: Array
    gap_signed: Array
    normal: Array
    rate: Array


def contact_kinematics(
    bearing: JournalBearing,
    e: Float[ArrayLike, "2"],
    e_dot: Float[ArrayLike, "2"],
    width: ArrayLike,
) -> ContactState:
    """Penetration, normal and penetration rate for journal displacement `e` (m), `e_dot` (m/s)."""
    e = jnp.asarray(e)
    r = _smooth.norm(e, width)
    safe_r = jnp.where(r > 0, r, 1.0)
    normal = jnp.where((r > 0)[..., None], e / safe_r[..., None], 0.0)
    gap_signed = r - bearing.clearance
    return ContactState(
        penetration=_smooth.ramp(gap_signed, width),
        gap_signed=gap_signed,
        normal=normal,
        rate=jnp.sum(normal * e_dot, axis=-1),
    )


CLIP_WIDTH = 1e-3
"""Dimensionless width of the smooth clip $F \\ge 0$, relative to $F_{el}$ (for $\\varepsilon > 0$)."""


FORCE_FLOOR = 1e-100
"""Elastic forces below this (N) are treated as exactly zero contact (see `normal_force`)."""


def effective_impact_rate(impact_rate: ArrayLike, floor: ArrayLike) -> Array:
    """$\\max(\\dot\\delta^-, v_{min})$ with a softplus of width $v_{min}/10$ (m/s).

    Restitution-based damping divides by the impact speed; for grazing or resting contact that
    speed tends to 0 and the damping to infinity. Below `floor` an impact is treated as a
    `floor`-speed impact (the model's only departure from the law; documented in the README).
    """
    return floor + _smooth.ramp(impact_rate - floor, 0.1 * floor)


def normal_force(
    law: AbstractContactLaw,
    bearing: JournalBearing,
    state: ContactState,
    impact_rate: ArrayLike,
    width: ArrayLike,
    rate_floor: ArrayLike = 1e-3,
) -> Float[Array, ""]:
    """Normal contact force magnitude (N), $\\ge 0$.

    The elastic part is multiplied by $d\\delta_+/d\\delta$ (the smooth ramp's slope, 1 in
    contact) so that with damping off the smoothed force is exactly the gradient of the potential
    $U(\\delta_+)$: energy is then conserved by the smoothed model, not just by its limit.
    The total is clipped at 0 by a ramp of width `CLIP_WIDTH` $\\cdot F_{el}$ (exact clip at
    $\\varepsilon = 0$): worst-case error `CLIP_WIDTH`$\\cdot\\ln 2\\cdot F_{el}$ where the
    damping cancels the elastic force, and exactly zero force while separated.

    **Arguments:**

    - `law`: the contact law.
    - `bearing`: geometry and material.
    - `state`: from `contact_kinematics`.
    - `impact_rate`: $\\dot\\delta^-$ (m/s), the contact's impact-rate state.
    - `width`: smoothing width $\\varepsilon$ (m).
    - `rate_floor`: $v_{min}$ (m/s), see `effective_impact_rate`.
    """
    slope = _smooth.step(state.gap_signed, width)
    elastic = law.elastic(bearing, state.penetration) * slope
    total = law.damped(
        bearing,
        state.penetration,
        state.rate,
        effective_impact_rate(impact_rate, rate_floor),
        elastic,
    )
    # Clip F >= 0 with a ramp whose width is a fixed fraction of F_el: F_el * ramp(F/F_el, w)
    # = ramp(F, w F_el). It vanishes with F_el, so a separated contact carries exactly no force
    # (a fixed force width would leave a constant ln2 * width push), and the bracket
    # [1 + chi rate / rate0] is smoothed over a dimensionless width of CLIP_WIDTH.
    # Below FORCE_FLOOR the elastic force is an exponentially small smoothing tail (the contact is
    # open): the force is set to exactly 0 there. Without this, the clip width CLIP_WIDTH * F_el
    # reaches 1e-286 N a fraction of a micrometre before contact, and the ramp's derivative with
    # respect to its width (x / w^2, w^2 underflowing to 0) turns reverse-mode gradients into NaN.
    f_el = law.elastic(bearing, state.penetration)
    live = f_el > FORCE_FLOOR
    clip = jnp.where(jnp.asarray(width) > 0, CLIP_WIDTH, 0.0) * jnp.where(live, f_el, 1.0)
    return jnp.where(live, _smooth.ramp(jnp.where(live, total, 0.0), clip), 0.0)


def rate_derivative(
    bearing: JournalBearing,
    e: Float[ArrayLike, "2"],
    e_dot: Float[ArrayLike, "2"],
    e_ddot: Float[ArrayLike, "2"],
    width: ArrayLike,
) -> Array:
    """$\\ddot\\delta = \\dot n\\cdot\\dot e + n\\cdot\\ddot e$ (m/s²), by forward-mode AD of the rate."""

    def rate(e_, e_dot_):
        return contact_kinematics(bearing, e_, e_dot_, width).rate

    return jax.jvp(rate, (jnp.asarray(e), jnp.asarray(e_dot)), (jnp.asarray(e_dot), jnp.asarray(e_ddot)))[1]


def impact_rate_derivative(
    state: ContactState,
    rate_dot: ArrayLike,
    impact_rate: ArrayLike,
    width: ArrayLike,
    relaxation_time: ArrayLike,
) -> Array:
    """Time derivative of the impact-rate state $v$ (m/s²).

    $\\dot v = (1 - H_\\varepsilon(\\delta))\\,[\\ddot\\delta + (\\dot\\delta - v)/\\tau]$: out of
    contact $v$ follows $\\dot\\delta$ exactly (the feed-forward $\\ddot\\delta$ removes the lag of a
    plain relaxation) and any offset left by the previous contact decays with time constant
    $\\tau$; in contact $v$ is frozen at the rate at which the impact began.
    `rate_dot` is $\\ddot\\delta$, computed by the caller from the accelerations.
    """
    free = 1.0 - _smooth.step(state.gap_signed, width)
    return free * (rate_dot + (state.rate - impact_rate) / relaxation_time)
