"""The reference paper's studies (Han, Liang, Zhao 2021, §3) as grids of scenes, and the
metrics we compare with its figures and tables.

Each study is a list of scenes (a label and a `Mechanism`), run at a *size*: `"small"` (a few
scenes, a few hundredths of a second: it proves the pipeline in CI) or `"full"` (the paper's
grids, coarser where noted, 3 s each with metrics over the last 1 s: hours of CPU for the 46
scenes). Scenes start in steady rolling at the commanded rate (free base, meshes
undeflected). That is not the loaded steady state: the servo then builds its lag against the
output drag, and the output's speed swings down to nearly a stop and back over the first ~2 s.
Metrics therefore start at `settle` = 2 s. The full size also records each scene's metrics over
0.3-1 s under `"start_up"`: a window inside that start-up, not the steady state.

Fidelity per joint, chosen for what each study asks: the *driving* joint is `"planetary"` (the
studies vary its planet, carrier and mesh clearances); the non-driving joint, which the paper
keeps at 100 µm throughout, is `"lumped"` (its output-bearing clearance and backlash, no
internal gear clearances). Dual-axis scenes have both joints planetary. The `fidelity` study
runs the 0.98 °/s scenes at lumped/lumped and planetary/planetary to measure what the cheap
fidelity misses.

A long horizon is `run(..., duration=, settle=)` (`tolerax studies --duration 20 --settle 19`),
saved after every scene and resumable (`done=`, `--resume`), so that a long horizon (the 46
scenes of 20 s that `benchmarks/study_horizon.py` compares) can run in several sittings.
"""

import dataclasses
import math
import time

import numpy as np

from .physics.gears import default_stage
from .mechanism.mechanism import Mechanism
from .mechanism.outputs import MechanismResult, pointing_metrics, vibration_amplitude
from .mechanism.scene import simulate
from .solve import DEFAULT_PID
from .mechanism.scenes import antenna

UM = 1e-6


@dataclasses.dataclass(frozen=True)
class StudySize:
    duration: float  # s per scene
    settle: float  # s skipped before metrics
    n_save: int
    full_grid: bool
    start_up: tuple[float, float] | None = None  # (s) a second window, recorded under "start_up"


SIZES = {
    "small": StudySize(duration=0.03, settle=0.01, n_save=61, full_grid=False),
    "full": StudySize(duration=3.0, settle=2.0, n_save=3001, full_grid=True, start_up=(0.3, 1.0)),
}

STUDIES = ("speed", "fidelity", "radial_clearance", "clearance_grid", "backlash", "coupling", "coupling_grid")


def _stage(carrier=100 * UM, planet=100 * UM, sun=100 * UM, backlash=100 * UM):
    return default_stage(
        carrier_clearance=carrier, planet_clearance=planet, sun_clearance=sun, backlash=backlash
    )


def _single(mode, driving_stage, rate_deg=0.98, other=None, fidelity=None):
    """Single-axis scene: the driving joint planetary with `driving_stage`, the other lumped
    with all 100 µm (or `other`)."""
    other = _stage() if other is None else other
    if mode == "azimuth":
        stages, fids = (driving_stage, other), ("planetary", "lumped")
    else:
        stages, fids = (other, driving_stage), ("lumped", "planetary")
    return antenna(
        mode,
        fidelity=fids if fidelity is None else fidelity,
        rate=math.radians(rate_deg),
        azimuth_stage=stages[0],
        pitch_stage=stages[1],
    )


