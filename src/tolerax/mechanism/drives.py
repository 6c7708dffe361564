"""What drives a joint: a PI servo on the motor tracking a commanded output angle (constant
speed or a back-and-forth scan), or a prescribed torque; and the output's drag law.

A servo acts on the motor (sun) shaft through the stage's rigid ratio $i = 1 + z_r/z_s$:
$$T = k_p\\,(i\\dot\\theta^*(t) - \\dot\\theta_s) + k_i\\,(i\\theta^*(t) - \\theta_s),$$
with $\\theta^*(t)$ the commanded *output* angle. A torque drive applies $T(t)$ at the output,
i.e. $T/i$ on the sun.
"""

import abc
import math

import equinox as eqx
import jax.numpy as jnp
from jaxtyping import Array, Float
from .. import _validate as V

DRAG_SPEED = 1e-3  # rad/s: drag torque T tanh(omega / DRAG_SPEED), smooth through zero speed


def drag(torque, omega):
    """Drag torque (N m) resisting an output turning at `omega` (rad/s): $T\\tanh(\\omega/\\omega_0)$,
    $\\omega_0$ = 1e-3 rad/s (harness and seal drag, smoothed through zero speed)."""
    return torque * jnp.tanh(omega / DRAG_SPEED)


class AbstractServo(eqx.Module):
    """A PI speed/position servo on the motor, tracking a commanded output angle $\\theta^*(t)$
    (see the module docstring). Subclasses define `angle(t)` and `rate(t)`."""

    proportional: eqx.AbstractVar[Float[Array, ""]]
    integral: eqx.AbstractVar[Float[Array, ""]]

    @abc.abstractmethod
    def angle(self, t) -> Array:
        """Commanded output angle $\\theta^*(t)$ (rad)."""

    @abc.abstractmethod
    def rate(self, t) -> Array:
        """Commanded output rate $\\dot\\theta^*(t)$ (rad/s)."""

    def motor_angle(self, ratio: float, t) -> Array:
        """Commanded motor (sun) angle $i\\theta^*(t)$ (rad)."""
        return ratio * self.angle(t)

    def torque(self, ratio: float, t, theta_s, omega_s):
        """Motor torque (N m) on the sun at angle `theta_s` (rad) and rate `omega_s` (rad/s)."""
        return self.proportional * (ratio * self.rate(t) - omega_s) + self.integral * (
            self.motor_angle(ratio, t) - theta_s
        )


def _gains(owner, proportional, integral):
    return V.real(owner, "proportional", proportional, "N m s/rad"), V.real(owner, "integral", integral, "N m/rad")


def _check_gains(module):
    V.check(module, proportional=V.NONNEGATIVE("N m s/rad"), integral=V.NONNEGATIVE("N m/rad"))


class SpeedServo(AbstractServo):
    """Constant commanded output rate: $\\theta^*(t) = \\Omega t$.

    - `output_rate`: $\\Omega$ (rad/s); the paper's 0.49, 0.98, 1.96 °/s. 0 holds the joint.
    - `proportional`: $k_p$ (N m s/rad); `integral`: $k_i$ (N m/rad).
    """

    output_rate: Float[Array, ""]
    proportional: Float[Array, ""]
    integral: Float[Array, ""]

    def __init__(self, output_rate=math.radians(0.98), proportional=0.2, integral=2.0):
        self.output_rate = V.real("SpeedServo", "output_rate", output_rate, "rad/s")
        self.proportional, self.integral = _gains("SpeedServo", proportional, integral)

    def __check_init__(self):
        V.check(self, output_rate=V.FINITE("rad/s"))
        _check_gains(self)

    def angle(self, t):
        return self.output_rate * t

    def rate(self, t):
        return self.output_rate * jnp.ones_like(t)

    def motor_angle(self, ratio, t):
        return ratio * self.output_rate * t  # (i Omega) t


class ScanServo(AbstractServo):
    """A back-and-forth scan: $\\theta^*(t) = A\\sin(2\\pi t/T)$, reversing every half period.

    Reversals are what make clearances and backlash show in the pointing error (a one-way drive
    at constant speed keeps every flank and bearing loaded on one side): at each reversal the
    output crosses its lost motion. Peak rate $2\\pi A/T$.

    - `amplitude`: $A$ (rad). `period`: $T$ (s).
    - `proportional`: $k_p$ (N m s/rad); `integral`: $k_i$ (N m/rad).
    """

    amplitude: Float[Array, ""]
    period: Float[Array, ""]
    proportional: Float[Array, ""]
    integral: Float[Array, ""]

    def __init__(self, amplitude=math.radians(0.5), period=2.0, proportional=0.2, integral=2.0):
        self.amplitude = V.real("ScanServo", "amplitude", amplitude, "rad")
        self.period = V.real("ScanServo", "period", period, "s")
        self.proportional, self.integral = _gains("ScanServo", proportional, integral)

    def __check_init__(self):
        V.check(self, amplitude=V.FINITE("rad"), period=V.POSITIVE("s"))
        _check_gains(self)

    def angle(self, t):
        return self.amplitude * jnp.sin(2.0 * jnp.pi * t / self.period)

    def rate(self, t):
        return self.amplitude * (2.0 * jnp.pi / self.period) * jnp.cos(2.0 * jnp.pi * t / self.period)


