"""The least-squares problem `tolerax.identification.identify` solves: the residual of a
recording against the model at the parameters $x$ (`_Fit`, µrad), its Jacobian (forward mode
through the solve, or central secants where the forward-mode one is not the residual's:
`_choose_jacobian`), the bounded Levenberg-Marquardt solve and Gauss-Newton polish on
optimistix, the screen of starts, the relative Fisher information and the intervals' check
along their profiles. Each program is module-level and takes the problem's data as arrays: one
compilation per scene structure and parameter names, whichever recording, start or width."""

import dataclasses
import math
from collections.abc import Callable

import diffrax
import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import optimistix as optx

from .._linearise import secant_once
from ..design.features import design_of
from ..design.objectives import PointingObjective
from .parameters import with_parameters
from .result import PROFILE_STEPS, interval_holds

UNIT = 1e-6  # rad: the residual's unit (µrad); features in µm inside the solve
# Levenberg-Marquardt's relative and absolute tolerance on the step (log µm, log of the scene's
# value); it stops where an accepted step moves the parameters less than that and changes no
# residual by more than RESIDUAL_TOL (1 + |r|) µrad (`_termination_norm`). A finer residual
# tolerance is below the adaptive solve's own noise in the residual: at the cost floor every
# further step is rejected on that noise and the solve runs to its step limit for no gain
# (measured in benchmarks/identify_wall_time.py). The estimate is then checked to a tenth of a
# standard error and polished where it is not (`identify`).
LM_TOL = 1e-4
RESIDUAL_TOL = 0.2
# Each parameter is kept within this factor of the scene's value either side (`_bounded`): an
# undetermined one would otherwise walk off to where the model is not physical (a stiffness of 1e51 N/m).
BOUND = 100.0
# The Gauss-Newton polish after it (`_polish`): steps and tolerance.
POLISH_STEPS, POLISH_TOL = 3, 1e-7
# Of the screened starts (`_starts`), Levenberg-Marquardt runs from this many of the lowest cost.
STARTS_KEPT = 2
# The Jacobian where the forward-mode one is not the residual's (`identify(secant=...)`): central
# secants at a relative step of SECANT_STEP in each parameter (2 %: wide against the
# trajectory's sensitivity to a perturbation through the impacts, narrow against the residual's
# curvature in a clearance), chosen
# automatically where the forward-mode Jacobian at the first start differs from the secants by
# more than SECANT_SWITCH of their norm (on the full planetary stage by orders of magnitude: the
# rattle scrambles the tangents; on the lumped joint they agree to the step's truncation error).
SECANT_STEP, SECANT_SWITCH = 0.02, 0.5
# The model's own realisations at the estimate (`_model_noise`): at least REALISATIONS points
# (those filling the intervals' check's batch) a relative REALISE from it (1e-9: its
# linearised effect ~1e-9 of a parameter's, far below what the simulation resolves; a
# rounding-level difference in a rattling stage's run changes its impacts all the same), or
# REALISATIONS_ALONE where the check runs one point at a time. The check reads a rise only where
# it exceeds COST_NOISE times the cost's spread between two realisations.
REALISATIONS, REALISATIONS_ALONE, REALISE = 16, 8, 1e-9
COST_NOISE = 2.0


