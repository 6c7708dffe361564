"""Outputs of the mechanism (docs/model.md §6): what is observed at a state, the result type of a
run, and the spectral vibration amplitude. Angles in rad (divide by `ARCSEC` for arcsec)."""

import math

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from jaxtyping import Array
from ..physics import smooth as _smooth
from ..physics.rigid import vee
from ..solve import SolverReport

ARCSEC = math.pi / (180.0 * 3600.0)
"""One arcsecond in radians: `angle_rad / ARCSEC` is the angle in arcsec."""


def pointing_metrics(
    result, window, peak_order: int | None = None, jitter_cutoff: float | None = None
) -> dict[str, Array]:
    """The pointing metrics of a run over the saved times where `window` (bool, per save time)
    holds: `pointing_rms` $\\sqrt{\\overline{e^2}}$ and `pointing_peak` $\\max e$ of the pointing
    error (arcsec), `tracking_speed_rms` (arcsec/s, RMS norm of the reflector's angular-velocity
    error) and, with `peak_order` $p$, `pointing_smooth_peak` $(\\overline{e^p})^{1/p}$ (a smooth
    surrogate of the peak, $\\le$ the peak, $\\ge$ the RMS). Differentiable (the speed norm is
    safe at 0) and traceable; values outside the window never enter, non-finite ones included.
    The one definition read by the design objective, the scene-file summary and the studies.

    With `jitter_cutoff` $f_c$ (Hz), also `pointing_jitter` (arcsec): the pointing *stability*,
    the RMS over the window of the pointing error high-passed above $f_c$ (`pointing_jitter`
    defines it). The jitter needs the window's length in Python: `window` must then be concrete
    (a NumPy array, not a traced one; `PointingObjective` builds it from its static save times),
    and one contiguous run of saves. Where `result.ts` is concrete, the sampling is checked
    (`check_jitter_sampling`: `ValueError` if too coarse for $f_c$).
    """
    out = _bias_metrics(result, window, peak_order)
    if jitter_cutoff is not None:
        try:
            mask = np.asarray(window, dtype=bool)
        except jax.errors.TracerArrayConversionError:
            raise ValueError(
                "pointing_metrics(jitter_cutoff=...) needs a concrete window (a NumPy bool array): the jitter's "
                "FFT length is its number of saves. Build the window from the static save times, as "
                "PointingObjective does, not from a traced `result.ts`."
            ) from None
        index = np.flatnonzero(mask)
        if index.size < 3 or index[-1] - index[0] + 1 != index.size:
            raise ValueError(f"the jitter window must be one contiguous run of at least 3 saves; got {index.size} saves "
                             f"at indices {index[:3].tolist()}...{index[-3:].tolist()}.")
        ts = result.ts
        if not isinstance(ts, jax.core.Tracer):
            ts = np.asarray(ts)[index]
            spacing = np.diff(ts)
            if not np.allclose(spacing, spacing[0], rtol=1e-9, atol=0.0):
                raise ValueError("the jitter needs equally spaced saves in its window.")
            check_jitter_sampling(float(spacing[0]), index.size, jitter_cutoff)
        first, last = int(index[0]), int(index[-1]) + 1
        spacing = (result.ts[last - 1] - result.ts[first]) / (last - first - 1)
        out["pointing_jitter"] = pointing_jitter(result.pointing_error[first:last], spacing, jitter_cutoff)
    return out


def _bias_metrics(result, window, peak_order):
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


JITTER_SAMPLES_PER_CUTOFF_PERIOD = 4
"""The jitter's minimum save rate, in saves per period of the cutoff: the Nyquist frequency at
least twice the cutoff, so that the band $[f_c, f_N]$ spans an octave or more."""


def check_jitter_sampling(spacing: float, n_saves: int, cutoff: float) -> None:
    """Raise `ValueError` unless saves `spacing` (s) apart, `n_saves` of them, can resolve a
    jitter band above `cutoff` (Hz): a save rate of at least `JITTER_SAMPLES_PER_CUTOFF_PERIOD`
    times the cutoff, and a window at least one cutoff period long (the high-pass must have
    bins below the cutoff to remove)."""
    if not (math.isfinite(cutoff) and cutoff > 0.0):
        raise ValueError(f"jitter_cutoff must be a positive frequency (Hz), got {cutoff!r}.")
    rate = 1.0 / spacing
    need = JITTER_SAMPLES_PER_CUTOFF_PERIOD * cutoff
    if rate < need * (1.0 - 1e-9):
        raise ValueError(
            f"the saves are {rate:.4g} per second, too few for a jitter above {cutoff:g} Hz: the Nyquist frequency "
            f"{rate / 2:.4g} Hz must be at least twice the cutoff. Save at least {need:g} per second (raise n_save), "
            "or lower the cutoff (or, in PointingObjective, set jitter_cutoff=None)."
        )
    length = (n_saves - 1) * spacing
    if length < (1.0 - 1e-9) / cutoff:
        raise ValueError(
            f"the jitter window is {length:.4g} s long, shorter than one period of its {cutoff:g} Hz cutoff: "
            "there is no slow part to remove. Lengthen the window (settle earlier) or raise the cutoff."
        )