class ProfileServo(AbstractServo):
    """A tabulated motion profile: the commanded output angle through the points $(t_k,
    \theta_k)$, a step, a slew and settle, a measured scan, by shape-preserving piecewise-cubic
    Hermite interpolation (PCHIP, Fritsch and Carlson: no overshoot between points, so a step
    stays a step; the knot slopes are SciPy's `PchipInterpolator`'s); before the first time the
    first angle, after the last the last angle held. The rate is the interpolant's derivative
    (continuous).

    - `times` (s, increasing, at least two), `angles` (rad), one per time.
    - `proportional`: $k_p$ (N m s/rad); `integral`: $k_i$ (N m/rad).
    """

    times: Float[Array, " k"]
    angles: Float[Array, " k"]
    slopes: Float[Array, " k"]
    proportional: Float[Array, ""]
    integral: Float[Array, ""]

    def __init__(self, times, angles, proportional=0.2, integral=2.0):
        import numpy as np
        import scipy.interpolate

        t, a = np.asarray(times, dtype=float), np.asarray(angles, dtype=float)
        if t.ndim != 1 or t.shape != a.shape or t.size < 2:
            raise ValueError(f"ProfileServo: times and angles must be two lists of the same length >= 2, got {times!r} and {angles!r}.")
        if not (np.all(np.isfinite(t)) and np.all(np.isfinite(a)) and np.all(np.diff(t) > 0)):
            raise ValueError(f"ProfileServo: times must be finite and increasing and angles finite (s, rad), got {times!r} and {angles!r}.")
        self.times, self.angles = jnp.asarray(t), jnp.asarray(a)
        self.slopes = jnp.asarray(scipy.interpolate.PchipInterpolator(t, a).derivative()(t))
        self.proportional, self.integral = _gains("ProfileServo", proportional, integral)

    def __check_init__(self):
        _check_gains(self)

    def _segment(self, t):
        t = jnp.asarray(t, dtype=float)
        k = jnp.clip(jnp.searchsorted(self.times, t) - 1, 0, self.times.shape[0] - 2)
        h = self.times[k + 1] - self.times[k]
        inside = (t >= self.times[0]) & (t <= self.times[-1])
        s = (t - self.times[k]) / h
        s = jnp.where(inside, s, jnp.clip(s, 0.0, 1.0))  # held beyond the table (no clip inside: its derivative at a knot)
        return k, h, s, inside

    def angle(self, t):
        k, h, s, _ = self._segment(t)
        h00, h10, h01, h11 = 2 * s**3 - 3 * s**2 + 1, s**3 - 2 * s**2 + s, -2 * s**3 + 3 * s**2, s**3 - s**2
        return h00 * self.angles[k] + h10 * h * self.slopes[k] + h01 * self.angles[k + 1] + h11 * h * self.slopes[k + 1]

    def rate(self, t):
        k, h, s, inside = self._segment(t)
        d00, d10, d01, d11 = 6 * s**2 - 6 * s, 3 * s**2 - 4 * s + 1, -6 * s**2 + 6 * s, 3 * s**2 - 2 * s
        value = (d00 * self.angles[k] + d01 * self.angles[k + 1]) / h + d10 * self.slopes[k] + d11 * self.slopes[k + 1]
        return jnp.where(inside, value, 0.0)


class TorqueDrive(eqx.Module):
    """Prescribed drive torque $T(t) = A\\cos(2\\pi f t + \\varphi)$ at the joint output (N m).

    Applied to the sun as $T/i$ (the motor torque that gives $T$ at the output through a rigid
    stage). The paper's Table 2: $A$ = 1.5 N m (azimuth), 0.8 N m (pitch), $f$ = 1 Hz.
    """

    amplitude: Float[Array, ""]
    frequency: Float[Array, ""]
    phase: Float[Array, ""]

    def __init__(self, amplitude, frequency=1.0, phase=0.0):
        self.amplitude = V.real("TorqueDrive", "amplitude", amplitude, "N m")
        self.frequency = V.real("TorqueDrive", "frequency", frequency, "Hz")
        self.phase = V.real("TorqueDrive", "phase", phase, "rad")

    def __check_init__(self):
        V.check(self, amplitude=V.FINITE("N m"), frequency=V.NONNEGATIVE("Hz"), phase=V.FINITE("rad"))

    def torque(self, t):
        return self.amplitude * jnp.cos(2.0 * jnp.pi * self.frequency * t + self.phase)


Drive = AbstractServo | TorqueDrive
