"""What a long design is doing, said as it goes: one line per phase (what it computes and how
many simulated units), with the time since the design started, on stderr. `propose_design(...,
progress=True)` (the command line's default) prints them beside the solver's progress bars;
silent otherwise."""

import sys
import time


class Phases:
    """`phases(text)`: print `text` with the minutes and seconds since this object was made,
    where `on` is true; hand the line to `on` where it is a callable instead (a notebook's or a
    test's list); nothing otherwise. `elapsed()`: the seconds since it was made."""

    def __init__(self, on, who: str = "propose_design"):
        self.sink = on if callable(on) else ((lambda line: print(line, file=sys.stderr, flush=True)) if on else None)
        self.on, self.who, self.start = self.sink is not None, who, time.perf_counter()

    def elapsed(self) -> float:
        return time.perf_counter() - self.start

    def __call__(self, text: str) -> None:
        if self.on:
            elapsed = int(self.elapsed())
            self.sink(f"{self.who} [{elapsed // 60:d}:{elapsed % 60:02d}] {text}")
