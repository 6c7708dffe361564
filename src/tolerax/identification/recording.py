"""Test recordings of a drive as data: the encoder angles of a unit's acceptance test.

A `Recording` holds the save times (s), the measured output angle of each recorded axis (rad,
the joint's output encoder) and optionally the commanded angle (rad) and the motor torque (N m:
the motor current times its torque constant). It is read from CSV or
netCDF with its units stated (`read_recording`), refused with the reason where it cannot be right
(times that do not increase, a missing value, a unit that is not an angle, angles no joint turns
through in radians), and resampled onto a model's save times by linear interpolation
(`Recording.at`), never extrapolated.

**CSV**: one header row, each column's name with its unit in brackets, then one row per sample::

    time [s], azimuth measured [deg], azimuth commanded [deg], azimuth torque [N m]
    0.000, 0.000000, 0.000000, 0.0123
    ...

Time in s or ms; angles in rad, mrad, urad (or µrad), deg or arcsec; torques in N m or mN m.
Columns `<axis> measured` (required for each axis), `<axis> commanded` and `<axis> torque`
(optional, for every recorded axis or none), `<axis>` one of `azimuth`, `pitch`.

**netCDF** (`xarray`): a coordinate `time` and variables `<axis>_measured`, `<axis>_commanded`,
`<axis>_torque`, each with a `units` attribute as above.
"""

import dataclasses
import difflib
import math
import pathlib
import re

import numpy as np

AXES = ("azimuth", "pitch")
TIME_UNITS = {"s": 1.0, "ms": 1e-3}
TORQUE_UNITS = {"N m": 1.0, "N·m": 1.0, "Nm": 1.0, "mN m": 1e-3, "mN·m": 1e-3, "mNm": 1e-3}
ANGLE_UNITS = {"rad": 1.0, "mrad": 1e-3, "urad": 1e-6, "µrad": 1e-6, "deg": math.pi / 180, "arcsec": math.pi / 180 / 3600}
MAX_ANGLE = 2 * math.pi  # rad: an output angle beyond a full turn is a unit slip (degrees read as radians)


class RecordingError(ValueError):
    """A recording that cannot be used as it is: the message says what and where."""


@dataclasses.dataclass(frozen=True)
class Recording:
    """A unit's test recording (module docstring).

    - `time` (s, (n,)): strictly increasing.
    - `measured` (rad, (n, k)): the output angle of each of `axes` (k = 1 or 2).
    - `axes`: the recorded joints, a subset of ("azimuth", "pitch") in that order.
    - `commanded` (rad, (n, k)) or None.
    - `noise` (rad) or None: the encoder's noise standard deviation where known (the
      identification estimates it from the residual otherwise).
    - `source`: where it came from (a path), for messages.
    - `torque` (N m, (n, k)) or None: each axis's motor torque (`AbstractJoint.motor_torque`);
      `torque_noise` (N m): its noise standard deviation, which an identification fitting the
      torque needs beside `noise` (the two channels are weighed by their noises).
    """

    time: np.ndarray
    measured: np.ndarray
    axes: tuple[str, ...] = ("azimuth",)
    commanded: np.ndarray | None = None
    noise: float | None = None
    source: str = "<arrays>"
    torque: np.ndarray | None = None
    torque_noise: float | None = None

    def __post_init__(self):
        time = np.asarray(self.time, dtype=float)
        measured = np.asarray(self.measured, dtype=float)
        measured = measured[:, None] if measured.ndim == 1 else measured
        object.__setattr__(self, "time", time)
        object.__setattr__(self, "measured", measured)
        object.__setattr__(self, "axes", tuple(self.axes))
        if self.commanded is not None:
            commanded = np.asarray(self.commanded, dtype=float)
            object.__setattr__(self, "commanded", commanded[:, None] if commanded.ndim == 1 else commanded)
        if self.torque is not None:
            torque = np.asarray(self.torque, dtype=float)
            object.__setattr__(self, "torque", torque[:, None] if torque.ndim == 1 else torque)
        _check(self)

    @property
    def duration(self) -> float:
        """The last sample's time (s)."""
        return float(self.time[-1])

    def at(self, times, which: str = "measured") -> np.ndarray:
        """The `which` ("measured" or "commanded" angles, rad; "torque", N m) at `times` (s),
        `(len(times), k)`, linearly interpolated; `RecordingError` where a time lies outside the
        recording."""
        times = np.asarray(times, dtype=float)
        if times.min() < self.time[0] - 1e-12 or times.max() > self.time[-1] + 1e-12:
            raise RecordingError(f"{self.source}: the recording covers {self.time[0]:g} to {self.time[-1]:g} s; the model's "
                                 f"saves run {times.min():g} to {times.max():g} s: record longer or shorten the scene's run.")
        values = getattr(self, which)
        return np.stack([np.interp(times, self.time, values[:, j]) for j in range(len(self.axes))], axis=1)

    def write_csv(self, path) -> pathlib.Path:
        """This recording as CSV (time in s, angles in rad, torques in N m), readable by
        `read_recording` (the noises are not written: a file states them elsewhere)."""
        path = pathlib.Path(path)
        columns = [("time [s]", self.time)]
        for j, axis in enumerate(self.axes):
            columns.append((f"{axis} measured [rad]", self.measured[:, j]))
            if self.commanded is not None:
                columns.append((f"{axis} commanded [rad]", self.commanded[:, j]))
            if self.torque is not None:
                columns.append((f"{axis} torque [N m]", self.torque[:, j]))
        rows = [", ".join(name for name, _ in columns)]
        rows += [", ".join(f"{values[i]:.17g}" for _, values in columns) for i in range(self.time.size)]
        path.write_text("\n".join(rows) + "\n")
        return path


