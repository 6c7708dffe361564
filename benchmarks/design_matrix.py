"""Does the tolerance design converge on mechanisms nobody tuned it on? A matrix of generated
mechanisms, each designed for a 99 % yield with `tolerax.propose_design` and checked by Monte
Carlo.

    python benchmarks/design_matrix.py [--seed 2026] [--fraction 0.8] [--check-units 200] [--quick] [--only K] [--results DIR]

The mechanisms are generated, not hand-picked: scene-file data (docs/scene_files.md) built from
a seeded NumPy generator (`numpy.random.default_rng([seed, k])` for mechanism k, so each one is
the same whatever else runs) and validated by `tolerax.SceneFile.from_data` exactly as a user's
file is. What varies: the builder (`scan`, or `antenna` with `drive = "scan"`/`"profile"`), the
driven axes (azimuth, pitch or both), the base (fixed or free), each lumped joint's gear data
(valid 2K-H stages: ring = sun + 2 planet, (sun + ring) divisible by the planet count, planets
that clear each other; module 0.6-1.5 mm; journal radii scaled with the gears), its nominal
clearances and backlash (50-150 um), the reflector's mass and inertia, the scan amplitude
(0.25-1.5 deg) and period (0.5-1.2 s), a tabulated motion profile instead of the sine on some
(`profile_times`/`profile_angles`, a back-and-forth slew), the bearings' contact law on some
(`[scene.*_stage.contact_law]`), one feature given rather than designed on some (`[tolerances]
fixed`), a shop's price table on some (`[tolerances.cost]`, `GradeTable`). Joints are lumped
(the non-driven joint ideal or lumped); the last mechanism is one tiny `planetary-scaled` case at
the fast setting (mass scaling 1000, rtol 1e-3, atol 1e-6, PI 0.3/0.3).

Per mechanism: a short horizon from a steady start that holds one reversal (scan: 0.4 T with the
window after 0.15 T; profile: to 0.15 s past the first reversal), 61 saves. The baseline is the
scene's own design (its nominals +- 10 um); its linearised 99 % quantile (`design_problem`'s
objective at the 0.1 um width, what `propose_design` reports as `report.baseline[3]`) sets the
requirement R = `--fraction` x it. Then `propose_design(ToleranceProblem(pointing, R,
Yield(0.99), Zones(...), cost), Sequential(), check=Check(--check-units))` (widths 1 um then
0.1 um, every requirement on its default constraint model, the scene file's `[tolerances]`
turned into zones and a cost as `tolerax design` does). Recorded: status and diagnosis, cost, gradients,
wall time of the design (compilation included; the baseline evaluation before it is timed apart),
the last Monte Carlo check's yield and 95 % Wilson interval.

Infeasible cases (`X..`): a mechanism of the matrix again, at a requirement below what its
tightest design reaches: min(0.2 x baseline, 0.5 x the tightest design's linearised quantile),
the tightest design being every band at its smallest and every lower limit at its functional
minimum. They should come back `"infeasible"`.

The JSON (`results/design_matrix.json`) is written after every mechanism; a rerun skips the
mechanisms already in it (delete the file, or a row, to redo them). `--quick` (a smoke run:
`M01` and its infeasible twin `X01`, 20 check units) writes `design_matrix_quick.*`.
`--stop-after S`: start no new mechanism after S seconds (the rest is left for a rerun). Each
mechanism is designed in a fresh process (`--in-process`: all in this one): one process's
compiled code for a dozen mechanisms exceeds the kernel's limit on memory maps
(`vm.max_map_count`, 65530 here), and LLVM then fails with "Cannot allocate memory".
"""

import json
import math
import os
import subprocess
import sys
import time
import traceback

import jax
import numpy as np

import tolerax as tx
from tolerax.design.outcome import tightest
from tolerax.design.propose import design_problem

import harness

WIDTH = 1e-7  # propose_design's last (judging) smoothing width
DEG = math.pi / 180


# ---------------------------------------------------------------------------------------------
# The generator