def scenes(study: str, size: str = "small") -> list[tuple[dict, Mechanism]]:
    """The scenes of one study: `[(labels, mechanism), ...]` (labels in µm and °/s)."""
    if study not in STUDIES:
        raise ValueError(f"study={study!r} is unknown; use one of {STUDIES}.")
    if size not in SIZES:
        raise ValueError(f"size={size!r} is unknown; use one of {tuple(SIZES)}.")
    full = SIZES[size].full_grid
    out = []
    modes = ("azimuth", "pitch")
    if study == "speed":  # Figs. 5-6 (single axis), 17-20 (dual); all clearances 100 um
        rates = (0.49, 0.98, 1.96) if full else (0.98,)
        for mode in ("azimuth", "pitch", "dual") if full else ("azimuth", "dual"):
            for r in rates:
                if mode == "dual":
                    mech = antenna("dual", fidelity="planetary", rate=math.radians(r))
                else:
                    mech = _single(mode, _stage(), r)
                out.append((dict(mode=mode, rate=r), mech))
    elif study == "fidelity":  # the 0.98 deg/s scenes at both fidelities
        for mode in ("azimuth", "pitch", "dual") if full else ("azimuth",):
            for fid in ("lumped", "planetary"):
                out.append((dict(mode=mode, fidelity=fid), antenna(mode, fidelity=fid)))
    elif study == "radial_clearance":  # Table 3, Figs. 7-8: driving-joint backlash 10 um
        cases = {"a": (100, 100), "b": (100, 10), "c": (10, 100)}
        for mode in modes if full else ("azimuth",):
            for case, (cc, cp) in cases.items() if full else list(cases.items())[:2]:
                st = _stage(carrier=cc * UM, planet=cp * UM, backlash=10 * UM)
                out.append((dict(mode=mode, case=case, carrier=cc, planet=cp), _single(mode, st)))
    elif study == "clearance_grid":  # Fig. 9, Tables 4-5: vibration vs (carrier, planet) clearance
        values = (10, 100)  # the paper's Fig. 9 is a fine grid: too costly here
        for mode in modes if full else ("pitch",):
            for cc in values:
                for cp in values if full else (100,):
                    st = _stage(carrier=cc * UM, planet=cp * UM, backlash=10 * UM)
                    out.append((dict(mode=mode, carrier=cc, planet=cp), _single(mode, st)))
    elif study == "backlash":  # Table 6, Figs. 10-11: clearances 10 um, backlash 10-100 um
        values = (10, 55, 100) if full else (10, 100)
        for mode in modes if full else ("azimuth",):
            for b in values:
                st = _stage(carrier=10 * UM, planet=10 * UM, sun=10 * UM, backlash=b * UM)
                out.append((dict(mode=mode, backlash=b), _single(mode, st)))
    elif study == "coupling":  # Table 7, Figs. 12-14: planet clearance x backlash, others 10 um
        cases = {"a": (100, 100), "b": (100, 10), "c": (10, 100)}
        for mode in modes if full else ("pitch",):
            for case, (cp, b) in cases.items() if full else list(cases.items())[:2]:
                st = _stage(carrier=10 * UM, sun=10 * UM, planet=cp * UM, backlash=b * UM)
                out.append((dict(mode=mode, case=case, planet=cp, backlash=b), _single(mode, st)))
    elif study == "coupling_grid":  # Figs. 15-16, Tables 8-9: pitch joint, cpp x b, 20-100 um
        # The paper's grid is fine; here its corners and centre (an interior peak shows at the
        # centre), for cost.
        points = [(20, 20), (20, 100), (100, 20), (100, 100), (60, 60)] if full else [(20, 100), (100, 100)]
        for cp, b in points:
            st = _stage(carrier=10 * UM, sun=10 * UM, planet=cp * UM, backlash=b * UM)
            out.append((dict(mode="pitch", planet=cp, backlash=b), _single("pitch", st)))
    return out


def metrics(mech: Mechanism, res: MechanismResult, settle: float, min_frequency: float = 2.0, end: float | None = None) -> dict:
    """Summary numbers of one run over `settle <= t` (and `t <= end` where given; s), units in
    the key names.

    - `force_*_N`: output-bearing radial contact force of the driving joint (azimuth for dual)
      — peak, mean and standard deviation — and `force_other_peak_N` of the other joint.
    - `pointing_rms_arcsec`, `pointing_peak_arcsec`: pointing error (includes the servo lag).
    - `speed_error_peak_{x,y,z}_urad_s`: tracking speed error, peak per base-frame component.
    - `position_error_peak_{x,y,z}_um`: reflector-centre position error, peak per component.
    - `radial_vibration_um`: `vibration_amplitude` of the reflector-centre position error's
      magnitude (µm, peak spectral amplitude above `min_frequency`).
    - `torsional_vibration_urad`: the same for the driving joint's angle error
      (commanded − actual output angle, µrad).
    """
    ts = np.asarray(res.ts)
    w = (ts >= settle) & (ts <= (np.inf if end is None else end))
    drive = 1 if mech.azimuth.drive.output_rate == 0 else 0  # pitch-only scenes drive joint 1
    force = np.asarray(res.output_force)[w]
    pointing = pointing_metrics(res, w)
    speed = np.asarray(res.tracking_speed_error)[w]
    pos = np.asarray(res.position_error)[w]
    angle_err = np.asarray(res.commanded_angle[:, drive] - res.joint_angle[:, drive])[w]
    out = dict(
        force_peak_N=float(force[:, drive].max()),
        force_mean_N=float(force[:, drive].mean()),
        force_std_N=float(force[:, drive].std()),
        force_other_peak_N=float(force[:, 1 - drive].max()),
        pointing_rms_arcsec=float(pointing["pointing_rms"]),
        pointing_peak_arcsec=float(pointing["pointing_peak"]),
        radial_vibration_um=float(vibration_amplitude(np.linalg.norm(pos, axis=1), ts[w], min_frequency)) / UM,
        torsional_vibration_urad=float(vibration_amplitude(angle_err, ts[w], min_frequency)) / UM,
        steps=int(res.num_steps),
        rejected=int(res.num_rejected),
    )
    for k, axis in enumerate("xyz"):
        out[f"speed_error_peak_{axis}_urad_s"] = float(np.abs(speed[:, k]).max()) / UM
        out[f"position_error_peak_{axis}_um"] = float(np.abs(pos[:, k]).max()) / UM
    return out