def pointing_jitter(error, spacing, cutoff: float = 20.0) -> Array:
    """Pointing stability (jitter, arcsec): the RMS of the pointing error `error` (rad, equally
    spaced samples `spacing` s apart spanning the window) with its slow part, everything below
    `cutoff` (Hz), removed.

    With $e_j$ ($j = 0 \\dots m-1$, arcsec) the samples, $u_j = j/(m-1)$ and $T = (m-1)\\Delta t$
    the window's length, the slow part is

    $$e_0 + (e_{m-1} - e_0)\\,u + \\sum_{f_k < f_c} b_k \\sin(\\pi k u) + c_0\\,u(1-u)(2-u) + c_1\\,u(1-u)(1+u),$$

    the chord through the end samples, the sines of frequency $f_k = k/(2T)$ below the cutoff,
    and two cubics that vanish at both ends with a curvature at one end each, with $b_k$, $c_0$,
    $c_1$ fitted by least squares; the jitter is $\\sqrt{\\tfrac1m \\sum_j h_j^2}$ of the residual
    $h$. Computed as a sine transform (`jnp.fft.rfft` of the chord residual's odd periodic
    extension, length $2(m-1)$, its bins below $f_c$ zeroed: the projection off the low sines),
    then the two cubics' high-passed shapes projected out (a 2 x 2 least-squares solve).

    Why this basis, not the FFT of the samples: the periodic extension of a window's slow part
    (hundreds of arcsec of lost motion) jumps at the ends and leaks $\\propto 1/f$ into the band;
    the odd extension of the chord's residual is continuous with a continuous slope, and leaks
    only through the slow part's curvature at the ends, $\\propto 1/f^3$, with the shape of the
    cubics' high-passed tails, which the cubics take out; what is left leaks $\\propto 1/f^5$ (a
    window starting inside a reversal's transient, thousands of arcsec/s$^2$, otherwise counts
    tenths of an arcsec of it as jitter). A sinusoid above the cutoff of amplitude $a$ gives
    $a/\\sqrt2$ (within 0.1-0.5 %; exact without the cubics when it vanishes at both ends and
    $f = k/(2T)$), one below it about 0; the fit takes about `2 cutoff T + 4` of the $m$
    degrees of freedom, a bias of that fraction in a noise's power.

    Linear in the samples before the RMS, so as smooth as the pointing error itself; the RMS
    has a finite gradient at 0 (`smooth.sqrt`). Sampling: the band is $[f_c, 1/(2\\Delta t)]$ of
    the *sampled* error; what the error holds above the Nyquist frequency $1/(2\\Delta t)$ (the
    rattle's kHz impacts) aliases into $[0, 1/(2\\Delta t)]$ and about a fraction
    $2 f_c \\Delta t$ of it falls below the cutoff and is lost. So the save rate must be well
    above the cutoff (`check_jitter_sampling`: at least 4x, and a window at least $1/f_c$
    long), and jitters are comparable only at the same save rate and window.

    **Arguments:** `error` (rad, $m \\ge 3$ samples), `spacing` (s, may be traced), `cutoff`
    (Hz, a Python number; default 20, where a pointing budget's stability band usually starts).

    **Returns:** the jitter (arcsec), a scalar.
    """
    e = jnp.asarray(error) / ARCSEC
    m = e.shape[0]
    u = jnp.arange(m) / (m - 1)
    frequency = jnp.arange(m) / (2 * (m - 1) * spacing)  # the sine transform's bins, f_k = k / (2T)

    def high_pass(r):  # r vanishes at both ends
        odd = jnp.concatenate([r, -r[-2:0:-1]])
        return jnp.fft.irfft(jnp.where(frequency >= cutoff, jnp.fft.rfft(odd), 0.0), n=odd.shape[0])[:m]

    high = high_pass(e - e[0] - (e[-1] - e[0]) * u)
    cubics = jnp.stack([high_pass(u * (1 - u) * (2 - u)), high_pass(u * (1 - u) * (1 + u))])
    high = high - jnp.linalg.solve(cubics @ cubics.T, cubics @ high) @ cubics
    return _smooth.sqrt(jnp.mean(high**2))


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