def _stage(rng, law=None):
    """`[scene.*_stage]` data: a valid 2K-H stage with random gear data and clearances."""
    while True:
        n = int(rng.choice([3, 4, 5]))
        zs, zp = int(rng.integers(14, 41)), int(rng.integers(14, 41))
        zr = zs + 2 * zp
        centre = (zs + zp) / 2  # in modules
        clear = 2 * centre * math.sin(math.pi / n) > zp + 2 + 0.5  # neighbouring planets' tips do not touch
        if (zs + zr) % n == 0 and clear:
            break
    module = float(np.round(rng.uniform(0.6e-3, 1.5e-3), 6))
    um = lambda lo, hi: float(np.round(rng.uniform(lo, hi), 1)) * 1e-6
    stage = dict(
        module=module, sun_teeth=zs, planet_teeth=zp, ring_teeth=zr, n_planets=n,
        # journals inside the gears' roots: scaled with the gear, never above tolerax's defaults
        sun_journal_radius=float(np.round(min(5e-3, 0.3 * module * zs), 6)),
        planet_journal_radius=float(np.round(min(4e-3, 0.3 * module * zp), 6)),
        carrier_clearance=um(50, 150), planet_clearance=um(50, 150), backlash=um(50, 150),
    )
    if law is not None:
        stage["contact_law"] = law
    return stage


def _law(rng, name):
    if name == "AdamsImpact":
        return dict(law="AdamsImpact", stiffness=float(np.round(10 ** rng.uniform(6.5, 7.5), -3)), exponent=1.5,
                    damping=float(np.round(rng.uniform(50, 200))), damping_depth=1e-5)
    return dict(law=name, restitution=float(np.round(rng.uniform(0.5, 0.95), 2)))


# Per mechanism: builder, driven axes, (azimuth, pitch) fidelity, base, motion, contact law,
# a fixed feature, a cost table. Values (gear data, clearances, masses, motion) are random.
PLAN = [
    dict(kind="scan", mode="azimuth", fidelity=("lumped", "ideal"), base="fixed", motion="scan"),
    dict(kind="scan", mode="pitch", fidelity=("ideal", "lumped"), base="fixed", motion="scan", law="HertzLN"),
    dict(kind="scan", mode="dual", fidelity=("lumped", "lumped"), base="fixed", motion="scan"),
    dict(kind="scan", mode="azimuth", fidelity=("lumped", "ideal"), base="fixed", motion="profile", fixed=True, cost=True),
    dict(kind="scan", mode="azimuth", fidelity=("lumped", "ideal"), base="free", motion="scan", law="Flores"),
    dict(kind="antenna", mode="azimuth", fidelity=("lumped", "ideal"), base="free", motion="scan"),
    dict(kind="scan", mode="dual", fidelity=("lumped", "lumped"), base="fixed", motion="profile", cost=True),
    dict(kind="scan", mode="pitch", fidelity=("ideal", "lumped"), base="free", motion="scan", fixed=True),
    dict(kind="antenna", mode="pitch", fidelity=("ideal", "lumped"), base="fixed", motion="profile", law="BaiZhao"),
    dict(kind="scan", mode="azimuth", fidelity=("lumped", "lumped"), base="fixed", motion="scan", cost=True),
    dict(kind="scan", mode="dual", fidelity=("lumped", "lumped"), base="free", motion="scan", law="AdamsImpact", fixed=True, cost=True),
    dict(kind="scan", mode="azimuth", fidelity=("planetary-scaled", "ideal"), base="fixed", motion="scan"),
    dict(kind="antenna", mode="dual", fidelity=("lumped", "lumped"), base="free", motion="scan", law="HertzLN"),
    dict(kind="scan", mode="pitch", fidelity=("ideal", "lumped"), base="fixed", motion="profile", fixed=True, cost=True),
    dict(kind="scan", mode="azimuth", fidelity=("lumped", "ideal"), base="free", motion="scan", law="AdamsImpact", fixed=True),
]
INFEASIBLE = {"X01": "M01", "X02": "M03", "X03": "M05"}  # an infeasible twin of these mechanisms
# The same mechanism again at a requirement binding by construction (the first pass's
# 0.8 x baseline was infeasible for M09 and not binding for M03): midway between the linearised
# quantiles of the tightest design and of the cheapest (every band at its widest, every lower
# limit at its functional minimum).
MIDWAY = {"R03": "M03", "R09": "M09", "R12": "M12"}
BASE = {**INFEASIBLE, **MIDWAY}
LAST = ("M12",)  # the planetary-scaled case: run after the rest (its compilation once took the process down)
COST_TABLES = ([5, 6, 7, 8, 9], [4.0, 2.2, 1.0, 0.8, 0.7]), ([5, 6, 7, 8, 9, 10], [6.0, 3.0, 1.0, 0.6, 0.5, 0.45])


