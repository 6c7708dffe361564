"""The dual-axis antenna pointing mechanism (docs/model.md §5): spacecraft body → azimuth joint →
link 1 → pitch joint → link 2 → reflector, with a fidelity choice per joint.

**Formulation.** Minimal coordinates and Kane's equations. Every rigid body's pose (centre
$p_b$, rotation $R_b$, world frame) is a function of the generalised coordinates $q$ and time
(prescribed ideal joints). With generalised speeds $u$ ($\\dot q = N(q)u$: the identity except
for the base quaternion), body twists are $v_b = J_b u + \\partial_t p_b$ and
$\\omega_b = J^\\omega_b u + \\ldots$. The Jacobians and the accelerations are propagated
down the chain frame by frame (`Mechanism.kinematics`: constant blocks for the base, rigid
offsets, each joint's planar motion in its housing from autodiff of its few coordinates), not
by differentiating the whole chain over all speeds. Then
$$M(q)\\dot u = Q - \\sum_b J_b^T m_b a_b^0 - \\sum_b J_b^{\\omega T}(I_b\\alpha^0_b + \\omega_b\\times I_b\\omega_b),$$
$M = \\sum_b m_bJ_b^TJ_b + J^{\\omega T}_bI_bJ^\\omega_b$, and $a^0_b, \\alpha^0_b$ the
accelerations at $\\dot u = 0$. $M\\dot u = f$ is solved by blocks: a speed that moves
one body alone (a gear's spin and its translations in its bearing) couples only with that
body's own speeds and the speeds it rides on, so those are eliminated body by body (small
Cholesky factorisations) and the shared speeds (base, carriers) solved from their Schur
complement, one more Cholesky: the same equations, a fraction of the dense product's work
(`tolerax.mechanism.blocks`; tests/_kane_reference.py keeps a `jacfwd` formulation the
equivalence tests compare against). Nothing is linearised: the gears spin inside a
housing that turns (gyroscopic terms included), and the base reacts. Internal forces (meshes,
contacts, servo and drive torques, drag) act on *relative* coordinates, so with a free base and
no external load linear and angular momentum are conserved exactly by the equations (a test).

**Bodies and default geometry**: `tolerax.mechanism.structure` (its docstring draws the chain).

**Joint fidelity** per joint is its class (`IdealJoint`, `LumpedJoint`, `PlanetaryJoint`,
`MassScaledPlanetaryJoint`, see `tolerax.mechanism.joints`); the mechanism asks each joint for its coordinates,
bodies, forces, contacts and any inertia added on its own speeds.
"""

import dataclasses
from typing import ClassVar
from collections.abc import Iterator

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
from . import loaded as _loaded, outputs as _outputs
from .blocks import KaneBlocks, block_solve, partition  # noqa: F401 (KaneBlocks: the return type named)
from .joints import AbstractJoint
from .stage_joints import PlanetaryJoint
from ..physics.rigid import PITCH_HOUSING, planar_to_world, quat_matrix, quat_rate, rz, small_einsum, vee, world_inertia
from .structure import Geometry, Inertias, MechanismLayout
from .kinematics import Frames, base_frame, offset, planar_frames, planar_motion, take
from .scene import AbstractScene
from ..solve import ACCURATE


BASES = ("free", "fixed")
MASS_SOLVES = ("blocks", "whole")


