"""`tolerax design` and `tolerax tradeoff`: tolerance proposals from the command line."""

import copy
import dataclasses
import inspect
import json
import textwrap
import sys
import time

from .._files import atomic_write, save_figure
from .commands import run_monte_carlo
from .values import DesignValues
from .common import (check_out, claim_out, command_line, has_features, human_seconds, load_average, read_scene_file, scene_jitter,
                     rough_wall, scene_and_settings, settings, versions, with_life)

NOT_A_PROPOSAL = 4  # the exit code of design and tradeoff where the answer is not a proposal (tolerax.design.outcome)


def _design_setup(parser, args, command):
    """The checks and inputs `design` and `tradeoff` share: `(out, scene_file, values)` (the
    output folder checked; `values` a `DesignValues`: the zones from the scene's [tolerances], the
    statistic, the solver, the check and the constraint model the flags name), or `None` after
    printing why (exit 2)."""
    out = check_out(parser, args.out, args.command, force=args.force)
    scene_file = read_scene_file(parser, args)
    if scene_file is None:
        return None
    if args.fidelity is not None:
        scene_file = with_fidelity(scene_file, args.fidelity)
    if not has_features(scene_file, command):
        return None
    tol = scene_file.data.get("tolerances", {})
    args.solver = args.solver or tol.get("solver", "sequential")  # --solver, else the scene's [tolerances] solver
    if args.yield_ is None and tol.get("yield") is not None:
        args.yield_ = tol["yield"]  # the scene's [tolerances] yield; --yield overrides it
    if args.yield_ is not None and not 0.0 < args.yield_ < 1.0:
        parser.error(f"--yield must be a fraction in (0, 1), e.g. 0.99, got {args.yield_!r}")
    if args.yield_ is not None and args.solver == "augmented-lagrangian":
        parser.error("--yield needs --solver sequential or slsqp (its Monte Carlo check re-solves the design)")
    if args.check is not None and args.yield_ is None:
        parser.error("--check needs --yield (it checks the yield of the proposal)")
    if args.secant_units is not None and args.yield_ is None:
        parser.error("--secant-units needs --yield (it linearises the yield objective)")
    names = _feature_names(scene_file)
    if args.secant_units is not None and args.secant_units <= len(names):
        parser.error(f"--secant-units must exceed the scene's {len(names)} design features (a line through K units), got {args.secant_units}")
    widths = (1e-6, 1e-7)
    if args.widths is not None:
        if any(a <= b for a, b in zip(args.widths, args.widths[1:])):
            parser.error(f"--widths must go wide to narrow (decreasing), got {args.widths}")
        widths = tuple(args.widths)
    if args.model is not None and args.model != "auto" and args.yield_ is None:
        parser.error(f"--model {args.model} needs --yield (a constraint model linearises the yield)")
    # --model, else the scene's model for a yield: one name, or a table by output (then each
    # requirement carries its own from the scene's problem: `problem_of`)
    model_name = args.model or (tol.get("model", "auto") if args.yield_ is not None else "auto")
    if isinstance(model_name, dict):
        model_name = "auto"
    if model_name == "tangents" and args.secant_units is not None:
        parser.error("--secant-units is the units of --model secants or surface (tangents fit no units)")
    from .._defaults import DESIGN_SOLVERS
    from ..design import solvers, spec
    from ..io.problem import check_of, cost_of, model_of, solver_of, zones_of

    # The solver the name builds (`solver_of`, as a scene file's), --outer its budget (each class's
    # own field: `budget`), --inner the augmented Lagrangian's steps per outer iteration.
    options = {} if args.outer is None else {getattr(solvers, DESIGN_SOLVERS[args.solver]).budget: args.outer}
    solver = solver_of(scene_file, args.solver, widths=widths, **options,
                       **({"inner_steps": args.inner} if args.solver == "augmented-lagrangian" else {}))
    model = model_of(model_name)
    if args.secant_units is not None and model is not None:
        model = dataclasses.replace(model, units=args.secant_units)
    # The scene's zones (its design +- `bands`, else `band`) start the design, the fixed features
    # held at theirs; its functional minima, band range and cost: as `SceneFile.problem()` reads them.
    values = DesignValues(
        statistic=spec.MeanPlusKStd(units=args.draws) if args.yield_ is None else spec.Yield(args.yield_),
        zones=zones_of(scene_file), cost=cost_of(scene_file), allow_proxy=args.allow_proxy, solver=solver, model=model,
        secant_units=args.secant_units,
        check=None if args.yield_ is None else check_of(scene_file, args.check, backend=args.backend),  # --check over [tolerances] check
        progress=not args.quiet)
    return out, scene_file, values