def mechanism(k: int, seed: int) -> dict:
    """Mechanism `k` (1-based): `{"key", "plan", "data" (scene-file data), "text" (one line)}`."""
    plan = PLAN[k - 1]
    rng = np.random.default_rng([seed, k])
    driven = ("azimuth", "pitch") if plan["mode"] == "dual" else (plan["mode"],)
    scene = dict(kind=plan["kind"], mode=plan["mode"], fidelity=list(plan["fidelity"]), base=plan["base"])
    modelled = [j for j, f in zip(("azimuth", "pitch"), plan["fidelity"]) if f != "ideal"]
    for joint in modelled:
        scene[f"{joint}_stage"] = _stage(rng, _law(rng, plan["law"]) if plan.get("law") and joint in driven else None)
    mass = float(np.round(rng.uniform(4.0, 20.0), 2))
    shape = rng.uniform(0.7, 1.4, size=3)
    inertia = [float(np.round(v, 4)) for v in np.array([0.68297, 1.05956, 0.68297]) * mass / 8.005 * shape]
    scene["inertias"] = dict(reflector_mass=mass, reflector_inertia=inertia)
    amplitude = float(np.round(rng.uniform(0.25, 1.5), 2)) * DEG
    if plan["motion"] == "scan":
        period = float(np.round(rng.uniform(0.5, 1.2), 2))
        if plan["kind"] == "scan":
            scene.update(amplitude=amplitude, period=period)
        else:
            scene.update(drive="scan", scan_amplitude=amplitude, scan_period=period)
        duration, settle = round(0.4 * period, 3), round(0.15 * period, 3)
        motion = f"scan +-{amplitude / DEG:.2f} deg, T {period:g} s"
    else:  # a back-and-forth slew: 0 -> A -> 0 -> -A at equal intervals (PCHIP: reversals at the extremes)
        t1 = float(np.round(rng.uniform(0.12, 0.2), 3))
        scene.update(profile_times=[0.0, t1, 2 * t1, 3 * t1], profile_angles=[0.0, amplitude, 0.0, -amplitude])
        if plan["kind"] == "antenna":
            scene["drive"] = "profile"
        duration, settle = round(t1 + 0.15, 3), round(max(t1 - 0.08, 0.0), 3)
        motion = f"profile 0/+{amplitude / DEG:.2f}/0/-{amplitude / DEG:.2f} deg every {t1:g} s"
    if "planetary-scaled" in plan["fidelity"]:
        scene["mass_scaling"] = 1000.0
    run = dict(duration=duration, settle=settle, start="steady", n_save=61)
    if "planetary-scaled" in plan["fidelity"]:
        run.update(rtol=1e-3, atol=1e-6, pcoeff=0.3, icoeff=0.3)
    tolerances = dict(band=1e-5, distribution="uniform")
    extras = []
    if plan.get("fixed"):
        joint = driven[int(rng.integers(len(driven)))]
        name = f"{joint}.{rng.choice(['carrier_clearance', 'planet_clearance', 'ring_backlash'])}"
        tolerances["fixed"] = [name]
        tolerances["bands"] = {name: float(np.round(rng.uniform(3, 12), 1)) * 1e-6}
        extras.append(f"fixed {name} +-{tolerances['bands'][name] * 1e6:g} um")
    if plan.get("cost"):
        grades, costs = COST_TABLES[int(rng.integers(len(COST_TABLES)))]
        tolerances["cost"] = dict(grades=grades, costs=costs)
        extras.append(f"cost table IT{grades[0]}-{grades[-1]}")
    if plan.get("law"):
        extras.append(f"contact {plan['law']}")
    stages = "; ".join(
        f"{j[:2]} z {s['sun_teeth']}/{s['planet_teeth']}/{s['ring_teeth']} x{s['n_planets']} m {s['module'] * 1e3:g} mm"
        for j in modelled for s in [scene[f"{j}_stage"]])
    fid = "/".join(f for f in plan["fidelity"])
    text = (f"{plan['kind']} {plan['mode']}, {fid}, {plan['base']} base; {stages}; reflector {mass:g} kg; {motion}; "
            f"{duration:g} s (window after {settle:g} s)" + ("; " + ", ".join(extras) if extras else ""))
    data = {"title": f"design matrix M{k:02d}", "scene": scene, "run": run, "tolerances": tolerances}
    return dict(key=f"M{k:02d}", plan=plan, data=data, text=text)