def _check(rec: Recording) -> None:
    where = rec.source
    if rec.time.ndim != 1 or rec.time.size < 3:
        raise RecordingError(f"{where}: a recording needs at least 3 samples of one time column, got shape {rec.time.shape}.")
    if not rec.axes or any(a not in AXES for a in rec.axes) or list(rec.axes) != [a for a in AXES if a in rec.axes]:
        raise RecordingError(f"{where}: axes must be 'azimuth', 'pitch' or both in that order, got {rec.axes!r}.")
    for name, values in (("measured", rec.measured), ("commanded", rec.commanded), ("torque", rec.torque)):
        if values is not None and values.shape != (rec.time.size, len(rec.axes)):
            raise RecordingError(f"{where}: {name} must have one row per sample and one column per axis "
                                 f"({rec.time.size}, {len(rec.axes)}), got {values.shape}.")
    for name, values in (("time", rec.time[:, None]), ("measured", rec.measured), ("commanded", rec.commanded),
                         ("torque", rec.torque)):
        if values is not None and not np.all(np.isfinite(values)):
            row, col = np.argwhere(~np.isfinite(values))[0]
            raise RecordingError(f"{where}: sample {row + 1} of {name}"
                                 + ("" if name == "time" else f" ({rec.axes[col]})")
                                 + f" is {float(values[row, col])!r}: a recording with gaps cannot be fitted; cut it before the gap.")
    steps = np.diff(rec.time)
    if np.any(steps <= 0):
        row = int(np.argmax(steps <= 0)) + 1
        what = ("repeats the time of the sample before" if steps[row - 1] == 0 else "goes back in time from the sample before")
        raise RecordingError(f"{where}: sample {row + 1} {what} ({rec.time[row - 1]:g} s, then {rec.time[row]:g} s): times "
                             "must increase strictly (a duplicated or reordered sample).")
    for name, values in (("measured", rec.measured), ("commanded", rec.commanded)):
        if values is not None and np.max(np.abs(values)) > MAX_ANGLE:
            raise RecordingError(f"{where}: a {name} angle reaches {np.max(np.abs(values)):.4g} rad, more than a full turn: is "
                                 "the column in degrees (say so in its header: [deg])?")
    if rec.noise is not None and not (math.isfinite(rec.noise) and rec.noise > 0):
        raise RecordingError(f"{where}: noise must be a standard deviation > 0 (rad), got {rec.noise!r}.")
    if rec.torque_noise is not None and not (math.isfinite(rec.torque_noise) and rec.torque_noise > 0):
        raise RecordingError(f"{where}: torque_noise must be a standard deviation > 0 (N m), got {rec.torque_noise!r}.")


_COLUMN = re.compile(r"^\s*(.+?)\s*\[\s*([^\]]+?)\s*\]\s*$")