def _more_requirements(parser, args, scene_file):
    """The further requirements (`Requirement`s): the scene's `[tolerances] require` table, each
    output's limit replaced by `--require OUTPUT=LIMIT` where given, and the `--require` ones it
    does not name; refused (exit 2) where one does not parse or repeats an output."""
    from ..design.requirements import Requirement
    from ..io.problem import further_requirements

    given = {text.replace("<=", "=").partition("=")[0].strip() for text in args.require or []}
    found = [r for r in further_requirements(scene_file) if r.output not in given]
    for text in args.require or []:
        name, _, limit = text.replace("<=", "=").partition("=")
        try:
            found.append(Requirement(name.strip(), float(limit)))
        except ValueError as err:
            parser.error(f"--require {text!r}: give OUTPUT=LIMIT, e.g. pointing_peak=2500 (arcsec): {err}")
    outputs = ["pointing_rms", *(["pointing_jitter"] if getattr(args, "jitter", None) else []), *(r.output for r in found)]
    if len(set(outputs)) != len(outputs):
        parser.error(f"--require: one requirement per output; got {', '.join(outputs)} (--requirement sets pointing_rms, --jitter pointing_jitter)")
    return found


def _statistic(args) -> str:
    return (f"mean + 1 std over {args.draws} units drawn uniformly within the bands" if args.yield_ is None
            else f"yield {args.yield_:.1%}: the {args.yield_:.1%} quantile over all units within the bands")


def _propose(pointing, requirement, values, command):
    """`(report, wall seconds)` of `propose_design` on `values` (`DesignValues`), or an exit code
    after printing why."""
    from ..design import propose as _p

    start = time.perf_counter()
    try:
        report = _p.propose_design(values.problem(pointing, requirement), values.solver, check=values.check, progress=values.progress)
    except ValueError as err:  # e.g. a starting band outside the optimiser's range
        print(f"tolerax {command}: {err}", file=sys.stderr)
        return 2
    except RuntimeError as err:  # a failed simulation makes the objective NaN
        print(f"tolerax {command}: {err}", file=sys.stderr)
        return 3
    return report, time.perf_counter() - start


def _life_allowance(pointing, report, requirements, values, args, scene_file, cutoff):
    """`--life`: a design for the end of life too (`report`) beside the same requirements at the
    beginning of life alone, designed with the same values on the as-built objective (its
    requirements linearised as such a design's are: by tangents unless secants are asked for),
    and both designs simulated at both ends of life on the same units (`--verify` N, else 32):
    `tolerax.design.life.life_comparison`'s markdown, or a note saying why it is missing (the
    main design is written either way)."""
    import jax

    from ..design.life import life_comparison

    alone_requirements = [r for r in requirements if not r.output.endswith("_eol")]
    print("tolerax design: the same requirements at the beginning of life alone (what the end of life's allowance is "
          "measured against) ...", flush=True)
    proposed = _propose(scene_file.objective(jitter_cutoff=cutoff, life=None), alone_requirements, values, "design")
    if isinstance(proposed, int):  # the main design stands: say why there is no comparison
        return ("## Over the mission's life: the wear allowance\n\nNot shown: the design for the beginning of life alone "
                "failed (above).")
    alone, _ = proposed
    units = args.verify or 32
    print(f"tolerax design: both designs on {units} units at both ends of life ...", flush=True)
    try:
        text, _ = life_comparison(pointing, report, alone, {r.output: r.limit for r in requirements}, units,
                                  jax.random.key(args.seed), chunk=args.chunk, progress=not args.quiet)
    except (ValueError, RuntimeError) as err:
        print(f"tolerax design: the life comparison failed: {err}", file=sys.stderr)
        return f"## Over the mission's life: the wear allowance\n\nNot shown: the comparison failed ({err})."
    return text


