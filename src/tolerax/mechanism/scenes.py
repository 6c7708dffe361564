"""Built-in scenes: the reference paper's antenna cases (`antenna`) and the tolerance-design
scene (`scan`), in which the motion reverses so that every clearance and backlash shows in the
pointing error."""

import math

import numpy as np

from .drives import ProfileServo, ScanServo, SpeedServo, TorqueDrive
from . import FIDELITIES
from .mechanism import Mechanism
from .structure import Geometry, Inertias
from ..physics.stage import PlanetaryStage


DRIVE_MODES = ("azimuth", "pitch", "dual")
DRIVES = ("speed", "scan", "torque", "profile")


def antenna(
    mode: str = "azimuth",
    *,
    fidelity: str | tuple[str, str] = "planetary",
    rate: float = math.radians(0.98),
    drive: str = "speed",
    base: str = "free",
    azimuth_stage: PlanetaryStage | None = None,
    pitch_stage: PlanetaryStage | None = None,
    torques: tuple[float, float] = (1.5, 0.8),
    servo_gains: tuple[float, float] = (0.2, 2.0),
    drag_torque: float = 0.05,
    motor_inertia: float = 2e-4,
    scan_amplitude: float = math.radians(0.5),
    scan_period: float = 2.0,
    mass_scaling: float | None = None,
    geometry: Geometry | None = None,
    inertias: Inertias | None = None,
    profile_times: list[float] | None = None,
    profile_angles: list[float] | None = None,
) -> Mechanism:
    """A scene of the paper: driving `mode` `"azimuth"`, `"pitch"` (single-axis) or `"dual"`.

    - `fidelity`: one for both joints or `(azimuth, pitch)`; a name in `FIDELITIES`
      (`"ideal"`, `"lumped"`, `"planetary"`, `"planetary-scaled"`), i.e. the joint classes
      `IdealJoint`, `LumpedJoint`, `PlanetaryJoint`, `MassScaledPlanetaryJoint` (its default
      `mass_scaling`).
    - `rate`: commanded output rate of each driven joint (rad/s; the paper's 0.49, 0.98,
      1.96 °/s). A non-driven joint is held by its servo at angle 0 (`drive="speed"`).
    - `drive`: `"speed"` (PI servo on each motor), `"scan"` (the servo tracks a back-and-forth
      scan $A\\sin(2\\pi t/T)$, `scan_amplitude` rad, `scan_period` s; see `ScanServo`) or
      `"torque"` (the paper's Table 2 torques `torques` = $(T_a, T_p)$ N m at 1 Hz on the driven
      joints). Either way a non-driven joint is held at angle 0 by its servo (an ideal one is
      locked).
    - `base`: `"free"` (floating spacecraft) or `"fixed"`.
    - `azimuth_stage`, `pitch_stage`: gear data (default `default_stage()`: 100 µm clearances
      and backlash).
    - `servo_gains`: $(k_p, k_i)$ of the motor servos (N m s/rad, N m/rad).
    - `mass_scaling`: $s \\ge 1$ of every `"planetary-scaled"` joint (default: the class's,
      10); an error with no such joint.
    - `geometry`, `inertias`: the structure (`Geometry`: offsets of the joints, links and
      reflector, m; `Inertias`: masses, kg, and principal inertias, kg m^2); default the
      paper's Table 1.
    """
    if mode not in DRIVE_MODES:
        raise ValueError(f"mode={mode!r} is unknown; use one of {DRIVE_MODES}.")
    if drive not in DRIVES:
        raise ValueError(f"drive={drive!r} is unknown; use one of {DRIVES}.")
    fids = (fidelity, fidelity) if isinstance(fidelity, str) else tuple(fidelity)
    if len(fids) != 2:
        raise ValueError(f"fidelity must be one name or an (azimuth, pitch) pair, got {fidelity!r}.")
    for fid in fids:
        if fid not in FIDELITIES:
            raise ValueError(f"fidelity={fid!r} is unknown; use one of {tuple(FIDELITIES)}.")
    for name, pair in (("torques", torques), ("servo_gains", servo_gains)):
        if np.shape(pair) != (2,):
            raise ValueError(f"antenna({name}=...) must be a pair of numbers, got {pair!r}.")
    if mass_scaling is not None and "planetary-scaled" not in fids:
        raise ValueError(f"mass_scaling={mass_scaling!r} needs a 'planetary-scaled' joint; fidelity is {fidelity!r}.")
    if (drive == "profile") != (profile_times is not None or profile_angles is not None):
        raise ValueError("profile_times and profile_angles go with drive='profile' (and it needs both).")
    scaling = {} if mass_scaling is None else dict(mass_scaling=mass_scaling)
    driven = (mode in ("azimuth", "dual"), mode in ("pitch", "dual"))
    joints = []
    for k, (stage, fid, on) in enumerate(zip((azimuth_stage, pitch_stage), fids, driven)):
        if drive == "torque" and on:
            drv = TorqueDrive(torques[k])
        elif drive == "scan" and on:
            drv = ScanServo(scan_amplitude, scan_period, *servo_gains)
        elif drive == "profile" and on:
            drv = ProfileServo(profile_times, profile_angles, *servo_gains)
        else:
            drv = SpeedServo(rate if on else 0.0, *servo_gains)
        extra = scaling if fid == "planetary-scaled" else {}
        joints.append(FIDELITIES[fid](stage, drv, motor_inertia=motor_inertia, drag_torque=drag_torque, **extra))
    return Mechanism(joints[0], joints[1], geometry=geometry, inertias=inertias, base=base)


