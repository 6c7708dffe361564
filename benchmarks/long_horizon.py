"""The planetary dual-axis antenna over a long horizon (issue 14): today's right-hand side, the
reference formulation and a tight reference in one process, and where the steps go.

    python benchmarks/long_horizon.py [--duration 5.0] [--tight-rtol 1e-8] [--runs new reference tight]
    python benchmarks/long_horizon.py --render   # rewrite the .md and .png from the saved .json and steps

Writes `benchmarks/results/long_horizon.{md,json,png}` (and the per-step arrays to `--steps-file`,
default `/tmp/long_horizon_steps.npz`, for `--render`; not committed, ~8 MB for 3 s).

Scene: `tolerax.antenna("dual", fidelity="planetary")` (the `mechanism_cost.py` scene: free base,
0.98 deg/s on both joints, 100 um clearances and backlash), steady start. Runs, in this order and
in one process:

1. `new`: `Mechanism.vector_field` (frames down the chain, Cholesky), Tsit5, rtol 1e-6, atol 1e-9
   (`simulate`'s defaults).
2. `reference`: `_mechanism._KaneByAutodiff` (jacfwd Kane, LU), same tolerances: today's code
   before the rewrite.
3. `tight`: the new code at `--tight-rtol` with atol scaled by the same factor (atol 1e-9 in m and
   rad is what limits the error on micrometre translations; tightening rtol alone would leave it).

`simulate` saves only at equally spaced times, so each run calls `diffrax.diffeqsolve` here with
exactly `simulate`'s solver, controller (`_solve._NanSafePID`, `dtmin` 1e-13, `dt0` 1e-6, `dtmax`
1e-3, `force_dtmin=False`), save times and observation (`scene.observe`, `scene.result`), plus two
recordings: every accepted step's end time (and, for `new`, its state) through
`SubSaveAt(steps=True)`, and every rejected step's start time, carried in the step-size
controller's state (`_RecordingPID`). A short check run compares this path with `simulate`
(same steps and outputs). Compile time: a first call over `--compile-horizon` s (same program:
only values change), timed apart.

Anatomy (from `new`): step size against time, accepted and rejected steps per 0.1 s window, each
bearing contact's state at the accepted steps (in contact: normal force above `--contact-force`
N), its switches, steps per switch, and how many rejected steps fall on a step across which some
contact switches ("rejected into an impact"). Cost per step against Tsit5's 6 right-hand-side
evaluations per step (FSAL), the RHS timed in this process by `rhs_anatomy.timed`.
"""

import argparse
import json
import os
import pathlib
import time

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np

import tolerax
from tolerax import _mechanism, _solve

import _results
import rhs_anatomy

RATE_DEG_S = 0.98  # the `antenna` scene's default slew rate on both joints (deg/s)
WINDOW = 0.1  # s: width of the step-count windows


class _RecordingPID(_solve._NanSafePID):
    """`_solve._NanSafePID` that also writes the start time of every rejected step into a buffer
    of `n_record` entries carried in its state (steps are decided exactly as by the parent)."""

    n_record: int = eqx.field(static=True, default=1)

    def init(self, terms, t0, t1, y0, dt0, args, func, error_order):
        t1, inner = super().init(terms, t0, t1, y0, dt0, args, func, error_order)
        return t1, (inner, jnp.full(self.n_record, jnp.inf), jnp.asarray(0))

    def adapt_step_size(self, t0, t1, y0, y1_candidate, args, y_error, error_order, controller_state):
        inner, rejected_t0, count = controller_state
        keep, next_t0, next_t1, jump, inner, result = super().adapt_step_size(
            t0, t1, y0, y1_candidate, args, y_error, error_order, inner
        )
        slot = jnp.minimum(count, self.n_record - 1)
        rejected_t0 = jnp.where(keep, rejected_t0, rejected_t0.at[slot].set(t0))
        return keep, next_t0, next_t1, jump, (inner, rejected_t0, count + jnp.where(keep, 0, 1)), result