def options_of(scene_file) -> dict:
    """`propose_design`'s problem options from a scene file's `[tolerances]`, as `tolerax
    design` makes them: the starting band, the fixed features at their bands, the functional
    minima, the band range, a shop's cost table."""
    tol = scene_file.data.get("tolerances", {})
    band = tol.get("band", 1e-5)
    options = dict(band=band, fixed={n: tol.get("bands", {}).get(n, band) for n in tol.get("fixed", [])})
    if "min_clearance" in tol:
        options["min_clearance"] = tol["min_clearance"]
    if "band_range" in tol:
        options["band_range"] = tuple(tol["band_range"])
    if tol.get("cost"):
        options["cost_model"] = tx.GradeTable(tol["cost"]["grades"], tol["cost"]["costs"])
    return options


# ---------------------------------------------------------------------------------------------
# One design


def run_one(key: str, seed: int, args) -> dict:
    infeasible, midway = key in INFEASIBLE, key in MIDWAY
    k = int(BASE.get(key, key)[1:])
    m = mechanism(k, seed)
    row = dict(key=key, mechanism=m["key"], description=m["text"], kind="infeasible" if infeasible else "feasible",
               policy="infeasible" if infeasible else "midway" if midway else f"{args.fraction:g} x baseline",
               scene_toml=None, load_start=harness.load(), commit=harness.commit(), started=time.strftime("%Y-%m-%d %H:%M:%S"))
    start = time.perf_counter()
    try:
        sf = tx.SceneFile.from_data(m["data"], name=m["key"])
        row["scene_toml"] = sf.to_toml()
        pointing = sf.objective()
        options = options_of(sf)
        names = tx.design_names(pointing.scene)
        row["features"] = list(names)
        problem = design_problem(pointing, yield_=args.yield_, **options)
        value = jax.jit(lambda x: problem.objective(x, problem.draws, WIDTH))
        baseline = float(value(problem.x0))
        row["baseline_quantile"] = baseline
        if infeasible or midway:
            tight = tightest(problem.lower, problem.upper, np.ones(len(names)))
            row["tightest_quantile"] = float(value(tight))
        if infeasible:
            requirement = min(0.2 * baseline, 0.5 * row["tightest_quantile"])
        elif midway:
            cheapest = type(tight)(np.asarray(problem.lower.nominal), np.asarray(problem.upper.band))
            row["cheapest_quantile"] = float(value(cheapest))
            requirement = 0.5 * (row["tightest_quantile"] + row["cheapest_quantile"])
        else:
            requirement = args.fraction * baseline
        row["requirement"] = requirement
        row["setup_s"] = time.perf_counter() - start
        print(f"[{key}] {m['text']}\n[{key}] baseline {baseline:.1f} arcsec, requirement {requirement:.1f} "
              f"({row['setup_s']:.0f} s setup)", flush=True)
        # The new API (issue 59): the problem, the solver and the check as values, every
        # requirement on its default constraint model (tx.Auto()).
        zones = tx.Zones(**{k: options[k] for k in ("band", "fixed", "min_clearance", "band_range") if k in options})
        spec = tx.ToleranceProblem(pointing, requirement, tx.Yield(args.yield_), zones, options.get("cost_model"))
        solver = tx.Sequential() if args.max_outer is None else tx.Sequential(max_gradients=args.max_outer)
        wall_s, report = harness.wall(tx.propose_design, spec, solver, check=tx.Check(args.check_units) if args.check_units else None)
        first = report.outcomes[0]
        check = first.checks[-1] if first.checks else None
        row.update(
            wall_s=wall_s, status=report.status, diagnosis=report.diagnosis, notes=list(getattr(report, "notes", ())), accepted=bool(getattr(report, "accepted", report.status == "converged")),
            cost=float(report.cost), baseline_cost=float(report.baseline[2]), report_baseline_quantile=float(report.baseline[3]),
            objective=float(first.objective), solved_for=float(first.target),
            optimiser_converged=bool(report.result.converged), gradients=int(np.asarray(report.result.history.steps)[-1]),
            n_checks=len(first.checks),
            check=None if check is None else dict(
                n=int(check.n), n_failed=int(check.n_failed), yield_simulated=float(check.yield_simulated),
                interval=[float(v) for v in check.interval], yield_linear=float(check.yield_linear),
                quantile_simulated=float(check.quantile_simulated), quantile_linear=float(check.quantile_linear),
                shift=float(check.shift), shift_se=float(check.shift_se)),
            design={n: [float(v), float(b)] for n, v, b in zip(report.names, report.nominal, report.band)},
        )
        try:  # details for the JSON; a failure here must not lose the design's result
            row.update(_details(report))
        except Exception as err:
            row["details_error"] = f"{type(err).__name__}: {err}"
        print(report.table(), flush=True)
    except Exception as err:  # recorded, not fixed: the matrix goes on
        row.update(status="exception", error=f"{type(err).__name__}: {err}", traceback=traceback.format_exc()[-4000:],
                   wall_s=time.perf_counter() - start)
        print(f"[{key}] EXCEPTION {row['error']}", flush=True)
    row["total_s"] = time.perf_counter() - start
    row["load_end"] = harness.load()
    return row


