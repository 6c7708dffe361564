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
