"""What a long design is doing, said as it goes: one line per phase (what it computes and how
many simulated units), with the time since the design started, on stderr. `propose_design(...,
progress=True)` (the command line's default) prints them beside the solver's progress bars;
silent otherwise."""

import sys
import time

from ..eta import human_seconds


class Phases:
    """`phases(text)`: print `text` with the minutes and seconds since this object was made,
    where `on` is true; hand the line to `on` where it is a callable instead (a notebook's or a
    test's list); nothing otherwise. `elapsed()`: the seconds since it was made; `took(kind,
    seconds)` keeps a phase's wall time and `at_pace(kind)` says the next one's at that pace."""

    def __init__(self, on, who: str = "propose_design"):
        self.sink = on if callable(on) else ((lambda line: print(line, file=sys.stderr, flush=True)) if on else None)
        self.on, self.who, self.start = self.sink is not None, who, time.perf_counter()
        self.paces = {}  # kind of phase -> the wall time (s) of the last one

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def took(self, kind: str, seconds: float) -> None:
        self.paces[kind] = float(seconds)

    def at_pace(self, kind: str) -> str:
        """`", about 1.5 min at the last one's pace"` where a phase of `kind` has run, else `""`."""
        last = self.paces.get(kind)
        return "" if last is None else f", about {human_seconds(last)} at the last one's pace"

    def __call__(self, text: str) -> None:
        if self.on:
            elapsed = int(self.elapsed())
            self.sink(f"{self.who} [{elapsed // 60:d}:{elapsed % 60:02d}] {text}")