def design_command(parser, args) -> int:
    import matplotlib.pyplot as plt

    from ..design.fidelity import check_fidelity
    from ..design.requirements import Requirement

    from ..io import scenefile as F
    from ..io.problem import problem_of

    setup = _design_setup(parser, args, "design")
    if setup is None:
        return 2
    out, scene_file, values = setup
    requirement = args.requirement if args.requirement is not None else scene_file.requirement
    if requirement is None:
        parser.error(f"scene {scene_file.name!r} sets no [tolerances] requirement: give --requirement (arcsec, RMS pointing)")
    if args.verify_fidelity is not None and not args.verify:
        parser.error("--verify-fidelity needs --verify N (the units to simulate)")
    cutoff = None
    scene_jitter(args, scene_file)
    if args.jitter is not None:
        if args.yield_ is None:
            parser.error("--jitter needs --yield Y (both requirements are met by a fraction Y of the units)")
        cutoff = args.jitter_cutoff
        if args.verify and args.verify_fidelity is None and set(_fidelities(scene_file)) - {"ideal", "planetary"}:
            args.verify_fidelity = "planetary"  # the jitter is read on the full stage (tolerax.design.fidelity)
            print(f"tolerax design: --verify simulates the units at planetary fidelity: {scene_file.name} has lumped or "
                  "planetary-scaled joints, which do not read the jitter as the full stage does.")
    if args.life is not None:
        try:
            scene_file = with_life(scene_file, args.life, args.wear_spread, fix=" Set --fidelity planetary (every joint at the full stage) or "
                                  "give the scene a joint at planetary fidelity.")
        except F.SceneFileError as err:
            print(f"tolerax design --life: {err}", file=sys.stderr)
            return 2
    elif args.wear_spread:
        parser.error("--wear-spread needs --life YEARS (the life whose wear rate it draws)")
    if args.wear_spread and args.yield_ is None:
        parser.error("--wear-spread needs --yield Y (the design meets a yield over units whose wear rates are drawn)")
    more = _more_requirements(parser, args, scene_file)
    if args.life is not None and not any(r.output == "pointing_rms_eol" for r in more):
        more.append(Requirement("pointing_rms_eol", requirement))  # one pointing budget over the whole life
    # The flags written into the scene's [tolerances]: its problem is then what `SceneFile.problem()`
    # reads (the requirements in order, the objective with the [life] only where an _eol one reads it).
    try:
        problem = problem_of(with_problem(scene_file, requirement, more, args.yield_, args.jitter if cutoff else None, cutoff,
                                          args.model))
    except F.SceneFileError as err:
        if "[life]" in err.message:
            parser.error("an end-of-life requirement (--require ..._eol=LIMIT) needs a [life] table in the scene file "
                         "(docs/scene_files.md)")
        print(f"tolerax design: {err}", file=sys.stderr)
        return 2
    pointing = problem.objective
    if scene_file.life is not None and pointing.life is None:  # no requirement reads the end of life
        print("tolerax design: the scene has a [life]; this design is for the beginning of life only (add --require "
              "pointing_rms_eol=LIMIT to meet a limit at the end of life too).")
    unknown = [r.output for r in more if r.output not in pointing.outputs]
    if unknown:
        parser.error(f"a further requirement on {', '.join(unknown)} (--require or the scene's [tolerances] require): not an output "
                     f"of this scene's objective; its outputs: {', '.join(pointing.outputs)}")
    print(f"tolerax design: {scene_file.name} ({scene_file.source}), {pointing.duration} s per unit, window from "
          f"{pointing.settle} s; requirement {requirement} arcsec (RMS pointing, {_statistic(args)})"
          + (f" and jitter above {cutoff:g} Hz <= {args.jitter} arcsec" if cutoff else "")
          + "".join(f" and {r.text()}" for r in more) + f"; solver {args.solver}.")
    if not args.quiet:
        unit = rough_wall(pointing.scene, pointing.duration, pointing.integrator)
        print(f"tolerax design: integrated with {pointing.integrated_with}"
              + ("" if unit is None else f"; one unit roughly {human_seconds(max(unit, 1.0))} on one core plus compilation (a design "
                 "simulates hundreds of units and their gradients: each phase is said below as it starts, with the time so far)")
              + ". --quiet silences these lines.", flush=True)
    requirements = list(problem.requirements)  # RMS, the further ones, the jitter
    try:  # before any work: a requirement the scene's joints do not read (tolerax.design.fidelity), with this command's remedy
        check_fidelity(pointing.scene, requirements, allow_proxy=args.allow_proxy, who="tolerax design",
                       remedy="--fidelity planetary (or the scene file's [scene] fidelity)")
    except ValueError as err:
        print(err, file=sys.stderr)
        return 2
    proposed = _propose(pointing, requirements, values, "design")
    if isinstance(proposed, int):
        return proposed
    report, wall = proposed
    life_text = _life_allowance(pointing, report, requirements, values, args, scene_file, cutoff) if args.life is not None else None
    claim_out(out, "design", fresh=args.force)
    F.save_scene(scene_file, out / "scene.toml")
    # A design that is not a proposal (not converged, infeasible, noise-limited, its check missed) is
    # never written as the answer unless the user allows it.
    as_answer = report.accepted or args.allow_unconverged
    written = scene_file.with_proposal(report, cutoff)
    proposal = F.save_scene(written, out / ("proposal.toml" if as_answer else "best_reached.toml"))  # the zones as drawn
    text = "\n".join([report.table(), "", *([life_text, ""] if life_text else []),
                      f"{wall:.1f} s of wall time (compilation included); {load_average()}.", "",
                      "Reproduce with:", "", "```", command_line(args), "```", "",
                      (f"The proposal as a scene file: `{proposal}`" if report.accepted else
                       f"The best design reached as a scene file ({report.status}, not a proposal): `{proposal}`")
                      + f" (verify it with `tolerax montecarlo {proposal} --n 200"
                      + (f" --jitter {args.jitter:g} --jitter-cutoff {cutoff:g}" if cutoff else "")
                      + f" --out {out / 'montecarlo'}`: its own folder, "
                      "so this report is kept)."])
    atomic_write(out / "design.md", text + "\n")
    for fig, name in ((report.plot(), "design.png"), (report.plot_history(), "design_history.png")):
        save_figure(fig, out / name, dpi=120)
        plt.close(fig)
    print(text)
    sections = [
        f"# Tolerance proposal: {scene_file.title}", "",
        f"Requirement: RMS pointing error <= {requirement:g} arcsec"
        + (f" and jitter (RMS pointing error above {cutoff:g} Hz) <= {args.jitter:g} arcsec" if cutoff else "")
        + "".join(f" and {r.text()}" for r in more) + f", {_statistic(args)}. Scene `{scene_file.source}`; "
        f"the {'proposal' if report.accepted else 'best design reached'} as a scene file: [{proposal.name}]({proposal.name}).", "",
        "## Proposal", "", report.table(), "", *([life_text, ""] if life_text else []),
        "![the zones with their grades and fits, and the sensitivities](design.png)", "",
        "![the optimiser's history](design_history.png)", "",
    ]
    _write_report(out, sections, scene_file, args, wall)
    print(f"wrote {out / 'scene.toml'}, {proposal}, {out / 'design.md'}, {out / 'design.png'}, {out / 'design_history.png'} and "
          f"{out / 'report.md'}")
    if not as_answer:
        print(f"tolerax design: not a proposal ({report.status}): {report.diagnosis} The best design reached is in {proposal}; "
              f"--allow-unconverged writes it as proposal.toml (exit {NOT_A_PROPOSAL}).", file=sys.stderr)
        return NOT_A_PROPOSAL
    if not args.verify:
        return 0
    verify = F.load_scene(proposal)
    if args.verify_fidelity is not None:
        verify = with_fidelity(verify, args.verify_fidelity)
    summary = run_monte_carlo(parser, verify, out / "verify", n=args.verify, seed=args.seed, backend=args.backend, chunk=args.chunk,
                              requirement=requirement, allow_clip=False, command="design --verify", jitter_cutoff=cutoff,
                              jitter_requirement=args.jitter, more_requirements={r.output: r.limit for r in more}, quiet=args.quiet)
    if summary is None:
        return 2
    s = summary["pointing_rms"]
    line = (f"yield {s['yield']:.3f} [{s['yield_low']:.3f}, {s['yield_high']:.3f}] (95 % Wilson) of {int(s['n_used'])} units "
            f"at RMS pointing <= {requirement:g} arcsec" + (f" (proposed for {args.yield_:.1%})" if args.yield_ is not None else "")
            + (f", simulated at {args.verify_fidelity} fidelity" if args.verify_fidelity else ""))
    if cutoff:
        j = summary["pointing_jitter"]
        line += (f"; jitter yield {j['yield']:.3f} [{j['yield_low']:.3f}, {j['yield_high']:.3f}] at jitter above {cutoff:g} Hz "
                 f"<= {args.jitter:g} arcsec")
    for r in more:
        m = summary[r.output]
        line += f"; {r.name} yield {m['yield']:.3f} [{m['yield_low']:.3f}, {m['yield_high']:.3f}] at {r.text()}"
    print(f"tolerax design --verify: {line}")
    sections += ["## Verification", "", f"{args.verify} fresh units of the proposal (seed {args.seed}, uniform within the zones): {line}; "
                 f"mean {s['mean']:.1f} arcsec, 99 % quantile {s['q99']:.1f} arcsec ({int(s['n_failed'])} failed solves).", "",
                 "![yield histogram against the requirement](verify/histogram.png)", ""]
    _write_report(out, sections, scene_file, args, wall)
    return 0 if s["n_failed"] == 0 else 3