class _Fit(eqx.Module):
    """The residual of `identify`: the model's output angles at the recording's saves (`rows`)
    and axes (`columns`) with the parameters `names` at `scale * x` (SI units) over `measured`
    (rad), in µrad; then, where the recording has the motor torque of `torque_axes`, the model's
    (`AbstractJoint.motor_torque`, N m) over `torque_measured`, times `torque_weight` (µrad per
    N m: the encoder's noise over the torque's, so that both parts carry the same noise)."""

    objective: PointingObjective
    names: tuple[str, ...] = eqx.field(static=True)
    scale: jax.Array
    rows: jax.Array
    columns: jax.Array
    measured: jax.Array
    # None: the Jacobian of forward mode through the solve; a step h: central secants at a
    # relative step h in each parameter (`SECANT_STEP`), static (a program per choice).
    secant: float | None = eqx.field(static=True, default=None)
    torque_axes: tuple[str, ...] = eqx.field(static=True, default=())
    torque_measured: jax.Array | None = None
    torque_weight: jax.Array | None = None

    def run(self, x, width):
        scene = with_parameters(self.objective.scene, self.names, self.scale * x)
        return eqx.tree_at(lambda o: o.scene, self.objective, scene).run(design_of(scene), width)

    def outputs(self, x, width):
        """`(residual, (model angles, commanded angles))` at `x`: the residual (µrad) and, from
        the same solve, the model's output and commanded angles (rad) at the fitted saves."""
        res = self.run(x, width)
        ok = res.result == diffrax.RESULTS.successful
        angles = jnp.where(ok, res.joint_angle[self.rows][:, self.columns], jnp.nan)
        residual = jnp.where(ok, (angles - self.measured) / UNIT, 1e6).ravel()
        if self.torque_axes:
            scene, (q, u) = with_parameters(self.objective.scene, self.names, self.scale * x), res.states[:2]
            torque = jax.vmap(lambda qi, ui, ti: _motor_torques(scene, qi, ui, ti, self.torque_axes))(
                q[self.rows], u[self.rows], res.ts[self.rows])
            residual = jnp.concatenate([residual, jnp.where(ok, (torque - self.torque_measured) * self.torque_weight, 1e6).ravel()])
        return residual, (angles, res.commanded_angle[self.rows][:, self.columns])

    def residual(self, x, width):
        return self.outputs(x, width)[0]


def _motor_torques(scene, q, u, t, axes):
    """The motor torque (N m) of each joint in `axes` of `scene` (a `Mechanism`) at coordinates
    `q`, speeds `u`, time `t` (`AbstractJoint.motor_torque`)."""
    joints = dict(zip(scene.JOINTS, scene.joints()))
    return jnp.stack([joints[a][0].motor_torque(q[joints[a][1]], u[joints[a][2]], t) for a in axes])


def _bounded_residual(w, fit: "_Fit", width, centre, reach):
    """The residual (µrad) at the optimiser's variable `w` (`_bounded`)."""
    return fit.residual(_bounded(w, centre, reach), width)


def _residual_in_w(fit: "_Fit"):
    """`_bounded_residual`, linearised by central secants in `w` (a step `fit.secant` in the
    logarithm of each parameter: relative) where the fit asks for them, else by forward mode."""
    return _bounded_residual if fit.secant is None else secant_once(_bounded_residual, fit.secant)


@eqx.filter_jit
def _polish(fit: "_Fit", w0, width, centre, reach):
    """A few Gauss-Newton steps (optimistix) at a tolerance finer than `LM_TOL` from
    Levenberg-Marquardt's estimate `w0`: LM stops within its tolerance of the minimum, about
    half a standard error for a parameter the recording determines to 1e-4. (solution, cost)."""
    residual = _residual_in_w(fit)
    fn = lambda w, width: residual(w, fit, width, centre, reach)  # noqa: E731
    sol = optx.least_squares(fn, optx.GaussNewton(rtol=POLISH_TOL, atol=POLISH_TOL), w0, args=width, max_steps=POLISH_STEPS,
                             throw=False)
    return sol.value, jnp.sum(fn(sol.value, width) ** 2)


