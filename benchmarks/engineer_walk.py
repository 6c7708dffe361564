"""The engineer's walk of issue 61, repeated and written down: a user's own drive from the docs,
designed at 99 %, the verify command the report prints, Monte Carlo, and the traps the issue
found (folders, a read-only folder, errors at their cause, an infeasible requirement, fast
arguments), each command with its exit code, wall time and what it printed.

Run from a fresh clone after `pip install .` (the installed `tolerax` on PATH):

    python benchmarks/engineer_walk.py --work /tmp/walk --out benchmarks/results/engineer_walk.md

Every number in the transcript is what the commands printed in that run; nothing is edited in.
"""

import argparse
import hashlib
import os
import pathlib
import re
import shlex
import subprocess
import sys
import time

DRIVE = pathlib.Path(__file__).resolve().parent / "scenes" / "newcomer_drive.toml"


def own_drive(work: pathlib.Path) -> pathlib.Path:
    """The newcomer's drive with every feature designed (no given carrier, no price table): a plain
    `[tolerances]` with its requirement, as a user writes it from docs/scene_files.md."""
    text = DRIVE.read_text()
    text = text.split("[tolerances]")[0] + '[tolerances]\nband = 10e-6\nrequirement = 2800.0   # arcsec\n'
    path = work / "my_drive.toml"
    path.write_text(text)
    return path


def checksums(folder: pathlib.Path) -> dict:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


class Walk:
    def __init__(self, work: pathlib.Path):
        self.work, self.lines = work, []

    def say(self, *text):
        self.lines += [*text, ""]

    def run(self, argv, keep=None, tail=12):
        """Run `tolerax ...` in the work folder; record the command, exit code, wall time and the
        printed lines matching `keep` (a regex), else the last `tail` lines."""
        start = time.perf_counter()
        done = subprocess.run(["tolerax", *argv], cwd=self.work, capture_output=True, text=True)
        wall = time.perf_counter() - start
        out = (done.stdout + done.stderr).splitlines()
        shown = [line for line in out if re.search(keep, line)] if keep else out[-tail:]
        self.lines += [f"```\n$ tolerax {shlex.join(argv)}", *[line[:400] for line in shown],
                       f"[exit {done.returncode}, {wall:.1f} s]\n```", ""]
        print(f"tolerax {shlex.join(argv)}: exit {done.returncode}, {wall:.1f} s", flush=True)
        return done, out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--work", type=pathlib.Path, required=True, help="an empty folder to work in")
    parser.add_argument("--out", type=pathlib.Path, required=True, help="the transcript (Markdown)")
    args = parser.parse_args(argv)
    work = args.work.resolve()
    work.mkdir(parents=True, exist_ok=False)
    walk = Walk(work)
    commit = subprocess.run(["git", "rev-parse", "--short", "HEAD"], capture_output=True, text=True,
                            cwd=pathlib.Path(__file__).parent).stdout.strip()
    walk.say("# The engineer's walk (issue 61), repeated", "",
             f"Commit {commit}, `python benchmarks/engineer_walk.py --work {args.work} --out {args.out}` after "
             "`pip install .` in a fresh virtual environment on a fresh clone; "
             f"{os.cpu_count()} CPU cores, load average before {os.getloadavg()[0]:.2f}. Every line below is what the "
             "command printed (trimmed to the lines that matter), with its exit code and wall time.")
    drive = own_drive(work)
    walk.say("## 0. The demo", "")
    walk.run(["demo"], keep=r"RMS pointing error|gradients over|Put on the drawing|^Continuous optimum")
    walk.say("## 1. Own drive → one proposal, its own check, the verify command it prints", "",
             f"`my_drive.toml`: `benchmarks/scenes/newcomer_drive.toml` (4 planets 24/24/72, written from "
             "docs/scene_files.md) with every feature designed and a plain `[tolerances]` (band 10 µm, requirement 2800 arcsec).")
    done, out = walk.run(["design", "my_drive.toml", "--yield", "0.99", "--out", "design"],
                         keep=r"^Put on the drawing|Monte Carlo check|verify it with|\| azimuth\.")
    verify = next((m.group(1) for line in out if (m := re.search(r"`(tolerax montecarlo [^`]+)`", line))), None)
    if verify is None:
        walk.say("The report printed no verify command.")
    else:
        walk.say("The verify command the report printed, run as printed:")
        walk.run(shlex.split(verify)[1:], keep=r"yield|pointing_rms:")
    walk.say("## 2. Fits for every clearance, backlash as tooth-thickness allowances", "",
             "The design's table above carries each journal's ISO 286 fit (or why none) and each backlash's "
             "allowances; `design/proposal.toml` carries the same callouts:")
    proposal = work / "design" / "proposal.toml"
    if proposal.exists():
        walk.say("```", *[line for line in proposal.read_text().splitlines() if "µm" in line][:8], "```")
    walk.say("## 3. Folders as a contract", "")
    before = checksums(work / "design")
    walk.run(["run", "my_drive.toml", "--out", "design"], tail=3)
    walk.run(["montecarlo", "my_drive.toml", "--n", "4", "--out", "design"], tail=3)
    walk.say(f"Every file of `design/` unchanged after both: {checksums(work / 'design') == before}.")
    walk.run(["design", "my_drive.toml", "--yield", "0.99", "--out", "design"], tail=3)
    walk.say("## 4. A folder that cannot be written", "")
    walk.run(["run", "my_drive.toml", "--out", "/sys/tolerax-walk"], tail=3)
    walk.say("## 5. Errors at their cause; notes before the work", "")
    bad = work / "bad_backlash.toml"
    bad.write_text(drive.read_text().replace("backlash = 70e-6", "backlash = 80"))
    walk.run(["run", "bad_backlash.toml", "--out", "bad"], tail=2)
    walk.run(["design", "my_drive.toml", "--yield", "0.99", "--life", "10", "--out", "life"], tail=2)
    wide = work / "wide_scan.toml"
    text = drive.read_text().replace("profile_times = [0.0, 0.12, 0.24, 0.36, 0.48]\n", "")
    wide.write_text(text.replace("profile_angles = [0.0, 0.015, 0.0, -0.015, 0.0]   # rad: +-0.86 deg",
                                 "amplitude = 1.0   # meant as 1 degree\nperiod = 0.5"))
    walk.run(["run", "wide_scan.toml", "--duration", "0.05", "--settle", "0", "--out", "wide"], keep=r"note|RMS pointing")
    walk.say("## 6. An infeasible requirement", "")
    walk.run(["design", "my_drive.toml", "--yield", "0.99", "--requirement", "1000", "--out", "infeasible"],
             keep=r"[Ii]nfeasible|meets|best_reached|proposal")
    walk.say("## 7. Fast arguments, exit codes in --help", "")
    walk.run(["design", "--bogus"], tail=1)
    (work / "not_toml.toml").write_text('title = "x"\n[scene\n')
    walk.run(["run", "not_toml.toml"], tail=1)
    walk.run(["design", "--help"], keep=r"[Ee]xit|4 the answer")
    args.out.parent.mkdir(parents=True, exist_ok=True)
    args.out.write_text("\n".join(walk.lines).rstrip() + "\n")
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
