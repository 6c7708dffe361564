"""The pointing-stability (jitter) metric: `pointing_jitter` against closed forms (a sinusoid
above the cutoff on a slow ramp gives amplitude / sqrt 2; a slow signal gives about 0) and
against its definition written out as a least-squares fit, its window, its sampling checks, its
derivative, and on a short lumped scan."""

import dataclasses

import jax
import jax.numpy as jnp
import numpy as np
import pytest

import tolerax as tx
from tolerax.mechanism.outputs import ARCSEC, pointing_jitter, pointing_metrics


@dataclasses.dataclass
class _Run:
    """The fields of a `MechanismResult` that `pointing_metrics` reads."""

    ts: np.ndarray
    pointing_error: np.ndarray

    @property
    def tracking_speed_error(self):
        return np.zeros((self.ts.shape[0], 3))


def _run(ts, arcsec):
    return _Run(np.asarray(ts), np.asarray(arcsec) * ARCSEC)


def _least_squares_residual(e, spacing, cutoff):
    """The definition written out as a least-squares fit, no FFT: the chord through the end
    samples removed, then the residual of a fit by the sines $\\sin(\\pi k u)$ below the cutoff
    ($k/(2T) < f_c$) and the cubics $u(1-u)(2-u)$, $u(1-u)(1+u)$."""
    e = np.asarray(e, dtype=float)
    m = e.size
    u = np.arange(m) / (m - 1)
    r = e - e[0] - (e[-1] - e[0]) * u
    k = np.arange(1, m - 1)
    low = k[k / (2 * (m - 1) * spacing) < cutoff]
    basis = np.concatenate([np.sin(np.pi * np.outer(low, u)), [u * (1 - u) * (2 - u), u * (1 - u) * (1 + u)]]).T
    coef, *_ = np.linalg.lstsq(basis, r, rcond=None)
    return r - basis @ coef


def _jitter(e, spacing, cutoff=20.0):
    return float(pointing_jitter(np.asarray(e) * ARCSEC, spacing, cutoff))


def test_sinusoid_on_a_ramp():
    """A sinusoid that vanishes at both ends at a frequency $k/(2T)$ on any ramp: the jitter is
    its samples' RMS, $a\\sqrt{(m-1)/(2m)}$ (the two zero end samples), within 0.1 % (the
    cubics of the slow part take a sliver of it: 0.06 % measured); the least-squares residual
    written out agrees to rounding; and the bias metrics are the ones without a cutoff."""
    m, T, a = 1001, 1.0, 0.4
    ts = np.linspace(0.0, T, m)
    e = 1500.0 - 300.0 * ts + a * np.sin(2 * np.pi * 50.0 * ts)  # 50 Hz = k / (2T), k = 100
    out = pointing_metrics(_run(ts, e), np.ones(m, bool), jitter_cutoff=20.0)
    np.testing.assert_allclose(out["pointing_jitter"], a * np.sqrt((m - 1) / (2 * m)), rtol=1e-3)
    residual = _least_squares_residual(e, ts[1] - ts[0], 20.0)
    np.testing.assert_allclose(out["pointing_jitter"], np.sqrt(np.mean(residual**2)), rtol=1e-10)
    plain = pointing_metrics(_run(ts, e), np.ones(m, bool))
    assert set(out) == set(plain) | {"pointing_jitter"}
    for name in plain:
        np.testing.assert_array_equal(out[name], plain[name])


@pytest.mark.parametrize("frequency, phase", [(37.3, 0.7), (61.0, 2.0), (143.9, -1.1)])
def test_sinusoid_above_the_cutoff_on_a_slow_curve(frequency, phase):
    """Any phase and frequency above the cutoff, on a slow part of hundreds of arcsec (a lost-
    motion-like ramp, a curvature and a 2 Hz swing): the jitter is $a/\\sqrt2$ within 1 % (a
    sinusoid that does not vanish at the ends puts its end values into the chord, whose line
    the high-pass mostly undoes; 0.1-0.3 % measured)."""
    m, T, a = 801, 0.8, 0.3
    ts = np.linspace(0.0, T, m)
    slow = 1200.0 + 400.0 * ts - 250.0 * ts**2 + 80.0 * np.sin(2 * np.pi * 2.0 * ts + 0.3)
    e = slow + a * np.sin(2 * np.pi * frequency * ts + phase)
    np.testing.assert_allclose(_jitter(e, ts[1] - ts[0]), a / np.sqrt(2.0), rtol=1e-2)


