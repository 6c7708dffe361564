"""`tolerax run`, `montecarlo` and `studies` (`design` and `tradeoff`: `tolerax.cli.design`)."""

import json
import pathlib
import sys
import time

from .._files import atomic_write, save_figure
from .common import (check_clipping, check_out, claim_out, command_line, has_features, human_seconds, load_average,
                     read_scene_file, rough_wall, scene_and_settings, scene_jitter, with_life, with_tolerances)


def studies_command(parser, args) -> int:
    from .. import studies as S

    names = args.names or list(S.STUDIES)
    for name in names:
        if name not in S.STUDIES:
            parser.error(f"unknown study {name!r}; choose from {', '.join(S.STUDIES)}")
    if args.size not in S.SIZES:
        parser.error(f"--size must be one of {', '.join(S.SIZES)}, got {args.size!r}")
    try:
        S.size_spec(args.size, args.duration, args.settle)
    except ValueError as err:
        parser.error(str(err))
    out = check_out(parser, args.out, "studies", force=args.force, resumes=args.resume)
    claim_out(out, "studies")
    for name in names:
        path = out / f"{name}-{args.size}.json"
        done = json.loads(path.read_text()) if args.resume and path.exists() else []

        def save(rows, path=path, done=done):
            # Every row so far, and the earlier run's rows this run has not reached yet, so an
            # interrupted run loses only the scene it was on.
            later = [r for r in done if not any(r is k for k in rows)]
            atomic_write(path, json.dumps(rows + later, indent=1))

        rows = S.run(name, args.size, not args.quiet, duration=args.duration, settle=args.settle, done=done, on_row=save)
        save(rows, done=[])
        print(f"wrote {path}")
    return 0


def montecarlo_command(parser, args) -> int:
    out = check_out(parser, args.out, "montecarlo", force=args.force, resumes=True)
    scene_file = montecarlo_scene(parser, args)
    if scene_file is None:
        return 2
    requirement = args.requirement if args.requirement is not None else scene_file.requirement
    scene_jitter(args, scene_file)
    cutoff = None if args.jitter is None else args.jitter_cutoff
    summary = run_monte_carlo(parser, scene_file, out, n=args.n, seed=args.seed, backend=args.backend, chunk=args.chunk,
                              requirement=requirement, allow_clip=args.allow_clip, command="montecarlo", jitter_cutoff=cutoff,
                              jitter_requirement=args.jitter, quiet=args.quiet, fresh=args.force)
    if summary is None:
        return 2
    if args.jitter is not None:
        j = summary["pointing_jitter"]
        print(f"tolerax montecarlo: jitter yield {j['yield']:.3f} [{j['yield_low']:.3f}, {j['yield_high']:.3f}] (95 % Wilson) of "
              f"{int(j['n_used'])} units at jitter above {cutoff:g} Hz <= {args.jitter:g} arcsec")
    return 0 if summary["pointing_rms"]["n_failed"] == 0 else 3


def montecarlo_scene(parser, args):
    """The scene file `tolerax montecarlo` simulates, from its arguments: `args.scene` with
    its `[run]` overrides, `--band` and `--distribution` in its `[tolerances]` and `--life YEARS`
    in its `[life]` (`with_life`); `None` where it cannot be simulated (the reason is printed:
    an invalid file, no feature to tolerance, a `--life` where nothing wears), before any
    simulation."""
    scene_file = read_scene_file(parser, args)
    if scene_file is None:
        return None
    scene_file = with_tolerances(scene_file, args.band, args.distribution)
    if not has_features(scene_file, "montecarlo"):
        return None
    if args.life is not None:
        try:
            scene_file = with_life(scene_file, args.life)
        except ValueError as err:  # a SceneFileError: the [life] the flag made
            print(f"tolerax montecarlo --life: {err}", file=sys.stderr)
            return None
    return scene_file