def _profile(fit: "_Fit", x, limits, cov_x, s2, width, batch: int | None, residual) -> tuple:
    """The linearised intervals checked against the residual itself, and the model's own
    realisations at `x` (`_model_noise`).

    The check: for each parameter $j$ the cost at $x \\pm k\\,\\Sigma e_j / \\sigma_j$ (the
    linearised profile path: the other parameters at their conditional best, where the linearised
    cost rises by exactly $k^2 s^2$) for $k$ in `PROFILE_STEPS`, as its rise over $k^2 s^2$: 1
    where the cost is quadratic out to there; NaN where a point would leave the bounds (`limits`:
    the lower and upper ends, x's units, (2, p)), the
    standard error is not finite, or the rise $k^2 s^2$ is below `COST_NOISE` times the cost's
    own spread over the model's realisations (the difference of two: a rise the model cannot
    reproduce is not a measurement of the residual's shape).

    Costed in batches of `batch` (the screen's: its compiled program), the realisations
    (`_realisation_points`, at least `REALISATIONS`) filling the batch's rest, or where no screen
    ran (`batch` None) one point at a time through `_fit_and_jacobian` (compiled for the
    assessment already: no program compiled for the check), `REALISATIONS_ALONE` of them, against
    `residual`, the assessment's own at `x` from that program (µrad).

    The same rise is read along each parameter's own line ($x \\pm k\\,\\sigma_j e_j$, the others
    held at the estimate) at the first two steps: any choice of the others costs at least the
    profile's, so where either path's cost stays low the profile's does too (`line`, read by
    `Identification.one_sided`). In a batch those points ride in its padding; one at a time they
    are costed only for a parameter whose path check failed.

    Returns `(ratios (parameters, 2 sides, steps), line ratios (parameters, 2 sides, 2 steps),
    realisations' x (k, p), their residuals (k, n))`."""
    se = np.sqrt(np.maximum(np.diag(cov_x), 0.0))
    ratio = np.full((x.size, 2, len(PROFILE_STEPS)), np.nan)
    line = np.full((x.size, 2, 2), np.nan)
    checked = math.isfinite(s2) and s2 > 0  # a residual of exactly zero: no scale to check against
    usable = [j for j in range(x.size if checked else 0) if np.isfinite(se[j]) and se[j] > 0]

    def steps(js, along):  # (point, (table, j, side, m, k)) for the parameters js, inside the bounds
        for j in js:
            for side, sign in enumerate((-1.0, 1.0)):
                for m, k in enumerate(PROFILE_STEPS if along == "path" else PROFILE_STEPS[:2]):
                    point = x + sign * k * (cov_x[:, j] / se[j] if along == "path" else se[j] * np.eye(x.size)[j])
                    if np.all(point > limits[0]) and np.all(point < limits[1]):
                        yield point, (ratio if along == "path" else line, j, side, m, k)

    checks = list(steps(usable, "path")) + (list(steps(usable, "line")) if batch is not None else [])
    points, where = [x, *(p for p, _ in checks)], [w for _, w in checks]
    if batch is None:
        realised = _realisation_points(x, REALISATIONS_ALONE)
        residuals = np.stack([np.asarray(residual)] + [np.asarray(_fit_and_jacobian(fit, jnp.asarray(p), width)[3])
                                                       for p in (*points[1:], *realised)])
    else:
        k = max(REALISATIONS, -len(points) % batch)
        realised = _realisation_points(x, k + -(len(points) + k) % batch)
        table = np.vstack([*points, realised])
        residuals = _in_batches(fit, table, width, batch)
    costs = np.sum(residuals**2, axis=1)  # [0]: x's, the assessment's own (batch None) or in the batch's program
    spread = math.sqrt(2.0) * float(np.std(np.concatenate([costs[:1], costs[len(points):]]), ddof=1))  # between two realisations

    def read(where_, costs_):
        for (table_, j, side, m, k), c in zip(where_, costs_):
            if k * k * s2 >= COST_NOISE * spread:
                table_[j, side, m] = (c - costs[0]) / (k * k * s2)

    read(where, costs[1:len(points)])
    if batch is None:  # the lines one point at a time, only where the path's check failed
        failed = [j for j in usable if interval_holds(ratio[j]) is False]
        more = list(steps(failed, "line"))
        read([w for _, w in more], [float(np.sum(np.asarray(_fit_and_jacobian(fit, jnp.asarray(p), width)[3]) ** 2))
                                   for p, _ in more])
        return ratio, line, realised, residuals[len(points):]  # x's residual is the assessment's own: its step the 0 `_model_noise` counts
    # x in the batch's program: one more realisation beside the assessment's
    return ratio, line, np.vstack([x[None], realised]), np.vstack([residuals[:1], residuals[len(points):]])


def _realisation_points(x, k: int) -> np.ndarray:
    """`k` points a relative `REALISE` from `x` in fixed pseudo-random directions: the model's
    output moves by its linearisation there, ~1e-9 of a parameter's effect, unless the run does
    not reproduce itself (`_model_noise`)."""
    return x[None, :] * (1.0 + REALISE * np.random.default_rng(0).standard_normal((k, x.size)))