@eqx.filter_jit
def _diffeqsolve(scene, y0, t1, ts, rtol, atol, max_steps, save_states, progress):
    """`_solve._solve` (adaptive branch) with step and rejection recordings."""
    controller = _RecordingPID(
        rtol=rtol, atol=atol, dtmin=_solve.DTMIN, dtmax=1e-3, force_dtmin=False, n_record=max_steps
    )
    # At the steps: the state (for the contacts), or only the time (a few MB for a million steps).
    at_steps = (lambda t, y, args: y) if save_states else (lambda t, y, args: t)
    saveat = diffrax.SaveAt(
        subs=(diffrax.SubSaveAt(ts=ts), diffrax.SubSaveAt(t1=True), diffrax.SubSaveAt(steps=True, fn=at_steps)),
        controller_state=True,
    )
    sol = diffrax.diffeqsolve(
        diffrax.ODETerm(scene.vector_field), diffrax.Tsit5(), t0=0.0, t1=t1, dt0=1e-6, y0=y0, saveat=saveat,
        stepsize_controller=controller, max_steps=max_steps, throw=False,
        progress_meter=diffrax.TextProgressMeter(minimum_increase=0.1) if progress else diffrax.NoProgressMeter(),
    )
    (ts_saved, t_last, t_steps), (ys, _, y_steps) = sol.ts, sol.ys
    _, rejected_t0, n_rejected = sol.controller_state
    stats = dict(sol.stats, t_reached=t_last[0])
    sol = eqx.tree_at(lambda s: (s.ts, s.ys, s.stats), sol, (ts_saved, ys, stats))
    observed = jax.vmap(scene.observe)(sol.ts, sol.ys)
    return sol, observed, t_steps, (y_steps if save_states else None), rejected_t0, n_rejected


def solve(scene, duration, rtol, atol, *, n_save, max_steps, save_states=False, progress=True):
    """Run `scene` from a steady start like `simulate`; returns the scene's result and the
    recordings (numpy): accepted step end times, states there (or None), rejected step starts."""
    y0 = scene.initial_state("steady")
    f64 = lambda x: jnp.asarray(x, dtype=float)  # noqa: E731
    ts = jnp.linspace(0.0, duration, n_save)
    sol, observed, t_steps, y_steps, rejected_t0, n_rej = _diffeqsolve(
        scene, y0, f64(duration), ts, f64(rtol), f64(atol), int(max_steps), bool(save_states), bool(progress)
    )
    result = scene.result(sol, observed, duration)
    jax.block_until_ready(result)
    n = int(result.num_steps)
    steps = np.asarray(t_steps)[:n]
    states = None if y_steps is None else jax.tree.map(lambda x: np.asarray(x)[:n], y_steps)
    rejected = np.sort(np.asarray(rejected_t0)[: min(int(n_rej), max_steps)])
    if int(n_rej) > max_steps:
        print(f"warning: {int(n_rej)} rejections, only {max_steps} recorded", flush=True)
    return result, steps, states, rejected


def rms(x):
    return float(np.sqrt(np.mean(np.square(x)))) if len(x) else float("nan")


def contact_forces(mech, t, states, chunk=4096):
    """Normal force of every bearing contact (N) at the given times and states, (n, contacts)."""

    @jax.jit
    def forces(t, q, u, v):
        return jax.vmap(lambda *a: jnp.concatenate([c for _, c in mech.joint_forces(a[1], a[2], a[3], a[0])]))(t, q, u, v)

    q, u, v = states
    out = [np.asarray(forces(t[k : k + chunk], q[k : k + chunk], u[k : k + chunk], v[k : k + chunk])) for k in range(0, len(t), chunk)]
    return np.concatenate(out) if out else np.zeros((0, mech.layout.size_v))


