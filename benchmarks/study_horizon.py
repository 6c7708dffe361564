"""The paper's studies at two horizons, scene by scene: what a longer run changes in each metric
the claims read.

    python benchmarks/study_horizon.py --long notebooks/results/horizon-20s --short notebooks/results

reads every `STUDY-full.json` in `--long` (written by `tolerax studies STUDY --size full
--duration 20 --settle 10 --out DIR`) and the same study's rows in `--short` (the committed 3 s
studies, metrics over 2-3 s), pairs the scenes by their labels, and writes
`benchmarks/results/study_horizon.md` (`--results DIR`: in DIR): per scene, the metrics over each run's window, the output
bearing forces of both joints, the largest tracking-speed-error peak over X/Y/Z, the torsional
and radial vibration amplitudes and the pointing error, plus steps and wall time. Nothing is run.
"""

import json
import pathlib

from tolerax.studies import SIZES

import harness

LABELS = ("mode", "rate", "case", "carrier", "planet", "backlash", "fidelity")
METRICS = (
    ("driven output force peak (N)", lambda r: r["force_peak_N"], ".3g"),
    ("other output force peak (N)", lambda r: r["force_other_peak_N"], ".3g"),
    ("speed error peak, max X/Y/Z (urad/s)", lambda r: max(r[f"speed_error_peak_{a}_urad_s"] for a in "xyz"), ".3g"),
    ("torsional vibration (urad)", lambda r: r["torsional_vibration_urad"], ".3g"),
    ("radial vibration (um)", lambda r: r["radial_vibration_um"], ".3g"),
    ("pointing RMS (arcsec)", lambda r: r["pointing_rms_arcsec"], ".1f"),
)


def _key(row):
    return tuple((k, row[k]) for k in LABELS if k in row)


def _window(row):
    """The row's metrics window; rows without a horizon have the full size's own."""
    full = SIZES["full"]
    return f"{row.get('settle_s', full.settle):g}-{row.get('duration_s', full.duration):g} s"


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--long", type=pathlib.Path, required=True, help="folder of the long-horizon JSON tables")
    parser.add_argument("--short", type=pathlib.Path, required=True, help="folder of the committed 3 s tables")
    args = harness.parse_args(parser)
    sections = []
    for path in sorted(args.long.glob("*-full.json")):
        study = path.name[: -len("-full.json")]
        long_rows = json.loads(path.read_text())
        short = {_key(r): r for r in json.loads((args.short / path.name).read_text())}
        rows = []
        for r in long_rows:
            s = short.get(_key(r))
            if s is None:
                continue
            label = ", ".join(f"{k} {v}" for k, v in _key(r))
            for name, get, fmt in METRICS:
                rows.append([label, name, format(get(s), fmt), format(get(r), fmt)])
            rows.append([label, "steps (wall s)", f"{s['steps']} ({s['wall_s']:.0f})", f"{r['steps']} ({r['wall_s']:.0f})"])
        if not rows:
            continue
        windows = (_window(next(iter(short.values()))), _window(long_rows[0]))
        sections.append(harness.Section(
            f"{study}: {len(long_rows)} scenes at the long horizon",
            ["scene", "metric", f"3 s run, metrics over {windows[0]}", f"long run, metrics over {windows[1]}"],
            rows,
        ))
    if not sections:
        raise SystemExit(f"no study of {args.long} has a row matching {args.short}")
    first = sections[0]
    harness.write_table(
        "study_horizon",
        "The paper's studies at 3 s and at a long horizon, scene by scene",
        harness.command(args),
        first.columns,
        first.rows,
        about=("Both runs start in steady rolling (`start=\"steady\"`, as every study) with the same scenes "
               "and solver (Tsit5, rtol 1e-6); each row is one metric of one scene over each run's window."),
        intro=["Wall times come from different sittings (the 3 s studies ran two processes at a time on the "
               "right-hand side of their day; the long runs one process per core, pinned, beside each other): "
               "compare steps, not walls, across the two columns.", f"## {first.heading}"],
        sections=sections[1:],
    )


if __name__ == "__main__":
    main()
