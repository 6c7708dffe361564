"""`tolerax identify SCENE RECORDING`: a unit's clearances and backlash from its test recording."""

import argparse
import json
import math
import pathlib
import sys
import time

from .._files import atomic_write, save_figure
from .common import check_out, claim_out, command_line, load_average, read_scene_file, scene_and_settings, wrap


def _scene_and_parameters(parser, args):
    """`(scene file, scene, parameters)` of the command line (`--parameters` checked against the
    scene: exit 2 naming the ones it has), or `None` where the scene file cannot be read."""
    from ..identification.parameters import check_names

    scene_file = read_scene_file(parser, args)
    if scene_file is None:
        return None
    scene = scene_file.build()
    try:
        return scene_file, scene, check_names(scene, args.parameters, f"--parameters of {scene_file.name}")
    except ValueError as err:
        parser.error(str(err))


def _run_settings(scene_file) -> dict:
    """The scene file's `[run]` settings but the window and saves, which the recording (or the
    planned test) sets: its start and its integrator (on a design unit's step budget, as
    `SceneFile.objective` takes it)."""
    from ..design.objectives import OBJECTIVE_INTEGRATOR

    return {"start": scene_file.run["start"], "integrator": scene_file.integrator(OBJECTIVE_INTEGRATOR.max_steps)}


def _bounds(given, scene, parameters) -> dict | str:
    """`--bounds NAME=LOW:HIGH ...` as `identify`'s `bounds` (SI: a clearance's µm to m), or the
    reason it cannot be (a name not identified, a form that is not LOW:HIGH, not 0 < LOW < HIGH):
    checked before any run."""
    import numpy as np

    from ..identification.fit import limits_of
    from ..identification.parameters import parameter_units, parameter_values

    out = {}
    for item in given:
        name, _, span = item.partition("=")
        low, _, high = span.partition(":")
        try:
            low, high = float(low), float(high)
        except ValueError:
            return f"--bounds {item!r}: write NAME=LOW:HIGH (µm for a clearance or backlash, SI for the others), e.g. azimuth.ring_backlash=20:300."
        unit = parameter_units(scene, [name])[0] if name in parameters else "m"
        out[name] = (1e-6 * low, 1e-6 * high) if unit == "m" else (low, high)
    values = np.asarray(parameter_values(scene, parameters), dtype=float)
    try:
        limits_of(parameters, values, np.ones(len(parameters)), out)
    except ValueError as err:
        return str(err).replace("identify: ", "--bounds: ") + " (--bounds take µm for a clearance or backlash.)"
    return out