def anatomy(steps, rejected, force, names, duration, threshold):
    """Where the steps go: per window, per contact; plain Python numbers for the JSON."""
    dt = np.diff(np.concatenate([[0.0], steps]))
    edges = np.arange(0.0, duration + WINDOW / 2, WINDOW)
    acc_w = np.histogram(steps, edges)[0]
    rej_w = np.histogram(rejected, edges)[0]
    med_w = [float(np.median(dt[(steps > a) & (steps <= b)])) if np.any((steps > a) & (steps <= b)) else float("nan") for a, b in zip(edges[:-1], edges[1:])]
    state = force > threshold
    # A step "crosses a switch" if some contact's state differs between its start and its end
    # (the first step starts from the initial state: treat it as unchanged).
    change = np.zeros(len(steps), dtype=bool)
    change[1:] = np.any(state[1:] != state[:-1], axis=1)
    # Each rejection starts where an accepted step starts: the one whose start time equals it.
    starts = np.concatenate([[0.0], steps[:-1]])
    idx = np.clip(np.searchsorted(starts, rejected, side="left"), 0, len(steps) - 1)
    on_switch = change[idx] | change[np.clip(idx + 1, 0, len(steps) - 1)]
    late = steps > 1.0
    per_contact = []
    for k, name in enumerate(names):
        flips = np.flatnonzero(state[1:, k] != state[:-1, k]) + 1
        late_flips = flips[steps[flips] > 1.0]
        per_contact.append(
            dict(
                name=name,
                switches=int(len(flips)),
                switches_after_1s=int(len(late_flips)),
                fraction_in_contact=float(state[:, k].mean()) if len(steps) else float("nan"),
                peak_force_N=float(force[:, k].max()) if len(steps) else float("nan"),
            )
        )
    total_switches = int(sum(c["switches"] for c in per_contact))
    return dict(
        window_s=WINDOW,
        accepted_per_window=acc_w.tolist(),
        rejected_per_window=rej_w.tolist(),
        median_dt_per_window=med_w,
        dt_percentiles_after_1s={p: float(np.percentile(dt[late], p)) for p in (1, 10, 50, 90, 99)} if late.any() else {},
        accepted_per_sim_s_after_1s=float(late.sum() / max(duration - 1.0, 1e-12)),
        rejected_per_sim_s_after_1s=float((rejected > 1.0).sum() / max(duration - 1.0, 1e-12)),
        steps_crossing_a_switch=int(change.sum()),
        rejected_on_a_switch=int(on_switch.sum()),
        rejected=int(len(rejected)),
        contacts=per_contact,
        total_switches=total_switches,
        accepted_per_switch=float(len(steps) / total_switches) if total_switches else float("inf"),
        contact_force_threshold_N=threshold,
    )


def run_all(args, stem):
    load = [os.getloadavg()]
    mech = tolerax.antenna("dual", fidelity="planetary")
    names = [f"azimuth {n}" for n in mech.azimuth.contact_names] + [f"pitch {n}" for n in mech.pitch.contact_names]
    scenes = {"new": mech, "reference": _mechanism._KaneByAutodiff(mech), "tight": mech}
    tols = {"new": (1e-6, 1e-9), "reference": (1e-6, 1e-9), "tight": (args.tight_rtol, 1e-9 * args.tight_rtol / 1e-6)}
    payload = dict(command=_results.command(args), duration=args.duration, n_save=args.n_save, contact_names=names, runs={}, load=[])
    # RHS cost in this process, for the cost per step against its evaluations.
    q, u, v = mech.initial_state("steady")
    t = jnp.asarray(0.01)
    rhs_args = (t, q, u, v, None, None, None)
    payload["rhs_us"] = {
        "new": rhs_anatomy.timed(rhs_anatomy.PIECES["vector field (all)"], mech, rhs_args, 300),
        "reference": rhs_anatomy.timed(rhs_anatomy.PIECES["vector field, reference (jacfwd Kane, LU)"], mech, rhs_args, 300),
    }
    payload["rhs_us"]["tight"] = payload["rhs_us"]["new"]
    print("rhs us", payload["rhs_us"], flush=True)
    # Check: this script's solve against `simulate` over a short horizon.
    check_t = args.check_horizon
    if check_t > 0:
        a = tolerax.simulate(mech, check_t, start="steady", n_save=11)
        b, *_ = solve(mech, check_t, 1e-6, 1e-9, n_save=11, max_steps=20_000, progress=False)
        payload["check"] = dict(
            horizon=check_t, simulate_steps=[int(a.num_steps), int(a.num_rejected)], script_steps=[int(b.num_steps), int(b.num_rejected)],
            max_pointing_diff_rad=float(jnp.max(jnp.abs(a.pointing_error - b.pointing_error))),
        )
        print("check", payload["check"], flush=True)
    saved = {}
    for name in args.runs:
        scene, (rtol, atol) = scenes[name], tols[name]
        max_steps = args.max_steps * (3 if name == "tight" else 1)
        record = name == "new"
        start = time.perf_counter()
        solve(scene, args.compile_horizon, rtol, atol, n_save=args.n_save, max_steps=max_steps, save_states=record)
        first = time.perf_counter() - start
        start = time.perf_counter()
        res, steps, states, rejected = solve(scene, args.duration, rtol, atol, n_save=args.n_save, max_steps=max_steps, save_states=record)
        wall = time.perf_counter() - start
        load.append(os.getloadavg())
        ts, pe = np.asarray(res.ts), np.asarray(res.pointing_error)
        rec = dict(
            rtol=rtol, atol=atol, success=bool(res.success), t_reached=float(res.t_reached), compile_s=first, wall_s=wall,
            per_sim_s=wall / args.duration, accepted=int(res.num_steps), rejected=int(res.num_rejected),
            us_per_step=wall / max(int(res.num_steps) + int(res.num_rejected), 1) * 1e6,
            pointing_rms_late=rms(pe[ts >= 1.0]), pointing_rms_all=rms(pe), pointing_max=float(pe.max()),
            load_after=load[-1],
        )
        rec["step_over_rhs"] = rec["us_per_step"] / (6 * payload["rhs_us"][name])
        saved[f"{name}_steps"], saved[f"{name}_rejected"] = steps, rejected
        saved[f"{name}_ts"], saved[f"{name}_pointing"] = ts, pe
        if record:
            force = contact_forces(mech, steps, states)
            saved["new_force"] = force
            rec["anatomy"] = anatomy(steps, rejected, force, names, args.duration, args.contact_force)
        payload["runs"][name] = rec
        payload["load"] = load
        print(name, {k: v for k, v in rec.items() if k != "anatomy"}, flush=True)
        # Partial results survive a run that does not finish.
        stem.with_suffix(".json").write_text(json.dumps(payload, indent=1, default=float))
        np.savez_compressed(args.steps_file, **saved)
    return payload