def _unit(column: str, units: dict, kind: str, where: str) -> tuple[str, float]:
    m = _COLUMN.match(column)
    if m is None:
        raise RecordingError(f"{where}: column {column!r} states no unit: write it as 'name [unit]', {kind} in "
                             f"{', '.join(units)}.")
    name, unit = m.group(1).strip().lower(), m.group(2).strip()
    if unit not in units:
        raise RecordingError(f"{where}: column {column!r}: {unit!r} is not {kind} unit; use one of {', '.join(units)}.")
    return name, units[unit]


def _from_columns(columns: dict, where: str) -> Recording:
    """A `Recording` from {header: values} (the CSV's columns)."""
    time = measured = None
    found: dict[tuple[str, str], np.ndarray] = {}
    for header, values in columns.items():
        if header.strip().lower().startswith("time"):
            _, scale = _unit(header, TIME_UNITS, "a time", where)
            time = values * scale
            continue
        torque = "torque" in header.lower().split("[")[0]
        name, scale = _unit(header, TORQUE_UNITS, "a torque", where) if torque else _unit(header, ANGLE_UNITS, "an angle", where)
        parts = name.replace("_", " ").split()
        if len(parts) != 2 or parts[0] not in AXES or parts[1] not in ("measured", "commanded", "torque"):
            guess = None
            if len(parts) == 2:  # a misspelt axis or kind: each word matched on its own
                axis, kind = (difflib.get_close_matches(w, choices, n=1, cutoff=0.75) for w, choices in
                              zip(parts, (AXES, ("measured", "commanded", "torque"))))
                guess = f"{axis[0]} {kind[0]}" if axis and kind else None
            raise RecordingError(f"{where}: column {header!r} is not '<axis> measured', '<axis> commanded' or '<axis> torque' with <axis> "
                                 "azimuth or pitch" + (f" (did you mean '{guess}'?)." if guess and guess != " ".join(parts) else "."))
        found[(parts[0], parts[1])] = values * scale
    if time is None:
        raise RecordingError(f"{where}: no 'time [s]' column.")
    axes = tuple(a for a in AXES if (a, "measured") in found)
    if not axes:
        raise RecordingError(f"{where}: no '<axis> measured [unit]' column (azimuth or pitch).")
    unmeasured = sorted({(a, kind) for a, kind in found if a not in axes}, key=lambda k: (AXES.index(k[0]), k[1]))
    if unmeasured:
        a, kind = unmeasured[0]
        raise RecordingError(f"{where}: a '{a} {kind}' column but no '{a} measured' one: the {a} axis is fitted on its "
                             f"measured angle; give its '{a} measured [unit]' column, or drop its other columns.")
    measured = np.stack([found[(a, "measured")] for a in axes], axis=1)
    commands = [a for a in axes if (a, "commanded") in found]
    if commands and len(commands) != len(axes):
        # Dropping them would check the recording's test against the scene's drive on no axis at all.
        raise RecordingError(f"{where}: a commanded column for {', '.join(commands)} but not for "
                             f"{', '.join(a for a in axes if a not in commands)}: give every recorded axis its commanded "
                             "angle, or none.")
    commanded = np.stack([found[(a, "commanded")] for a in axes], axis=1) if commands else None
    torques = [a for a in axes if (a, "torque") in found]
    if torques and len(torques) != len(axes):
        raise RecordingError(f"{where}: a torque column for {', '.join(torques)} but not for "
                             f"{', '.join(a for a in axes if a not in torques)}: give every recorded axis its torque, or none.")
    torque = np.stack([found[(a, "torque")] for a in axes], axis=1) if torques else None
    return Recording(time, measured, axes, commanded, source=where, torque=torque)