class Mechanism(AbstractScene):
    """The antenna pointing mechanism: two joints (any `AbstractJoint`: the fidelity is the
    joint's class), geometry, inertias and the base (static: `"free"` floating, 6 DOF, the
    on-orbit case; or `"fixed"`, a ground test stand). Build the paper's scenes with `antenna`.

    `mass_solve` (static): `"blocks"` (the default) solves the equations of motion by blocks
    (`kane_blocks`); `"whole"` forms the whole mass matrix and factorises it (the same
    equations to rounding; kept for the benchmarks that compare the two). It
    is static: build a new `Mechanism(...)` to change it (`eqx.tree_at` cannot)."""

    azimuth: AbstractJoint
    pitch: AbstractJoint
    geometry: Geometry
    inertias: Inertias
    base: str = eqx.field(static=True)
    mass_solve: str = eqx.field(static=True)
    _what = "mechanism"
    # The joints' names (the fields above), base to reflector: what everything outside the
    # mechanism reads instead of naming them (`named_joints`, `named_stages`).
    JOINTS: ClassVar[tuple[str, ...]] = ("azimuth", "pitch")

    def __init__(self, azimuth=None, pitch=None, geometry=None, inertias=None, base="free", *, mass_solve="blocks"):
        if base not in BASES:
            raise ValueError(f"base={base!r} is unknown; use 'free' (floating spacecraft) or 'fixed'.")
        if mass_solve not in MASS_SOLVES:
            raise ValueError(f"mass_solve={mass_solve!r} is unknown; use one of {MASS_SOLVES}.")
        self.mass_solve = mass_solve
        self.azimuth = PlanetaryJoint() if azimuth is None else azimuth
        self.pitch = PlanetaryJoint() if pitch is None else pitch
        self.geometry = Geometry() if geometry is None else geometry
        self.inertias = Inertias() if inertias is None else inertias
        self.base = base
        for name, cls in ((self.JOINTS[0], AbstractJoint), (self.JOINTS[1], AbstractJoint), ("geometry", Geometry), ("inertias", Inertias)):
            if not isinstance(getattr(self, name), cls):
                raise TypeError(f"Mechanism.{name} must be a {cls.__name__}, got {type(getattr(self, name)).__name__}.")

    @property
    def layout(self) -> MechanismLayout:
        bq, bu = (7, 6) if self.base == "free" else (0, 0)
        na, npi = self.azimuth.layout.size, self.pitch.layout.size
        ca, cp = len(self.azimuth.contact_names), len(self.pitch.contact_names)
        return MechanismLayout(
            base_q=bq,
            base_u=bu,
            azimuth_q=slice(bq, bq + na),
            pitch_q=slice(bq + na, bq + na + npi),
            azimuth_u=slice(bu, bu + na),
            pitch_u=slice(bu + na, bu + na + npi),
            azimuth_v=slice(0, ca),
            pitch_v=slice(ca, ca + cp),
            size_q=bq + na + npi,
            size_u=bu + na + npi,
            size_v=ca + cp,
        )

    def named_joints(self) -> tuple[tuple[str, AbstractJoint], ...]:
        """`(name, joint)` for each joint, base to reflector (`JOINTS`)."""
        return tuple((name, getattr(self, name)) for name in self.JOINTS)

    def automatic_integrator(self):
        stiff = [name for name, joint in self.named_joints() if joint.stiff_contact_modes]
        if stiff:
            joints = f"the {stiff[0]} joint" if len(stiff) == 1 else f"the {' and '.join(stiff)} joints"
            # Measured and fallen back: FAST_STAGE is faster but reads less closely (tolerax.solve).
            return ACCURATE, (f"the full planetary stage of {joints}: FAST_STAGE (SRK53 at rtol 1e-4) runs it faster but "
                              "reads its pointing, jitter and bearing forces less closely than this on most scenes measured "
                              "(benchmarks/auto_integrator.py); name it, integrator=tolerax.solve.FAST_STAGE, where "
                              "that accuracy is enough")
        return ACCURATE, "no joint carries the full planetary stage: accuracy, not its contact modes, sets the step"

    def named_stages(self):
        return tuple(
            (name, lambda x, name=name: getattr(x, name).stage, joint.design_features) for name, joint in self.named_joints()
        )

    def joints(self) -> Iterator[tuple[AbstractJoint, slice, slice, slice]]:
        """`(joint, q slice, u slice, impact-rate slice)` for the azimuth, then the pitch joint."""
        lay = self.layout
        yield self.azimuth, lay.azimuth_q, lay.azimuth_u, lay.azimuth_v
        yield self.pitch, lay.pitch_q, lay.pitch_u, lay.pitch_v

    # ---------------------------------------------------------------------------------------
    # Kinematics

    def base_pose(self, q):
        if self.base == "fixed":
            return jnp.zeros(3), jnp.eye(3)
        return q[:3], quat_matrix(q[3:7])

    def qdot(self, q, u):
        """$\\dot q = N(q)u$: the quaternion rate $\\tfrac12 q\\otimes(0,\\omega_B)$."""
        if self.base == "fixed":
            return u
        return jnp.concatenate([u[:3], quat_rate(q[3:7], u[3:6]), u[self.layout.base_u :]])

    def chain(self, p_b, r_b, q, t):
        """World poses of every body, given the base pose. Returns `(positions (nb, 3),
        rotations (nb, 3, 3))` in the order of `body_inertia`: base, azimuth gears, link 1,
        pitch gears, link 2, reflector."""
        lay, g = self.layout, self.geometry

        def joint_poses(joint, qj, p_h, r_h):
            centres, angles, out_c, out_a = joint.planar(qj, t)
            gears = planar_to_world(p_h, r_h, centres, angles)
            p_o, r_o = planar_to_world(p_h, r_h, out_c[None], out_a[None])
            return gears, p_o[0], r_o[0]

        (pa, ra), p_oa, r_oa = joint_poses(self.azimuth, q[lay.azimuth_q], p_b + r_b @ g.azimuth_position, r_b)
        p_l1 = p_oa + r_oa @ g.link1_centre
        p_hp, r_hp = p_oa + r_oa @ g.pitch_position, r_oa @ jnp.asarray(PITCH_HOUSING)
        (pp, rp), p_op, r_op = joint_poses(self.pitch, q[lay.pitch_q], p_hp, r_hp)
        p_l2 = p_op + r_op @ g.link2_centre
        p_rf = p_op + r_op @ g.reflector_centre
        positions = jnp.concatenate([p_b[None], pa, p_l1[None], pp, p_l2[None], p_rf[None]])
        rotations = jnp.concatenate([r_b[None], ra, r_oa[None], rp, r_op[None], r_op[None]])
        return positions, rotations

    def poses(self, q, t):
        p_b, r_b = self.base_pose(q)
        return self.chain(p_b, r_b, q, t)

    def body_inertia(self):
        """Masses (nb,) and principal inertias (nb, 3) in the order of `chain`."""
        i = self.inertias
        ma, ia = self.azimuth.body_inertia()
        mp, ip = self.pitch.body_inertia()
        masses = jnp.concatenate([i.base_mass[None], ma, i.link1_mass[None], mp, i.link2_mass[None], i.reflector_mass[None]])
        tensors = jnp.concatenate(
            [i.base_inertia[None], ia, i.link1_inertia[None], ip, i.link2_inertia[None], i.reflector_inertia[None]]
        )
        return masses, tensors

    def twists(self, q, u, t):
        """Body velocities (nb, 3) and angular velocities (nb, 3), world frame."""
        (p, r), (pd, rd) = jax.jvp(lambda q_, t_: self.poses(q_, t_), (q, t), (self.qdot(q, u), jnp.ones_like(t)))
        return pd, vee(jnp.einsum("bij,bkj->bik", rd, r))  # skew(omega) = R' R^T

    def kinematics(self, q, u, t, columns=None) -> "Frames":
        """Every body's pose, twist Jacobians, twist and acceleration at $\\dot u = 0$, by
        propagating frames down the chain (see `Frames`), in the order of `body_inertia`.

        `columns` (static, (nb, C) integers, or `None`: every speed in order): the speeds the
        Jacobians' C columns stand for, body by body (`self.layout.size_u`: none, a zero
        column). Every body a frame rides on must stand for the same speeds in every column as
        the bodies riding on it (`KaneBlocks.columns`: the shared speeds, then a body's own)."""
        lay, g = self.layout, self.geometry
        n = lay.size_u
        base = base_frame(self, q, u, None if columns is None else columns[0])
        parts = [base]
        housing = offset(base, g.azimuth_position)
        # The joints' planar motion is independent of their housings: both in one batch.
        motions = self.each_joint(lambda joint, qj, uj: planar_motion(joint, qj, uj, t), ("q", q), ("u", u))
        first = 1  # the joint's first gear body in `columns`
        for k, (motion, su) in enumerate(zip(motions, (lay.azimuth_u, lay.pitch_u))):
            index = None
            if columns is not None:
                # Its gears' rows, then the link riding on its output (the output's speeds).
                rows = np.asarray(columns)[first : first + motion[0].shape[0]]
                inside = (rows >= su.start) & (rows < su.stop)
                index = np.where(inside, rows - su.start, su.stop - su.start)  # the joint's coordinate, or none
            first += motion[0].shape[0]
            bodies = planar_frames(housing, motion, su, n, index)
            gears, out = take(bodies, slice(0, -1)), take(bodies, slice(-1, None))
            if k == 0:  # azimuth: link 1 and the pitch housing ride on its output
                parts += [gears, offset(out, g.link1_centre)]
                housing = offset(out, g.pitch_position, PITCH_HOUSING)
            else:  # pitch: link 2 and the reflector
                parts += [gears, offset(out, g.link2_centre), offset(out, g.reflector_centre)]
        return jax.tree.map(lambda *xs: jnp.concatenate(xs), *parts)

    def body_columns(self) -> tuple[tuple[int, ...], ...]:
        """For each body, in the order of `body_inertia`, the speeds (indices into `u`) its
        twist depends on (static): the base's own; a joint's bodies their housing's and their
        joint's `AbstractJoint.body_coordinates`; link 1, the pitch joint's housing, link 2
        and the reflector those of the output they ride on."""
        lay = self.layout
        base = tuple(range(lay.base_u))

        def joint_bodies(joint, su, housing):
            every = [housing + tuple(su.start + i for i in cols) for cols in joint.body_coordinates()]
            return every[:-1], every[-1]  # gears, output

        for name, joint in self.named_joints():
            count = int(jnp.shape(joint.body_inertia()[0])[0]) + 1
            if len(joint.body_coordinates()) != count:
                raise ValueError(
                    f"The {name} joint's body_coordinates() has {len(joint.body_coordinates())} entries; it needs one per "
                    f"body of its planar() and one for its output ({count})."
                )
        azimuth_gears, azimuth_out = joint_bodies(self.azimuth, lay.azimuth_u, base)
        pitch_gears, pitch_out = joint_bodies(self.pitch, lay.pitch_u, azimuth_out)
        return (base, *azimuth_gears, azimuth_out, *pitch_gears, pitch_out, pitch_out)

    def kane_blocks(self) -> "KaneBlocks | None":
        """The static partition of the speeds behind the block solve of `accelerations`, or
        `None` where there is nothing to eliminate (no speed moves one body alone), a joint
        adds inertia of its own (`AbstractJoint.added_inertia`, which may couple any of its
        speeds) or `mass_solve="whole"`: then $M$ is formed whole and factorised (`dynamics`)."""
        if self.mass_solve == "whole" or any(joint.added_inertia() is not None for joint, *_ in self.joints()):
            return None
        return partition(self.body_columns(), self.layout.size_u)

    def _kane_terms(self, q, u, t, columns=None):
        """Per body: the stacked twist Jacobian (nb, 6, C) with the angular rows in body axes
        (columns as `kinematics`), the weights (nb, 6) (mass, principal inertias) and the
        inertial terms $g$ (nb, 6) ($m a^0$, $I\\alpha^0 + \\omega\\times I\\omega$):
        $M = \\sum J^TWJ$, $b = \\sum J^Tg$."""
        masses, principal = self.body_inertia()
        f = self.kinematics(q, u, t, columns)
        # Angular quantities in body axes, where the inertia is diagonal.
        # Small batched contractions as fused sums (`small_einsum`): XLA:CPU would call a
        # library kernel per body for each.
        jw = small_einsum("bji,bjn->bin", f.rot, f.jw)
        w, alpha = (small_einsum("bji,bj->bi", f.rot, x) for x in (f.w, f.alpha))
        rot_term = principal * alpha + jnp.cross(w, principal * w)
        jac = jnp.concatenate([f.jv, jw], axis=1)
        weights = jnp.concatenate([jnp.broadcast_to(masses[:, None], f.a.shape), principal], axis=1)
        return jac, weights, jnp.concatenate([masses[:, None] * f.a, rot_term], axis=1)

    def dynamics(self, q, u, t):
        """Mass matrix $M(q)$ and the velocity-product and inertial terms $b(q,u)$ with
        $M\\dot u = Q - b$ (Kane's equations over the body Jacobians of `kinematics`), whole."""
        jac, weights, g = self._kane_terms(q, u, t)
        # One stacked Jacobian J (6 nb x n) and weights W: M = J^T W J and b = J^T g as two
        # products (fewer, larger kernels than one pair per translation and rotation). The rows
        # flattened first: XLA compiles this form faster than the per-body contraction, vmapped.
        jac, weights, g = jac.reshape(-1, jac.shape[-1]), weights.reshape(-1), g.reshape(-1)
        mass = jnp.einsum("kn,k,km->nm", jac, weights, jac)
        bias = jnp.einsum("kn,k->n", jac, g)
        return self._with_added_inertia(mass), bias

    def _solve(self, q, u, t, force):
        """$\\dot u$ from $M\\dot u = Q - b$ with $Q$ = `force`: by blocks (`kane_blocks`,
        `tolerax.mechanism.blocks.block_solve`), or whole (Cholesky of $M$) where there are none."""
        blocks = self.kane_blocks()
        if blocks is None:
            mass, bias = self.dynamics(q, u, t)
            # M is symmetric positive definite: Cholesky, half the work of a pivoted LU.
            return jax.scipy.linalg.cho_solve(jax.scipy.linalg.cho_factor(mass), force - bias)
        jac, weights, g = self._kane_terms(q, u, t, blocks.columns)
        return block_solve(blocks, jac, weights, g, force)

    def _with_added_inertia(self, mass):
        """`mass` plus each joint's constant `added_inertia` on its own speeds (no bias term:
        constant in the joint's coordinates, whose speeds are their rates)."""
        for joint, _, su, _ in self.joints():
            added = joint.added_inertia()
            if added is not None:
                mass = mass.at[su, su].add(added)
        return mass

    def momentum(self, q, u, t):
        """Total linear (kg m/s) and angular momentum about the world origin (kg m²/s)."""
        masses, principal = self.body_inertia()
        pos, rot = self.poses(q, t)
        v, w = self.twists(q, u, t)
        inertia = world_inertia(rot, principal)
        lin = masses[:, None] * v
        ang = jnp.cross(pos, lin) + jnp.einsum("bij,bj->bi", inertia, w)
        return jnp.sum(lin, 0), jnp.sum(ang, 0)

    def kinetic_energy(self, q, u, t):
        masses, principal = self.body_inertia()
        _, rot = self.poses(q, t)
        v, w = self.twists(q, u, t)
        w_body = jnp.einsum("bji,bj->bi", rot, w)
        energy = 0.5 * jnp.sum(masses * jnp.sum(v**2, -1)) + 0.5 * jnp.sum(principal * w_body**2)
        for joint, _, su, _ in self.joints():
            added = joint.added_inertia()
            if added is not None:
                energy += 0.5 * u[su] @ added @ u[su]
        return energy

    def potential_energy(self, q):
        """Elastic energy (J) of conservative joints (linear meshes; contact laws with a
        potential). Raises for joints whose smoothed forces have no closed-form potential."""
        return sum(joint.potential_energy(q[sq]) for joint, sq, _, _ in self.joints())

    def reference_angles(self, q, t):
        """Commanded joint angles (azimuth, pitch; rad): the servo's $\\theta^*(t)$; the measured
        output angle for a torque drive (its pointing error is then the error from clearances and
        deflections alone)."""
        out = []
        for joint, sq, _, _ in self.joints():
            cmd = joint.commanded_angle(t)
            out.append(joint.output_angle(q[sq], t) if cmd is None else cmd)
        return jnp.stack(out)

    def output_angles(self, q, t):
        """Measured output angles (azimuth, pitch; rad)."""
        return jnp.stack([joint.output_angle(q[sq], t) for joint, sq, _, _ in self.joints()])

    def ideal_reflector(self, angles):
        """Reflector centre (m) and rotation in the *base* frame for ideal joints at `angles`
        (azimuth, pitch; rad): the commanded pose."""
        g = self.geometry
        r_oa = rz(angles[0])
        r_hp = r_oa @ jnp.asarray(PITCH_HOUSING)
        p_hp = g.azimuth_position + r_oa @ g.pitch_position
        r_op = r_hp @ rz(angles[1])
        return p_hp + r_op @ g.reflector_centre, r_op

    def reflector_in_base(self, q, t):
        """Actual reflector centre and rotation relative to the base (base frame)."""
        pos, rot = self.chain(jnp.zeros(3), jnp.eye(3), q, t)
        return pos[-1], rot[-1]

    # ---------------------------------------------------------------------------------------
    # Forces and the equations of motion

    def each_joint(self, fn, *vectors):
        """`[fn(joint, *parts) for each joint]`, where `parts` are each joint's slices of
        `vectors` (named by kind: `("q", q)`, `("u", u)`, `("v", v)`).

        Two joints of the same structure (class, static fields, array shapes: the paper's
        scenes) are evaluated as one batch of two (`vmap`), which halves the number of small
        kernels a CPU runs for them; otherwise one after the other."""
        lay = self.layout
        cut = {"q": (lay.azimuth_q, lay.pitch_q), "u": (lay.azimuth_u, lay.pitch_u), "v": (lay.azimuth_v, lay.pitch_v)}
        parts = [tuple(x[cut[kind][k]] for kind, x in vectors) for k in range(2)]
        arrays, rest = zip(*(eqx.partition(j, eqx.is_array) for j in (self.azimuth, self.pitch)))
        twins = jax.tree.structure(arrays[0]) == jax.tree.structure(arrays[1]) and all(
            a.shape == b.shape and a.dtype == b.dtype for a, b in zip(jax.tree.leaves(arrays[0]), jax.tree.leaves(arrays[1]))
        )
        twins = twins and eqx.tree_equal(rest[0], rest[1]) is True
        if not twins:
            return [fn(joint, *part) for joint, part in zip((self.azimuth, self.pitch), parts)]
        stacked = jax.tree.map(lambda a, b: jnp.stack([a, b]), *arrays)
        columns = [jnp.stack(pair) for pair in zip(*parts)]
        out = jax.vmap(lambda a, *xs: fn(eqx.combine(a, rest[0]), *xs))(stacked, *columns)
        return [jax.tree.map(lambda x: x[k], out) for k in range(2)]

    def joint_forces(self, q, u, v, t):
        """Generalised forces on the joints' coordinates and the contact forces, per joint."""
        return self.each_joint(lambda joint, qj, uj, vj: joint.forces(qj, uj, vj, t), ("q", q), ("u", u), ("v", v))

    def accelerations(self, t, q, u, v):
        """`(udot, (azimuth contact forces, pitch contact forces))`. One jitted call (XLA inlines
        it where it is traced into a program): a solve traces it in the vector field and again in
        `observe`, the loaded state's and identification's Jacobians several times, and JAX keeps
        a nested jit's trace for the next call with the same structure and shapes."""
        return _accelerations(self, t, q, u, v)

    def _accelerations(self, t, q, u, v):
        lay = self.layout
        (qa, ca), (qp, cp) = self.joint_forces(q, u, v, t)
        return self._solve(q, u, t, jnp.concatenate([jnp.zeros(lay.base_u), qa, qp])), (ca, cp)

    def _accelerations_and_mass(self, t, q, u, v):
        """`accelerations` and the whole mass matrix of the same equations (`dynamics`)."""
        ud, contacts = self.accelerations(t, q, u, v)
        return ud, contacts, self.dynamics(q, u, t)[0]

    def vector_field(self, t, y, args):
        q, u, v = y
        with jax.named_scope("mechanism_dynamics"):
            ud, _ = self.accelerations(t, q, u, v)
        with jax.named_scope("impact_memory"):
            vd = self.each_joint(lambda joint, *x: joint.impact_rate_rates(*x), ("q", q), ("u", u), ("u", ud), ("v", v))
        return self.qdot(q, u), ud, jnp.concatenate(vd)

    def observe(self, t, y):
        """Instantaneous outputs at a state (see `MechanismResult`)."""
        q, u, v = y
        _, contacts = self.accelerations(t, q, u, v)
        return _outputs.observe(self, t, q, u, contacts)

    def initial_impact_rates(self, q, u):
        """Consistent impact-rate states: each contact's current penetration rate (m/s)."""
        parts = [joint.initial_impact_rates(q[sq], u[su]) for joint, sq, su, _ in self.joints()]
        return jnp.concatenate(parts)

    def initial_state(self, start: str = "rest"):
        """`(q, u, impact_rates)` at t = 0; the base at rest.

        - `start="rest"`: everything centred, joint angles 0, the joints at rest (a servo
          start-up follows).
        - `"steady"`: as `"rest"`, but each servo-driven joint already turning at its commanded
          rate in rigid kinematics (sun at $i\\Omega$, planets rolling), meshes undeflected and
          the servo at zero lag. The servo then builds its lag against the output drag: the
          output's speed swings and settles over ~2 s at the default gains.
        - `"loaded"`: the loaded steady state itself (`loaded_state`): speeds as `"steady"`, and
          each servo lagging its command by what the drag needs, the gear train's play taken up
          on the loaded flanks and every mesh and contact deflected under that load. Needs
          constant-rate servos (`SpeedServo`) with an integral gain; solves a small nonlinear
          least-squares problem (compiles once per structure).

        Prescribed (ideal) joints are at their commanded state in every case."""
        lay = self.layout
        q = jnp.zeros(lay.size_q)
        if self.base == "free":
            q = q.at[3].set(1.0)  # identity quaternion
        u = jnp.zeros(lay.size_u)
        if start in ("steady", "loaded"):
            for joint, _, su, _ in self.joints():
                u = u.at[su].set(joint.steady_speeds())
        if start == "loaded":
            q = self.loaded_state(q, u)
        return q, u, self.initial_impact_rates(q, u)

    def loaded_state(self, q, u, *, max_steps: int = 200):
        """The coordinates `q` at t = 0 at which the joints, turning at speeds `u` (the steady
        speeds), are in equilibrium: zero accelerations of every joint coordinate.

        Start: each joint's closed form (`AbstractJoint.loaded_coordinates`: servo lag
        $T/(i k_i)$ on the sun, play taken up on the loaded flanks). Then Levenberg-Marquardt
        (`optimistix`) on the joint coordinates (base pose held) for the residual
        $\\sqrt{M_{kk}}\\,\\dot u_k$ over the joint speeds (the generalised force per unit
        square-root inertia: balances sun, planets and heavy output), plus a weak anchor
        `LOADED_ANCHOR` $(x - x_0)$ to the closed form (a ~1 N/m spring against 1e8 N/m meshes):
        members floating in clearance and backlash allow many equilibria (a probe without it
        put the pitch joint's sun against its bearing and the planets at unequal spins), and
        the anchor picks the one nearest the closed form (moved by <= 1.6 urad, 35 nm).

        Outside `jit`, a `ValueError` if the polish leaves more than 1 % of the residual that
        the `"steady"` state has. What remains is the
        pitch output's radial load (the centripetal force of link 2 and the reflector turning
        about the azimuth axis, ~1e-3 N): the carrier floats in its clearance, where that force
        has no gradient to follow, so it drifts to the bearing wall over the first 1-2 s of a
        run (lumped joints: output-bearing contacts of a few newtons from about 1 s, a speed
        error of a few urad/s)."""
        return _loaded.loaded_state(self, q, u, max_steps)

    def check_runnable(self):
        if self.layout.size_u == 0:
            raise ValueError(
                "This mechanism has nothing to integrate: a fixed base with both joints ideal and "
                "speed-driven is pure prescribed kinematics. Use base='free', a torque drive, or a "
                "lumped/planetary joint."
            )

    def result(self, sol, observed, duration):
        return _outputs.MechanismResult.from_solution(
            sol,
            duration,
            ts=sol.ts,
            **{f.name: getattr(observed, f.name) for f in dataclasses.fields(observed)},
            states=sol.ys,
            azimuth_contact_names=self.azimuth.contact_names,
            pitch_contact_names=self.pitch.contact_names,
        )


@eqx.filter_jit
def _accelerations(mechanism, t, q, u, v):
    return mechanism._accelerations(t, q, u, v)