def render(payload, steps_file, stem):
    runs = payload["runs"]
    duration = payload["duration"]
    tight = runs.get("tight")
    rows = []
    for name, label in (("new", "new (frames, Cholesky)"), ("reference", "reference (jacfwd Kane, LU)"), ("tight", "tight reference (new code)")):
        if name not in runs:
            continue
        r = runs[name]
        rel_late = rel_all = "—"
        if tight and name != "tight":
            rel_late = f"{(r['pointing_rms_late'] - tight['pointing_rms_late']) / tight['pointing_rms_late'] * 100:+.3f} %"
            rel_all = f"{(r['pointing_rms_all'] - tight['pointing_rms_all']) / tight['pointing_rms_all'] * 100:+.3f} %"
        rows.append([
            label, f"{r['rtol']:g} / {r['atol']:g}", "yes" if r["success"] else f"no (t = {r['t_reached']:.3g} s)",
            f"{r['compile_s']:.1f}", f"{r['wall_s']:.1f}", f"{r['per_sim_s']:.1f}", str(r["accepted"]), str(r["rejected"]),
            f"{r['us_per_step']:.0f}", f"{r['step_over_rhs']:.2f}",
            f"{r['pointing_rms_late'] / tolerax.ARCSEC:.3f}", f"{r['pointing_rms_all'] / tolerax.ARCSEC:.3f}", rel_late, rel_all,
        ])
    loads = "; ".join(", ".join(f"{x:.2f}" for x in l) for l in payload["load"])
    rhs = payload["rhs_us"]
    intro = [
        f"Load average (1, 5, 15 min) at start and after each run: {loads}. The machine (2 cores) is shared: "
        "wall times are noisy; the ratios within this run are what to read.",
        f"One RHS evaluation in this process (compiled, 300 calls, best of 3): new {rhs['new']:.1f} µs, "
        f"reference {rhs['reference']:.1f} µs. 'step / 6 RHS': wall time per attempted step (accepted + rejected) "
        "over Tsit5's 6 evaluations per step.",
    ]
    if "check" in payload:
        c = payload["check"]
        intro.append(
            f"Check of this script's solve against `simulate` over {c['horizon']} s: steps (accepted, rejected) "
            f"{tuple(c['script_steps'])} against {tuple(c['simulate_steps'])}, largest pointing difference "
            f"{c['max_pointing_diff_rad']:.1e} rad."
        )
    sections = []
    an = runs.get("new", {}).get("anatomy")
    if an:
        acc, rej = an["accepted_per_window"], an["rejected_per_window"]
        w = an["window_s"]
        sections.append(_results.Section(
            f"Where the steps go (new code, rtol 1e-6): per {w} s window",
            ["window (s)", "accepted", "rejected", "median step (µs)"],
            [[f"{k * w:.1f}–{(k + 1) * w:.1f}", str(a), str(b), f"{m * 1e6:.1f}"] for k, (a, b, m) in enumerate(zip(acc, rej, an["median_dt_per_window"]))],
            [
                "Step sizes after 1 s (percentiles 1, 10, 50, 90, 99): "
                + ", ".join(f"{v * 1e6:.1f}" for v in an["dt_percentiles_after_1s"].values())
                + f" µs. After 1 s: {an['accepted_per_sim_s_after_1s']:.0f} accepted and "
                f"{an['rejected_per_sim_s_after_1s']:.0f} rejected steps per simulated second.",
            ],
        ))
        sections.append(_results.Section(
            "Bearing contacts at the accepted steps (new code)",
            ["contact", "switches", "switches after 1 s", "fraction of steps in contact", "peak force (N)"],
            [[c["name"], str(c["switches"]), str(c["switches_after_1s"]), f"{c['fraction_in_contact']:.3f}", f"{c['peak_force_N']:.3g}"] for c in an["contacts"]],
            [
                f"In contact: normal force above {an['contact_force_threshold_N']:g} N. {an['total_switches']} switches in all, "
                f"{an['accepted_per_switch']:.0f} accepted steps per switch; {an['steps_crossing_a_switch']} accepted steps "
                f"have some contact switching across them. Of {an['rejected']} rejected steps, {an['rejected_on_a_switch']} "
                f"({an['rejected_on_a_switch'] / max(an['rejected'], 1) * 100:.1f} %) were rejected on the step (or the one after) "
                "across which a contact switches: rejected into an impact.",
            ],
        ))
    notes = list(payload.get("notes", []))
    if tight and pathlib.Path(steps_file).exists():
        data = np.load(steps_file)
        if "tight_pointing" in data:
            ts, ref = data["tight_ts"], data["tight_pointing"]
            late = ts >= 1.0
            parts = []
            for name in ("new", "reference"):
                if f"{name}_pointing" in data:
                    d = data[f"{name}_pointing"] - ref
                    parts.append(
                        f"{name}: RMS of the difference {rms(d[late]) / tolerax.ARCSEC:.3f} arcsec over 1 s–end, "
                        f"largest {np.max(np.abs(d)) / tolerax.ARCSEC:.3f} arcsec"
                    )
            notes.insert(0, "Pointing error against the tight run, sample by sample: " + "; ".join(parts) + ".")
            # The RMS is mostly a steady offset (the lag the drive holds); its fluctuation about the
            # mean is the rattle's share, compared apart.
            spread = {n: float(np.std(data[f"{n}_pointing"][data[f"{n}_ts"] >= 1.0])) for n in ("new", "reference", "tight") if f"{n}_pointing" in data}
            notes.insert(1, "Standard deviation of the pointing error about its mean over 1 s–end: " + ", ".join(
                f"{n} {v / tolerax.ARCSEC:.2f} arcsec" + (f" ({(v - spread['tight']) / spread['tight'] * 100:+.1f} % vs tight)" if n != "tight" else "")
                for n, v in spread.items()
            ) + ".")
    _results.write_table(
        stem.name,
        f"Planetary dual-axis antenna over {duration:g} s: today's and the new right-hand side, and a tight reference",
        payload["command"],
        ["run", "rtol / atol", "reached", "compile (s)", "wall (s)", "wall per simulated s", "accepted", "rejected", "µs per step",
         "step / 6 RHS", "pointing RMS 1 s–end (arcsec)", "pointing RMS all (arcsec)", "Δ RMS 1 s–end vs tight", "Δ RMS all vs tight"],
        rows,
        about=f"`tolerax.antenna('dual', fidelity='planetary')`, steady start, {RATE_DEG_S} deg/s, Tsit5, {duration:g} s, "
        f"pointing saved at {payload['n_save']} equally spaced times.",
        intro=intro,
        notes=notes,
        sections=sections,
    )
    plot(payload, steps_file, stem.with_suffix(".png"))


