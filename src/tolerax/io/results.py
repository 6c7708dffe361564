"""The results of a scene-file run: the time series as an `xarray.Dataset` with units, the
pointing statistics over the window, the plots, and `summary.json` / `summary.md`."""

import json
import os
import pathlib

import numpy as np

from .._defaults import JITTER_CUTOFF
from .._files import atomic_write, save_figure
from .schema import SERIES
from ..design import features as _design
from ..mechanism.mechanism import Mechanism
from .scenefile import SceneFile, save_scene

JOINTS = Mechanism.JOINTS

def timeseries(scene_file: SceneFile, result, series=None):
    """The time series of a `MechanismResult` as an `xarray.Dataset` (SI units in each
    variable's `units` attribute; the scene file's TOML and the solver report in the global
    attributes). `series`: names from `SERIES` (default `[outputs] series`). Contact series of
    a joint without clearances (no columns) are left out."""
    import xarray as xr

    from .. import __version__

    series = scene_file.outputs["series"] if series is None else series
    coords = {
        "time": ("time", np.asarray(result.ts), {"units": "s", "long_name": "simulated time"}),
        "joint": ("joint", list(JOINTS)),
        "axis": ("axis", ["x", "y", "z"], {"long_name": "base (spacecraft) frame axis"}),
    }
    for joint in JOINTS:
        coords[f"{joint}_contact_name"] = (f"{joint}_contact_name", list(getattr(result, f"{joint}_contact_names")))
    variables = {}
    for name in series:
        dims, unit, long_name = SERIES[name]
        values = np.asarray(getattr(result, name))
        if values.size == 0:
            continue
        variables[name] = (("time", *dims), values, {"units": unit, "long_name": long_name})
    used = {d for dims, _, _ in variables.values() for d in dims}
    ds = xr.Dataset(variables, coords={k: v for k, v in coords.items() if k in used})
    ds.attrs.update(
        scene=scene_file.name,
        title=scene_file.title,
        scene_toml=scene_file.to_toml(),
        tolerax_version=__version__,
        solver_result="successful" if result.success else "; ".join(result.failures()),
        t_reached_s=float(result.t_reached),
        steps_accepted=int(result.num_steps),
        steps_rejected=int(result.num_rejected),
    )
    return ds


def _window_stats(scene_file: SceneFile, result) -> dict:
    """Summary numbers over the window `t >= settle` (units in the key names)."""
    from ..mechanism.outputs import pointing_metrics

    ts = np.asarray(result.ts)
    finite = np.isfinite(ts) & np.all(np.isfinite(np.asarray(result.joint_angle)), axis=1)
    w = finite & (ts >= scene_file.run["settle"])
    if not np.any(w):
        return {}
    pointing = pointing_metrics(result, w)
    force = np.asarray(result.output_force)[w]
    runout = np.asarray(result.runout)[w]
    angle = np.degrees(np.asarray(result.joint_angle)[w])
    out = dict(
        window_s=[float(ts[w][0]), float(ts[w][-1])],
        pointing_rms_arcsec=float(pointing["pointing_rms"]),
        pointing_peak_arcsec=float(pointing["pointing_peak"]),
        tracking_speed_error_rms_arcsec_s=float(pointing["tracking_speed_rms"]),
    )
    # The pointing stability, the baseline a jitter requirement (`tolerax design --jitter`) is
    # chosen against: the RMS above JITTER_CUTOFF Hz up to the saves' Nyquist frequency, where
    # the saves resolve it.
    try:
        jitter = float(pointing_metrics(result, w, jitter_cutoff=JITTER_CUTOFF)["pointing_jitter"])
        out["pointing_jitter_arcsec"] = jitter
        out["jitter_band_hz"] = [JITTER_CUTOFF, 0.5 / float(ts[1] - ts[0])]
    except ValueError as err:
        out["pointing_jitter_arcsec"] = None
        out["jitter_not_resolved"] = str(err)
    # The jitter is the stage's vibration: read as the full stage does only at planetary
    # fidelity (tolerax.design.fidelity); the joints that model their play more coarsely.
    from ..design.fidelity import joint_fidelities, proxies

    model = scene_file.build()
    out["jitter_read_by"] = proxies(model, "planetary")
    out["joint_fidelity"] = joint_fidelities(model)
    for k, joint in enumerate(JOINTS):
        # The output bearing's force and runout: null where the joint's output does not translate
        # (an ideal joint, a rigid output support); a lumped joint's are its own (a proxy's).
        moves = getattr(model, joint).layout.carrier_xy is not None
        out[f"{joint}_output_force_peak_N"] = float(force[:, k].max()) if moves else None
        out[f"{joint}_runout_peak_um"] = float(runout[:, k].max() * 1e6) if moves else None
        out[f"{joint}_angle_range_deg"] = [float(angle[:, k].min()), float(angle[:, k].max())]
    return out


