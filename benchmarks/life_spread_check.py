"""The two designs of `design_life.md` verified again with what the life model gained after them
(issue 43): the tooth flanks' wear (`ArchardWear(flanks=True)`, the backlash opening) and the
wear rate drawn per unit from the lubricant's band (`MissionLife(spread=...)`).

    python benchmarks/life_spread_check.py [--units 50] [--results DIR]

Reads each design's zones and the requirement from `results/design_life.md` (made with the
journals' wear only, every unit at the median rate). Verifies both on the same `--units` fresh
units (zones drawn with `tolerax.sample`, key 2026: the units `design_life.py`'s verification
drew, up to the table's 0.1 um rounding of the zones), each simulated three ways at both ends of life: journals only at the median rate (the
committed verification, rerun), journals and flanks at the median rate, and journals and flanks
with each unit's rate drawn log-uniformly over the lubricant's low-high band (key 7: one factor
per unit, `spread_of_lubricant`). The same scene and run settings as `design_life.py` (azimuth
scan, planetary, window 0.3-0.6 s, 500 saves/s, 10 years at duty 1 of sputtered MoS2, 2 life
points, smoothing width 1e-7 m). Yields with 95 % Wilson intervals.
"""

import pathlib
import re
import time

import jax
import numpy as np

import tolerax as tx
from tolerax.design.life import MissionLife, spread_of_lubricant
from tolerax.physics import wear as W
from tolerax.uncertainty.montecarlo import evaluate
from tolerax.uncertainty.results import wilson_interval

import _design
import harness

LUBRICANT = "MoS2 sputtered film, vacuum"


def designs_of(path):
    """`(R, {label: (nominal (m), band (m))})` from design_life.md's table."""
    text = pathlib.Path(path).read_text()
    (limit,) = set(re.findall(r"RMS <= ([\d.]+)\)", text))
    rows = [line.strip().strip("|").split("|") for line in text.splitlines() if line.startswith("| beginning")]
    out = {}
    for cells in rows:
        zones = re.findall(r"([\d.]+)\+-([\d.]+)", cells[8])
        out[cells[0].strip()] = (np.array([float(m) for m, _ in zones]) * 1e-6, np.array([float(b) for _, b in zones]) * 1e-6)
    return float(limit), out


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--units", type=int, default=50)
    parser.add_argument("--chunk", type=int, default=10)
    args = harness.parse_args(parser)
    start = time.perf_counter()
    limit, designs = designs_of(pathlib.Path(__file__).parent / "results" / "design_life.md")
    scene = tx.scan("azimuth", fidelity=("planetary", "ideal"))
    names = tx.design_names(scene)
    spread = spread_of_lubricant(LUBRICANT)
    models = {
        "journals, median rate": MissionLife.from_years(10.0, 1.0, W.ArchardWear.from_lubricant(LUBRICANT, flanks=False), points=2),
        "journals and flanks, median rate": MissionLife.from_years(10.0, 1.0, W.ArchardWear.from_lubricant(LUBRICANT), points=2),
        "journals and flanks, rate drawn per unit": MissionLife.from_years(10.0, 1.0, W.ArchardWear.from_lubricant(LUBRICANT), points=2,
                                                                         spread=spread),
    }
    low, high = np.log(spread)
    factors = np.asarray(jax.random.uniform(jax.random.key(7), (args.units,), minval=low, maxval=high))
    rows = []
    for label, (nominal, band) in designs.items():
        units = np.asarray(tx.sample(tx.Tolerances(names, nominal, band), jax.random.key(2026), args.units))
        for model_label, life in models.items():
            pointing = _design.at_width(tx.PointingObjective(scene, duration=0.6, settle=0.3, start="steady", n_save=301, life=life),
                                        1e-7)
            values = np.concatenate([units, factors[:, None]], axis=1) if life.spread is not None else units
            wall, out = harness.wall(lambda: {k: np.asarray(v) for k, v in
                                              _chunks(pointing, values, args.chunk).items()})
            ok = out["success"]
            cells = []
            for name in ("pointing_rms", "pointing_rms_eol"):
                met = int(np.sum(ok & (out[name] <= limit)))
                lo, hi = wilson_interval(met, int(ok.sum()))
                cells += [f"{met / max(int(ok.sum()), 1):.3f} [{float(lo):.3f}, {float(hi):.3f}]",
                          f"{np.quantile(out[name][ok], 0.9):.1f}"]
            rows.append((label, model_label, f"{int(ok.sum())} of {args.units}", *cells, f"{wall:.0f}"))
            print(rows[-1], f"({time.perf_counter() - start:.0f} s so far)", flush=True)
    harness.write_table(
        "life_spread_check", "The end-of-life designs verified again with flank wear and the wear rate drawn per unit",
        harness.command(args),
        ["design (design_life.md)", "life model", "units used", f"yield as built [95 % Wilson] (RMS <= {limit:.1f})",
         "90% quantile as built", f"yield at end of life [95 % Wilson] (RMS <= {limit:.1f})", "90% quantile at end of life",
         "wall (s)"],
        rows,
        about=(f"Azimuth scan at planetary fidelity, window 0.3-0.6 s, 10 years at duty 1 of `{LUBRICANT}`, 2 life points, "
               f"smoothing width 1e-7 m; each design's {args.units} units (key 2026) simulated with each life model; the drawn rates "
               f"log-uniform over x{spread[0]:.3g} to x{spread[1]:.3g} the median (key 7, the same factors for both designs). Total wall "
               f"{time.perf_counter() - start:.0f} s, compilation included."),
    )


def _chunks(pointing, values, chunk):
    """`evaluate` over `values` in chunks of `chunk` units (one compile)."""
    parts = [evaluate(pointing, values[k : k + chunk], size=chunk) for k in range(0, len(values), chunk)]
    return {name: np.concatenate([p[name] for p in parts]) for name in parts[0]}


if __name__ == "__main__":
    main()
