"""Speed against error of the full planetary dual antenna in developed rattle (issue 41's
must-show scene), and of the step-size controller on every fidelity, in one run.

    python benchmarks/rattle_window.py [--warmup 1.0] [--window 1.0] [--n-save 2001]
        [--jitter-cutoff 20] [--configs ...] [--rounds 1] [--scenes ...] [--results DIR]

A configuration is `SOLVER:CONTROLLER:RTOL`, or `SOLVER:CONTROLLER:RTOL:PROGRAM` for the
right-hand side as it was before a change: `whole`, the mechanism's equations of motion solved
with the whole mass matrix (`Mechanism(mass_solve="whole")`, as before the block solve) instead
of by blocks; `forward`, the planetary joints' deflection Jacobian by forward-mode autodiff
(`harness.with_forward_jacobian`) instead of in closed form, compiled with Eigen's products over
the CPU's threads (`harness.eigen_threads`) as before `tolerax.solve.CPU_COMPILER_OPTIONS`
turned that off; `original`, both (the program issue 41 started from, less what else changed
since); `@REV`, the whole of tolerax as it was at git revision REV (`harness.tolerax_at`: the
scene built by that version's `antenna`, solved by its `simulate`): the before and after of the
vector field's cost in one run. Writes `results/rattle_window.md` and the
work-precision picture `results/rattle_window.png` (wall seconds per simulated second against
the window's largest pointing difference from the reference and its RMS error, one line per
solver, controller and way of solving the equations of motion, across rtol).

**Work-precision** (`--configs`): `tolerax.antenna("dual", fidelity="planetary")` (free base,
100 um clearances and backlash, 0.98 deg/s on both joints) from a steady start over
`warmup + window` seconds through the public `tolerax.simulate`, one configuration per row
(solver, rtol, the controller's (pcoeff, icoeff); atol = rtol / 1000; solvers by their names in
`tolerax.solve.SOLVERS`, SRK53 among them; controllers `I` = (pcoeff, icoeff) (0, 1), `PI` = (0.3, 0.3),
`PI2` = (0.2, 0.2)). Each row's program is
compiled first by a 0.01 s call of the same structure (the duration is a value), then the whole
run is timed once per round (`--rounds`: every row once in each, the fastest kept, and the
slowest over the fastest as the machine's noise): **wall seconds per simulated second** over the run, accepted and rejected
steps, right-hand-side evaluations (stages per attempted step). Outputs over the window
`[warmup, warmup + window]` (the rattle developed, `fast_modes.md`): the pointing RMS and its
jitter (the RMS of the pointing error high-passed above `--jitter-cutoff` Hz: the project's
stability metric, `pointing_metrics`), each against the reference row (Tsit5, rtol 1e-10, the
I-controller) as a relative error, and the largest difference of the pointing error over the
window's saves (arcsec). The rattle is chaotic: two correct solves at different tolerances part
after a while, so the jitter's difference between two tight solves is part of what "within the
solver's error" means; the table has the I- and the PI-controller's Tsit5 at rtol 1e-6 and tighter
rows to read that against.

**Controllers across scenes** (`--scenes`): the same comparison of diffrax's I-controller (0, 1;
tolerax's default, `tolerax.solve.DEFAULT_PID`) against the PI controller (0.3, 0.3) at rtol 1e-6 on the other scenes a user
runs: the default joint on its bench from rest (0.4 s), the dual antenna with lumped joints
(2 s), the azimuth scan at planetary fidelity (the Monte Carlo scene, 0.6 s). Wall time,
attempted steps, and each one's difference from the reference setting on the same scene (the
largest over the saves, and of the RMS over the run's second half) of the pointing error (the
bench: the output angle error).
"""

import contextlib
import dataclasses
import time

import numpy as np

import tolerax as tx
from tolerax.mechanism.outputs import pointing_metrics
from tolerax.solve import SOLVERS

import harness

CONTROLLERS = {"I": (0.0, 1.0), "PI": (0.3, 0.3), "PI2": (0.2, 0.2)}
DEFAULT_CONFIGS = (
    "Tsit5:I:1e-6", "Tsit5:PI:1e-6", "Tsit5:I:1e-8", "Tsit5:PI:1e-8", "Tsit5:PI:1e-4", "Dopri5:PI:1e-6",
    "Bosh3:I:1e-4", "Bosh3:PI:1e-3", "Bosh3:PI:1e-4", "Bosh3:PI:1e-5",
)
REFERENCE = "Tsit5:I:1e-10"


