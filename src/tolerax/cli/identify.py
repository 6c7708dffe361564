"""`tolerax identify SCENE RECORDING`: a unit's clearances and backlash from its test recording."""

import json
import pathlib
import sys
import time

from .._files import atomic_write, save_figure
from .common import check_out, claim_out, command_line, load_average, read_scene_file, scene_and_settings


def identify_command(parser, args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from ..design.features import design_names
    from ..identification.identify import identify
    from ..identification.recording import RecordingError, read_recording
    from ..uncertainty.sampling import Tolerances

    try:
        recording = read_recording(args.recording)
    except RecordingError as err:
        print(f"tolerax identify: {err}", file=sys.stderr)
        return 2
    scene_file = read_scene_file(parser, args)
    if scene_file is None:
        return 2
    scene = scene_file.build()
    names = design_names(scene)
    parameters = args.parameters or list(names)
    unknown = [p for p in parameters if p not in names]
    if unknown:
        parser.error(f"--parameters {' '.join(unknown)}: not design features of {scene_file.name}; its features: {', '.join(names)}")
    out = check_out(parser, args.out, "identify", force=args.force)
    duration = recording.duration if args.duration is None else args.duration
    print(f"tolerax identify: {', '.join(parameters)} of {scene_file.title} from {recording.source} "
          f"({recording.time.size} samples over {recording.duration:g} s, axes {', '.join(recording.axes)}); results in {out}/",
          flush=True)
    start = time.perf_counter()
    # Every [run] key is a PointingObjective field (SceneFile.objective): all pass through but the
    # window and saves, which identify sets from the recording.
    run = {k: v for k, v in scene_file.run.items() if k not in ("duration", "settle", "n_save")}
    try:
        got = identify(scene, recording, parameters, settle=args.settle, duration=duration, starts=tuple(args.starts), **run)
    except (RecordingError, ValueError) as err:
        print(f"tolerax identify: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    claim_out(out, "identify", fresh=args.force)
    # The identified unit: its values under [design], their uncertainty as zones (normal, band = 3 standard errors).
    zones = Tolerances(got.names, got.estimate, 3.0 * got.standard_error, "normal")
    identified = scene_file.with_tolerances(zones)
    data = identified.data | {"title": f"Identified unit: {scene_file.title}",
                              "description": f"Written by tolerax identify from {recording.source}: " + "; ".join(
                                  f"{n} {1e6 * e:.2f} +- {1.96e6 * s:.2f} um (95 %, {st})"
                                  for n, e, s, st in zip(got.names, got.estimate, got.standard_error, got.status()))}
    from ..io import scenefile as F

    path = F.save_scene(F.SceneFile.from_data(data, "identified", "<identified>"), out / "identified.toml")
    text = "\n".join([
        f"# Identified unit: {scene_file.title}", "", f"Recording `{recording.source}`; {wall:.1f} s of wall time (compilation "
        f"included); {load_average()}.", "", got.table(), "",
        f"The unit as a scene file: `{path}` (its values under [design], each zone 3 standard errors, normal): "
        f"`tolerax run {path}` simulates it, `tolerax montecarlo {path} --out {out / 'montecarlo'}` spreads it over what the "
        "recording leaves open.", "", "Reproduce with:", "", "```", command_line(args), "```", "",
        *scene_and_settings(scene_file)])
    atomic_write(out / "identification.md", text + "\n")
    atomic_write(out / "identification.json", json.dumps({
        "names": list(got.names), "estimate_m": [float(v) for v in got.estimate],
        "standard_error_m": [float(v) for v in got.standard_error], "status": list(got.status()),
        "sigma_rad": got.sigma, "samples": got.n, "converged": got.converged, "wall_s": wall}, indent=2) + "\n")
    fig, (top, bottom) = plt.subplots(2, 1, figsize=(8, 6), sharex=True)
    for j, axis in enumerate(recording.axes):
        top.plot(got.times, np.degrees(got.measured[:, j]), ".", ms=3, label=f"{axis}: recording")
        top.plot(got.times, np.degrees(got.fitted[:, j]), "-", lw=1, label=f"{axis}: identified model")
        bottom.plot(got.times, 1e6 * got.residual[:, j], lw=0.8, label=axis)
    top.set_ylabel("output angle (deg)")
    top.legend(fontsize=8)
    bottom.set_ylabel("model - recording (µrad)")
    bottom.set_xlabel("time (s)")
    top.set_title(f"{scene_file.title}: identified " + ", ".join(f"{n.split('.')[-1]} {1e6 * e:.1f} µm" for n, e in zip(got.names, got.estimate)),
                  fontsize=9)
    save_figure(fig, out / "identification.png", dpi=120)
    plt.close(fig)
    print(text)
    return 0 if got.converged else 3


def add_parser(sub, out_options, positive, non_negative, epilog):
    parser = sub.add_parser(
        "identify", help="a unit's clearances and backlash from its test recording (encoder angles)",
        description="Estimate the chosen clearances and backlash of SCENE that reproduce RECORDING (a CSV or netCDF of "
        "the output encoder's angles while the unit ran SCENE's drive: tolerax.identification.recording), by least squares "
        "through the simulation (Levenberg-Marquardt, exact Jacobian), with 95 % intervals and which of them the "
        "recording determines. Writes identification.md, identification.json, identification.png and identified.toml "
        "(the unit as a scene file).", epilog=epilog)
    parser.add_argument("scene", help="built-in scene name or path to a .toml scene file: the model, with the test's drive")
    parser.add_argument("recording", type=pathlib.Path, help="the recording: .csv or .nc with units in its headers")
    parser.add_argument("--parameters", nargs="+", default=None, metavar="FEATURE",
                        help="design features to identify (default all), e.g. azimuth.ring_backlash")
    parser.add_argument("--settle", type=non_negative, default=0.0, help="fit the samples from this time on, s (default 0)")
    parser.add_argument("--duration", type=positive, default=None, help="the model's run, s (default the recording's length)")
    parser.add_argument("--starts", type=positive, nargs="+", default=[1.0, 0.5, 2.0],
                        help="starting points as multiples of the scene's values (default 1 0.5 2)")
    out_options(parser, "identify")
    return parser
