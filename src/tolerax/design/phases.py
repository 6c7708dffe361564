"""What a long design is doing, said as it goes: one line per phase (what it computes and how
many simulated units), with the time since the design started, on stderr. `propose_design(...,
progress=True)` (the command line's default) prints them beside the solver's progress bars;
silent otherwise."""

import sys
import time


class Phases:
    """`phases(text)`: print `text` with the minutes and seconds since this object was made,
    where `on`; nothing otherwise."""

    def __init__(self, on: bool, who: str = "propose_design"):
        self.on, self.who, self.start = bool(on), who, time.perf_counter()

    def __call__(self, text: str) -> None:
        if self.on:
            elapsed = int(time.perf_counter() - self.start)
            print(f"{self.who} [{elapsed // 60:d}:{elapsed % 60:02d}] {text}", file=sys.stderr, flush=True)