def _model_noise(jac, x, residual, points, realised, cov_x, s2) -> tuple[np.ndarray, float]:
    """The estimate's covariance from the model's own irreproducibility, and its size in the
    residual (µrad RMS).

    At `points` (`_realisation_points` about the estimate `x`, and where it was costed in
    another program, `x` itself) the model's residuals `realised` differ from the assessment's
    `residual` by their linearisation $J\\,\\delta x$ (~1e-9 of the parameters' effect) plus
    whatever the run does not reproduce: through a rattling stage a perturbation at rounding
    level changes which impacts happen where a contact grazes (a float-level difference
    between two compiled programs of the same model does the same). Each such difference
    $d_k$ moves the least-squares estimate by $\\Delta_k = -(J^TJ)^{-1}J^T d_k$; the recording is
    one realisation and the fit another, so the estimate's error from them has the covariance
    of the difference of two: $2\\,\\mathrm{Cov}_k(\\Delta_k)$ (over the $\\Delta_k$ and the
    assessment's own, 0). A recording of the model itself is one such realisation; a real
    unit's is not, and the model's error against the physics is not in this term. Zero to
    rounding where the runs reproduce themselves (the lumped joint); `cov_x` is
    $s^2 (J^TJ)^{-1}$ (`_information`). Realisations whose run failed (the residual's 1e6) are
    left out."""
    keep = np.all(np.abs(realised) < 1e5, axis=1)
    d = realised[keep] - residual[None, :] - (points[keep] - x[None, :]) @ jac.T
    if d.shape[0] < 2 or not np.all(np.isfinite(cov_x)):
        return np.zeros_like(cov_x), 0.0
    shifts = -(d @ jac) @ (cov_x / s2)
    return 2.0 * np.atleast_2d(np.cov(np.vstack([np.zeros(x.size), shifts]), rowvar=False)), float(np.sqrt(np.mean(d**2)))


def _unbounded(x, centre, reach):
    """The optimiser's variable at `x` (`_bounded`'s inverse; `x` inside the bounds)."""
    return reach * np.arctanh(np.clip((np.log(x) - centre) / reach, -1 + 1e-12, 1 - 1e-12))


@eqx.filter_jit
def _residuals(fit: "_Fit", points, width):
    """The residual (µrad) at each row of `points` (x), in one batched run: `(rows, residuals)`."""
    return eqx.filter_vmap(lambda v: fit.residual(v, width))(points)


def _in_batches(fit: "_Fit", points, width, batch: int) -> np.ndarray:
    """`_residuals` at the rows of `points`, `batch` at a time (a whole number of batches: the
    screen's compiled program each time)."""
    return np.concatenate([np.asarray(_residuals(fit, jnp.asarray(points[i:i + batch]), width)) for i in range(0, len(points), batch)])


def _costs(fit: "_Fit", points, width) -> np.ndarray:
    """$\\lVert r\\rVert^2$ (µrad²) at each row of `points` (x), in one batched run (`_residuals`)."""
    return np.sum(np.asarray(_residuals(fit, points, width)) ** 2, axis=1)


def _starts(fit, x0, width, starts, search: float, limits):
    """The Levenberg-Marquardt starts (x): `starts` multiples of `x0` as given, or (an int) the
    `STARTS_KEPT` lowest-cost of `starts` points of a scrambled Sobol sequence over the box
    $[x_0/s, s\\,x_0]$ (log-uniform, $s$ = `search`; moved inside the bounds `limits`, (2, p)) and
    `x0` itself, costed against the recording in one batched run at the scene's width. Returns
    `(starts, screened)`, `screened` the number of points costed (0 where the starts were given)."""
    if isinstance(starts, int):
        from scipy.stats import qmc

        if starts < 1 or not 1 < search < BOUND:
            raise ValueError(f"identify: starts={starts!r} must be >= 1 and search={search!r} in (1, {BOUND:g}).")
        unit = qmc.Sobol(len(x0), scramble=True, seed=0).random(starts)
        points = np.vstack([x0, inside(x0 * search ** (2 * unit - 1), limits)])
        cost = np.asarray(_costs(fit, jnp.asarray(points), width))
        cost = np.where(np.isfinite(cost), cost, np.inf)
        return points[np.argsort(cost)[:STARTS_KEPT]], len(points)
    out = []
    for factor in starts:
        if not np.all((limits[0] < x0 * float(factor)) & (x0 * float(factor) < limits[1])):
            raise ValueError(f"identify: a start {factor!r} times the scene's values is outside the bounds (a factor {BOUND:g} "
                             "either side of the scene's values, or those given): start nearer.")
        out.append(x0 * float(factor))
    return out, 0