def size_spec(size: str, duration: float | None = None, settle: float | None = None) -> StudySize:
    """The `StudySize` of `size`, with its horizon `duration` (s) and metrics start `settle` (s)
    overridden where given; the save rate stays the size's (1 kHz at full size)."""
    if size not in SIZES:
        raise ValueError(f"size={size!r} is unknown; use one of {tuple(SIZES)}.")
    spec = SIZES[size]
    duration = spec.duration if duration is None else float(duration)
    settle = spec.settle if settle is None else float(settle)
    if not (math.isfinite(duration) and duration > 0):
        raise ValueError(f"duration={duration!r} s must be positive.")
    if not (math.isfinite(settle) and 0 <= settle < duration):
        raise ValueError(f"settle={settle!r} s must satisfy 0 <= settle < duration = {duration:g} s "
                         "(the metrics are taken over settle <= t <= duration).")
    if spec.start_up is not None and spec.start_up[1] > duration:
        raise ValueError(f"duration={duration:g} s is shorter than the start-up window {spec.start_up} s "
                         f"the {size!r} size records; give at least {spec.start_up[1]:g} s.")
    rate = (spec.n_save - 1) / spec.duration
    return dataclasses.replace(spec, duration=duration, settle=settle, n_save=int(round(duration * rate)) + 1)


def _same_scene(row: dict, labels: dict, spec: StudySize, size: str) -> bool:
    """Whether `row` (of an earlier run) is the scene `labels` at the horizon of `spec`, solved
    with today's step control (`simulate`'s default controller, `DEFAULT_PID`). Rows written
    before horizons could be overridden carry none: theirs is the size's own; rows written before
    the controller was recorded were solved with diffrax's I-controller (0, 1)."""
    own = SIZES[size]
    horizon = (row.get("duration_s", own.duration), row.get("settle_s", own.settle))
    control = (row.get("pcoeff", 0.0), row.get("icoeff", 1.0))
    return (all(math.isclose(a, b) for a, b in zip(horizon, (spec.duration, spec.settle)))
            and all(math.isclose(a, b) for a, b in zip(control, DEFAULT_PID))
            and all(row.get(k) == v for k, v in labels.items()))


def run(
    study: str,
    size: str = "small",
    progress: bool = True,
    *,
    duration: float | None = None,
    settle: float | None = None,
    done: list[dict] = (),
    on_row=None,
) -> list[dict]:
    """Run every scene of `study` at `size`; one dict per scene (labels, metrics, the horizon
    `duration_s` and `settle_s`, wall time, and for the full size the metrics of the start-up
    window under `"start_up"`).

    - `duration`, `settle` (s): override the size's horizon and metrics start (`size_spec`).
    - `done`: rows of an earlier run (its JSON); a scene with a row there of the same labels and
      horizon and step control (`pcoeff`, `icoeff`, recorded in each row) is not run again and its
      row is kept (a long study resumes where it stopped).
    - `on_row(rows)`: called with the rows so far after each scene (to save them as they come).
    - `progress`: before the study, how many scenes and roughly how long (`tolerax.eta`, before
      compilation); after each scene a line with its wall time and the time left at the pace so far.
    """
    from .eta import human_seconds, rough_wall, time_left

    spec = size_spec(size, duration, settle)
    rows, todo = [], []
    for labels, mech in scenes(study, size):
        kept = next((r for r in done if r.get("study", study) == study and _same_scene(r, labels, spec, size)), None)
        todo.append((labels, mech, kept))
    fresh = [mech for _, mech, kept in todo if kept is None]
    if progress:
        guesses = [rough_wall(mech, spec.duration) for mech in fresh]
        guess = "" if not fresh or None in guesses else f", roughly {human_seconds(max(sum(guesses), 1.0))} on one core plus compilation"
        print(f"{study}: {len(fresh)} of {len(todo)} scenes to run, {spec.duration:g} s simulated each{guess}", flush=True)
    ran, spent = 0, 0.0
    for labels, mech, kept in todo:
        if kept is not None:
            rows.append(kept)
            if progress:
                print(f"{study} {labels}: kept from the earlier run", flush=True)
            continue
        start = time.perf_counter()
        res = simulate(mech, spec.duration, n_save=spec.n_save, start="steady")
        wall = time.perf_counter() - start
        row = dict(study=study, **labels, **metrics(mech, res, spec.settle), duration_s=spec.duration,
                   settle_s=spec.settle, pcoeff=DEFAULT_PID[0], icoeff=DEFAULT_PID[1], wall_s=wall)
        if spec.start_up is not None:
            early = metrics(mech, res, spec.start_up[0], end=spec.start_up[1])
            row["start_up"] = {k: v for k, v in early.items() if k not in ("steps", "rejected")}
        rows.append(row)
        if on_row is not None:
            on_row(rows)
        ran, spent = ran + 1, spent + wall
        if progress:
            print(f"{study} {labels}: {wall:.1f} s wall, {row['steps']} steps; {ran} of {len(fresh)} run"
                  + time_left(spent, ran, len(fresh)), flush=True)
    return rows