def test_slow_signal_gives_no_jitter():
    """Below the cutoff there is (almost) nothing. A slow part in the fitted basis (any cubic,
    sines below the cutoff) gives 0 to rounding. A generic slow curve of 210 arcsec swing leaks
    under 1e-4 arcsec (only $\\propto 1/f^5$; without the cubics it leaked 0.025 arcsec, the
    $1/f^3$ tail of its end curvatures). A 10 Hz sinusoid: under 0.1 % of its RMS."""
    m, T = 801, 0.8
    ts = np.linspace(0.0, T, m)
    dt = ts[1] - ts[0]
    u = ts / T
    basis = 900.0 - 50.0 * u + 300.0 * u**2 - 120.0 * u**3 + 40.0 * np.sin(np.pi * 3 * u) - 7.0 * np.sin(np.pi * 20 * u)
    assert _jitter(basis, dt) < 1e-9
    slow = 1200.0 + 400.0 * ts - 250.0 * ts**2 + 80.0 * np.sin(2 * np.pi * 2.0 * ts + 0.3)
    assert _jitter(slow, dt) < 1e-4
    assert _jitter(0.3 * np.sin(2 * np.pi * 10.0 * ts + 0.4), dt) < 1e-3 * 0.3 / np.sqrt(2.0)


def test_against_least_squares_and_the_window():
    """On noise plus a slow curve: the FFT computation equals the least-squares fit written out;
    only the window's samples enter (what lies outside, NaN included, changes nothing); a white
    noise keeps the share of its power the fit leaves, (m - fitted) / m."""
    rng = np.random.default_rng(0)
    n, m0, m1, dt = 600, 150, 551, 1e-3
    ts = np.arange(n) * dt
    e = 1000.0 + 300.0 * np.sin(2 * np.pi * ts) + 0.2 * rng.standard_normal(n)
    window = (np.arange(n) >= m0) & (np.arange(n) < m1)
    expected = np.sqrt(np.mean(_least_squares_residual(e[window], dt, 20.0) ** 2))
    got = pointing_metrics(_run(ts, e), window, jitter_cutoff=20.0)["pointing_jitter"]
    np.testing.assert_allclose(got, expected, rtol=1e-10)
    spoiled = e.copy()
    spoiled[:m0] = np.nan
    spoiled[m1:] = 1e9
    np.testing.assert_array_equal(pointing_metrics(_run(ts, spoiled), window, jitter_cutoff=20.0)["pointing_jitter"], got)
    m = m1 - m0
    fitted = 2 + 2 + int(np.ceil(2 * (m - 1) * dt * 20.0)) - 1  # chord, cubics, sines k = 1 .. below 2 T f_c
    np.testing.assert_allclose(got, 0.2 * np.sqrt((m - fitted) / m), rtol=0.1)  # one draw: ~1/sqrt(2m) spread


def test_derivative():
    """Linear before the RMS, so homogeneous: d jitter / d a = jitter / a for a sinusoid of
    amplitude a, in forward and reverse mode; 0 along the ramp (the chord takes it); finite
    (not NaN) at a zero high-passed signal."""
    m, T = 1001, 1.0
    ts = jnp.linspace(0.0, T, m)
    dt = float(ts[1] - ts[0])

    def jitter(a, slope):
        return pointing_jitter((1500.0 + slope * ts + a * jnp.sin(2 * jnp.pi * 50.0 * ts)) * ARCSEC, dt, 20.0)

    expected = float(jitter(0.4, -300.0)) / 0.4
    np.testing.assert_allclose(jax.grad(jitter)(0.4, -300.0), expected, rtol=1e-9)
    np.testing.assert_allclose(jax.jvp(lambda a: jitter(a, -300.0), (0.4,), (1.0,))[1], expected, rtol=1e-9)
    np.testing.assert_allclose(expected, np.sqrt((m - 1) / (2 * m)), rtol=1e-3)
    np.testing.assert_allclose(jax.grad(jitter, argnums=1)(0.4, -300.0), 0.0, atol=1e-9)
    assert np.all(np.isfinite(jax.grad(jitter, argnums=(0, 1))(0.0, -300.0)))