def _write_report(out, sections, scene_file, args, wall):
    """`OUT/report.md`: one self-contained page per job for a design review (its figures beside it)."""
    text = "\n".join([
        *sections, *scene_and_settings(scene_file, f"- {wall:.1f} s of wall time for the design (compilation included); {load_average()}",
                                        f"- reproduce with: `{command_line(args)}`"),
    ])
    atomic_write(out / "report.md", text)


def _feature_names(scene_file):
    from ..design.features import design_names

    return design_names(scene_file.build())


def _fidelities(scene_file) -> list[str]:
    """The fidelity of each joint of the scene (`[scene] fidelity`, or its builder's default)."""
    from ..io.schema import BUILDERS

    scene = scene_file.data["scene"]
    current = scene.get("fidelity", inspect.signature(BUILDERS[scene["kind"]]).parameters["fidelity"].default)
    return [current, current] if isinstance(current, str) else list(current)


def with_problem(scene_file, requirement, more=(), yield_=None, jitter=None, cutoff=None, model=None):
    """`scene_file` with its `[tolerances]` stating a design problem (its other keys kept): the RMS
    `requirement` (arcsec), the further `more` (`Requirement`s: `require`), a `yield_`, a `jitter`
    (arcsec) above `cutoff` (Hz) and a constraint `model` name where given (`None` drops a yield
    or a jitter, keeps the scene's model): what `tolerax design`'s flags ask, read back by
    `SceneFile.problem()` as a scene file's own keys are. `SceneFileError` as for a file."""
    from ..io import scenefile as F

    data = copy.deepcopy(scene_file.data)
    tol = data.setdefault("tolerances", {})
    tol |= {"requirement": float(requirement), "require": {r.output: float(r.limit) for r in more}}
    for key, value in (("yield", yield_), ("jitter", jitter), ("jitter_cutoff", cutoff)):
        if value is None:
            tol.pop(key, None)
        else:
            tol[key] = float(value)
    if model is not None:
        tol["model"] = model
    return F.SceneFile.from_data(data, scene_file.name, scene_file.source)