@dataclasses.dataclass(frozen=True)
class Config:
    solver: str
    controller: str
    rtol: float
    program: str = "now"  # "now", "whole", "forward", "original" or "@REV" (the module docstring)

    @classmethod
    def parse(cls, text: str) -> "Config":
        solver, controller, rtol, *rest = text.split(":")
        at_rev = len(rest) == 1 and rest[0].startswith("@") and len(rest[0]) > 1
        if solver not in SOLVERS or controller not in CONTROLLERS or not (at_rev or rest in ([], ["whole"], ["forward"], ["original"])):
            raise ValueError(f"{text!r}: use SOLVER:CONTROLLER:RTOL[:whole|:forward|:original|:@REV] with SOLVER in {sorted(SOLVERS)}, "
                             f"CONTROLLER in {sorted(CONTROLLERS)}")
        return cls(solver, controller, float(rtol), *rest)

    @property
    def label(self) -> str:
        return f"{self.solver}:{self.controller}:{self.rtol:g}" + ("" if self.program == "now" else f":{self.program}")

    @property
    def package(self):
        """The tolerax this row runs: today's, or the one at `@REV` (`harness.tolerax_at`)."""
        return harness.tolerax_at(self.program[1:]) if self.program.startswith("@") else tx

    def scene(self, mech):
        """`mech` (a `tolerax.Mechanism`) with this row's right-hand side (for `@REV`, the same
        scene built by that version)."""
        if self.program.startswith("@"):
            return self.package.antenna("dual", fidelity="planetary")
        if self.program in ("whole", "original"):
            mech = harness.with_mass_solve(mech, "whole")
        return harness.with_forward_jacobian(mech) if self.program in ("forward", "original") else mech

    def compiled(self):
        """The context this row's runs are compiled in (Eigen's threads for `forward`, `original`)."""
        return harness.eigen_threads() if self.program in ("forward", "original") else contextlib.nullcontext()

    def options(self) -> dict:
        pcoeff, icoeff = CONTROLLERS[self.controller]
        return dict(solver=SOLVERS[self.solver](), rtol=self.rtol, atol=1e-3 * self.rtol, pcoeff=pcoeff, icoeff=icoeff)

    def evaluations_per_step(self) -> int:
        tableau = SOLVERS[self.solver]().tableau
        return len(tableau.b_sol) - (1 if tableau.fsal else 0)


def timed_run(scene, duration, n_save, start="steady", package=tx, **options):
    """(wall s of the timed run, result): compiled first by a 0.01 s run of the same program;
    `package`'s `simulate` (today's tolerax, or an earlier one's, `Config.package`)."""
    run = lambda seconds: package.simulate(scene, seconds, start=start, n_save=n_save, max_steps=20_000_000, **options)  # noqa: E731
    run(0.01)
    return harness.wall(run, duration)


def window_outputs(result, warmup, cutoff):
    ts = np.asarray(result.ts)
    window = ts >= warmup - 1e-12
    metrics = pointing_metrics(result, window, jitter_cutoff=cutoff)
    error = np.asarray(result.pointing_error)[window] / tx.ARCSEC
    return float(metrics["pointing_rms"]), float(metrics["pointing_jitter"]), error