def plot(payload, steps_file, path):
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    if not pathlib.Path(steps_file).exists():
        print(f"no {steps_file}: no figure", flush=True)
        return
    data = np.load(steps_file)
    names = payload["contact_names"]
    fig, axes = plt.subplots(3, 1, figsize=(11, 9), sharex=True, gridspec_kw=dict(height_ratios=[3, 1.5, 2.5]), constrained_layout=True)
    ax = axes[0]
    for name, colour in (("tight", "tab:green"), ("reference", "tab:orange"), ("new", "tab:blue")):
        if f"{name}_steps" not in data:
            continue
        s = data[f"{name}_steps"]
        rej = data[f"{name}_rejected"]
        if name == "new" and len(rej):
            # A rejected step's own size is not recorded: mark it at the size of the accepted
            # step that then starts at the same time.
            idx = np.clip(np.searchsorted(s, rej, side="right"), 1, len(s) - 1)
            ax.plot(rej, np.diff(s)[idx - 1], "x", ms=1.0, color="tab:red", alpha=0.2, rasterized=True, label="new: rejected (at the retried step's size)")
        ax.plot(s[1:], np.diff(s), ".", ms=0.6, color=colour, alpha=0.5, rasterized=True, label=f"{name} ({len(s)} steps)")
    ax.set_yscale("log")
    ax.set_ylabel("accepted step size (s)")
    ax.legend(fontsize=7, markerscale=8, loc="lower left")
    ax.grid(True, which="both", alpha=0.3)
    an = payload["runs"].get("new", {}).get("anatomy")
    if an:
        w = an["window_s"]
        x = np.arange(len(an["accepted_per_window"])) * w
        axes[1].bar(x, an["accepted_per_window"], width=w, align="edge", color="tab:blue", alpha=0.7, label="accepted")
        axes[1].bar(x, an["rejected_per_window"], width=w, align="edge", color="tab:red", alpha=0.7, label="rejected")
        axes[1].set_ylabel(f"steps per {w} s")
        axes[1].legend(fontsize=7)
    if "new_force" in data:
        s, state = data["new_steps"], data["new_force"] > an["contact_force_threshold_N"]
        for k in range(state.shape[1]):
            on = state[:, k]
            flips = np.flatnonzero(np.diff(on.astype(int)) != 0) + 1
            bounds = np.concatenate([[0], flips, [len(on)]])
            segs = [(s[a], s[min(b, len(s) - 1)] - s[a]) for a, b in zip(bounds[:-1], bounds[1:]) if on[a]]
            axes[2].broken_barh(segs, (k - 0.4, 0.8), color="tab:purple")
        axes[2].set_yticks(range(len(names)), names, fontsize=7)
        axes[2].set_ylabel("in contact")
    axes[2].set_xlabel("time (s)")
    fig.suptitle(f"Planetary dual-axis antenna, steady start, Tsit5: steps and bearing contacts over {payload['duration']:g} s", fontsize=9)
    fig.savefig(path, dpi=110)


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--duration", type=float, default=5.0, help="simulated seconds per run")
    parser.add_argument("--tight-rtol", type=float, default=1e-8, help="rtol of the tight reference (atol scaled alike)")
    parser.add_argument("--runs", nargs="+", choices=["new", "reference", "tight"], default=["new", "reference", "tight"])
    parser.add_argument("--n-save", type=int, default=5001, help="equally spaced save times (pointing error)")
    parser.add_argument("--max-steps", type=int, default=600_000, help="step budget (x3 for the tight run); also the recording size")
    parser.add_argument("--compile-horizon", type=float, default=1e-3, help="s: the first (compiling) call's horizon")
    parser.add_argument("--check-horizon", type=float, default=0.05, help="s: horizon of the check against `simulate` (0: skip)")
    parser.add_argument("--contact-force", type=float, default=1e-3, help="N: a contact is 'in contact' above this normal force")
    parser.add_argument("--steps-file", default="/tmp/long_horizon_steps.npz")
    parser.add_argument("--render", action="store_true", help="rewrite the .md and .png from the saved .json and steps file")
    args = parser.parse_args()
    stem = _results.results_dir() / "long_horizon"
    if args.render:
        payload = json.loads(stem.with_suffix(".json").read_text())
    else:
        payload = run_all(args, stem)
    render(payload, args.steps_file, stem)


if __name__ == "__main__":
    main()
