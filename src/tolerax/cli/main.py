"""Command line of tolerax.

- `tolerax demo`: the paper's dual-axis antenna scanning +-0.5 deg on both axes (built-in scene
  `scan`): its pointing error over time, then a short tolerance proposal on the azimuth scan
  (`--bench`: the default joint on its test bench instead).
- `tolerax run SCENE`: simulate a scene file: netCDF time series, plots and a markdown summary.
- `tolerax design [SCENE]`: propose clearances, backlash and tolerance bands that meet an RMS
  pointing requirement at the lowest cost.
- `tolerax montecarlo [SCENE]`: pointing-error distribution and yield over manufacturing errors
  (netCDF, summary JSON, histogram; resumable).
- `tolerax tradeoff [SCENE] --requirements R1 R2 ...`: the cost-against-requirement curve, one
  proposal per requirement.
- `tolerax studies`: the reference paper's studies (a JSON table per study).
- `tolerax identify SCENE RECORDING`: a built unit's clearances and backlash from its test
  recording (encoder angles), with intervals, and the unit as a scene file.
- `tolerax plan-test SCENE --parameters ...`: before that test, the scan whose recording
  determines the chosen parameters best.

The engineer's path in three commands (design, verify, trade off):

    tolerax design my_drive.toml --requirement 700 --yield 0.99 --verify 200   # writes tolerax-out/design/proposal.toml
    tolerax montecarlo tolerax-out/design/proposal.toml --n 1000   # verify it further (into tolerax-out/montecarlo)
    tolerax tradeoff my_drive.toml --yield 0.99 --requirements 400 700 1000   # what tighter pointing costs

SCENE is a built-in scene name (`tolerax run --list`) or a path to a .toml scene file (schema:
docs/scene_files.md); design, montecarlo and tradeoff default to `scan-azimuth`. `tolerax COMMAND --help`
lists a command's options.

Exit codes: 0 done, 2 bad input (a bad option, an unreadable or invalid scene file: the message
names the file, line and key; an output folder holding another command's results, or an earlier
run's without --force, or one that cannot be written: refused before any work), 3 a simulation or optimisation failed, 4 (design, tradeoff) the answer
is not a proposal: not converged, infeasible, noise-limited, or its Monte Carlo check missed (the best
design reached is written as best_reached.toml, the report says why first; --allow-unconverged
writes it as proposal.toml and exits 0).

Compiled programs are kept in ~/.cache/tolerax/jax (TOLERAX_CACHE_DIR to move it,
TOLERAX_CACHE=off to turn it off): a second command on the same scene structure starts faster.
"""

import argparse
import sys
import warnings

from .. import __version__  # the package's import is light (tolerax/__init__.py): the options are checked first
from .._defaults import DESIGN_SOLVERS
from .commands import montecarlo_command, run_command, studies_command
from .design import design_command, tradeoff_command
from .common import (DEFAULT_SCENE, JITTER_CUTOFF, DESIGN_EPILOG, EPILOG, MONTECARLO_EPILOG, band_um, count, figures_to_files, length_in, non_negative, out_options, positive, positive_length,
                     integrator_option, scene_options, wrap)
from .demo import demo_command
from .identify import add_parser as identify_parser, add_plan_parser, identify_command, plan_test_command

# What an interrupted command has kept, and how to go on.
RESUME = {
    "montecarlo": "finished chunks are kept under OUT/chunks: rerun the same command to resume",
    "studies": "finished rows are kept in OUT/STUDY-SIZE.json: rerun with --resume to go on",
    "tradeoff": "the points finished are in OUT/tradeoff.json and OUT/proposal-R.toml",
}


# `--solver`'s names -> the design solver classes they build (tolerax.design.solvers).
SOLVERS = DESIGN_SOLVERS


def solver_option(parser, names, text):
    """`--solver NAME` (one of `names`, a design solver class by its name on the command line),
    and the former `--method NAME`, still taken for one release (hidden; `main` says what
    replaces it)."""
    parser.add_argument("--solver", choices=tuple(names), default=None, help=text)
    parser.add_argument("--method", choices=tuple(names), default=None, help=argparse.SUPPRESS)