def test_sampling_checks():
    ts = np.linspace(0.0, 1.0, 61)  # 60 saves per second: Nyquist 30 Hz
    run = _run(ts, np.zeros_like(ts))
    with pytest.raises(ValueError, match="too few for a jitter above 20 Hz"):
        pointing_metrics(run, np.ones(61, bool), jitter_cutoff=20.0)
    pointing_metrics(run, np.ones(61, bool), jitter_cutoff=15.0)  # 4 saves per period: enough
    with pytest.raises(ValueError, match="shorter than one period"):
        pointing_metrics(run, ts < 0.05, jitter_cutoff=15.0)
    with pytest.raises(ValueError, match="contiguous"):
        pointing_metrics(run, (ts < 0.3) | (ts > 0.6), jitter_cutoff=15.0)
    with pytest.raises(ValueError, match="concrete window"):
        jax.jit(lambda t: pointing_metrics(_Run(t, run.pointing_error), t >= 0.0, jitter_cutoff=15.0))(ts)
    # The objective checks its static sampling before solving anything.
    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    coarse = tx.PointingObjective(scene, duration=2.0, settle=0.3, n_save=101, jitter_cutoff=20.0)  # 50 saves per second
    with pytest.raises(ValueError, match="raise n_save"):
        coarse(tx.design_of(scene))
    short = tx.PointingObjective(scene, duration=0.6, settle=0.58, n_save=121, jitter_cutoff=20.0)
    with pytest.raises(ValueError, match="shorter than one period"):
        short(tx.design_of(scene))


@pytest.fixture(scope="module")
def lumped_run():
    scene = tx.scan("azimuth", fidelity=("lumped", "ideal"))
    pointing = tx.PointingObjective(scene, duration=0.4, settle=0.3, start="steady", n_save=161, jitter_cutoff=20.0)
    p0 = tx.design_of(scene)
    return pointing, p0, pointing(p0, 1e-6), pointing.run(p0, 1e-6)


def test_lumped_scan_jitter(lumped_run):
    """A short run past the first reversal (0.25 s): the objective's jitter is the least-squares
    residual of the run's own samples over `[settle, duration]`, its window the one the other
    outputs use, and the bias outputs unchanged by the cutoff: those of the objective without
    it (the default, which has no jitter output) and of `pointing_metrics` without it."""
    pointing, p0, out, res = lumped_run
    assert bool(out["success"])
    window = np.asarray(res.ts) >= pointing.settle
    np.testing.assert_array_equal(pointing.jitter_window(), window)
    e = np.asarray(res.pointing_error)[window] / ARCSEC
    expected = np.sqrt(np.mean(_least_squares_residual(e, pointing.duration / (pointing.n_save - 1), 20.0) ** 2))
    np.testing.assert_allclose(out["pointing_jitter"], expected, rtol=1e-8)
    plain = pointing_metrics(res, window, pointing.peak_order)
    without = dataclasses.replace(pointing, jitter_cutoff=None)(p0, 1e-6)
    assert set(out) == set(without) | {"pointing_jitter"}
    for name in plain:
        np.testing.assert_array_equal(out[name], plain[name])
        np.testing.assert_array_equal(out[name], without[name])
    # Stability is a small part of the error: well below the bias it rides on, but not zero.
    assert 0.0 < float(out["pointing_jitter"]) < 0.05 * float(out["pointing_rms"])
