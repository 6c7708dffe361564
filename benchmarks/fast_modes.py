"""Where the planetary antenna's fast eigenvalues come from, and what a reduced fidelity would
gain (issue 14).

    python benchmarks/fast_modes.py [--times 1.0 1.5]

Writes `benchmarks/results/fast_modes.md`. Scene: `tolerax.antenna("dual", fidelity="planetary")`
(the `long_horizon.py` scene: free base, 0.98 deg/s on both joints, 100 um clearances and
backlash), steady start, Tsit5 rtol 1e-6 (`simulate`'s defaults). It runs to the latest of
`--times` and, at each of those instants (the rattle developed; each contact as it is then):

1. **The stability limit from the eigenvalues.** The whole vector field $\\dot y = f(t, y)$,
   $y = (q, u, v)$, is linearised by `jax.jacfwd` and its eigenvalues $\\lambda$ taken. Tsit5 is
   stable for a mode while $|R(h\\lambda)| \\le 1$, $R$ its amplification polynomial (from
   diffrax's tableau), so each eigenvalue allows steps up to $r(\\arg\\lambda)/|\\lambda|$, $r$ the
   radius of the stability region in that direction; the smallest over all eigenvalues is the
   stability limit. It is compared with the steps the solver took there in one continuous run:
   the median accepted step of the 0.1 s window starting at that instant, read from
   `results/long_horizon.json` (same scene and solver; its command is printed). A run restarted
   from a saved state is no substitute: with no error yet in the fast modes the controller
   accepts steps beyond the limit until those modes grow, and 50 ms restarts at 1.0 and 1.5 s
   averaged 75 and 44 us with a third of their steps rejected.
2. **Where each fast mode lives.** Undamped modes of $M\\ddot x + Kx = 0$ over the speeds, $M$ the
   mass matrix (`Mechanism.dynamics`) and $K = -\\partial Q/\\partial q$ the joints' generalised
   forces (meshes, contacts, servo) differentiated at the current state; for each mode the
   kinetic-energy share of each coordinate, summed by family (sun rotation, sun translation,
   planet spin, planet translation, carrier rotation, carrier translation, base) and joint.
3. **What a reduced fidelity would gain.** Making a family quasi-static (its mass neglected:
   the singular-perturbation limit) replaces $K$ by Guyan's static condensation
   $K_R = K_{RR} - K_{RS}K_{SS}^{-1}K_{SR}$ with $M_R = M_{RR}$; the table gives the fastest
   remaining frequency and the stable step it allows ($r$ at the fastest mode's damping ratio
   over $\\omega$), for each candidate family and combination, in both joints at once.

4. **What an IMEX split would leave explicit.** With the joints' internal forces (meshes,
   supports, clearance contacts: `forces` less `drive_forces`) taken implicitly through the true
   mass matrix, $f_I = (\dot q_j = u_j;\ \dot u = M(q)^{-1}[0; Q_{int}];\ 0)$, as diffrax's
   IMEX Runge-Kutta methods (KenCarp3/4/5) would with `MultiTerm(explicit, implicit)`, the
   explicit remainder $f_E = f - f_I$ carries the servo, the drag, the velocity terms, the base's
   kinematics and the impact-rate states. The table gives the fastest eigenvalue of $\partial
   f_E/\partial y$ and the step the explicit tableau of KenCarp4 allows for it. This is a
   necessary condition only: an additive method's stability is not that of its two parts, and
   it says nothing of accuracy (the implicit window of `implicit_window.md` took smaller steps
   than Tsit5 in the developed rattle), or of the cost (a Jacobian of $f_I$ over all states and
   an LU per step, five implicit stages).

The linearisation holds each contact in its current state (in or out of contact, smoothed law
differentiated where it is): it is the stiffness the solver sees between two switches.
"""

import argparse
import itertools
import json
import pathlib

import diffrax
import jax
import jax.numpy as jnp
import numpy as np
from jax.flatten_util import ravel_pytree

import tolerax

import _results
import _split

FAMILIES = {
    "sun rotation": ("theta_s",),
    "sun translation": ("x_s", "y_s"),
    "planet spin": ("theta_p0", "theta_p1", "theta_p2"),
    "planet translation": ("zeta_p0", "eta_p0", "zeta_p1", "eta_p1", "zeta_p2", "eta_p2"),
    "carrier rotation": ("theta_c",),
    "carrier translation": ("x_c", "y_c"),
}
# Families a reduced fidelity could make quasi-static, alone and together (both joints).
CANDIDATES = (
    (),
    ("sun translation",),
    ("planet spin",),
    ("planet translation",),
    ("carrier translation",),
    ("sun translation", "planet spin"),
    ("sun translation", "planet translation"),
    ("sun translation", "planet spin", "planet translation"),
    ("sun translation", "planet spin", "planet translation", "carrier translation"),
)