def read_recording(path) -> Recording:
    """A `Recording` from a CSV (`.csv`) or netCDF (`.nc`) file (module docstring for the
    layouts); `RecordingError` naming the file, row or column where it cannot be used."""
    path = pathlib.Path(path)
    where = str(path)
    if not path.is_file():
        raise RecordingError(f"{where}: no such file.")
    if path.suffix == ".nc":
        import xarray as xr

        with xr.open_dataset(path) as ds:
            if "time" not in ds.coords and "time" not in ds:
                raise RecordingError(f"{where}: no 'time' coordinate.")
            columns = {f"time [{ds['time'].attrs.get('units', '?')}]": np.asarray(ds["time"].values, dtype=float)}
            for name in ds.data_vars:
                columns[f"{name} [{ds[name].attrs.get('units', '?')}]"] = np.asarray(ds[name].values, dtype=float)
        return _from_columns(columns, where)
    lines = [(i, line) for i, line in enumerate(path.read_text().splitlines(), 1)
             if line.strip() and not line.lstrip().startswith("#")]
    if len(lines) < 2:
        raise RecordingError(f"{where}: a header row and at least one sample are needed.")
    header = lines[0][1]
    for other in (";", "\t"):
        if other in header and "," not in header:
            raise RecordingError(f"{where}:{lines[0][0]}: the columns are separated by {other!r}: a recording's CSV is "
                                 "comma-separated (time [s], azimuth measured [deg], ...).")
    headers = [h.strip() for h in header.split(",")]
    rows = []
    for i, line in lines[1:]:
        cells = [c.strip() for c in line.split(",")]
        if len(cells) != len(headers):
            raise RecordingError(f"{where}:{i}: {len(cells)} values for {len(headers)} columns.")
        try:
            rows.append([float(c) if c else math.nan for c in cells])
        except ValueError:
            raise RecordingError(f"{where}:{i}: a value that is not a number: {line!r}.") from None
    data = np.asarray(rows, dtype=float)
    return _from_columns({h: data[:, j] for j, h in enumerate(headers)}, where)


# A recording without a commanded column is held against the model's output at the scene's
# values (`_check_measured`): a measured angle whose span lies outside this factor of the model's
# either way is not the scene's test (or its unit is wrong). Lost motion changes the span by far
# less (100 µm of backlash on a 40 mm ring: 2.5 mrad of output angle, against a 1 degree scan's
# 17 mrad). Judged where the model's output spans at least SPAN_JUDGED (rad): a
# dwell's span is the rattle's.
SPAN_FACTOR = 3.0
SPAN_JUDGED = 1e-3


def _check_measured(recording: Recording, measured, model) -> None:
    """Refuse (`RecordingError`) a recording whose measured angle (rad, (saves, axes) in the
    residual's window) spans more than `SPAN_FACTOR` times the `model`'s output angle (rad, the
    same shape: the scene at its own values) on that axis or less than its inverse, where the
    model's spans at least `SPAN_JUDGED`: another test than the scene's, or values under the
    wrong unit's header (named where the two are a unit's factor apart)."""
    for j, axis in enumerate(recording.axes):
        simulated, recorded = float(np.ptp(model[:, j])), float(np.ptp(measured[:, j]))
        if simulated >= SPAN_JUDGED and not 1 / SPAN_FACTOR <= recorded / simulated <= SPAN_FACTOR:
            raise RecordingError(
                f"{recording.source}: the recording's measured {axis} angle spans {recorded:.6g} rad, the scene's output at its "
                f"own values {simulated:.6g} rad: not the scene's test, or its unit is wrong. The model must run the test's "
                "profile (the scene's scan or profile_times/profile_angles), with the recording's unit stated in its header."
                + _unit_slip(measured[:, j], model[:, j], within=0.1))


def _unit_slip(recorded, reference, within: float = 0.01) -> str:
    """A sentence naming the unit slip where the `recorded` angle is the scene's `reference` (its
    command, or its output at its own values) times the factor between two angle units (values
    in one written under the other's header) to `within` (1 % against a command; an output
    carries the clearances' lost motion too, and no two factors lie closer than 3.2x), else ""."""
    big = np.abs(reference) > 0.5 * np.max(np.abs(reference))
    if not np.any(big):
        return ""
    ratio = float(np.median(recorded[big] / reference[big]))
    units = {f: u for u, f in ANGLE_UNITS.items()}  # one name per factor (µrad for urad and µrad alike)
    for said, written in ((s, w) for s in units for w in units if s != w):
        if abs(ratio / (said / written) - 1) < within:
            return (f" The two are {ratio:.4g}x apart: the header's unit is likely wrong (values in {units[written]} under a "
                    f"[{units[said]}] header?).")
    return ""