def _plot(name: str, result, settle: float, title: str):
    import matplotlib.pyplot as plt

    from ..mechanism.outputs import ARCSEC

    ts = np.asarray(result.ts)
    fig, ax = plt.subplots(figsize=(7, 3.6))
    if name == "pointing_error":
        ax.plot(ts, np.asarray(result.pointing_error) / ARCSEC, lw=0.8)
        ax.set_ylabel("pointing error (arcsec)")
    elif name == "joint_angle":
        for k, joint in enumerate(JOINTS):
            line, = ax.plot(ts, np.degrees(np.asarray(result.joint_angle[:, k])), lw=0.8, label=f"{joint}")
            ax.plot(ts, np.degrees(np.asarray(result.commanded_angle[:, k])), lw=0.8, ls="--", color=line.get_color(), label=f"{joint} commanded")
        ax.set_ylabel("output angle (deg)")
        ax.legend(fontsize=8)
    elif name == "output_force":
        for k, joint in enumerate(JOINTS):
            ax.plot(ts, np.asarray(result.output_force[:, k]), lw=0.8, label=joint)
        ax.set_ylabel("output-bearing radial contact force (N)")
        ax.legend(fontsize=8)
    elif name == "tracking_speed_error":
        for k, axis in enumerate("xyz"):
            ax.plot(ts, np.asarray(result.tracking_speed_error[:, k]) / ARCSEC, lw=0.8, label=axis)
        ax.set_ylabel("tracking speed error (arcsec/s)")
        ax.legend(fontsize=8, title="base frame")
    if settle > 0:
        ax.axvline(settle, color="0.6", lw=0.8, ls=":", label="window start")
    ax.set_xlabel("time (s)")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    return fig


def write_results(scene_file: SceneFile, result, out: str | os.PathLike, *, wall_s: float | None = None, command: str | None = None) -> dict:
    """Write a run's results into the folder `out`: `scene.toml` (the scene as run),
    `timeseries.nc` (netCDF, h5netcdf engine; `timeseries`), one PNG per `[outputs] plots`,
    `summary.json` and `summary.md`. Returns the summary dict."""
    import matplotlib.pyplot as plt

    out = pathlib.Path(out)
    out.mkdir(parents=True, exist_ok=True)
    save_scene(scene_file, out / "scene.toml")
    ds = timeseries(scene_file, result)
    atomic_write(out / "timeseries.nc", lambda tmp: ds.to_netcdf(tmp, engine="h5netcdf"))
    settings = scene_file.outputs
    plots = []
    for name in settings["plots"]:
        fig = _plot(name, result, scene_file.run["settle"], f"{scene_file.name}: {name.replace('_', ' ')}")
        save_figure(fig, out / f"{name}.png", dpi=settings["dpi"])
        plt.close(fig)
        plots.append(f"{name}.png")
    model = scene_file.build()
    summary = dict(
        scene=scene_file.name,
        title=scene_file.title,
        source=scene_file.source,
        run={k: v for k, v in scene_file.run.items() if v is not None},
        integrated_with=result.integrated_with,
        result="successful" if result.success else "failed",
        failures=result.failures(),
        t_reached_s=float(result.t_reached),
        steps_accepted=int(result.num_steps),
        steps_rejected=int(result.num_rejected),
        wall_s_including_compile=None if wall_s is None else round(wall_s, 2),
        design_um={n: float(v) * 1e6 for n, v in zip(_design.design_names(model), np.asarray(_design.design_of(model)))},
        metrics=_window_stats(scene_file, result),
        files=["scene.toml", "timeseries.nc", *plots, "summary.json", "summary.md"],
        command=command,
    )
    atomic_write(out / "summary.json", json.dumps(summary, indent=2))
    atomic_write(out / "summary.md", summary_md(summary))
    return summary


