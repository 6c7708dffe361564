"""Outputs of the mechanism (docs/model.md §6): what is observed at a state, the result type of a
run, and the spectral vibration amplitude. Angles in rad (divide by `ARCSEC` for arcsec)."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
from jaxtyping import Array
from ..physics import smooth as _smooth
from ..physics.rigid import vee
from ..solve import SolverReport

ARCSEC = math.pi / (180.0 * 3600.0)
"""One arcsecond in radians: `angle_rad / ARCSEC` is the angle in arcsec."""


def pointing_metrics(result, window, peak_order: int | None = None) -> dict[str, Array]:
    """The pointing metrics of a run over the saved times where `window` (bool, per save time)
    holds: `pointing_rms` $\\sqrt{\\overline{e^2}}$ and `pointing_peak` $\\max e$ of the pointing
    error (arcsec), `tracking_speed_rms` (arcsec/s, RMS norm of the reflector's angular-velocity
    error) and, with `peak_order` $p$, `pointing_smooth_peak` $(\\overline{e^p})^{1/p}$ (a smooth
    surrogate of the peak, $\\le$ the peak, $\\ge$ the RMS). Differentiable (the speed norm is
    safe at 0) and traceable; values outside the window never enter, non-finite ones included.
    The one definition read by the design objective, the scene-file summary and the studies."""
    window = jnp.asarray(window)
    weight = window / jnp.sum(window)
    e = jnp.where(window, jnp.asarray(result.pointing_error) / ARCSEC, 0.0)
    squared_speed = jnp.sum(jnp.where(window[:, None], jnp.asarray(result.tracking_speed_error), 0.0) ** 2, axis=-1)
    speed = jnp.sqrt(squared_speed + 1e-300) / ARCSEC
    out = dict(
        pointing_rms=jnp.sqrt(jnp.sum(weight * e**2)),
        pointing_peak=jnp.max(e),
        tracking_speed_rms=jnp.sqrt(jnp.sum(weight * speed**2)),
    )
    if peak_order is not None:
        out["pointing_smooth_peak"] = jnp.sum(weight * e**peak_order) ** (1.0 / peak_order)
    return out


class Observation(eqx.Module):
    """Instantaneous outputs (see `MechanismResult` for definitions)."""

    joint_angle: Array
    commanded_angle: Array
    pointing_error: Array
    position_error: Array
    tracking_speed_error: Array
    runout: Array
    azimuth_contact: Array
    pitch_contact: Array
    momentum: Array
    angular_momentum: Array
    kinetic_energy: Array


def observe(mech, t, q, u, contacts) -> Observation:
    """The outputs of `mech` at time `t` (s), coordinates `q`, speeds `u`, with the joints'
    contact forces `contacts` (N)."""
    qd = mech.qdot(q, u)
    ones = jnp.ones_like(t)
    # Motion relative to the base: the base-frame chain and its time derivative.
    (p_act, r_act), (v_act, rd_act) = jax.jvp(mech.reflector_in_base, (q, t), (qd, ones))
    angles, rates = jax.jvp(lambda t_: mech.reference_angles(q, t_), (t,), (ones,))
    actual, actual_rate = jax.jvp(mech.output_angles, (q, t), (qd, ones))
    # For a torque drive the reference follows the measured angle: its rate is the measured rate.
    for k, (joint, _, _, _) in enumerate(mech.joints()):
        if joint.commanded_angle(t) is None:
            rates = rates.at[k].set(actual_rate[k])
    (p_cmd, r_cmd), (v_cmd, rd_cmd) = jax.jvp(mech.ideal_reflector, (angles,), (rates,))
    boresight = r_act[:, 1]
    commanded = r_cmd[:, 1]
    cross = _smooth.norm(jnp.cross(boresight, commanded), 0.0)
    pointing = jnp.arctan2(cross, jnp.dot(boresight, commanded))
    lin, ang = mech.momentum(q, u, t)
    return Observation(
        joint_angle=actual,
        commanded_angle=angles,
        pointing_error=pointing,
        position_error=p_act - p_cmd,
        tracking_speed_error=vee(rd_act @ r_act.T) - vee(rd_cmd @ r_cmd.T),
        runout=jnp.stack([joint.runout(q[sq]) for joint, sq, _, _ in mech.joints()]),
        azimuth_contact=contacts[0],
        pitch_contact=contacts[1],
        momentum=lin,
        angular_momentum=ang,
        kinetic_energy=mech.kinetic_energy(q, u, t),
    )


class MechanismResult(SolverReport, Observation):
    """Time series of a mechanism run. SI units, angles in rad, vectors in the base frame.

    - `ts` (s). `joint_angle`, `commanded_angle`: (n, 2) azimuth and pitch output angles; the
      commanded angle is the servo's $\\theta^*(t)$, the measured angle for a torque drive.
    - `pointing_error`: angle (rad) between the actual boresight and the commanded one (ideal
      joints at the commanded angles), both in the base (spacecraft) frame.
    - `position_error`: reflector centre minus its commanded position (m), (n, 3).
    - `tracking_speed_error`: reflector angular velocity relative to the base minus the
      commanded one (rad/s), (n, 3).
    - `runout`: radial runout of each joint output, $|(x_c, y_c)|$ (m), (n, 2); 0 where the
      fidelity has no output translation.
    - `azimuth_contact`, `pitch_contact`: normal force of each clearance contact (N), columns
      `azimuth_contact_names` / `pitch_contact_names`; `output_force` (property) is the output
      bearing's (carrier's) radial contact force per joint.
    - `momentum`, `angular_momentum` (about the world origin), `kinetic_energy`: invariants.
    - `states`: `(q, u, impact_rates)`.
    - solver report (`SolverReport`): `result`, `t_reached`, `num_steps`, `num_rejected`,
      `duration`; `success`, `failures()`, `report()` (per sample for a batch).
    """

    _what = "mechanism"

    # The Observation's series (one row per save time), and:
    ts: Array
    states: tuple
    azimuth_contact_names: tuple[str, ...] = eqx.field(static=True)
    pitch_contact_names: tuple[str, ...] = eqx.field(static=True)

    @property
    def output_force(self) -> Array:
        """(n, 2) radial contact force at the azimuth and pitch outputs (N); 0 without clearance."""
        cols = []
        for force, names in ((self.azimuth_contact, self.azimuth_contact_names), (self.pitch_contact, self.pitch_contact_names)):
            cols.append(force[:, names.index("carrier")] if "carrier" in names else jnp.zeros(force.shape[0]))
        return jnp.stack(cols, axis=1)


def vibration_amplitude(signal, ts, min_frequency: float = 1.0):
    """Peak of the single-sided amplitude spectrum of `signal` above `min_frequency` (Hz).

    The signal (uniformly sampled at `ts`) has its mean and linear trend removed, then
    $A(f_k) = 2|X_k|/n$ (a sinusoid of amplitude $a$ at a bin frequency gives $a$). Below
    `min_frequency` lie the servo's start-up and drift, which are not vibration. Same units as
    `signal`. This is how the reflector's radial and torsional vibration amplitudes are defined.
    """
    signal = jnp.asarray(signal)
    ts = jnp.asarray(ts)
    n = signal.shape[0]
    tc = ts - jnp.mean(ts)
    slope = jnp.sum(tc * (signal - jnp.mean(signal))) / jnp.sum(tc**2)
    detrended = signal - jnp.mean(signal) - slope * tc
    spectrum = 2.0 * jnp.abs(jnp.fft.rfft(detrended)) / n
    freqs = jnp.fft.rfftfreq(n, d=(ts[1] - ts[0]))
    return jnp.max(jnp.where(freqs >= min_frequency, spectrum, 0.0))
