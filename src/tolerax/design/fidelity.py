"""Which joint fidelity reads which output: a requirement is designed and verified only at a
fidelity that answers it.

The joint fidelities (README, "Fidelity per joint") are models of one 2K-H stage at decreasing
cost. What each keeps decides what it can answer:

- `lumped` condenses the stage to one mesh with backlash, the pin play and the output bearing:
  the lost motion at reversals, hence the pointing error's RMS and peaks, but none of the
  stage's internal modes (sun, planets, carrier floating in their clearances).
- `planetary-scaled` keeps every body and clearance but scales the masses of the fastest
  relative motions (`MassScaledPlanetaryJoint`): it lowers those modes' frequencies by
  $\\sqrt{s}$ on purpose, to take longer steps. Quasi-static outputs (lost motion, mean
  loads) survive; the amplitude and spectrum of the stage's vibration do not: the modes move
  into and out of the stability band.
- `planetary` is the full stage.

So the vibration outputs (`VIBRATION_OUTPUTS`: the jitter, the RMS of the pointing error above
a cutoff frequency) are read at `planetary` fidelity only; the others at any fidelity that models
the joint's clearances. `fidelity_agreement` measures it (`benchmarks/fidelity_adequacy.py` runs
it): every output at every fidelity against the full stage on paired units.

A requirement states the fidelity it is read at (`Requirement.fidelity`, default by its
output: `read_at`); `check_fidelity` refuses a design whose scene models a joint below it,
naming the joint, the output and what to do.
"""

from collections.abc import Sequence

import numpy as np

# Outputs of the stage's vibration: read on the full planetary stage only.
VIBRATION_OUTPUTS = frozenset({"pointing_jitter"})
FIDELITIES = ("ideal", "lumped", "planetary-scaled", "planetary")


def joint_fidelities(scene) -> dict[str, str]:
    """`{joint: fidelity}` of the scene's joints (`"ideal"`, `"lumped"`, `"planetary-scaled"`,
    `"planetary"`), by their classes; a joint of a class tolerax does not know reads as its
    class name."""
    from ..mechanism.joints import IdealJoint, LumpedJoint
    from ..mechanism.stage_joints import MassScaledPlanetaryJoint, PlanetaryJoint

    kinds = ((MassScaledPlanetaryJoint, "planetary-scaled"), (PlanetaryJoint, "planetary"), (LumpedJoint, "lumped"),
             (IdealJoint, "ideal"))
    found = {}
    for joint in ("azimuth", "pitch"):
        j = getattr(scene, joint, None)
        if j is not None:
            found[joint] = next((name for cls, name in kinds if isinstance(j, cls)), type(j).__name__)
    return found


def read_at(requirement) -> str:
    """The fidelity `requirement` is read at: its own `fidelity`, else `"planetary"` for a
    vibration output (`VIBRATION_OUTPUTS`), else `"any"`."""
    if getattr(requirement, "fidelity", None) is not None:
        return requirement.fidelity
    # An end-of-life twin (`_eol`, `PointingObjective(life=...)`) is read where its output is.
    return "planetary" if requirement.output.removesuffix("_eol") in VIBRATION_OUTPUTS else "any"


def proxies(scene, fidelity: str) -> dict[str, str]:
    """The joints of `scene` modelled below `fidelity` (`{joint: its fidelity}`): every modelled
    (not ideal) joint that is not at `fidelity`, for `"planetary"` and `"planetary-scaled"`;
    none for `"any"` or `"lumped"`. An ideal joint models no clearance, so it is nobody's
    proxy: it stands for a joint whose play the requirement does not involve."""
    if fidelity in ("any", "lumped"):
        return {}
    rank = {"lumped": 1, "planetary-scaled": 2, "planetary": 3}
    return {joint: f for joint, f in joint_fidelities(scene).items() if f != "ideal" and rank.get(f, 0) < rank[fidelity]}


def check_fidelity(scene, requirements: Sequence, *, allow_proxy: bool = False, who: str = "propose_design",
                   remedy: str = "build the scene with those joints at that fidelity") -> list[str]:
    """Refuse (`ValueError`) requirements read at a fidelity the scene does not model: for each,
    the joints below it, the output and what to do. With `allow_proxy` nothing is refused and
    the same findings come back as sentences (for the report) instead."""
    findings = []
    for r in requirements:
        fidelity = read_at(r)
        if fidelity not in ("any",) + FIDELITIES[1:]:
            raise ValueError(f"{who}: the requirement {r.text()} is read at fidelity {fidelity!r}; one of 'any', "
                             f"{', '.join(repr(f) for f in FIDELITIES[1:])}.")
        below = proxies(scene, fidelity)
        if below:
            joints = ", ".join(f"the {joint} joint is {f}" for joint, f in below.items())
            findings.append(f"The requirement {r.text()} is read at {fidelity} fidelity, but {joints}: a proxy that does not "
                            f"read {r.name} as the full stage does (tolerax.design.fidelity: on paired units the cheaper "
                            "fidelities do not follow the full stage's vibration, unit by unit).")
    if findings and not allow_proxy:
        raise ValueError(f"{who}: " + " ".join(findings) + f" To design it: {remedy}; or allow the proxy knowingly "
                         "(allow_proxy=True, `--allow-proxy`).")
    return findings


def fidelity_agreement(full: np.ndarray, proxy: np.ndarray, *, confidence: float = 0.95) -> dict:
    """How a cheaper fidelity reads an output against the full stage on paired units (the same
    manufactured values simulated at both): `full`, `proxy` (n,) the output per unit.

    Returns the ratio of the means $\\bar p / \\bar f$ with its `confidence` interval (delta
    method over the paired units: $\\mathrm{var}(\\bar p - r \\bar f) / \\bar f^2$, Student t),
    the median of the unit-by-unit ratios, the correlation of the two over the units (does the
    proxy order the units as the full stage does), and n. Units where either is not finite are
    left out."""
    import scipy.stats

    full, proxy = np.asarray(full, dtype=float), np.asarray(proxy, dtype=float)
    ok = np.isfinite(full) & np.isfinite(proxy)
    f, p = full[ok], proxy[ok]
    n = int(f.size)
    if n < 3 or np.mean(f) == 0:
        return dict(n=n, ratio=float("nan"), interval=(float("nan"), float("nan")), median_ratio=float("nan"),
                    correlation=float("nan"))
    r = float(np.mean(p) / np.mean(f))
    se = float(np.std(p - r * f, ddof=1) / np.sqrt(n) / abs(np.mean(f)))
    t = float(scipy.stats.t.ppf(0.5 + confidence / 2, n - 1))
    corr = float(np.corrcoef(f, p)[0, 1]) if np.std(f) > 0 and np.std(p) > 0 else float("nan")
    return dict(n=n, ratio=r, interval=(r - t * se, r + t * se), median_ratio=float(np.median(p / f)), correlation=corr)