def summary_md(s: dict) -> str:
    lines = [f"# {s['title']}", "", f"Scene `{s['scene']}` ({s['source']}); the scene as run is `scene.toml`.", ""]
    if s["command"]:
        lines += ["Reproduce with:", "", "```", s["command"], "```", ""]
    run = s["run"]
    lines += [
        "## Run", "",
        f"- {run['duration']} s simulated from `start = \"{run['start']}\"`, {run['n_save']} saved times; "
        f"pointing window from {run['settle']} s.",
        f"- Integrated with {s['integrated_with']}.",
        f"- Solver: **{s['result']}**, reached {s['t_reached_s']:.6g} s in {s['steps_accepted']} accepted and "
        f"{s['steps_rejected']} rejected steps"
        + (f"; {s['wall_s_including_compile']} s of wall time including compilation." if s["wall_s_including_compile"] is not None else "."),
    ]
    lines += [f"- Failure: {line}" for line in s["failures"]]
    if s["design_um"]:
        lines += ["", "## Design (clearances and backlash)", "", "| feature | value (µm) |", "|---|---|"]
        lines += [f"| {n} | {v:.4g} |" for n, v in s["design_um"].items()]
    m = s["metrics"]
    if m:
        lines += ["", f"## Results over {m['window_s'][0]:.4g}-{m['window_s'][1]:.4g} s", "", "| quantity | value |", "|---|---|"]
        lines += [
            f"| RMS pointing error | {m['pointing_rms_arcsec']:.4g} arcsec |",
            f"| peak pointing error | {m['pointing_peak_arcsec']:.4g} arcsec |",
            f"| RMS tracking speed error | {m['tracking_speed_error_rms_arcsec_s']:.4g} arcsec/s |",
            (f"| jitter (RMS of the pointing error over {m['jitter_band_hz'][0]:g}-{m['jitter_band_hz'][1]:.4g} Hz) | "
             f"{m['pointing_jitter_arcsec']:.4g} arcsec |" if m.get("pointing_jitter_arcsec") is not None else
             f"| jitter above {JITTER_CUTOFF:g} Hz | not resolved by these saves: raise `n_save` |"),
        ]
        if m.get("jitter_read_by"):  # a proxy's jitter: say so beside the number
            joints = ", ".join(f"the {joint} joint is {f}" for joint, f in m["jitter_read_by"].items())
            lines[-1] = lines[-1][:-1] + (f"(a proxy, not the full stage's: {joints}, and the jitter is the full stage's "
                                          "vibration; `[scene] fidelity = \"planetary\"` reads it) |")
        for joint in JOINTS:
            lo, hi = m[f"{joint}_angle_range_deg"]
            kind = m.get("joint_fidelity", {}).get(joint)
            force, runout = m[joint + "_output_force_peak_N"], m[joint + "_runout_peak_um"]
            absent = (f"not modelled (the {joint} joint is ideal: its output does not translate)" if kind == "ideal" else
                      f"not modelled (the {joint} joint's output support is rigid: its output does not translate)")
            proxy = (f" (the {joint} joint is lumped: its own output bearing, not read as the full stage reads it; "
                     "`[scene] fidelity = \"planetary\"` does)") if kind == "lumped" else ""
            lines += [
                f"| {joint} output angle | {lo:.4g} to {hi:.4g} deg |",
                f"| {joint} peak output-bearing force | {absent if force is None else format(force, '.4g') + ' N' + proxy} |",
                f"| {joint} peak runout | {absent if runout is None else format(runout, '.4g') + ' µm' + proxy} |",
            ]
    lines += ["", "## Files", ""] + [f"- `{f}`" for f in s["files"]]
    return "\n".join(lines) + "\n"