def _details(report) -> dict:
    """The optimiser's path and every check, for the JSON."""
    h = report.result.history
    n = len(np.asarray(h.cost))
    return dict(
            chosen_iteration=int(report.result.iteration),
            optimality=float(report.result.optimality), band_optimality=float(report.result.band_optimality),
            checks=[dict(yield_simulated=float(c.yield_simulated), interval=[float(v) for v in c.interval],
                         quantile_simulated=float(c.quantile_simulated), quantile_linear=float(c.quantile_linear),
                         shift=float(c.shift), shift_se=float(c.shift_se)) for c in report.outcomes[0].checks],
            # one entry per iterate: cost, linearised quantile (arcsec), smoothing width (m), gradients so far
            history={f: np.asarray(getattr(h, f), dtype=float).reshape(n, -1)[:, 0].tolist()
                     for f in ("cost", "objective", "continuation", "steps")},
            report_table=report.table(),
    )


# ---------------------------------------------------------------------------------------------
# Results


def _cells(r, yield_):
    ok_check = r.get("check") and r["check"]["interval"][1] >= yield_
    if r.get("status") in ("exception", "crashed"):
        return (r["key"], r["description"], f"{r['baseline_quantile']:.1f}" if "baseline_quantile" in r else "-",
                f"{r['requirement']:.1f}" if "requirement" in r else "-", "-", r["status"], f"`{r['error'][:300]}`", "-",
                "-" if math.isnan(r["wall_s"]) else f"{r['wall_s']:.0f}", "-", "-", "-")
    c = r.get("check")
    check = "-" if not c else (f"{c['yield_simulated']:.3f} [{c['interval'][0]:.3f}, {c['interval'][1]:.3f}]"
                               + (f" ({c['n_failed']} failed)" if c["n_failed"] else ""))
    expected = "infeasible" if r["kind"] == "infeasible" else "converged"
    status = r["status"] + ("" if r["status"] == expected else f" (expected {expected})")
    return (
        r["key"], r["description"], f"{r['baseline_quantile']:.1f}", f"{r['requirement']:.1f} ({_policy(r)})",
        f"{r['cost']:.3f} (baseline {r['baseline_cost']:.3f})", status, " ".join([r["diagnosis"]] + r.get("notes", [])).strip() or "-", f"{r['gradients']}",
        f"{r['wall_s']:.0f}", check, "-" if not c else ("yes" if ok_check else "no") + f" ({r['n_checks']} checks)",
        "-" if not c else f"{c['quantile_simulated']:.1f} / {c['quantile_linear']:.4g}" + _flags(r),
    )