def _solver_of(command_parser, args) -> None:
    """`args.solver` from `--solver`, else the deprecated `--method` (said on stderr), else
    None (the scene file's `[tolerances] solver`, else sequential: the command decides); both
    given and different: refused (exit 2)."""
    if not hasattr(args, "solver"):
        return
    if args.method is not None:
        if args.solver is not None and args.solver != args.method:
            command_parser.error(f"--solver {args.solver} and --method {args.method} disagree; give --solver alone")
        print(f"tolerax {args.command}: --method is deprecated and will be removed; use --solver {args.method} (the design solver "
              f"tolerax.{SOLVERS[args.method]}()).", file=sys.stderr)
        args.solver = args.method


def optimiser_options(parser):
    """The proposal's options, shared by `design` and `tradeoff`."""
    parser.add_argument("--draws", type=count(2), default=4,
                        help="manufactured units in the robust objective, mean + 1 std (default 4, at least 2)")
    solver_option(parser, SOLVERS,
                  "the design solver (default: the scene file's [tolerances] solver, else sequential, tolerax.Sequential(): a stack-up linearised from the simulation "
                  "at each iterate, solved exactly in a trust region; augmented-lagrangian, tolerax.AugmentedLagrangian(): "
                  "Adam on an augmented Lagrangian, no yield; slsqp, tolerax.SLSQP(): SciPy's SLSQP on the same problem, the "
                  "reference, tangent slopes only)")
    parser.add_argument("--outer", type=count(1), default=None,
                        help="sequential: gradients per smoothing width at most (default 20); augmented-lagrangian: outer "
                        "iterations (default 6); slsqp: its iterations per width (default 100)")
    parser.add_argument("--inner", type=count(1), default=10, help="augmented-lagrangian: steps per outer iteration (default 10)")
    parser.add_argument("--widths", type=positive_length("m"), nargs="+", default=None, metavar="W",
                        help="smoothing widths of the contacts, m (or with a unit: 1um), wide to narrow; the design is judged at the last (default "
                        "1e-6 1e-7; propose_design's widths)")
    parser.add_argument("--yield", dest="yield_", type=float, default=None, metavar="Y",
                        help="a yield requirement: P(RMS pointing <= requirement) >= Y, e.g. 0.99 (linearised at the zone "
                        "middles, checked on --check fresh units); default: the scene's [tolerances] yield, else mean + 1 std "
                        "over --draws units")
    parser.add_argument("--check", type=count(0), default=None,
                        help="with --yield: fresh units simulated to check (and correct) the yield (default: the scene file's [tolerances] check, else 200; 0: none)")
    parser.add_argument("--backend", default="auto", choices=("auto", "vmap", "processes"),
                        help="how the Monte Carlo checks' units (and design's --verify) are simulated: auto (default), "
                        "batched in this process with worker processes beside it on idle cores; vmap, this process alone; "
                        "processes, a pool of one worker per core")
    parser.add_argument("--allow-unconverged", action="store_true",
                        help="write the best design reached as proposal.toml (and exit 0) even where it is not a proposal: "
                        "not converged, infeasible, noise-limited, or its Monte Carlo check missed (otherwise it is written as "
                        "best_reached.toml and the command exits 4)")
    parser.add_argument("--fidelity", choices=("lumped", "planetary", "planetary-scaled"), default=None,
                        help="design at this fidelity: every joint of the scene that is not ideal (default: the scene's own)")
    parser.add_argument("--allow-proxy", action="store_true",
                        help="design requirements whose output the scene's joints do not read as the full stage does (the "
                        "jitter on lumped or planetary-scaled joints) instead of refusing them (tolerax.design.fidelity)")
    parser.add_argument("--model", choices=("auto", "tangents", "secants", "surface"), default=None,
                        help="with --yield: how every requirement's yield is linearised (tolerax.design.spec; default: the "
                        "scene's [tolerances] model, else auto): auto ("
                        "tangents, finished on secants where they stall; the jitter on a response surface), tangents, secants "
                        "(a line through units of the zone) or surface (a response surface refitted as the design moves)")
    parser.add_argument("--secant-units", type=count(2), default=None, metavar="K",
                        help="with --yield: fit the linearised yield's value and slopes over K units of the zone (more than the "
                        "features; forward solves only) instead of forward-mode tangents at its middle, which are rough where "
                        "contacts rattle (alone: the automatic model on K units, Auto(units=K): each output's measured scatter picks a "
                        "response surface on K units or a line through K units; with --model secants or surface, their units)")