def tsit5_radius(direction: complex) -> float:
    """Radius of Tsit5's stability region along the unit complex `direction`."""
    return stability_radius(diffrax.Tsit5.tableau, direction)


def stability_radius(tableau, direction: complex) -> float:
    """Radius of an explicit Butcher tableau's stability region along the unit complex
    `direction` (scan of $|R(z)| = 1$ from the origin)."""
    n = len(tableau.b_sol)
    a = np.zeros((n, n))
    for i, row in enumerate(tableau.a_lower):
        a[i + 1, : len(row)] = row
    b, ones = np.asarray(tableau.b_sol), np.ones(n)

    def amplification(z):
        return abs(1 + z * b @ np.linalg.solve(np.eye(n) - z * a, ones))

    radii = np.linspace(1e-3, 6.0, 6000)
    unstable = np.array([amplification(r * direction) > 1 + 1e-12 for r in radii])
    return float(radii[np.argmax(unstable) - 1]) if unstable.any() else float(radii[-1])


def coordinate_labels(mech):
    """Family and joint of each speed coordinate."""
    labels = ["base"] * mech.layout.base_u
    for name in ("azimuth", "pitch"):
        for coord in getattr(mech, name).layout.names:
            family = next(f for f, members in FAMILIES.items() if coord in members)
            labels.append(f"{name} {family}")
    return labels


def linearise(mech, t, y):
    """(eigenvalues of df/dy, M, K over the speeds, df/dy) at state `y` and time `t`."""
    flat, unravel = ravel_pytree(y)
    jac = jax.jacfwd(lambda x: ravel_pytree(mech.vector_field(t, unravel(x), None))[0])(flat)
    q, u, v = y
    lay = mech.layout
    mass, _ = mech.dynamics(q, u, t)

    def joint_q_forces(qj_all):
        qq = q.at[lay.base_q:].set(qj_all)
        (qa, _), (qp, _) = mech.joint_forces(qq, u, v, t)
        return jnp.concatenate([qa, qp])

    dq = jax.jacfwd(joint_q_forces)(q[lay.base_q:])  # joint coordinates: q_j and u_j coincide
    stiffness = jnp.zeros((lay.size_u, lay.size_u)).at[lay.base_u:, lay.base_u:].set(-dq)
    return np.linalg.eigvals(np.asarray(jac)), np.asarray(mass), np.asarray(stiffness), jac


def explicit_remainder(mech, t, y, jac):
    """Eigenvalues of d(f - f_I)/dy, f_I the joints' internal forces through M(q)^-1 (see item 4);
    `jac` is df/dy at the same state (from `linearise`)."""
    flat, unravel = ravel_pytree(y)
    internal = _split.internal_field(mech)

    def f_imp(x):
        return ravel_pytree(internal(t, unravel(x), None))[0]

    return np.linalg.eigvals(np.asarray(jac - jax.jacfwd(f_imp)(flat)))


def modes(mass, stiffness):
    """Undamped frequencies (Hz, ascending) and mode shapes (columns) of M x'' + K x = 0; the
    rigid-body and near-zero modes come out with frequency ~0."""
    w2, vecs = np.linalg.eig(np.linalg.solve(mass, stiffness))
    w2, vecs = w2.real, vecs.real
    order = np.argsort(w2)
    return np.sqrt(np.clip(w2[order], 0.0, None)) / (2 * np.pi), vecs[:, order]


def energy_shares(mass, shape, labels):
    """Kinetic-energy share of each label in a mode shape (sums to 1)."""
    e = np.abs(shape * (mass @ shape))
    e = e / e.sum()
    out = {}
    for label, share in zip(labels, e):
        out[label] = out.get(label, 0.0) + share
    return dict(sorted(out.items(), key=lambda kv: -kv[1]))