def _flags(r) -> str:
    """What makes a row a weak test: the linear model far from the simulation, a requirement
    the design does not touch."""
    c, out = r["check"], []
    ratio = c["quantile_linear"] / c["quantile_simulated"] if c["quantile_simulated"] > 0 else math.inf
    if not 0.5 <= ratio <= 2.0:
        out.append(f"linear model off by x{ratio:.3g}")
    if r["kind"] == "feasible" and r["objective"] < 0.9 * r["requirement"]:
        out.append("requirement not binding")
    return "" if not out else " (" + "; ".join(out) + ")"


def _policy(r) -> str:
    policy = r.get("policy", "infeasible" if r["kind"] == "infeasible" else "0.8 x baseline")
    if policy == "midway":
        return f"midway: tightest {r['tightest_quantile']:.1f}, cheapest {r['cheapest_quantile']:.1f}"
    if policy == "infeasible":
        return f"tightest {r['tightest_quantile']:.1f}"
    return policy


def summary(rows, yield_) -> str:
    feas = [r for r in rows if r["kind"] == "feasible"]
    inf = [r for r in rows if r["kind"] == "infeasible"]
    conv = sum(r.get("status") == "converged" for r in feas)
    checked = [r for r in feas if r.get("check")]
    within = sum(r["check"]["interval"][1] >= yield_ for r in checked)
    at_yield = sum(r["check"]["yield_simulated"] >= yield_ for r in checked)
    named = sum(r.get("status") == "infeasible" for r in inf)
    weak = [r["key"] for r in feas if r.get("check") and _flags(r)]
    exc = sum(r.get("status") in ("exception", "crashed") for r in rows)
    walls = [r["wall_s"] for r in rows if r.get("status") not in ("exception", "crashed")]
    return (f"**Summary:** {conv} of {len(feas)} feasible mechanisms converged; {within} of {len(checked)} Monte Carlo checks "
            f"met the {yield_:.0%} yield within their 95 % Wilson interval ({at_yield} at or above it as a point estimate); "
            f"{named} of {len(inf)} infeasible cases named infeasible; {exc} exception(s) or crash(es); max wall per design "
            f"{max(walls) if walls else float('nan'):.0f} s (propose_design alone, compilation included)."
            + (f" Weak tests (requirement not binding, or the linear model off by more than x2 from the check): {', '.join(weak)}."
               if weak else ""))