PATH = __doc__[__doc__.index("The engineer's path"):__doc__.index("SCENE is a built-in")].strip()


def _refuse_unknown(command_parser, command: str, unknown) -> None:
    """Exit 2 naming the arguments `command` does not take, the nearest option where one is
    misspelt (`--requirment`: `--requirement`), and where its options are listed."""
    import difflib

    options = [o for action in command_parser._actions for o in action.option_strings]
    early = [u for u in unknown if u.split("=")[0] in options]  # the command's own, given before it
    near = [m for u in unknown if u.startswith("-") and u not in early
            for m in difflib.get_close_matches(u.split("=")[0], options, n=1, cutoff=0.75)]
    command_parser.error(f"unrecognized arguments: {' '.join(unknown)}"
                         + (f" ({', '.join(early)}: an option of `tolerax {command}`: give it after the command)" if early else "")
                         + (f" (did you mean {', '.join(near)}?)" if near else "") + f"; `tolerax {command} --help` lists its options")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="tolerax", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--version", action="version", version=f"tolerax {__version__}")
    sub = parser.add_subparsers(dest="command", required=True)
    demo = sub.add_parser(
        "demo", help="the dual-axis antenna: pointing error over time and a short tolerance proposal",
        description="Simulate the built-in scene `scan` (the paper's dual-axis antenna, both joints scanning +-0.5 deg "
        "at 1 Hz, lumped joints with 100 um clearances and backlash) and plot its pointing error over time; then "
        f"propose tolerances for `{DEFAULT_SCENE}` with a few optimiser steps. Writes demo.png, demo.md, scan/ (as "
        "`tolerax run`) and design/ into the output folder. --bench runs the default joint on its test bench instead.",
        epilog=EPILOG,
    )
    demo.add_argument("--duration", type=positive, default=None,
                      help="simulated time, s (default 1, one scan period; with --bench 2); the pointing window starts at 0.3 s "
                      "when the run is longer")
    demo.add_argument("--steps", type=count(0), default=6,
                      help="0 skips the proposal; with --solver augmented-lagrangian: steps per outer iteration (default 6)")
    demo.add_argument("--outer", type=count(1), default=None,
                      help="sequential: gradients per smoothing width at most (default 20); augmented-lagrangian: outer "
                      "iterations (default 3)")
    solver_option(demo, ("sequential", "augmented-lagrangian"),
                  "the proposal's design solver (default sequential, tolerax.Sequential(); augmented-lagrangian, "
                  "tolerax.AugmentedLagrangian())")
    demo.add_argument("--draws", type=count(2), default=2,
                      help="manufactured units in the robust objective, mean + 1 std (default 2, at least 2)")
    demo.add_argument("--requirement", type=positive, default=700.0,
                      help="RMS pointing requirement of the proposal, arcsec (default 700)")
    demo.add_argument("--bench", action="store_true", help="run the default joint on its test bench instead (bench.png, summary.json)")
    demo.add_argument("--rate", type=float, default=None, help="with --bench: commanded output rate, deg/s (default 0.98)")
    demo.add_argument("--clearance", type=length_in("um"), default=None,
                      help="with --bench: every radial clearance, um (or with a unit: 0.1mm; default 100)")
    demo.add_argument("--backlash", type=length_in("um"), default=None,
                      help="with --bench: every mesh backlash, um (or with a unit: 0.1mm; default 100)")
    out_options(demo, "demo")
    demo.add_argument("--progress", action="store_true", help="show the integrator's progress")
    run = sub.add_parser(
        "run", help="simulate a scene file: netCDF time series, plots and a markdown summary",
        description="Simulate a scene file (a built-in scene name or a path to a .toml file; schema in "
        "docs/scene_files.md) and write scene.toml, timeseries.nc, PNG plots, summary.json and summary.md "
        "into the output folder. Exit codes: 0 done, 2 bad input (the message names the key and line), "
        "3 the solver failed (the partial results are still written).",
    )
    run.add_argument("scene", nargs="?", help="built-in scene name (see --list) or path to a .toml scene file")
    run.add_argument("--list", action="store_true", help="list the built-in scenes and exit")
    out_options(run, "run", default="./tolerax-out/SCENE_NAME")
    run.add_argument("--duration", type=positive, default=None, help="override run.duration, s")
    run.add_argument("--settle", type=non_negative, default=None, help="override run.settle (start of the pointing window), s")
    run.add_argument("--n-save", type=count(2), default=None, help="override run.n_save (saved times)")
    run.add_argument("--start", choices=("rest", "steady", "loaded"), default=None, help="override run.start")
    run.add_argument("--life", type=positive, default=None, metavar="YEARS",
                     help="then the window again over a mission of YEARS years, the clearances grown by wear (life.md): the "
                     "scene's [life] years (its other keys kept; without one, sputtered MoS2 at its median rate, duty 1, 2 life "
                     "points). Needs a joint at planetary fidelity")
    integrator_option(run)
    run.add_argument("--progress", action="store_true", help="show the integrator's progress")
    design = sub.add_parser(
        "design", help="propose clearances, backlash and tolerance bands for a pointing requirement",
        description=wrap(
            "Propose, for each clearance and backlash of the scene, the tolerance zone (lower limit and half-width) of lowest "
            "cost (ISO 286 grades) whose RMS pointing error meets the requirement: mean + 1 std over a few manufactured units, "
            "or with --yield Y in a fraction Y of all units (tolerax.propose_design). Starts from the scene's zones (its design and "
            "its [tolerances] bands). Writes scene.toml, design.md, design.png, design_history.png and proposal.toml (the scene with the proposed "
            "nominals and bands filled in, which run, montecarlo and design read back); --verify N simulates N units of it."),
        epilog=PATH + "\n\n" + wrap(DESIGN_EPILOG), formatter_class=argparse.RawDescriptionHelpFormatter,
    )
    scene_options(design, "design", "design")
    design.add_argument("--requirement", type=positive, default=None,
                        help="RMS pointing requirement, arcsec (default: the scene's [tolerances] requirement)")
    optimiser_options(design)
    design.add_argument("--jitter", type=positive, default=None, metavar="J",
                        help="with --yield: a pointing-stability requirement beside the RMS one: the jitter (RMS pointing error "
                        "above --jitter-cutoff Hz over the window), arcsec, met by the same fraction Y of units. Both are "
                        "linearised over units (default, --model auto: a response surface over 64 units from the functional "
                        "minimum to 100 um, the jitter's line on its logarithm, refitted over the design's zones up to six "
                        "times; --secant-units K: the same on K units; --model secants: plain secants). The jitter is "
                        "read on the full stage only: a scene with lumped or planetary-scaled joints is refused (give "
                        "--fidelity planetary, or --allow-proxy to design on the proxy knowingly). Default: the scene's "
                        "[tolerances] jitter")
    design.add_argument("--require", action="append", metavar="OUTPUT=LIMIT",
                        help="a further requirement on another output of the pointing objective, met at the same statistic "
                        "or yield, e.g. --require pointing_peak=2500 (arcsec; outputs: pointing_peak, pointing_smooth_peak, "
                        "tracking_speed_rms in arcsec/s); repeat for more. The scene's [tolerances] require table gives "
                        "further requirements too; --require replaces its limit for the same output")
    design.add_argument("--life", type=positive, default=None, metavar="YEARS",
                        help="design for the end of a mission of YEARS years as well: the RMS requirement met at the end of "
                        "life too (one budget over the life; --require pointing_rms_eol=LIMIT sets another), the clearances "
                        "grown by wear from the simulated contacts. The scene's [life] table gives the rest (lubricant, duty, "
                        "points, flanks, spread); without one, sputtered MoS2 at its median rate, duty 1, 2 life points. Each "
                        "unit costs points + 1 runs. The same requirements are then designed for the beginning of life alone, "
                        "and design.md shows the wear allowance per feature and both designs' yields at both ends of life on "
                        "the same units (--verify N of them, else 32). Needs a planetary joint (--fidelity planetary)")
    design.add_argument("--wear-spread", action="store_true",
                        help="with --life: each unit's wear rate drawn over the lubricant's published band ([life] spread = "
                        "true), so the design meets its yield over the band, not at one rate (needs --yield)")
    design.add_argument("--jitter-cutoff", type=positive, default=JITTER_CUTOFF, metavar="HZ",
                        help="with --jitter: the start of the stability band, Hz (default: the scene's [tolerances] "
                        "jitter_cutoff, else 20)")
    design.add_argument("--verify", type=count(0), default=0, metavar="N",
                        help="then simulate N units of the written proposal.toml (as `tolerax montecarlo OUT/proposal.toml --n N`, "
                        "into OUT/verify) and report its yield with a 95 %% Wilson interval (default 0: none)")
    design.add_argument("--verify-fidelity", choices=("lumped", "planetary", "planetary-scaled"), default=None,
                        help="with --verify: simulate the units at this fidelity (every joint that is not ideal), e.g. a "
                        "lumped design verified on the planetary stage (default: the scene's own; with --jitter, planetary)")
    design.add_argument("--seed", type=int, default=0, help="with --verify: the units' random seed (as montecarlo's)")
    design.add_argument("--chunk", type=count(1), default=None,
                        help="with --verify: units per chunk (default: the scene's, 10 with a full planetary stage, else 50)")
    tradeoff = sub.add_parser(
        "tradeoff", help="the cost of the cheapest tolerances against the pointing requirement",
        description="One proposal (as `tolerax design`) per requirement: writes tradeoff.md (the table), tradeoff.json, "
        "tradeoff.png (cost against requirement) and each proposal as proposal-R.toml (verify one with "
        "`tolerax montecarlo OUT/proposal-R.toml --out OUT/montecarlo-R`). Every point reuses the compiled simulation: only the requirement changes.",
        epilog=DESIGN_EPILOG,
    )
    scene_options(tradeoff, "design", "tradeoff")
    tradeoff.add_argument("--requirements", type=positive, nargs="+", required=True, metavar="R",
                          help="RMS pointing requirements, arcsec, e.g. --requirements 400 550 700 1000")
    optimiser_options(tradeoff)
    mc = sub.add_parser(
        "montecarlo", help="pointing-error distribution and yield over manufacturing errors",
        description="Simulate manufactured units of the scene, each clearance and backlash drawn within its "
        "[tolerances] band, and write their pointing statistics (montecarlo.nc), a summary (summary.json, with "
        "the yield when a requirement is known) and a histogram. Chunks are checkpointed under OUT/chunks: "
        "rerun the same command to resume, or with a larger --n to extend a finished run (its first units kept, bitwise).",
        epilog=MONTECARLO_EPILOG,
    )
    scene_options(mc, "per-unit", "montecarlo")
    mc.add_argument("--n", type=count(1), default=64, help="manufactured units (default 64)")
    mc.add_argument("--band", type=band_um, default=None,
                    help="override the tolerance half-width of every feature, um, e.g. 10 (or 10um, 0.01mm) for +-10 um (default: the scene's "
                    "[tolerances])")
    mc.add_argument("--distribution", default=None, choices=("uniform", "normal"), help="override [tolerances] distribution")
    mc.add_argument("--requirement", type=positive, default=None,
                    help="RMS pointing requirement for the yield, arcsec (default: the scene's [tolerances] requirement)")
    mc.add_argument("--jitter", type=positive, default=None, metavar="J",
                    help="a stability requirement too: each unit's jitter (RMS pointing error above --jitter-cutoff Hz over the "
                    "window), arcsec, and its yield at <= J (what a design with --jitter is verified against; default: the "
                    "scene's [tolerances] jitter, which a proposal carries)")
    mc.add_argument("--jitter-cutoff", type=positive, default=JITTER_CUTOFF, metavar="HZ",
                    help="with --jitter: the stability band's start, Hz (default: the scene's [tolerances] jitter_cutoff, else 20)")
    mc.add_argument("--life", type=positive, default=None, metavar="YEARS",
                    help="each unit also over a mission of YEARS years, its clearances grown by wear (its outputs at the end "
                    "of life: *_eol; the requirement's yield there too): the scene's [life] years (its other keys kept: "
                    "lubricant, duty, points, flanks, spread; without one, sputtered MoS2 at its median rate, duty 1, 2 life "
                    "points). Each unit costs points + 1 runs. Needs a joint at planetary fidelity (default: the scene's "
                    "[life], if any)")
    mc.add_argument("--backend", default="auto", choices=("auto", "vmap", "processes"),
                    help="auto (default): chunks batched in this process and in worker processes beside it on idle cores "
                    "(bitwise the same units); vmap: this process alone; processes: a pool of one worker per core")
    mc.add_argument("--chunk", type=count(1), default=None,
                    help="units per chunk (default: the scene's, 10 with a full planetary stage, else 50)")
    mc.add_argument("--seed", type=int, default=0)
    mc.add_argument("--allow-clip", action="store_true",
                    help="accept bands reaching below zero (units drawn there are clipped to 0 um); refused otherwise")
    identify = identify_parser(sub, out_options, positive, non_negative, EPILOG)
    plan_test = add_plan_parser(sub, out_options, positive, non_negative, EPILOG)
    studies = sub.add_parser("studies", help="run the reference paper's studies, write a JSON table per study")
    studies.add_argument("names", nargs="*", help="studies to run (default: all)")
    studies.add_argument("--size", default="small", help="'small' (seconds) or 'full' (the paper's grids)")
    out_options(studies, "studies")
    studies.add_argument("--duration", type=positive, default=None,
                         help="simulated time per scene, s (default: the size's, full 3 s)")
    studies.add_argument("--settle", type=float, default=None,
                         help="metrics from this time on, s (default: the size's, full 2 s)")
    studies.add_argument("--resume", action="store_true",
                         help="keep the rows of STUDY-SIZE.json in --out whose scene and horizon match; run the rest")
    studies.add_argument("--quiet", action="store_true", help="no estimate or line per scene (errors are still printed)")
    args, unknown = parser.parse_known_args(argv)
    if unknown:  # refused by the command's own parser, with the option nearest a misspelt one
        _refuse_unknown(sub.choices[args.command], args.command, unknown)
    args.argv = argv
    # What can be wrong with the scene file before the simulator loads (unreadable, not TOML, an
    # unknown top-level table: tolerax.io.checker) is answered first, as the command would.
    if getattr(args, "scene", None) is not None:
        from ..io.checker import SceneFileError, precheck

        try:
            precheck(args.scene)
        except SceneFileError as err:
            print(f"tolerax {args.command}: {err}", file=sys.stderr)
            return 2
    # The simulator's modules only now (the commands import theirs when they run): a bad option
    # or --help answers before they load.
    from ..io.schema import SceneFileNote

    commands = {
        "demo": (demo, demo_command), "run": (run, run_command), "design": (design, design_command), "montecarlo": (mc, montecarlo_command),
        "tradeoff": (tradeoff, tradeoff_command),
        "studies": (parser, studies_command), "identify": (identify, identify_command),
        "plan-test": (plan_test, plan_test_command),
    }
    command_parser, command = commands[args.command]
    _solver_of(command_parser, args)
    from ..cache import enable_compilation_cache

    enable_compilation_cache()  # a later command on the same scene structure skips its compilation (TOLERAX_CACHE=off: not)
    try:
        with warnings.catch_warnings(), figures_to_files():
            warnings.simplefilter("always", SceneFileNote)
            shown = warnings.showwarning
            # A scene file's note (a valid but unlikely value) as a line of its own, not a Python warning.
            warnings.showwarning = lambda message, category, *rest, **kw: (
                print(f"tolerax {args.command}: note: {message}", file=sys.stderr) if issubclass(category, SceneFileNote)
                else shown(message, category, *rest, **kw))
            return command(command_parser, args)
    except KeyboardInterrupt:
        print(f"\ntolerax {args.command}: interrupted; " + RESUME.get(args.command, "nothing was written after the last 'wrote' line"),
              file=sys.stderr)
        return 130


if __name__ == "__main__":
    sys.exit(main())
