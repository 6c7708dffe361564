"""`tolerax run`, `design`, `montecarlo` and `studies`."""

import json
import pathlib
import sys
import time

from .common import command_line, has_features, load_average, read_scene_file, with_tolerances


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
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    for name in names:
        path = out / f"{name}-{args.size}.json"
        done = json.loads(path.read_text()) if args.resume and path.exists() else []

        def save(rows, path=path, done=done):
            # Every row so far, and the earlier run's rows this run has not reached yet, so an
            # interrupted run loses only the scene it was on.
            later = [r for r in done if not any(r is k for k in rows)]
            tmp = path.with_suffix(".json.tmp")
            tmp.write_text(json.dumps(rows + later, indent=1))
            tmp.replace(path)

        rows = S.run(name, args.size, duration=args.duration, settle=args.settle, done=done, on_row=save)
        save(rows, done=[])
        print(f"wrote {path}")
    return 0


def montecarlo_command(parser, args) -> int:
    import jax
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..uncertainty import montecarlo as MC
    from ..io import scenefile as F
    from ..design.objectives import UNITS

    scene_file = read_scene_file(parser, args)
    if scene_file is None:
        return 2
    scene_file = with_tolerances(scene_file, args.band, args.distribution)
    if not has_features(scene_file, "montecarlo"):
        return 2
    requirement = args.requirement if args.requirement is not None else scene_file.requirement
    pointing = scene_file.objective()
    tolerances = scene_file.tolerances(pointing.scene)
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    bands = ", ".join(f"{n} +-{b * 1e6:.3g}" for n, b in zip(tolerances.names, tolerances.band.tolist()))
    print(f"tolerax montecarlo: {args.n} units of {scene_file.name} ({scene_file.source}), {pointing.duration} s each, "
          f"window from {pointing.settle} s; features at nominal {bands} um ({tolerances.distribution}); "
          f"checkpoints in {out / 'chunks'} (rerun to resume).")
    try:
        res = MC.monte_carlo(pointing, tolerances, args.n, jax.random.key(args.seed), backend=args.backend,
                             chunk_size=args.chunk, out=out / "chunks", units=UNITS,
                             requirement=None if requirement is None else {"pointing_rms": requirement})
    except ValueError as err:  # e.g. checkpoints of other settings in the output folder
        print(f"tolerax montecarlo: {err}", file=sys.stderr)
        return 2
    F.save_scene(scene_file, out / "scene.toml")  # after the checkpoints were accepted as this run's
    res.save(out / "montecarlo.nc")
    summary = res.summary()
    (out / "summary.json").write_text(json.dumps(summary, indent=2, default=float))
    fig = res.plot_histogram("pointing_rms", requirement=requirement).figure
    fig.savefig(out / "histogram.png", dpi=120)
    plt.close(fig)
    print(res.report())
    print(f"wrote {out / 'scene.toml'}, {out / 'montecarlo.nc'}, {out / 'summary.json'} and {out / 'histogram.png'}")
    return 0 if summary["pointing_rms"]["n_failed"] == 0 else 3


def design_command(parser, args) -> int:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    from ..design import propose as _propose
    from ..io import scenefile as F

    scene_file = read_scene_file(parser, args)
    if scene_file is None:
        return 2
    requirement = args.requirement if args.requirement is not None else scene_file.requirement
    if requirement is None:
        parser.error(f"scene {scene_file.name!r} sets no [tolerances] requirement: give --requirement (arcsec, RMS pointing)")
    if not has_features(scene_file, "design"):
        return 2
    tol = scene_file.data.get("tolerances", {})
    band = tol.get("band", F.TOLERANCE_KEYS["band"][1])
    if tol.get("bands"):
        print(f"tolerax design: the optimiser starts every feature at the scene's band +-{band * 1e6:g} um; "
              "the per-feature [tolerances.bands] are not used.")
    if args.yield_ is not None and not 0.0 < args.yield_ < 1.0:
        parser.error(f"--yield must be a fraction in (0, 1), e.g. 0.99, got {args.yield_!r}")
    if args.yield_ is not None and args.method != "sequential":
        parser.error("--yield needs --method sequential (its Monte Carlo check re-solves the design)")
    if args.check is not None and args.yield_ is None:
        parser.error("--check needs --yield (it checks the yield of the proposal)")
    pointing = scene_file.objective()
    statistic = (f"mean + 1 std over {args.draws} units drawn uniformly within the bands" if args.yield_ is None
                 else f"yield {args.yield_:.1%}: the {args.yield_:.1%} quantile over all units within the bands")
    print(f"tolerax design: {scene_file.name} ({scene_file.source}), {pointing.duration} s per unit, window from "
          f"{pointing.settle} s; requirement {requirement} arcsec (RMS pointing, {statistic}); method {args.method}.")
    start = time.perf_counter()
    options = dict(n_draws=args.draws) if args.yield_ is None else dict(yield_=args.yield_, check_units=args.check)
    try:
        report = _propose.propose_design(pointing, requirement, band=band, max_outer=args.outer, inner_steps=args.inner,
                                         method=args.method, progress=True, **options)
    except ValueError as err:  # e.g. a starting band outside the optimiser's range
        print(f"tolerax design: {err}", file=sys.stderr)
        return 2
    except RuntimeError as err:  # a failed simulation makes the objective NaN
        print(f"tolerax design: {err}", file=sys.stderr)
        return 3
    wall = time.perf_counter() - start
    out = pathlib.Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    F.save_scene(scene_file, out / "scene.toml")
    text = "\n".join([report.table(), "", f"{wall:.1f} s of wall time (compilation included); {load_average()}.", "",
                      "Reproduce with:", "", "```", command_line(args), "```"])
    (out / "design.md").write_text(text + "\n")
    fig = report.plot()
    fig.savefig(out / "design.png", dpi=120)
    plt.close(fig)
    print(text)
    print(f"wrote {out / 'scene.toml'}, {out / 'design.md'} and {out / 'design.png'}")
    return 0


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
    out = pathlib.Path(args.out if args.out is not None else pathlib.Path("tolerax-out") / scene_file.name)
    print(f"tolerax run: {scene_file.title} ({scene_file.source}); {scene_file.run['duration']} s simulated; results in {out}/")
    start = time.perf_counter()
    try:
        result = scene_file.simulate(throw=False, progress=args.progress)
    except (ValueError, TypeError) as err:  # values the builders could not see (checked at solve time)
        print(f"tolerax run: {err}", file=sys.stderr)
        return 2
    wall = time.perf_counter() - start
    summary = R.write_results(scene_file, result, out, wall_s=wall, command=command_line(args))
    print(R.summary_md(summary))
    if not result.success:
        print("tolerax run: " + "\n".join(result.failures()), file=sys.stderr)
        return 3
    return 0