def scan(
    mode: str = "dual",
    *,
    fidelity: str | tuple[str, str] = "lumped",
    amplitude: float = math.radians(0.5),
    period: float = 1.0,
    base: str = "fixed",
    azimuth_stage: PlanetaryStage | None = None,
    pitch_stage: PlanetaryStage | None = None,
    servo_gains: tuple[float, float] = (2.0, 40.0),
    drag_torque: float = 0.05,
    motor_inertia: float = 2e-4,
    mass_scaling: float | None = None,
    geometry: Geometry | None = None,
    inertias: Inertias | None = None,
    profile_times: list[float] | None = None,
    profile_angles: list[float] | None = None,
) -> Mechanism:
    """The tolerance-design scene: the driven joints scan back and forth.

    A one-way drive at constant speed keeps every flank and bearing loaded on one side, so the
    clearances and backlash hide (their gradients are exactly zero); a scan reverses every half
    period, and at each reversal the output crosses its lost motion and the bearings change
    side. Defaults: both joints scan $\\pm 0.5°$ with a 1 s period (peak rate 3.1 °/s) at lumped
    fidelity on a fixed base (a ground test: the spacecraft's reaction changes the boresight
    relative to the base by less than the clearances do, and costs 6 more coordinates); the
    servos are stiffer than the paper's speed loop ($k_p$ = 2 N m s/rad, $k_i$ = 40 N m/rad, a
    ~5 Hz position loop on the motor) so that they follow a 1 Hz scan and what remains of the
    pointing error is the joints' own: lost motion, compliance and rattle. Arguments as
    `antenna`; verify a design at `fidelity="planetary"`. `profile_times`, `profile_angles`
    (s, rad): the driven joints track this tabulated profile instead of the sine (a step, a
    slew and settle: `ProfileServo`); `amplitude` and `period` are then unused.
    """
    profile = profile_times is not None or profile_angles is not None
    return antenna(
        mode,
        fidelity=fidelity,
        drive="profile" if profile else "scan",
        profile_times=profile_times,
        profile_angles=profile_angles,
        base=base,
        azimuth_stage=azimuth_stage,
        pitch_stage=pitch_stage,
        servo_gains=servo_gains,
        drag_torque=drag_torque,
        motor_inertia=motor_inertia,
        scan_amplitude=amplitude,
        scan_period=period,
        mass_scaling=mass_scaling,
        geometry=geometry,
        inertias=inertias,
    )