def write(name, meta, rows, args):
    rows = sorted(rows, key=lambda r: (r["kind"] == "infeasible", r["key"]))
    columns = ["key", "mechanism", f"baseline {args.yield_:.0%} quantile (arcsec)", "requirement (arcsec)", "cost (IT7 = 1 per feature)",
               "status", "diagnosis (and notes)", "gradients", "design wall (s)", "check yield [95 % Wilson]", "check meets yield",
               f"check {args.yield_:.0%} quantile: simulated / linear (arcsec)"]
    sections = []
    if SUPERSEDED:
        old = sorted(SUPERSEDED.values(), key=lambda r: r["key"])
        sections.append(harness.Section(
            "Superseded rows", columns + ["ran at"], [(*_cells(r, args.yield_), r.get("commit", "?")) for r in old],
            notes=["Rows designed again after src/ changed under the run (delete a row from the JSON's `rows` to redo it; the "
                   "earlier result is kept here)."]))
    harness.write_table(
        name, f"Design matrix: {args.yield_:.0%}-yield tolerance designs on generated mechanisms", meta["command"],
        columns, [_cells(r, args.yield_) for r in rows],
        about=(f"Seed {meta['seed']}; requirement {meta['fraction']:g} x the baseline's linearised {args.yield_:.0%} quantile "
               f"(infeasible cases: min(0.2 x baseline, 0.5 x the tightest design's)); `propose_design(ToleranceProblem(..., "
               f"Yield({args.yield_:g})), Sequential(), check=Check({meta['check_units']}))`, default widths and constraint models; one core (`taskset -c 1`). Runs (resumed runs "
               f"append): " + "; ".join(meta.get("runs", [])) + "."),
        intro=[summary(rows, args.yield_)],
        notes=["Status: what `DesignReport.status` says (expected: `converged` for M.., `infeasible` for X..). Design wall: "
               "`propose_design` alone (its compilation included; the baseline evaluation that set the requirement is apart, "
               "`setup_s` in the JSON). Check: the last Monte Carlo check of the returned design (`report.outcomes[0].checks[-1]`); meets "
               "yield: the upper end of its Wilson interval reaches the yield. The scene files, designs and check details are in "
               f"`{name}.json`. Each row's `commit` in the JSON is the code it ran on (src/ was being edited during these runs).",
               ] + _commits(rows),
        sections=sections,
    )


def _commits(rows) -> list[str]:
    by = {}
    for r in rows:
        by.setdefault(r.get("commit", "unknown"), []).append(r["key"])
    return ["Code each row ran on: " + "; ".join(f"{c}: {', '.join(k)}" for c, k in by.items()) + "."]