def identify_command(parser, args) -> int:
    import dataclasses

    import matplotlib.pyplot as plt
    import numpy as np

    from ..identification.identify import identify
    from ..identification.result import show
    from ..identification.recording import RecordingError, read_recording

    try:
        recording = read_recording(args.recording)
    except RecordingError as err:
        print(f"tolerax identify: {err}", file=sys.stderr)
        return 2
    if args.noise is not None or args.encoder_bits is not None:  # the encoder's stated noise: the misfit is judged against it
        step = 0.0 if args.encoder_bits is None else 2 * math.pi / 2**args.encoder_bits
        recording = dataclasses.replace(recording, noise=math.hypot(1e-6 * (args.noise or 0.0), step / math.sqrt(12)))
    if recording.torque is not None and (args.angles_only or args.torque_noise is not None):
        recording = dataclasses.replace(recording, torque=None) if args.angles_only else dataclasses.replace(
            recording, torque_noise=1e-3 * args.torque_noise)
    read = _scene_and_parameters(parser, args)
    if read is None:
        return 2
    scene_file, scene, parameters = read
    bounds = _bounds(args.bounds or (), scene, parameters)
    if isinstance(bounds, str):
        print(f"tolerax identify: {bounds}", file=sys.stderr)
        return 2
    out = check_out(parser, args.out, "identify", force=args.force)
    duration = recording.duration if args.duration is None else args.duration
    print(f"tolerax identify: {', '.join(parameters)} of {scene_file.title} from {recording.source} "
          f"({recording.time.size} samples over {recording.duration:g} s, axes {', '.join(recording.axes)}); results in {out}/",
          flush=True)
    start = time.perf_counter()
    run = _run_settings(scene_file)
    try:
        starts = {} if args.starts is None else {"starts": tuple(args.starts)}
        got = identify(scene, recording, parameters, settle=args.settle, duration=duration, search=args.search,
                       progress=not args.quiet, bounds=bounds, **starts, **run)
    except (RecordingError, ValueError) as err:
        print(f"tolerax identify: {err}" + (" On the command line: --torque-noise MNM with --noise or --encoder-bits, or "
                                            "--angles-only." if "motor torque" in str(err) else ""), file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    claim_out(out, "identify", fresh=args.force)
    # The identified unit: its clearances and backlash under [design], their uncertainty as zones
    # (Identification.scene_file), the drag where the file can hold it, the meshes' stiffness and damping.
    physical = got.unwritten()
    rugged = [n for n, held, walked, stop in zip(got.names, got.holds(), got.walked(), got.stopped())
              if held is False or walked or stop is not None]
    from ..io import scenefile as F

    path = F.save_scene(got.scene_file(scene_file, recording.source), out / "identified.toml")
    text = "\n".join([
        f"# Identified unit: {scene_file.title}", "", f"Recording `{recording.source}`; {wall:.1f} s of wall time (compilation "
        f"included); {load_average()}.", "", got.table(), "",
        f"The unit as a scene file: `{path}` (its values under [design], each identified zone's standard deviation the standard error, in the file's distribution; an identified drag as its drag_torque where one joint's drag acts, a mesh family's stiffness or damping in its joint's stage table): "
        f"`tolerax run {path}` simulates it, `tolerax montecarlo {path} --out {out / 'montecarlo'}` spreads it over what the "
        "recording leaves open" + (" (with its [life]: at the end of life too)" if scene_file.life is not None else
                                   " (`--life YEARS`: at the end of a mission of that many years too, where a joint wears)") + "."
        + (f" Not in it: {', '.join(physical)} (the scene file's one drag_torque would set another joint's "
           "drag too: the estimates are in identification.json)." if physical else "")
        + (f" Kept at the scene's values and zones: {', '.join(rugged)} (their intervals do not hold, stop at a bound of the fit, "
                    "or bound them on one side only or by their profile: the part of a drawn zone inside the bounds is kept)." if rugged else ""),
        "", "Reproduce with:", "", "```", command_line(args), "```", "",
        *scene_and_settings(scene_file)])
    atomic_write(out / "identification.md", text + "\n")
    atomic_write(out / "identification.json", json.dumps({
        "names": list(got.names), "units": list(got.units), "estimate": [float(v) for v in got.estimate],
        "standard_error": [float(v) for v in got.standard_error], "status": list(got.status()), "interval_holds": list(got.holds()),
        "interval_95": [[float(v) if math.isfinite(v) else None for v in pair] for pair in zip(*got.bounds())],
        "sigma_rad": got.sigma, "residual_sd_rad": got.residual_sd, "noise_rad": got.noise, "samples": got.n, "converged": got.converged, "jacobian": got.jacobian, "wall_s": wall}
        | ({} if got.torque_fitted is None else {"torque_residual_sd_n_m": float(np.std(got.torque_fitted - got.torque_measured)),
                                                 "torque_noise_n_m": recording.torque_noise}), indent=2) + "\n")
    torque = got.torque_fitted is not None
    fig, (top, bottom, *more) = plt.subplots(2 + torque, 1, figsize=(8, 6 + 2 * torque), sharex=True)
    for j, axis in enumerate(recording.axes if torque else ()):
        more[0].plot(got.times, 1e3 * got.torque_measured[:, j], ".", ms=3, label=f"{axis}: recording")
        more[0].plot(got.times, 1e3 * got.torque_fitted[:, j], "-", lw=1, label=f"{axis}: identified model")
        more[0].set_ylabel("motor torque (mN m)")
        more[0].legend(fontsize=8)
    for j, axis in enumerate(recording.axes):
        top.plot(got.times, np.degrees(got.measured[:, j]), ".", ms=3, label=f"{axis}: recording")
        top.plot(got.times, np.degrees(got.fitted[:, j]), "-", lw=1, label=f"{axis}: identified model")
        bottom.plot(got.times, 1e6 * got.residual[:, j], lw=0.8, label=axis)
    top.set_ylabel("output angle (deg)")
    top.legend(fontsize=8)
    bottom.set_ylabel("model - recording (µrad)")
    (more[0] if torque else bottom).set_xlabel("time (s)")
    top.set_title(f"{scene_file.title}: identified " + ", ".join(f"{n.split('.')[-1]} {show(e, u)}"
                                                                 for n, u, e in zip(got.names, got.units, got.estimate)),
                  fontsize=9)
    save_figure(fig, out / "identification.png", dpi=120)
    plt.close(fig)
    print(text)
    return 0 if got.converged and not rugged else 3


# What a recording holds (tolerax.identification.recording's docstring, which is the reference),
# for `identify --help`: the prose wrapped to the terminal, the example as it is.
def _recording_layout() -> str:
    example = "    time [s], azimuth measured [deg], azimuth commanded [deg]\n    0.000, 0.000000, 0.000000\n    ..."
    return "\n\n".join([
        wrap("A recording, CSV: one header row, each column's name with its unit in brackets, then one row per sample:"),
        example,
        wrap("Time in s or ms; angles in rad, mrad, urad, deg or arcsec; a column `AXIS measured` for each recorded axis "
             "(azimuth, pitch), `AXIS commanded` optional. netCDF: a coordinate `time` and variables `azimuth_measured`, "
             "`azimuth_commanded`, ..., each with a `units` attribute. The unit ran SCENE's own drive (a test planned by "
             "`tolerax plan-test` is written as test.toml). To try this on a simulated unit: `tx.synthetic_recording(scene, "
             "values, duration=..., n_save=..., noise=...)` and its `write_csv(path)`."),
    ])


def add_parser(sub, out_options, positive, non_negative, epilog):
    parser = sub.add_parser(
        "identify", help="a unit's clearances and backlash from its test recording (encoder angles)",
        description=wrap("Estimate the chosen clearances and backlash of SCENE that reproduce RECORDING (a CSV or netCDF of "
        "the output encoder's angles while the unit ran SCENE's drive: tolerax.identification.recording), by least squares "
        "through the simulation (Levenberg-Marquardt, exact Jacobian), with 95 % intervals and which of them the "
        "recording determines. Writes identification.md, identification.json, identification.png and identified.toml "
        "(the unit as a scene file). Exits 3 where the fit did not converge or an interval does not hold (the residual "
        "not quadratic along it: the report says which and what would change it)."), epilog=_recording_layout() + "\n\n" + wrap(epilog),
        formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("scene", help="built-in scene name or path to a .toml scene file: the model, with the test's drive")
    parser.add_argument("recording", type=pathlib.Path, help="the recording: .csv or .nc with units in its headers")
    parser.add_argument("--parameters", nargs="+", default=None, metavar="PARAMETER",
                        help="parameters to identify (default all the design features): clearances and backlash, e.g. "
                        "azimuth.ring_backlash, or the joints' azimuth.drag_torque, azimuth.sun_mesh_stiffness, "
                        "azimuth.ring_mesh_stiffness, azimuth.sun_mesh_damping_ratio, azimuth.ring_mesh_damping_ratio")
    parser.add_argument("--settle", type=non_negative, default=0.0, help="fit the samples from this time on, s (default 0)")
    parser.add_argument("--duration", type=positive, default=None, help="the model's run, s (default the recording's length)")
    parser.add_argument("--starts", type=positive, nargs="+", default=None,
                        help="starting points as multiples of the scene's values (default: the best 2 of 32 points screened "
                        "within --search of them, doubled for each further parameter)")
    parser.add_argument("--bounds", nargs="+", default=None, metavar="NAME=LOW:HIGH",
                        help="what the unit can physically have, e.g. azimuth.ring_backlash=20:300 (µm for a clearance or "
                        "backlash, SI for the others; default a factor 100 of the scene's value either side)")
    parser.add_argument("--search", type=float, default=2.0,
                        help="the screened box: within this factor of the scene's values either side (default 2)")
    parser.add_argument("--noise", type=positive, default=None,
                        help="the encoder's noise, µrad standard deviation: with it (or --encoder-bits) the report says "
                        "where the residual exceeds what the encoder explains (a model that misses part of the unit)")
    parser.add_argument("--encoder-bits", type=int, default=None, help="the encoder's resolution, bits per turn (its rounding)")
    parser.add_argument("--torque-noise", type=positive, default=None, metavar="MNM",
                        help="the recorded motor torque's noise, mN m standard deviation: a recording with '<axis> torque' "
                        "columns is fitted in its torque too, weighed against the encoder's noise (--noise or --encoder-bits)")
    parser.add_argument("--angles-only", action="store_true", help="fit the encoder's angles alone, not a recorded motor torque")
    parser.add_argument("--quiet", action="store_true", help="no time estimate or phase lines while it runs (the report and errors are still printed)")
    out_options(parser, "identify")
    return parser


def plan_test_command(parser, args) -> int:
    """`tolerax plan-test SCENE --parameters ...`: the test (a sine scan, or slews with dwells)
    whose recording determines them best."""
    from ..identification.testdesign import design_test

    read = _scene_and_parameters(parser, args)
    if read is None:
        return 2
    scene_file, scene, parameters = read
    out = check_out(parser, args.out, "plan-test", force=args.force)
    noise = math.hypot(1e-6 * args.noise, 2 * math.pi / 2**args.encoder_bits / math.sqrt(12))
    limits = dict(max_amplitude=None if args.max_amplitude is None else math.radians(args.max_amplitude),
                  max_rate=None if args.max_rate is None else math.radians(args.max_rate))
    run = _run_settings(scene_file)
    print(f"tolerax plan-test: the test of {scene_file.title} whose {args.duration:g} s recording determines "
          f"{', '.join(parameters)} best; results in {out}/", flush=True)
    start = time.perf_counter()
    try:
        plan = design_test(scene, parameters, duration=args.duration, n_save=args.samples, noise=noise, settle=args.settle,
                           dwells=args.dwells, criterion=args.criterion, progress=not args.quiet, **limits, **run)
    except ValueError as err:
        print(f"tolerax plan-test: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    claim_out(out, "plan-test", fresh=args.force)
    from ..io import scenefile as F

    data = scene_file.data | {"title": f"Test: {scene_file.title}"}
    antenna = data["scene"].get("kind") == "antenna"  # an antenna's keys are scan_amplitude, scan_period; drive = "profile"
    prefix, scene = "scan_" if antenna else "", dict(data["scene"])
    if plan.slewing(plan.best):  # the tabulated profile in place of the scan's amplitude and period
        times, angles = plan.profile(plan.best)
        scene = {k: v for k, v in scene.items() if k not in (f"{prefix}amplitude", f"{prefix}period")} | (
            {"drive": "profile"} if antenna else {}) | {"profile_times": [float(v) for v in times],
                                                         "profile_angles": [float(v) for v in angles]}
    else:
        scene |= {f"{prefix}amplitude": float(plan.amplitude[plan.best]), f"{prefix}period": float(plan.period[plan.best])}
    data["scene"] = scene
    data["run"] = dict(data.get("run", {})) | {"duration": args.duration, "settle": args.settle, "n_save": args.samples}
    path = F.save_scene(F.SceneFile.from_data(data, "test", "<plan-test>"), out / "test.toml")
    text = "\n".join([
        f"# Test plan: {scene_file.title}", "", f"{wall:.1f} s of wall time ({len(plan.amplitude)} candidates, compilation "
        f"included); {load_average()}; encoder: {args.encoder_bits} bits and {args.noise:g} µrad of noise.", "",
        plan.table(), "", f"The test as a scene file: `{path}`. Record the unit running it, then "
        f"`tolerax identify {path} RECORDING --parameters {' '.join(parameters)}"
        + (f" --settle {args.settle:g}`." if args.settle else "`."), "", "Reproduce with:", "", "```",
        command_line(args), "```", "", *scene_and_settings(scene_file)])
    atomic_write(out / "test_plan.md", text + "\n")
    print(text)
    return 0


def add_plan_parser(sub, out_options, positive, non_negative, epilog):
    parser = sub.add_parser(
        "plan-test", help="the scan whose recording determines the chosen clearances and parameters best",
        description="Before a unit's acceptance test: of the sine scans (and, with --dwells, slews with dwells at each end) "
        "inside the mechanism's limits (amplitude, peak rate; default the scene's own scan's), the one whose recording of --duration s through the encoder determines "
        "--parameters best at the scene's values (tolerax.identification.testdesign), against the scene's own scan. "
        "Writes test_plan.md and test.toml (the scene running the proposed test, for tolerax identify).", epilog=epilog)
    parser.add_argument("scene", help="built-in scene name or path to a .toml scene file whose joints scan")
    parser.add_argument("--parameters", nargs="+", required=True, metavar="PARAMETER",
                        help="what the test must determine (tolerax identify --help lists the kinds)")
    parser.add_argument("--duration", type=positive, default=1.0, help="the recording's length, s (default 1)")
    parser.add_argument("--samples", type=int, default=401, help="samples over it (default 401)")
    parser.add_argument("--settle", type=non_negative, default=0.0, help="fit the samples from this time on, s (default 0)")
    parser.add_argument("--encoder-bits", type=int, default=20, help="the output encoder's resolution, bits (default 20)")
    parser.add_argument("--noise", type=positive, default=2.0, help="its noise, µrad standard deviation (default 2)")
    parser.add_argument("--max-amplitude", type=positive, default=None, metavar="DEG",
                        help="the largest scan amplitude the unit may run, deg (default the scene's)")
    parser.add_argument("--max-rate", type=positive, default=None, metavar="DEG_PER_S",
                        help="the highest rate, deg/s (default the scene's scan's peak rate)")
    parser.add_argument("--dwells", type=positive, nargs="+", default=(), metavar="S",
                        help="slews between the ends at the rate limit with these dwells at each end (s) join the candidates "
                        "(default none: their fits were rugged where measured, benchmarks/identify_test_design.py)")
    parser.add_argument("--criterion", default="weakest", choices=("weakest", "D"),
                        help="the weakest parameter's error (default) or the joint region's volume (D-optimal)")
    parser.add_argument("--quiet", action="store_true", help="no time estimate or line per candidate while it runs (the plan "
                        "and errors are still printed)")
    out_options(parser, "plan-test")
    return parser