def with_fidelity(scene_file, fidelity):
    """`scene_file` with every joint that is not ideal at `fidelity` (e.g. a lumped design
    verified at planetary fidelity; features the design did not model keep the scene's values
    and its [tolerances] band)."""
    from ..io import scenefile as F

    data = copy.deepcopy(scene_file.data)
    data["scene"]["fidelity"] = [f if f == "ideal" else fidelity for f in _fidelities(scene_file)]
    return F.SceneFile.from_data(data, scene_file.name, scene_file.source)


def tradeoff_command(parser, args) -> int:
    """One proposal per requirement: the cost-against-requirement curve (tradeoff.md, .json,
    .png) and each proposal as a scene file (proposal-R.toml)."""
    import matplotlib.pyplot as plt

    import numpy as np

    from ..eta import time_left
    from ..io import scenefile as F

    setup = _design_setup(parser, args, "tradeoff")
    if setup is None:
        return 2
    out, scene_file, values = setup
    requirements = sorted(set(args.requirements))
    pointing = scene_file.objective(life=None)  # the requirements are the beginning of life's
    print(f"tolerax tradeoff: {scene_file.name} ({scene_file.source}), {pointing.duration} s per unit, window from "
          f"{pointing.settle} s; requirements {', '.join(f'{r:g}' for r in requirements)} arcsec (RMS pointing, {_statistic(args)}).")
    others = [k for k in ("jitter", "require") if k in scene_file.data.get("tolerances", {})]
    if others:
        print(f"tolerax tradeoff: the curve is the RMS requirement's alone; the scene's [tolerances] {' and '.join(others)} "
              "are not designed for here (tolerax design meets them at one requirement).")
    claim_out(out, "tradeoff", fresh=args.force)
    points, rows = [], []
    for k, requirement in enumerate(requirements):
        proposed = _propose(pointing, requirement, values, "tradeoff")
        if isinstance(proposed, int):
            return proposed
        report, wall = proposed
        if not args.quiet:  # the pace so far: each point is one design
            spent = sum(p["wall_s"] for p in points) + wall
            print(f"tolerax tradeoff: {requirement:g} arcsec {report.status} in {human_seconds(wall)}; {k + 1} of "
                  f"{len(requirements)} points" + time_left(spent, k + 1, len(requirements)), flush=True)
        path = F.save_scene(scene_file.with_proposal(report),
                            out / f"{'proposal' if report.accepted or args.allow_unconverged else 'best_reached'}-{requirement:g}.toml")
        # The proposal is the zones as drawn (whole grades) and their own check, where there are some.
        drawn = report.drawable.checks if report.drawable is not None and report.drawable.checks else ()
        first = report.outcomes[0]
        check = drawn[0] if drawn else first.checks[-1] if first.checks else None
        zones = report.tolerances
        points.append(dict(
            requirement=requirement, target=first.target, objective=first.objective, cost=report.proposal_cost,
            continuous_cost=report.cost, baseline_cost=report.baseline[2], converged=bool(report.result.converged), status=report.status,
            diagnosis=report.diagnosis, names=list(report.names), cost_unit=report.cost_unit, extrapolated=list(report.extrapolated),
            nominal_um=(np.asarray(zones.nominal) * 1e6).tolist(), band_um=(np.asarray(zones.band) * 1e6).tolist(), proposal=str(path),
            wall_s=wall,
            check=None if check is None else dict(units=check.n - check.n_failed, yield_=check.yield_simulated, interval=list(check.interval)),
        ))
        rows.append(f"| {requirement:g} | {first.objective:.1f} | {report.proposal_cost:.3f} | {report.status} | "
                    + ", ".join(f"{b * 1e6:.1f}" for b in np.asarray(zones.band)) + " | "
                    + ("" if check is None else f"{check.yield_simulated:.3f} [{check.interval[0]:.3f}, {check.interval[1]:.3f}]")
                    + f" | {path.name} | {wall:.0f} |")
        # Written after every point: an interrupted run keeps the points it finished.
        atomic_write(out / "tradeoff.json", json.dumps(dict(command=command_line(args), scene=scene_file.source, points=points), indent=1))
    what = "objective (arcsec)" if args.yield_ is None else f"linearised {args.yield_:.1%} quantile (arcsec)"
    text = "\n".join([
        f"# Tolerance cost against the pointing requirement: {scene_file.title}", "",
        f"RMS pointing, {_statistic(args)}; cost in {points[0]['cost_unit']} (baseline {points[0]['baseline_cost']:.3f}). "
        f"Features: {', '.join(points[0]['names'])}.", "",
        *[line for p in points if p["extrapolated"] for line in (f"At {p['requirement']:g} arcsec: {' '.join(p['extrapolated'])}", "")],
        f"| requirement (arcsec) | {what} | cost (as drawn) | outcome | bands as drawn +- (um) | Monte Carlo check: yield [95 % Wilson] | proposal | wall (s) |",
        "|---|---|---|---|---|---|---|---|", *rows, "",
        "![cost against requirement](tradeoff.png)", "",
        f"Solver (`[run]`): {settings(scene_file)}. {versions()}. {load_average()}. Reproduce with:", "", "```", command_line(args), "```",
    ])
    atomic_write(out / "tradeoff.md", text + "\n")
    fig, ax = plt.subplots(figsize=(5.5, 3.8))
    req = [p["requirement"] for p in points]
    cost = [p["cost"] for p in points]
    ax.plot(req, cost, "-", color="C0", lw=1)
    for p in points:
        ok = p["status"] == "converged"
        ax.plot(p["requirement"], p["cost"], "o" if ok else "x", color="C0" if ok else "C3")
    ax.plot([], [], "o", color="C0", label="proposal (converged)")
    ax.plot([], [], "x", color="C3", label="not a proposal")
    ax.axhline(points[0]["baseline_cost"], color="0.5", ls=":", label="baseline bands")
    ax.set_xlabel("RMS pointing requirement (arcsec)")
    ax.set_ylabel("tolerance cost\n(" + textwrap.shorten(points[0]["cost_unit"], 48, placeholder="...") + ")", fontsize=8)
    ax.set_title(_statistic(args).split(":")[0], fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    save_figure(fig, out / "tradeoff.png", dpi=120)
    plt.close(fig)
    print(text)
    print(f"wrote {out / 'tradeoff.md'}, {out / 'tradeoff.json'}, {out / 'tradeoff.png'} and {len(points)} proposal-R.toml "
          "(best_reached-R.toml where a point is not a proposal)")
    missed = [p for p in points if p["status"] != "converged"]
    for p in missed:
        print(f"tolerax tradeoff: {p['requirement']:g} arcsec is not a proposal ({p['status']}): {p['diagnosis']}", file=sys.stderr)
    return NOT_A_PROPOSAL if missed and not args.allow_unconverged else 0