def limits_of(names, x0, scale, bounds) -> np.ndarray:
    """The fit's bounds in x (the parameters over `scale`), `(2, p)`: each parameter's
    `bounds[name]` (`(low, high)`, its SI unit: m for a clearance), else a factor `BOUND` either
    side of its scene's value `x0`. `ValueError` for a name not identified, bounds that are not
    0 < low < high (finite), or a scene's value outside its bounds (it is the first start)."""
    bounds = dict(bounds or {})
    unknown = sorted(set(bounds) - set(names))
    if unknown:
        raise ValueError(f"identify: bounds for {', '.join(unknown)}, which is not identified here (the parameters: "
                         f"{', '.join(names)}).")
    out = np.stack([x0 / BOUND, x0 * BOUND])
    for j, name in enumerate(names):
        if name not in bounds:
            continue
        low, high = (float(v) for v in bounds[name])
        if not (0 < low < high < math.inf):
            raise ValueError(f"identify: the bounds of {name} must be 0 < low < high, finite (its SI unit: m for a clearance), "
                             f"got ({low!r}, {high!r}).")
        out[:, j] = low / scale[j], high / scale[j]
        if not out[0, j] < x0[j] < out[1, j]:
            raise ValueError(f"identify: the scene's value of {name} ({x0[j] * scale[j]:.6g}, SI) lies outside its bounds "
                             f"({low:.6g}, {high:.6g}): it is the first start; give the scene a value inside them.")
    return out


def centre_reach(limits, x0) -> tuple[np.ndarray, np.ndarray]:
    """`_bounded`'s centre and reach for the bounds `limits` ((2, p)): their geometric middle
    and half their span, in the logarithm; for a parameter at the default bounds (a factor
    `BOUND` of its scene's value `x0`) $\\log x_0$ and $\\log$ `BOUND` as such (the same to the
    last bit: a fit on a flat cost ends where rounding sends it)."""
    limits, x0 = np.asarray(limits, dtype=float), np.asarray(x0, dtype=float)
    logs = np.log(limits)
    default = (limits[0] == x0 / BOUND) & (limits[1] == x0 * BOUND)
    return (np.where(default, np.log(x0), logs.mean(axis=0)),
            np.where(default, math.log(BOUND), 0.5 * (logs[1] - logs[0])))


def inside(points, limits):
    """`points` (x, (k, p)) moved inside the open bounds `limits` ((2, p)), by a relative 1e-9."""
    return np.clip(points, limits[0] * (1 + 1e-9), limits[1] * (1 - 1e-9))


def at_bound(x, step, se, limits) -> tuple[str | None, ...]:
    """Per parameter, `"lower"` or `"upper"` where the estimate `x` stopped at that bound of
    `limits` ((2, p)): it lies within one standard error `se` of it and the Gauss-Newton step
    `step` from it (all in x's units) points past it, so the residual's local quadratic has its
    minimum beyond the bound (the recording asks for a value the bounds exclude); else None."""
    out = []
    for j, (v, s, e) in enumerate(zip(x, step, se)):
        near = [abs(v - limits[k, j]) < e for k in (0, 1)]
        past = [v + s < limits[0, j], v + s > limits[1, j]]
        out.append(next((side for side, n, p in zip(("lower", "upper"), near, past) if n and p and np.isfinite(s)), None))
    return tuple(out)


def _bounded(w, centre, reach):
    """x from the optimiser's unbounded variable `w`: $\\log x = c + R\\tanh(w/R)$, inside a factor
    $e^R$ either side of $e^c$, the bounds' geometric middle (`limits_of`); $w = \\log x - c$ near
    the centre."""
    return jnp.exp(centre + reach * jnp.tanh(w / reach))


