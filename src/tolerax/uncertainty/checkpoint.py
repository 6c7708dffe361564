"""A Monte Carlo run's checkpoint folder: `manifest.json` (the run's settings, checked on
resume) and one netCDF file per finished chunk, each written atomically."""

import json
import pathlib

import xarray as xr

from .._files import atomic_write


def chunk_path(out: pathlib.Path, k: int) -> pathlib.Path:
    return out / f"chunk-{k:05d}.nc"


def open_folder(out, settings: dict, grow: bool = False) -> tuple[pathlib.Path, dict[int, xr.Dataset]]:
    """Create `out` with its manifest, or check that the manifest there matches; load the chunks
    already finished there. `grow`: a manifest that differs only by a smaller `n` is a run being
    extended: the manifest takes the new `n` (the caller decides which chunks still hold)."""
    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    manifest = out / "manifest.json"
    settings = json.loads(json.dumps(settings))  # as it reads back (tuples become lists)
    if manifest.exists():
        previous = json.loads(manifest.read_text())
        if previous != settings:
            differ = {k for k in previous.keys() | settings.keys() if previous.get(k) != settings.get(k)}
            if not (grow and differ == {"n"} and settings["n"] > previous["n"]):
                hint = (" A run grows to a larger n, not a smaller one." if differ == {"n"} else "")
                raise ValueError(
                    f"{out} holds a run with other settings ({'; '.join(_differences(previous, settings))}).{hint} "
                    "Resume with the same arguments (or a larger n to extend it), or give another `out` folder."
                )
            atomic_write(manifest, lambda tmp: tmp.write_text(json.dumps(settings, indent=1)))
    else:
        if any(out.glob("chunk-*.nc")):
            raise ValueError(f"{out} holds chunk files but no manifest.json; give an empty or new `out` folder.")
        atomic_write(manifest, lambda tmp: tmp.write_text(json.dumps(settings, indent=1)))
    for stale in out.glob("*.tmp"):
        stale.unlink()  # written by a run killed mid-write: never renamed, so never counted
    done = {}
    for path in sorted(out.glob("chunk-*.nc")):
        done[int(path.stem.split("-")[1])] = xr.load_dataset(path, engine="h5netcdf")
    return out, done


def _differences(there: dict, now: dict, prefix: str = "") -> list[str]:
    lines = []
    for key in sorted(there.keys() | now.keys()):
        old, new = there.get(key), now.get(key)
        if isinstance(old, dict) and isinstance(new, dict):
            lines += _differences(old, new, f"{prefix}{key}.")
        elif old != new:
            said = (_said(old), _said(new)) if _said(old) != _said(new) else (repr(old), repr(new))  # apart below 6 digits
            lines.append(f"{prefix}{key}: {said[0]} there, {said[1]} now")
    return lines


def _said(value) -> str:
    """A setting as a message shows it: floats to 6 significant digits (a band of 20 um read
    back as 1.9999999999999998e-05 m reads 2e-05), the rest as `repr`."""
    if isinstance(value, float):
        return f"{value:.6g}"
    if isinstance(value, list):
        return "[" + ", ".join(_said(v) for v in value) + "]"
    return repr(value)
