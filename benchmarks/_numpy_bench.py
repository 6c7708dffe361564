"""The test bench's equations of motion written in plain NumPy, as a Python user without JAX would
write them for `scipy.integrate.solve_ivp`: the SciPy baseline of `work_precision.py`.

Same model as `tolerax.TestBench.vector_field` (docs/model.md §2-4; `tolerax.physics.planetary`): the stage in
Lin & Parker's coordinates with a fixed ring, clearance contacts at the sun, carrier and planet
pins (the paper's BaiZhao law), nonlinear meshes with time-varying stiffness, profile error and
dynamic backlash, smoothed with the stage's width, a PI speed servo on the sun and a smoothed drag
on the carrier. Every Jacobian is written out by hand (forward-mode chain rule on 15-vectors), not
taken from JAX; `work_precision.numpy_check` compares the two right-hand sides. Only the default bench's structure is
covered (fixed ring, clearance supports, nonlinear meshes, BaiZhao contacts, `SpeedServo`):
anything else raises.

State: the flattened `(q, qd, impact_rates)` of `TestBench.initial_state`, 15 + 15 + 5 numbers.
"""

import math

import numpy as np

import tolerax

DRAG_SPEED = 1e-3  # rad/s, tolerax.mechanism.drives
CLIP_WIDTH = 1e-3  # tolerax.physics.contact
FORCE_FLOOR = 1e-100


def _ramp(x, w):
    return w * np.logaddexp(0.0, x / w)


def _step(x, w):
    return 0.5 * (1.0 + np.tanh(0.5 * x / w))  # the logistic sigmoid, overflow-free