def _termination_norm(tree):
    """The norm of Levenberg-Marquardt's Cauchy termination (optimistix's `norm`: it measures the
    step in the parameters and the change in the residual, each divided by `LM_TOL` (1 + |.|)):
    the max norm, the residual's (the `{"residual": r}` of `_solve`) read at `RESIDUAL_TOL`."""
    return optx.max_norm(tree) * (LM_TOL / RESIDUAL_TOL if isinstance(tree, dict) else 1.0)


class _FirstDamping(optx.AbstractSearch):
    """optimistix's classical trust region (`optx.ClassicalTrustRegion`: the step size x3.5
    after a good step, x0.25 after a rejected one), its first step size `first` in place of 1.
    Levenberg-Marquardt's damping is $\\lambda$ = 1 / step size, against the curvature $J^TJ$ in
    the residual's units (µrad² per unit of log x squared: the noise variance over the squared
    relative standard error, ~1e6-1e7 for a clearance a recording determines to 0.1 %), so a
    first damping of 1 is no damping, and each rejection raises it fourfold only (a dozen
    rejections to reach the curvature's scale)."""

    inner: optx.ClassicalTrustRegion
    first: jax.Array

    def init(self, y, f_info_struct):
        return eqx.tree_at(lambda s: s.step_size, self.inner.init(y, f_info_struct), self.first)

    def step(self, first_step, y, y_eval, f_info, f_eval_info, state):
        return self.inner.step(first_step, y, y_eval, f_info, f_eval_info, state)


def _quiet(**_):
    """No step-by-step log (optimistix's `verbose=False`)."""


class _LevenbergMarquardt(optx.AbstractGaussNewton):
    """`optx.LevenbergMarquardt` (the damped Newton descent in its trust region), its first
    damping Marquardt's: $\\lambda_0 = \\tau \\max_j (J^TJ)_{jj}$ at the start, $\\tau$ =
    `DAMPING` (Madsen, Nielsen & Tingleff, *Methods for non-linear least squares problems*,
    DTU 2004, eq. 3.14), so that it starts on the residual's own scale."""

    rtol: float
    atol: float
    norm: Callable
    descent: optx.DampedNewtonDescent
    search: _FirstDamping
    verbose: Callable = _quiet  # optimistix's hook for a step-by-step log


# Marquardt's tau: the first damping as a fraction of the largest diagonal of J^TJ (`_LevenbergMarquardt`).
DAMPING = 1e-3


@eqx.filter_jit
def _solve(fit: _Fit, w0, width, max_steps: int, centre, reach):
    """Levenberg-Marquardt on `w` (`_bounded`) from `w0`: (solution, cost, steps, converged)."""
    residual = _residual_in_w(fit)
    fn = lambda w, width: {"residual": residual(w, fit, width, centre, reach)}  # noqa: E731
    curvature = jnp.sum(jax.jacfwd(lambda w: fn(w, width)["residual"])(w0) ** 2, axis=0)  # diag(J^TJ) at the start
    first = 1.0 / (DAMPING * jnp.maximum(jnp.max(jnp.where(jnp.isfinite(curvature), curvature, 0.0)), 1e-12))
    solver = _LevenbergMarquardt(rtol=LM_TOL, atol=LM_TOL, norm=_termination_norm, descent=optx.DampedNewtonDescent(),
                                 search=_FirstDamping(optx.ClassicalTrustRegion(), first))
    sol = optx.least_squares(fn, solver, w0, args=width, max_steps=max_steps, throw=False)
    return sol.value, jnp.sum(fn(sol.value, width)["residual"] ** 2), sol.stats["num_steps"], sol.result == optx.RESULTS.successful


@eqx.filter_jit
def _fit_and_jacobian(fit: _Fit, x, width):
    """The residual's Jacobian (µrad per unit of x), the fitted angles and the scene's commanded
    angles (rad) and the residual (µrad) at `x`: from one forward-mode solve (the angles are its
    primal), or where the fit takes secants (`_Fit.secant`) from one batched run of `x` and the
    central secants at $x\\,e^{\\pm h}$ in each parameter."""
    if fit.secant is None:
        jac, (residual, (angles, commanded)) = jax.jacfwd(lambda v: (lambda r, aux: (r, (r, aux)))(*fit.outputs(v, width)),
                                                          has_aux=True)(x)
        return jac, angles, commanded, residual
    points, span = _secant_points(x, fit.secant)
    residuals, (angles, commanded) = jax.vmap(lambda v: fit.outputs(v, width))(jnp.concatenate([x[None], points]))
    return _central(residuals[1:], span), angles[0], commanded[0], residuals[0]