def main():
    parser = harness.argument_parser(__doc__)
    parser.add_argument("--seed", type=int, default=2026)
    parser.add_argument("--yield", dest="yield_", type=float, default=0.99)
    parser.add_argument("--fraction", type=float, default=0.8, help="requirement = FRACTION x the baseline's linearised quantile")
    parser.add_argument("--check-units", type=int, default=200, help="propose_design's Monte Carlo check units")
    parser.add_argument("--max-outer", type=int, default=None, help="propose_design's max_outer (default: its own, 20)")
    parser.add_argument("--quick", action="store_true", help="smoke run: M01 and X01, 20 check units, design_matrix_quick.*")
    parser.add_argument("--only", default=None, help="run this one mechanism (M03, X01, or 3)")
    parser.add_argument("--stop-after", type=float, default=None, help="start no new mechanism after this many seconds")
    parser.add_argument("--retry-crashed", action="store_true", help="run again the mechanisms whose process died (status crashed)")
    parser.add_argument("--list", action="store_true", help="print the mechanisms (validated as scene files) and exit")
    parser.add_argument("--in-process", action="store_true", help="design every mechanism in this process (default: one process each)")
    args = harness.parse_args(parser)
    keys = [f"M{k:02d}" for k in range(1, len(PLAN) + 1)]
    keys = ([k for k in keys if k not in LAST] + list(INFEASIBLE) + [k for k in MIDWAY if MIDWAY[k] not in LAST]
            + [k for k in keys if k in LAST] + [k for k in MIDWAY if MIDWAY[k] in LAST])
    if args.list:
        for key in keys:
            m = mechanism(int(BASE.get(key, key)[1:]), args.seed)
            sf = tx.SceneFile.from_data(m["data"], name=m["key"])
            print(key, m["text"], tx.design_names(sf.build()))
        return
    if args.quick:
        args.check_units = min(args.check_units, 20)
        keys = ["M01", "X01"]
    if args.only is not None:
        only = args.only.upper()
        only = f"M{int(only):02d}" if only.isdigit() else only
        if only not in keys:
            parser.error(f"--only: unknown mechanism {args.only!r}; one of {', '.join(keys)}")
        keys = [only]
    name = "design_matrix_quick" if args.quick else "design_matrix"
    path = harness.results_dir() / f"{name}.json"
    cmd = harness.command(args)
    if path.exists():
        saved = json.loads(path.read_text())
        for k in ("seed", "fraction", "check_units", "yield"):
            if saved["meta"][k] != {"seed": args.seed, "fraction": args.fraction, "check_units": args.check_units, "yield": args.yield_}[k]:
                parser.error(f"{path} was made with {k}={saved['meta'][k]!r}; delete it or use --results to start another")
        meta, rows = saved["meta"], saved["rows"]
        SUPERSEDED.update(saved.get("superseded", {}))
    else:
        meta, rows = dict(seed=args.seed, fraction=args.fraction, check_units=args.check_units, yield_=None, runs=[]), {}
        meta["yield"] = args.yield_
        meta.pop("yield_")
    meta["command"] = harness.command(argparse_free(args))
    run_entry = f"`{cmd}` from {time.strftime('%Y-%m-%d %H:%M')} ({harness.environment()})"
    start = time.perf_counter()
    for key in keys:
        if key in rows and args.retry_crashed and rows[key].get("status") == "crashed":
            del rows[key]
        if key in rows:
            print(f"[{key}] already in {path.name}: skipped", flush=True)
            continue
        if args.stop_after is not None and time.perf_counter() - start > args.stop_after:
            print(f"[{key}] not started: --stop-after {args.stop_after:g} s reached", flush=True)
            continue
        if args.only is None and not args.in_process:
            # Each mechanism in a fresh process: compiled code of a dozen mechanisms exhausts the
            # kernel's memory-map limit (vm.max_map_count 65530) in one process, and LLVM then
            # fails with "Cannot allocate memory" (measured: ~5,000 maps per mechanism).
            subprocess.run([sys.executable, __file__, *sys.argv[1:], "--only", key], check=False)
            saved = json.loads(path.read_text())  # the child wrote its row, and its run under meta["runs"]
            meta, rows = saved["meta"], saved["rows"]
            SUPERSEDED.update(saved.get("superseded", {}))
            continue
        # A row that says the process died, replaced by the result: a crash below Python (a
        # segfault in the compiler) leaves it, and a rerun skips the mechanism (--retry-crashed).
        if run_entry is not None:  # a run that designs something is recorded once
            meta.setdefault("runs", []).append(run_entry)
            run_entry = None
        m = mechanism(int(BASE.get(key, key)[1:]), args.seed)
        rows[key] = dict(key=key, mechanism=m["key"], description=m["text"], kind="infeasible" if key in INFEASIBLE else "feasible",
                         status="crashed", error="the process died while designing it (no Python exception; see the run's log)",
                         wall_s=math.nan, started=time.strftime("%Y-%m-%d %H:%M:%S"))
        _save(path, meta, rows)
        rows[key] = run_one(key, args.seed, args)
        _save(path, meta, rows)
        write(name, meta, list(rows.values()), args)
    write(name, meta, list(rows.values()), args)


SUPERSEDED = {}  # rows run again (at a later commit), kept under "superseded" in the JSON: "KEY@commit" -> row


def _save(path, meta, rows):
    tmp = path.with_suffix(".json.tmp")
    tmp.write_text(json.dumps(dict(meta=meta, rows=rows, superseded=SUPERSEDED), indent=1))
    os.replace(tmp, path)


def argparse_free(args):
    """The options that reproduce the whole table: without `--only` and `--stop-after` (a run
    of part of it)."""
    import argparse

    d = {k: v for k, v in vars(args).items() if k not in ("only", "stop_after", "list", "retry_crashed", "in_process")}
    return argparse.Namespace(**d)


if __name__ == "__main__":
    main()