def run_monte_carlo(parser, scene_file, out, *, n, seed, backend, chunk, requirement, allow_clip, command, jitter_cutoff=None, quiet=False,
                    jitter_requirement=None, more_requirements=None, fresh=False):
    """`n` units of `scene_file` (its [tolerances] around its design) into the folder `out`:
    montecarlo.nc, summary.json, histogram.png and the scene; the summary (`None` where the
    checkpoints in `out` belong to other settings: the message is printed). `fresh`
    (`--force`): an earlier run's results and chunks in `out` removed first. What `tolerax
    montecarlo` runs, and `tolerax design --verify` on the proposal it wrote (with
    `jitter_cutoff` (Hz) the units' jitter too, its yield against `jitter_requirement`; and
    the yield of each output against its limit in `more_requirements`, {output: limit})."""
    import jax
    import matplotlib.pyplot as plt

    from ..uncertainty import montecarlo as MC
    from ..io import scenefile as F
    from ..design.objectives import UNITS

    pointing = scene_file.objective(jitter_cutoff=jitter_cutoff)
    tolerances = scene_file.tolerances(pointing.scene)
    check_clipping(parser, tolerances, allow_clip)
    chunk = MC.default_chunk(pointing) if chunk is None else chunk  # the scene's (`AbstractScene.unit_chunk`)
    claim_out(out, "montecarlo", fresh=fresh)  # design's --verify writes here too: its folder is montecarlo's
    kept = len(list((out / "chunks").glob("chunk-*.nc")))
    bands = ", ".join(f"{name} {m * 1e6:.4g} +- {b * 1e6:.3g}" for name, m, b in
                      zip(tolerances.names, tolerances.nominal.tolist(), tolerances.band.tolist()))
    print(f"tolerax {command}: {n} units of {scene_file.name} ({scene_file.source}), {pointing.duration} s each, "
          f"window from {pointing.settle} s; features (um) {bands} ({tolerances.distribution}); "
          f"checkpoints in {out / 'chunks'} (rerun to resume, or with a larger --n to extend the run)." + ("" if requirement is not None else
          " No requirement: give --requirement (arcsec, RMS pointing) for a yield.")
          + ("" if pointing.life is None else f" [life]: each unit also run at {pointing.life.points} life points (its outputs at "
             "the end of life: *_eol)" + (f"; its wear rate drawn over x{pointing.life.spread[0]:.3g} to x{pointing.life.spread[1]:.3g} "
                                          "(spread)." if pointing.uncertain_inputs else ".")))
    if kept and command == "montecarlo":  # design's --verify: its own --force means something else
        print(f"tolerax {command}: {kept} finished chunk{'s' if kept > 1 else ''} of an earlier run in {out / 'chunks'}: read back, "
              "not simulated again, where this run's settings are theirs (--force starts afresh).", flush=True)
    estimate = rough_wall(pointing.scene, pointing.duration, pointing.integrator)
    runs = n * (1 if pointing.life is None else pointing.life.points + 1)
    if estimate is not None and not quiet:
        helpers = MC.helper_count(-(-(n - kept * chunk) // chunk))[0] if backend == "auto" else 0
        beside = (f", about {human_seconds(max(estimate * runs / (helpers + 1), 1.0))} here with {helpers} worker process"
                  f"{'es' if helpers > 1 else ''} beside this one on idle cores" if helpers else "")
        print(f"tolerax {command}: integrated with {pointing.integrated_with}; roughly {human_seconds(max(estimate * runs, 1.0))} "
              f"on one core{beside} plus compilation ({runs} runs of {pointing.duration} s; a rattling unit can take several "
              "times longer); the bar below shows the chunks done and the time left.", flush=True)
    if pointing.uncertain_inputs:  # a [life] with spread: each unit's wear-rate factor is drawn with its zones
        tolerances = tolerances.joined(pointing.life.spread_tolerances(tolerances.distribution))
    try:
        res = MC.monte_carlo(pointing, tolerances, n, jax.random.key(seed), backend=backend, chunk_size=chunk, out=out / "chunks",
                             units=UNITS, progress=not quiet, requirement=None if requirement is None else {
                                 "pointing_rms": requirement, **({"pointing_jitter": jitter_requirement} if jitter_requirement else {}),
                                 # a [life]: the RMS requirement at the end of life too (one budget over the life)
                                 **({"pointing_rms_eol": requirement} if pointing.life is not None else {}),
                                 **(more_requirements or {})})
    except ValueError as err:  # e.g. checkpoints of other settings in the output folder
        print(f"tolerax {command}: {err}" + (" (--force starts afresh there.)" if command == "montecarlo" else ""), file=sys.stderr)
        return None
    F.save_scene(scene_file, out / "scene.toml")  # after the checkpoints were accepted as this run's
    res.save(out / "montecarlo.nc")
    summary = res.summary()
    for name, row in summary.items():  # each output's statistics in its unit, said beside them
        row["unit"] = pointing.units.get(name, "")
    atomic_write(out / "summary.json", json.dumps(summary, indent=2, default=float))
    fig = res.plot_histogram("pointing_rms", requirement=requirement).figure
    save_figure(fig, out / "histogram.png", dpi=120)
    plt.close(fig)
    print(res.report())
    _write_montecarlo_report(out, scene_file, res, summary, requirement, n, seed, command)
    print(f"wrote {out / 'scene.toml'}, {out / 'montecarlo.nc'}, {out / 'summary.json'}, {out / 'histogram.png'} and {out / 'report.md'}")
    return summary


def _write_montecarlo_report(out, scene_file, res, summary, requirement, n, seed, command):
    """`OUT/report.md` of a Monte Carlo run: the yield with its interval, the statistics with their
    units, what drives the pointing error (rank correlations), the histogram, the scene."""
    from ..design.objectives import UNITS

    rows = ["| output | units used | mean | std | q50 | q90 | q99 | unit |", "|---|---|---|---|---|---|---|---|"]
    for name, row in summary.items():
        rows.append(f"| {name} | {row['n_used']} of {row['n_samples']} | {row['mean']:.4g} | {row['std']:.4g} | {row['q50']:.4g} | "
                    f"{row['q90']:.4g} | {row['q99']:.4g} | {UNITS.get(name, '')} |")
    s = summary["pointing_rms"]
    verdict = ("No requirement given (--requirement, arcsec, RMS pointing): no yield." if requirement is None else
               f"Yield at RMS pointing <= {requirement:g} arcsec: **{s['yield']:.3f}** [{s['yield_low']:.3f}, {s['yield_high']:.3f}] "
               f"(95 % Wilson) over {int(s['n_used'])} units ({int(s['n_failed'])} failed solves).")
    drivers = res.drivers("pointing_rms")
    sections = [
        f"# Monte Carlo: {scene_file.title}", "", f"{n} manufactured units (seed {seed}) of `{scene_file.source}`, every feature "
        "drawn within its [tolerances] zone.", "", verdict, "", *rows, "",
        "What drives the RMS pointing error (Spearman rank correlation with each feature): "
        + ", ".join(f"{name} {rho:+.2f}" for name, rho in drivers.items()) + ".", "",
        "![histogram of the RMS pointing error against the requirement](histogram.png)", "",
        *scene_and_settings(scene_file, f"- {load_average()}",
                             f"- `tolerax {command}`; rerun the same command to resume, or with a larger --n to extend"),
    ]
    atomic_write(out / "report.md", "\n".join(sections))


def run_command(parser, args) -> int:
    from ..io import results as R, scenefile as F

    if args.list:
        for name, title in F.builtin_titles().items():
            print(f"{name:28s} {title}")
        return 0
    if args.scene is None:
        parser.error("run needs a SCENE: a built-in scene name or a .toml file (`tolerax run --list` names the built-in ones)")
    scene_file = read_scene_file(parser, args, n_save=args.n_save, start=args.start)
    if scene_file is None:
        return 2
    if args.life is not None:
        try:
            scene_file = with_life(scene_file, args.life)
        except ValueError as err:  # a SceneFileError: the [life] the flag made
            print(f"tolerax run --life: {err}", file=sys.stderr)
            return 2
    out = check_out(parser, args.out if args.out is not None else pathlib.Path("tolerax-out") / scene_file.name, "run", force=args.force)
    estimate = rough_wall(scene_file.build(), scene_file.run["duration"], scene_file.objective().integrator)
    guess = "" if estimate is None else f", roughly {human_seconds(max(estimate, 1.0))} on one core plus compilation"
    print(f"tolerax run: {scene_file.title} ({scene_file.source}); {scene_file.run['duration']} s simulated{guess}; results in {out}/")
    if estimate is not None and estimate > 120 and not args.progress:
        print("tolerax run: a long run: --progress shows how far it got (Ctrl-C stops it; --duration shortens it)")
    start = time.perf_counter()
    try:
        result = scene_file.simulate(throw=False, progress=args.progress)
    except (ValueError, TypeError) as err:  # values the builders could not see (checked at solve time)
        print(f"tolerax run: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    claim_out(out, "run", fresh=args.force)
    summary = R.write_results(scene_file, result, out, wall_s=wall, command=command_line(args))
    print(R.summary_md(summary))
    if not result.success:
        print("tolerax run: " + "\n".join(result.failures()), file=sys.stderr)
        return 3
    if scene_file.life is not None:
        life = scene_file.life
        print(f"tolerax run: [life] {life.points + 1} more runs of the window (the clearances worn over the life) ...", flush=True)
        text = life_summary(scene_file)
        atomic_write(out / "life.md", text)
        print(text)
    return 0


def life_summary(scene_file) -> str:
    """Markdown: the scene file's `[life]`: at each life point, the pointing outputs and each
    clearance's (and mesh backlash's) growth by wear (`PointingObjective(life=...).over_life`)."""
    import equinox as eqx
    import numpy as np

    from ..design.features import design_of
    from ..design.life import worn_joints

    pointing = scene_file.objective()
    life, table = pointing.life, scene_file.data["life"]
    outputs, depths = eqx.filter_jit(lambda p, v: p.over_life(v))(pointing, design_of(pointing.scene))
    joints = worn_joints(pointing.scene, life)
    years = float(table["years"])
    head = ["life point", "years", "RMS pointing error (arcsec)", "peak (arcsec)"]
    head += [f"{joint}.{contact} growth (um)" for joint, names in joints for contact in names]
    rows = []
    for k in range(life.points + 1):
        growth = [f"{float(depths[joint][k, i]) * 1e6:.3g}" for joint, names in joints for i in range(len(names))]
        rows.append([str(k), f"{years * k / life.points:.3g}", f"{float(outputs['pointing_rms'][k]):.1f}",
                     f"{float(outputs['pointing_peak'][k]):.1f}", *growth])
    ok = bool(np.all(np.asarray(outputs["success"])))
    lubricant = table.get("lubricant", "MoS2 sputtered film, vacuum")
    lines = [
        "## Over the mission's life",
        "",
        f"{years:g} years, {float(table.get('duty', 1.0)):.0%} of the time in this run's regime, {lubricant} "
        f"({table.get('estimate', 'median')} wear rate): the journal clearances grown by Archard wear from the simulated contact "
        f"forces over the window, and each mesh's backlash by its flanks' wear, re-simulated at {life.points} life points "
        "(tolerax.design.life). "
        + ("" if ok else "**Some runs failed: their rows are meaningless.**"),
        "",
        "| " + " | ".join(head) + " |",
        "|" + "---|" * len(head),
        *("| " + " | ".join(r) + " |" for r in rows),
        "",
    ]
    return "\n".join(lines)