def _secant_points(x, h: float):
    """The $2n$ points $x\\,e^{\\pm h}$ along each parameter of `x` (shape `(n,)`; first the $n$
    raised, then the $n$ lowered: relative steps, the parameters' scales differ by orders of
    magnitude) and each pair's span $x_j(e^h - e^{-h})$."""
    n = x.shape[0]
    return x[None] * jnp.exp(h * jnp.concatenate([jnp.eye(n), -jnp.eye(n)])), x * (math.exp(h) - math.exp(-h))


def _central(values, span):
    """The central secants (one column per parameter) from `values` at `_secant_points`' $2n$
    points (leading axis) and their spans."""
    n = span.shape[0]
    return (values[:n] - values[n:]).reshape(n, -1).T / span[None, :]


def _choose_jacobian(fit: _Fit, x, width, secant) -> tuple[_Fit, str]:
    """The fit with the residual's Jacobian `identify(secant=...)` asks for, and that choice in
    words: where it is automatic (`None`), the forward-mode Jacobian and the central secants at
    `x` (the first start) compared, secants taken where they differ by more than `SECANT_SWITCH`
    (or cannot be compared: a run that failed)."""
    if secant is False:
        return fit, "forward mode through the solve (as asked)"
    if secant is not None:
        if not (isinstance(secant, (int, float)) and not isinstance(secant, bool) and 0 < secant < 1):
            raise ValueError(f"identify: secant={secant!r} must be None (chosen), False (forward mode) or a relative step in "
                             "(0, 1), e.g. 0.02.")
        return dataclasses.replace(fit, secant=float(secant)), f"central secants at ±{100 * secant:g} % of each parameter (as asked)"
    secants = dataclasses.replace(fit, secant=SECANT_STEP)
    # Both from the forward-mode program (compiled for the assessment in any case): its
    # Jacobian at x and its primal, the residual, at x e^(+-h) along each parameter.
    x = np.asarray(x, dtype=float)
    forward = np.asarray(_fit_and_jacobian(fit, jnp.asarray(x), width)[0])
    points, span = _secant_points(jnp.asarray(x), SECANT_STEP)
    residuals = np.stack([np.asarray(_fit_and_jacobian(fit, point, width)[3]) for point in points])
    central = np.asarray(_central(residuals, span))
    scale = float(np.linalg.norm(central))
    differs = float(np.linalg.norm(forward - central)) / scale if scale > 0 else math.inf
    if np.isfinite(differs) and differs <= SECANT_SWITCH:
        return fit, f"forward mode through the solve (within {differs:.2g} of the central secants at the first start)"
    return secants, (f"central secants at ±{100 * SECANT_STEP:g} % of each parameter: the forward-mode Jacobian at the first "
                     f"start differs from them by {differs:.3g} of their norm (through a rattling stage the trajectory's "
                     "tangents grow with the impacts' sensitivity, while the trajectory moves smoothly with a clearance)")


def _information(jac, x, s2):
    """The relative Fisher information $D J^TJ D / s^2$ ($D$ = `x`, the values the Jacobian
    `jac` is taken at, in its units) in its eigenvectors, and the covariance of `x`:
    `(scaled Jacobian, (eigenvalues, eigenvectors), covariance)`. A direction the recording does
    not see has an eigenvalue at rounding level: floored there, its variance is huge, not
    dropped (a pseudo-inverse would drop it and report the parameters that load on it as sharply
    determined)."""
    scaled = jac * x[None, :]
    values, vectors = np.linalg.eigh(scaled.T @ scaled / s2)
    if not float(values.max()) > 1e-200:  # the recording sees none of them (no reversal, a joint that does not move)
        return scaled, (np.full_like(values, 1e-200), vectors), np.full((x.size, x.size), np.inf)
    values = np.maximum(values, float(values.max()) * 1e-15)
    return scaled, (values, vectors), x[:, None] * ((vectors / values) @ vectors.T) * x[None, :]