def numpy_rhs(bench):
    """`rhs(t, y) -> dy/dt` in NumPy for a default-structure `TestBench` (see the module docstring)."""
    st = bench.stage
    lay = st.layout
    if not (isinstance(bench.servo, tolerax.SpeedServo) and st.ring_support.kind == "rigid"
            and all(s.kind == "clearance" for n, s in st.supports() if n != "ring")
            and st.sun_mesh.kind == st.ring_mesh.kind == "nonlinear"
            and st.sun_mesh.dynamic_backlash and st.ring_mesh.dynamic_backlash
            and st.sun_torsion is None and st.carrier_torsion is None
            and isinstance(st.contact_law, tolerax.BaiZhao)):
        raise ValueError("numpy_rhs covers only the default bench structure (see its module docstring).")
    f = lambda x: np.asarray(x, dtype=float)  # noqa: E731
    N, n = st.n_planets, lay.size
    w = float(st.smoothing_width)
    psi = f(st.planet_angles)
    a_s, a_r = float(st.sun_pressure_angle), float(st.ring_pressure_angle)
    rs, rp, rc = float(st.sun_base_radius), float(st.planet_base_radius), float(st.carrier_radius)
    zs, zr = st.sun_teeth, st.ring_teeth
    ratio = st.ratio
    m_s, m_c = float(st.sun_mass), float(st.carrier_mass) + float(bench.load_mass)
    m_p = float(st.planet_mass)
    I_s = float(st.sun_inertia) + float(bench.motor_inertia)
    I_c = float(st.carrier_inertia) + float(bench.load_inertia)
    I_p = float(st.planet_inertia)
    kp, ki, omega = float(bench.servo.proportional), float(bench.servo.integral), float(bench.servo.output_rate)
    T_load = float(bench.load_torque)
    chi = float(st.contact_law.chi())
    floor, tau = float(st.impact_rate_floor), float(st.impact_memory_time)
    # Index map.
    TS, TC, TP = lay.sun_theta, lay.carrier_theta, np.arange(n)[lay.planet_theta]
    SXY, CXY = np.arange(n)[lay.sun_xy], np.arange(n)[lay.carrier_xy]
    PXY = np.arange(n)[lay.planet_xy].reshape(N, 2)
    e_r = np.stack([np.cos(psi), np.sin(psi)], -1)  # (N, 2)
    e_t = np.stack([-np.sin(psi), np.cos(psi)], -1)
    S = np.array([[0.0, -1.0], [1.0, 0.0]])  # d/dtheta R(theta) = R(theta) S
    # Mesh families: the sun meshes (external) and the ring meshes (internal), their constants.
    meshes = []
    for mesh, alpha, internal in ((st.sun_mesh, a_s, False), (st.ring_mesh, a_r, True)):
        m_eq = (I_p * float(st.sun_inertia) / (I_p * rs**2 + float(st.sun_inertia) * rp**2)) if not internal else I_p / rp**2
        meshes.append(dict(
            km=float(mesh.stiffness), eps=float(mesh.contact_ratio), xi=float(mesh.damping_ratio), m_eq=m_eq,
            b0=f(mesh.backlash), E=float(mesh.profile_error), phe=float(mesh.profile_phase), phk=f(mesh.stiffness_phase),
            alpha=alpha, internal=internal, cos0=rc * math.cos(alpha),
            inv0=math.tan(alpha) - alpha,
        ))
    # Contacts, in state order: sun, carrier, planets.
    bearings = [st.sun_support.bearing, st.carrier_support.bearing] + [st.planet_support.bearing] * N
    idx = [SXY, CXY] + [PXY[k] for k in range(N)]
    def per_contact(field):  # a bearing field per contact (the pins' may be per planet)
        return np.array([float(np.broadcast_to(getattr(b, field), (N,))[max(i - 2, 0)]) for i, b in enumerate(bearings)])

    clear, length, modulus = per_contact("clearance"), per_contact("length"), per_contact("modulus")
    nc = len(idx)
    # Constant mass-matrix pieces (sun, carrier, planet spins); the planets' translation is
    # added per call.
    M0 = np.zeros((n, n))
    M0[TS, TS], M0[TC, TC] = I_s, I_c
    M0[TP, TP] = I_p
    M0[SXY, SXY] = m_s
    M0[CXY, CXY] = m_c

    def rot(a):
        c, s = math.cos(a), math.sin(a)
        return np.array([[c, -s], [s, c]])

    def rhs(t, y):
        q, qd, v = y[:n], y[n:2 * n], y[2 * n:]
        th_s, th_c = q[TS], q[TC]
        R = rot(th_c)
        # ---- inertia: planet centres P = p_c + R l, l = (rc + zeta) e_r + eta e_t.
        zeta, eta = q[PXY[:, 0]], q[PXY[:, 1]]
        zd, ed = qd[PXY[:, 0]], qd[PXY[:, 1]]
        l = (rc + zeta)[:, None] * e_r + eta[:, None] * e_t  # (N, 2)
        ld = zd[:, None] * e_r + ed[:, None] * e_t
        M = M0.copy()
        bias = np.zeros(n)
        wc = qd[TC]
        for k in range(N):
            J = np.zeros((2, n))
            J[:, CXY] = np.eye(2)
            J[:, TC] = R @ S @ l[k]
            J[:, PXY[k, 0]] = R @ e_r[k]
            J[:, PXY[k, 1]] = R @ e_t[k]
            M += m_p * J.T @ J
            # Jdot qd = R S S l wc^2 + 2 R S ld wc = -R l wc^2 + 2 wc R S ld.
            acc = -R @ l[k] * wc**2 + 2.0 * wc * (R @ S @ ld[k])
            bias += m_p * J.T @ acc
        # ---- deflections with their gradients (value, d/dq).
        Rm = R.T  # carrier axes
        xs, gxs = Rm @ q[SXY], np.zeros((2, n))
        gxs[:, SXY] = Rm
        gxs[:, TC] = -S @ xs  # d(R(-th) x)/dth = -S R(-th) x
        xc, gxc = Rm @ q[CXY], np.zeros((2, n))
        gxc[:, CXY] = Rm
        gxc[:, TC] = -S @ xc
        zt = zeta + e_r @ xc  # planet displacement from its nominal place, carrier axes
        et = eta + e_t @ xc
        gzt, get = e_r @ gxc, e_t @ gxc  # (N, n)
        gzt[np.arange(N), PXY[:, 0]] += 1.0
        get[np.arange(N), PXY[:, 1]] += 1.0
        Q = np.zeros(n)
        for mesh in meshes:
            internal, alpha = mesh["internal"], mesh["alpha"]
            if not internal:
                lam = psi - alpha
                other, gother = xs, gxs
                g = (-xs[0] * np.sin(lam) + xs[1] * np.cos(lam) - zt * math.sin(alpha) - et * math.cos(alpha)
                     + rs * th_s + rp * q[TP] - rc * math.cos(alpha) * th_c)
                gg = (-np.outer(np.sin(lam), gxs[0]) + np.outer(np.cos(lam), gxs[1]) - math.sin(alpha) * gzt - math.cos(alpha) * get)
                gg[:, TS] += rs
                gg[np.arange(N), TP] += rp
                gg[:, TC] -= rc * math.cos(alpha)
                phase = zs * (th_s - th_c) + mesh["phk"]
                gphase = np.zeros(n)
                gphase[TS], gphase[TC] = zs, -zs
            else:
                other, gother = np.zeros(2), np.zeros((2, n))
                g = zt * math.sin(alpha) - et * math.cos(alpha) - rp * q[TP] - rc * math.cos(alpha) * th_c
                gg = math.sin(alpha) * gzt - math.cos(alpha) * get
                gg[np.arange(N), TP] -= rp
                gg[:, TC] -= rc * math.cos(alpha)
                phase = zr * th_c + mesh["phk"]
                gphase = np.zeros(n)
                gphase[TC] = zr
            # Profile error e(phase) and its gradient.
            err = mesh["E"] * np.sin(phase + mesh["phe"])
            gerr = (mesh["E"] * np.cos(phase + mesh["phe"]))[:, None] * gphase[None, :]
            # Dynamic backlash from the planet centre's distance to the other gear's centre.
            px = (rc + zt) * np.cos(psi) - et * np.sin(psi) - other[0]
            py = (rc + zt) * np.sin(psi) + et * np.cos(psi) - other[1]
            gpx = np.cos(psi)[:, None] * gzt - np.sin(psi)[:, None] * get - gother[0][None, :]
            gpy = np.sin(psi)[:, None] * gzt + np.cos(psi)[:, None] * get - gother[1][None, :]
            A = np.sqrt(px**2 + py**2)
            gA = (px[:, None] * gpx + py[:, None] * gpy) / A[:, None]
            cos0 = mesh["cos0"]
            arg = cos0 / np.maximum(A, cos0)
            live = (A > cos0) & (arg < 1.0 - 1e-12)
            arg = np.clip(arg, -1.0, 1.0 - 1e-12)
            ap = np.arccos(arg)
            change = 2.0 * cos0 * (np.tan(ap) - ap - mesh["inv0"])
            # d inv(a')/dA = tan^2(a') da'/dA, da'/dA = cos0 / (A^2 sin a') (zero where clipped).
            dchange = np.where(live, 2.0 * cos0 * np.tan(ap) ** 2 * cos0 / (A**2 * np.sin(ap)), 0.0)
            sgn = -1.0 if internal else 1.0
            b = mesh["b0"] + sgn * change + err
            gb = sgn * dchange[:, None] * gA + gerr
            h, gh = g + b, gg + gb
            gdot, hdot = gg @ qd, gh @ qd
            k = mesh["km"] * (1.0 + (mesh["eps"] - 1.0) * np.cos(phase))
            d = 2.0 * mesh["xi"] * np.sqrt(mesh["m_eq"] * k)
            f_drive = k * _ramp(g, w) + d * _step(g, w) * gdot
            f_back = -k * _ramp(-h, w) + d * _step(-h, w) * hdot
            Q -= f_drive @ gg + f_back @ gh
        # ---- clearance contacts: e is a plain slice of q (housing axes for the sun and
        # carrier, carrier axes for the pins), so its Jacobian is a selection.
        e = np.stack([q[i] for i in idx])
        edot = np.stack([qd[i] for i in idx])
        r = np.sqrt(np.sum(e * e, 1) + w * w)
        normal = e / r[:, None]
        gap = r - clear
        pen = _ramp(gap, w)
        rate = np.sum(normal * edot, 1)
        pd = np.maximum(pen, 0.0)
        f_el = length * 0.5 * math.pi * modulus * pd**1.5 / np.sqrt(2.0 * (clear + pd))  # BaiZhao
        v_eff = floor + _ramp(v - floor, 0.1 * floor)
        total = f_el * _step(gap, w) * (1.0 + chi * rate / v_eff)
        alive = f_el > FORCE_FLOOR
        clip = CLIP_WIDTH * np.where(alive, f_el, 1.0)
        F = np.where(alive, _ramp(np.where(alive, total, 0.0), clip), 0.0)
        for c in range(nc):
            Q[idx[c]] -= F[c] * normal[c]
        # ---- drive and load.
        Q[TS] += kp * (ratio * omega - qd[TS]) + ki * (ratio * omega * t - th_s)
        Q[TC] -= T_load * np.tanh(qd[TC] / DRAG_SPEED)
        qdd = np.linalg.solve(M, Q - bias)
        # ---- impact-rate memory: delta_ddot = ndot . edot + n . eddot, eddot = a slice of qdd.
        eddot = np.stack([qdd[i] for i in idx])
        ndot = edot / r[:, None] - e * (np.sum(e * edot, 1) / r**3)[:, None]
        rate_dot = np.sum(ndot * edot, 1) + np.sum(normal * eddot, 1)
        vd = (1.0 - _step(gap, w)) * (rate_dot + (rate - v) / tau)
        return np.concatenate([qd, qdd, vd])

    return rhs