def plot(curves, path):
    """Work-precision picture of the main table's rows (see the module docstring)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 2, figsize=(11, 4.2))
    for name, points in sorted(curves.items()):
        points = sorted(points)
        before = name.endswith((":whole", ":forward", ":original"))
        for ax, k in zip(axes, (2, 3)):
            ax.plot([p[1] for p in points], [p[k] for p in points], "o--" if before else "o-", mfc="none" if before else None,
                    label=name.replace(":whole", ", whole M (before the blocks)").replace(":forward", ", forward-mode Jacobian (before)")
                    .replace(":original", ", whole M and forward-mode Jacobian (the start)"))
            for p in points:
                ax.annotate(f"{p[0]:g}", (p[1], p[k]), fontsize=7, xytext=(3, 3), textcoords="offset points")
    for ax, what in zip(axes, ("largest pointing difference over the window (arcsec)", "pointing RMS rel. error over the window")):
        ax.set_xlabel("wall s per simulated s (one core)")
        ax.set_ylabel(what)
        ax.set_yscale("log")
        ax.grid(alpha=0.3)
    axes[0].legend(fontsize=8)
    fig.suptitle("Full planetary dual antenna in developed rattle: work against error (labels: rtol)", fontsize=10)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--warmup", type=float, default=1.0, help="seconds before the window (s)")
    parser.add_argument("--window", type=float, default=1.0, help="window length (s)")
    parser.add_argument("--n-save", type=int, default=2001, help="saves over the whole run")
    parser.add_argument("--jitter-cutoff", type=float, default=20.0, help="jitter high-pass (Hz)")
    parser.add_argument("--configs", nargs="+", default=list(DEFAULT_CONFIGS), help="SOLVER:CONTROLLER:RTOL rows")
    parser.add_argument("--reference", default=REFERENCE, help="the reference row, SOLVER:CONTROLLER:RTOL")
    parser.add_argument("--rounds", type=int, default=1,
                        help="timed runs of every configuration, in interleaved rounds, the fastest of each (a noisy machine: 3)")
    parser.add_argument("--scenes", nargs="*", default=["bench", "dual-lumped", "scan-planetary"],
                        help="scenes for the I/PI comparison (none: skip)")
    args = harness.parse_args(parser)
    configs = [Config.parse(c) for c in args.configs]
    reference = Config.parse(args.reference)
    duration = args.warmup + args.window
    mech = tx.antenna("dual", fidelity="planetary")
    start_all = time.perf_counter()

    print(f"reference {reference.label} ...", flush=True)
    ref_wall, ref = timed_run(mech, duration, args.n_save, **reference.options())
    ref_rms, ref_jitter, ref_error = window_outputs(ref, args.warmup, args.jitter_cutoff)
    rows = []
    curves = {}  # "SOLVER:CONTROLLER[:PROGRAM]" -> [(rtol, wall s per simulated s, max diff, RMS rel. error)]
    walls, results = {}, {}
    for round_ in range(args.rounds):  # every configuration once per round: a slow spell falls on all alike
        for config in configs:
            print(f"{config.label} (round {round_ + 1} of {args.rounds}) ...", flush=True)
            with config.compiled():
                wall_s, res = timed_run(config.scene(mech), duration, args.n_save, package=config.package, **config.options())
            walls.setdefault(config.label, []).append(wall_s)
            results.setdefault(config.label, res)  # the same steps every round: the first one's outputs
    for config in configs:
        wall_s, res = min(walls[config.label]), results[config.label]
        rms, jitter, error = window_outputs(res, args.warmup, args.jitter_cutoff)
        accepted, rejected = int(res.num_steps), int(res.num_rejected)
        rows.append([
            config.solver, config.controller, f"{config.rtol:g}", config.program, f"{wall_s:.1f}", f"{max(walls[config.label]) / wall_s:.2f}",
            f"{wall_s / duration:.2f}",
            f"{accepted} ({rejected})", str(config.evaluations_per_step() * (accepted + rejected)),
            f"{1e6 * wall_s / (accepted + rejected):.0f}", f"{rms:.2f}", f"{abs(rms / ref_rms - 1):.1e}",
            f"{jitter:.3f}", f"{abs(jitter / ref_jitter - 1):.1e}", f"{np.max(np.abs(error - ref_error)):.1e}",
        ])
        print(rows[-1], flush=True)
        curves.setdefault(f"{config.solver}:{config.controller}" + ("" if config.program == "now" else f":{config.program}"), []).append(
            (config.rtol, wall_s / duration, float(np.max(np.abs(error - ref_error))), abs(rms / ref_rms - 1)))

    scene_rows = []
    scenes = {
        "bench": (lambda: tx.TestBench(), 0.4, "rest", 401),
        "dual-lumped": (lambda: tx.antenna("dual", fidelity="lumped"), 2.0, "steady", 2001),
        "scan-planetary": (lambda: tx.scan("azimuth", fidelity=("planetary", "ideal")), 0.6, "steady", 601),
    }
    for name in args.scenes:
        make, seconds, start, n_save = scenes[name]
        scene = make()
        cells = []
        for config in (Config("Tsit5", "I", 1e-6), Config("Tsit5", "PI", 1e-6), reference):
            print(f"{name} {config.label} ...", flush=True)
            wall_s, res = timed_run(scene, seconds, n_save, start=start, **config.options())
            out = (np.asarray(res.output_angle_error) if name == "bench" else np.asarray(res.pointing_error)) / tx.ARCSEC
            cells.append((wall_s, int(res.num_steps), int(res.num_rejected), out))
        (w_i, a_i, r_i, o_i), (w_p, a_p, r_p, o_p), (_, _, _, o_ref) = cells
        late = slice(len(o_ref) // 2, None)  # the second half of the run: RMS there
        rms = lambda o: np.sqrt(np.mean(o[late] ** 2))  # noqa: E731
        scene_rows.append([
            name, "output angle error" if name == "bench" else "pointing error", f"{seconds:g}", f"{w_i:.2f}", f"{a_i} ({r_i})",
            f"{w_p:.2f}", f"{a_p} ({r_p})", f"{(a_p + r_p) / (a_i + r_i):.3f}", f"{w_p / w_i:.2f}",
            f"{np.max(np.abs(o_i - o_ref)):.1e} / {abs(rms(o_i) / rms(o_ref) - 1):.1e}",
            f"{np.max(np.abs(o_p - o_ref)):.1e} / {abs(rms(o_p) / rms(o_ref) - 1):.1e}",
        ])
        print(scene_rows[-1], flush=True)

    plot(curves, harness.results_dir() / "rattle_window.png")
    harness.write_table(
        "rattle_window",
        "Full planetary dual antenna in developed rattle: speed against error, and the step-size controller across scenes",
        harness.command(args),
        ["solver", "controller", "rtol", "right-hand side (now, or as before: whole M, forward Jacobian, original: both; @REV: tolerax at that git revision)", "wall (s)",
         "slowest / fastest round", "wall s per simulated s", "accepted (rejected) steps",
         "RHS evaluations", "µs per attempted step", "pointing RMS over the window (arcsec)", "RMS rel. error",
         "jitter (arcsec)", "jitter rel. error", "pointing max diff (arcsec)"],
        rows,
        about=(f"`tolerax.antenna('dual', fidelity='planetary')`, steady start, {duration:g} s ({args.n_save} saves); the window "
               f"is {args.warmup:g}-{duration:g} s; jitter above {args.jitter_cutoff:g} Hz. Controller I = (pcoeff, icoeff) "
               f"(0, 1), diffrax's and tolerax's default; PI = (0.3, 0.3); PI2 = (0.2, 0.2); atol = rtol / 1000. Reference {reference.label}: "
               f"{ref_wall:.1f} s, {int(ref.num_steps)} accepted ({int(ref.num_rejected)} rejected) steps, pointing RMS "
               f"{ref_rms:.3f} arcsec and jitter {ref_jitter:.4f} arcsec over the window. Each row compiled by a 0.01 s run first, "
               f"then timed once in each of {args.rounds} interleaved rounds, the fastest kept. Total wall {time.perf_counter() - start_all:.0f} s."),
        sections=[harness.Section(
            "The I- and the PI controller on the other scenes (Tsit5, rtol 1e-6, atol 1e-9)",
            ["scene", "output", "simulated s", "I: wall (s)", "I: accepted (rejected)", "PI: wall (s)", "PI: accepted (rejected)",
             "PI / I attempted steps", "PI / I wall", "I against the reference: max diff (arcsec) / RMS rel. error",
             "PI against the reference: max diff (arcsec) / RMS rel. error"],
            scene_rows,
            notes=["Reference: the main table's reference setting on each scene; RMS over the run's second half. Scenes: `bench` = `tolerax.TestBench()` from rest; `dual-lumped` = `tolerax.antenna('dual', "
                   "fidelity='lumped')`, steady start; `scan-planetary` = `tolerax.scan('azimuth', fidelity=('planetary', "
                   "'ideal'))`, steady start (the Monte Carlo throughput scene)."],
        )] if scene_rows else [],
    )


if __name__ == "__main__":
    main()