def condensed_fmax(mass, stiffness, labels, families):
    """Fastest undamped frequency (Hz) with `families` (both joints) made massless."""
    slave = np.array([any(lab.endswith(" " + f) for f in families) for lab in labels])
    if not slave.any():
        return modes(mass, stiffness)[0][-1]
    r, s = ~slave, slave
    # Pseudo-inverse: a condensed coordinate with no stiffness at all (a member floating in its
    # clearance, out of contact) transmits no force and simply drops out.
    k_ss_inv = np.linalg.pinv(stiffness[np.ix_(s, s)], rcond=1e-12)
    k = stiffness[np.ix_(r, r)] - stiffness[np.ix_(r, s)] @ k_ss_inv @ stiffness[np.ix_(s, r)]
    return modes(mass[np.ix_(r, r)], k)[0][-1]


def _recorded():
    path = pathlib.Path(__file__).parent / "results" / "long_horizon.json"  # the committed run
    return json.loads(path.read_text()) if path.exists() else None


def recorded_command():
    saved = _recorded()
    return saved["command"] if saved else "(no long_horizon.json)"


def recorded_median_step(t):
    """Median accepted step (s) of the 0.1 s window starting at `t` in the recorded continuous
    run of `long_horizon.py` (new code, rtol 1e-6), or None where it did not reach `t`."""
    saved = _recorded()
    if saved is None:
        return None
    anatomy = saved["runs"]["new"]["anatomy"]
    k = int(round(t / anatomy["window_s"]))
    medians = anatomy["median_dt_per_window"]
    return medians[k] if k < len(medians) else None


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--times", nargs="+", type=float, default=[1.0, 1.5], help="s: instants to linearise at")
    parser.add_argument(
        "--mass-scaling", type=float, help="linearise the mass-scaled joints (`MassScaledPlanetaryJoint`) instead; "
        "writes fast_modes_scaled.md, without the recorded steps (those are the full stage's)"
    )
    args = parser.parse_args()
    mech = tolerax.antenna("dual", fidelity="planetary")
    name, fidelity = "fast_modes", "planetary"
    if args.mass_scaling is not None:
        mech = tolerax.antenna("dual", fidelity="planetary-scaled", mass_scaling=args.mass_scaling)
        name, fidelity = "fast_modes_scaled", "planetary-scaled"
    labels = coordinate_labels(mech)
    t_end = max(args.times)
    n_save = int(round(t_end / 0.01)) + 1
    res = tolerax.simulate(mech, t_end, start="steady", n_save=n_save)
    ts = np.asarray(res.ts)
    states = res.states
    zeta_mesh = float(mech.azimuth.stage.sun_mesh.damping_ratio)
    r_mesh = tsit5_radius(complex(-zeta_mesh, np.sqrt(1 - zeta_mesh**2)))
    rows, mode_rows, what_if, imex_rows = [], [], {}, []
    kencarp = diffrax.KenCarp4.tableau.tableaus[0]  # the explicit half of the additive tableau
    for t in args.times:
        k = int(np.argmin(np.abs(ts - t)))
        y = jax.tree.map(lambda x: x[k], states)
        eig, mass, stiffness, jac = linearise(mech, ts[k], y)
        fast = eig[np.abs(eig) > 2 * np.pi * 100.0]
        steps = np.array([tsit5_radius(lam / abs(lam)) / abs(lam) if lam.real < 0 else np.inf for lam in fast])
        worst = fast[np.argmin(steps)]
        n_unstable = int(np.sum(fast.real >= 0))
        dt_taken = recorded_median_step(ts[k]) if args.mass_scaling is None else None
        freqs, shapes = modes(mass, stiffness)
        rows.append([
            f"{ts[k]:.2f}", f"{abs(worst) / (2 * np.pi):.0f}", f"{-worst.real / abs(worst):.3f}",
            f"{np.min(steps) * 1e6:.1f}", "—" if dt_taken is None else f"{dt_taken * 1e6:.1f}",
            f"{freqs[-1]:.0f}", str(n_unstable),
        ])
        for j in range(1, 9):
            shares = energy_shares(mass, shapes[:, -j], labels)
            top = ", ".join(f"{lab} {share:.2f}" for lab, share in itertools.islice(shares.items(), 3))
            mode_rows.append([f"{ts[k]:.2f}", str(j), f"{freqs[-j]:.0f}", top])
        for cand in CANDIDATES:
            what_if.setdefault(cand, []).append(condensed_fmax(mass, stiffness, labels, cand))
        print(rows[-1], flush=True)
        eig_e = explicit_remainder(mech, ts[k], y, jac)
        decaying = eig_e[(np.abs(eig_e) > 2 * np.pi * 1.0) & (eig_e.real < 0)]
        steps_e = np.array([stability_radius(kencarp, lam / abs(lam)) / abs(lam) for lam in decaying])
        worst_e = decaying[np.argmin(steps_e)]
        fastest_e = eig_e[np.argmax(np.abs(eig_e))]
        growing = int(np.sum((eig_e.real >= 0) & (np.abs(eig_e) > 2 * np.pi * 10.0)))
        imex_rows.append([
            f"{ts[k]:.2f}", f"{abs(fastest_e) / (2 * np.pi):.0f}", f"{abs(worst_e) / (2 * np.pi):.0f}",
            f"{-worst_e.real / abs(worst_e):.3f}", f"{np.min(steps_e) * 1e6:.0f}",
            f"{np.min(steps_e) / np.min(steps):.0f}", str(growing),
        ])
        print("imex", imex_rows[-1], flush=True)
    base_f = np.array(what_if[()])
    cand_rows = []
    for cand, fmax in what_if.items():
        fmax = np.array(fmax)
        dt = r_mesh / (2 * np.pi * fmax)
        cand_rows.append([
            " + ".join(cand) if cand else f"none ({fidelity} joints as they are)",
            " / ".join(f"{f:.0f}" for f in fmax),
            " / ".join(f"{d * 1e6:.1f}" for d in dt),
            " / ".join(f"{x:.1f}" for x in base_f / fmax),
        ])
    at = " / ".join(f"{t:g} s" for t in args.times)
    _results.write_table(
        name,
        "Planetary dual-axis antenna: where the fast eigenvalues come from",
        _results.command(args),
        ["t (s)", "limiting mode (Hz)", "its damping ratio", "stability limit (µs)", "step taken (µs)",
         "undamped fastest (Hz)", "Re λ >= 0"],
        rows,
        about=f"`tolerax.antenna('dual', fidelity='{fidelity}')`"
        + ("" if args.mass_scaling is None else f" with mass_scaling {args.mass_scaling:g}")
        + f", steady start, Tsit5 rtol 1e-6, linearised at {at} "
        "(the rattle developed; each contact held as it is at that instant).",
        intro=[
            f"Stability limit: the smallest r(arg λ)/|λ| over the eigenvalues of ∂f/∂y with |λ| > 2π·100 Hz "
            f"(r: Tsit5's stability radius along λ); 'step taken': median accepted step of the 0.1 s window from "
            f"that instant in the continuous run recorded by `{recorded_command()}`. 'Undamped fastest': the top frequency of "
            "M x'' + K x = 0 (K = -∂Q/∂q of the joints). 'Re λ >= 0': eigenvalues above 100 Hz that no step "
            "size makes stable (none expected).",
        ],
        sections=[
            _results.Section(
                "The eight fastest undamped modes: kinetic-energy shares",
                ["t (s)", "rank", "frequency (Hz)", "largest shares (joint, family)"],
                mode_rows,
            ),
            _results.Section(
                "What a reduced fidelity would gain: families made quasi-static in both joints",
                ["made quasi-static", f"fastest remaining (Hz) at {at}", "stable Tsit5 step (µs)", "step gain"],
                cand_rows,
                [
                    f"Stable step: r/ω with r = {r_mesh:.2f}, Tsit5's stability radius at the mesh damping ratio "
                    f"{zeta_mesh:g}. Quasi-static = massless (Guyan condensation of K, the exact small-mass "
                    "limit); a reduced fidelity would also need the condensed contacts' forces solved at "
                    "each evaluation (a small nonlinear solve), which this table does not cost.",
                ],
            ),
            _results.Section(
                "What an IMEX split would leave explicit: the joints' internal forces implicit (item 4 above)",
                ["t (s)", "fastest |λ| of the remainder (Hz)", "limiting mode (Hz)", "its damping ratio",
                 "KenCarp4 explicit-tableau limit (µs)", "x the Tsit5 limit of the whole field", "Re λ >= 0 above 10 Hz"],
                imex_rows,
                [
                    "Limit: the smallest r(arg λ)/|λ| over the decaying eigenvalues of ∂(f - f_I)/∂y above 1 Hz, r the "
                    "stability radius of KenCarp4's explicit tableau (6 stages, not FSAL) along λ. Eigenvalues with "
                    "Re λ >= 0 no step makes stable (growth of the physical or the split system): counted, not in the limit.",
                ],
            ),
        ],
    )

if __name__ == "__main__":
    main()
