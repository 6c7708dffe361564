"""The recipes of docs/architecture.md followed literally, from outside the package: a new
contact law ("Recipe: a contact law") and a fourth joint fidelity ("Recipe: a joint fidelity"),
each written from what the page says, run through `tx.simulate` and checked against a closed
form. If these tests need a change to `src/` to pass, the page is wrong. The line counts the page
quotes are those of the two classes below (`class` line to last line, docstring included)."""

import equinox as eqx
import jax
import jax.numpy as jnp
import numpy as np
import pytest
from jaxtyping import Array, Float

import tolerax as tx
from _kane_reference import twisted_scan_state
from tolerax.mechanism.joints import JointLayout, disc_tensors, planet_spin_ratio

# -- Recipe: a contact law ----------------------------------------------------------------------


class KelvinVoigt(tx.AbstractContactLaw):
    """Linear spring-dashpot (Kelvin-Voigt) contact $F = k\\delta + c\\min(\\delta/d, 1)\\dot\\delta$
    (N): stiffness $k$ (N/m), damping $c$ (N s/m), the dashpot ramped in over a depth $d$ (m)."""

    stiffness: Float[Array, ""]
    damping: Float[Array, ""]
    depth: Float[Array, ""]

    def __init__(self, stiffness=2e8, damping=1e3, depth=1e-7):
        self.stiffness, self.damping, self.depth = (jnp.asarray(x, dtype=float) for x in (stiffness, damping, depth))

    def elastic(self, bearing, penetration):
        return self.stiffness * penetration

    def damped(self, bearing, penetration, rate, impact_rate, elastic):
        return elastic + self.damping * jnp.clip(penetration / self.depth, 0.0, 1.0) * rate

    def potential(self, bearing, penetration):
        return 0.5 * self.stiffness * penetration**2


def _force(law, bearing, e, e_dot, width):
    state = tx.contact.contact_kinematics(bearing, jnp.asarray(e), jnp.asarray(e_dot), width)
    return float(tx.contact.normal_force(law, bearing, state, jnp.asarray(0.1), width))


def test_new_contact_law_against_its_closed_form_and_in_a_simulation():
    k, c = 2e8, 1e3
    law = KelvinVoigt(k, c)
    bearing = tx.contact.JournalBearing(journal_radius=5e-3, clearance=10e-6, length=8e-3)
    # 3 um into a 10 um clearance, closing at 0.05 m/s: F = k delta + c rate, exactly at width 0
    # (the primitives' exact limit); at the stage's default 1 nm within the smoothed norm's
    # eps^2 / (2|e|) = 4e-14 m of penetration (1.3e-8 relative; the ramps are exact 3000 widths in).
    for width, rtol in ((0.0, 1e-14), (1e-9, 1e-7)):
        np.testing.assert_allclose(_force(law, bearing, [13e-6, 0.0], [0.05, 0.0], width), k * 3e-6 + c * 0.05, rtol=rtol)
        # Separating fast (c rate < -k delta): the contact does not pull.
        assert 0.0 <= _force(law, bearing, [13e-6, 0.0], [-1.0, 0.0], width) < 1e-12
    # 50 nm short of the wall, closing at 1 m/s: no force (the dashpot is switched by the
    # penetration; an ungated c * rate would push with 1000 N here).
    assert _force(law, bearing, [9.95e-6, 0.0], [1.0, 0.0], 1e-9) < 1e-12
    # The potential's derivative is the elastic force (energy checks rely on it).
    np.testing.assert_allclose(float(jax.grad(law.potential, argnums=1)(bearing, 3e-6)), k * 3e-6, rtol=1e-14)

    # The law in every clearance of the default joint on its bench, from rest: the run succeeds,
    # members land in their bearings and carry load, and no contact pulls.
    res = tx.simulate(tx.TestBench(tx.default_stage(contact_law=law)), 0.3, n_save=31)
    assert res.success
    forces = np.asarray(res.contact_force)
    assert forces.min() >= 0.0 and forces.max() > 0.1


# -- Recipe: a joint fidelity -------------------------------------------------------------------


class TorsionalJoint(tx.AbstractJoint):
    """Sun and output coupled by the stage's equivalent mesh (`tx.lumped_mesh`), linear: no
    backlash, no bearing clearance, planets rolling rigidly on the ring."""

    @property
    def layout(self):
        return JointLayout(2, 0, 1, None, ("theta_s", "theta_c"))

    def planar(self, qj, t):
        theta_s, theta_c = qj[0], qj[1]
        psi = self.stage.planet_angles + theta_c
        planets = self.stage.carrier_radius * jnp.stack([jnp.cos(psi), jnp.sin(psi)], axis=-1)
        spins = jnp.broadcast_to(planet_spin_ratio(self.stage) * theta_c, psi.shape)
        angles = jnp.concatenate([jnp.stack([theta_s, theta_c]), spins])
        return jnp.concatenate([jnp.zeros((2, 2)), planets]), angles, jnp.zeros(2), theta_c

    def body_inertia(self):
        return disc_tensors(self.stage, self.motor_inertia, 2 + self.stage.n_planets)

    def forces(self, qj, uj, vj, t):
        mesh, i = tx.lumped_mesh(self.stage, self.motor_inertia), self.stage.ratio
        tooth = mesh.lever * (mesh.stiffness * (qj[0] / i - qj[1]) + mesh.damping * (uj[0] / i - uj[1]))
        force = self.drive_forces(qj, uj, t)
        return force.at[0].add(-tooth * mesh.lever / i).at[1].add(tooth * mesh.lever), jnp.zeros(0)


LINEAR_STAGE = {"mesh": "linear", "sun_support": "rigid", "carrier_support": "rigid", "planet_support": "rigid"}


def test_fourth_fidelity_in_the_antenna_settles_to_torque_over_stiffness():
    # The azimuth joint turning the antenna (pitch held, fixed base) at a constant 0.98 deg/s,
    # from rigid rolling with no twist and no servo lag. About a fixed axis at a constant rate the
    # rotating antenna needs no torque, so once the start-up has died out (by 0.8 s with a stiff
    # servo) the mesh carries exactly the output's drag T: the joint's twist is T over its
    # torsional stiffness K r^2, and the servo's integral term alone supplies T/i on the sun,
    # which therefore lags its command by T / (i k_i).
    stage = tx.default_stage(**LINEAR_STAGE)
    rate, k_i, drag = np.radians(0.98), 40.0, 0.05
    joint = TorsionalJoint(stage, tx.SpeedServo(rate, 2.0, k_i), drag_torque=drag)
    mech = tx.Mechanism(joint, tx.IdealJoint(stage, tx.SpeedServo(0.0)), base="fixed")
    res = tx.simulate(mech, 1.0, start="steady", n_save=21)
    assert res.success
    (_, sq, _, _), _ = mech.joints()
    late = np.asarray(res.ts) >= 0.8
    theta_s, theta_c = np.asarray(res.states[0])[late][:, sq].T
    i, torque = float(stage.ratio), drag * np.tanh(rate / 1e-3)
    mesh = tx.lumped_mesh(stage, joint.motor_inertia)
    # 1e-3: the twist (0.15 urad) is a difference of angles of tens of mrad integrated at rtol 1e-6
    # (measured within 4e-5 from 0.8 s on).
    np.testing.assert_allclose(theta_s / i - theta_c, torque / (float(mesh.stiffness) * float(mesh.lever) ** 2), rtol=1e-3)
    np.testing.assert_allclose(theta_s - i * rate * np.asarray(res.ts)[late], -torque / (i * k_i), rtol=1e-4)
    np.testing.assert_allclose(np.asarray(res.joint_angle)[late, 0], theta_c, rtol=0, atol=1e-15)


def _new_and_lumped():
    stage = tx.default_stage(**LINEAR_STAGE)
    drive, held = tx.ScanServo(np.radians(0.5), 1.0, 2.0, 40.0), tx.IdealJoint(stage, tx.SpeedServo(0.0))
    return stage, [tx.Mechanism(cls(stage, drive), held, base="fixed") for cls in (TorsionalJoint, tx.LumpedJoint)]


@eqx.filter_jit
def _field(mech, t, y):
    return mech.vector_field(t, y, None)


def test_fourth_fidelity_equals_lumped_on_a_clearance_free_stage():
    # On linear meshes with rigid supports the library's LumpedJoint models exactly this joint
    # (no backlash, pin play or output bearing left): the same vector field, to rounding (the
    # two write the same forces in a different order), at random states of the azimuth scan
    # (motor and output anywhere, twisted against each other by up to 1 mrad, speeds of order
    # 1 rad/s). The recipe's joint in a run: the test above; this one over the scan beside the
    # lumped joint: the slow `test_fourth_fidelity_run_equals_lumped`.
    stage, (new, ref) = _new_and_lumped()
    lay = ref.layout
    assert new.layout == lay
    i = float(stage.ratio)
    for k, t in enumerate((0.0, 0.3, 0.8)):
        y = twisted_scan_state(lay, i, jax.random.key(k))
        got, want = _field(new, jnp.asarray(t), y), _field(ref, jnp.asarray(t), y)
        assert float(jnp.abs(want[1]).max()) > 1.0  # the mesh torque accelerates the gears
        for a, b in zip(jax.tree.leaves(got), jax.tree.leaves(want)):
            np.testing.assert_allclose(np.asarray(a), np.asarray(b), rtol=0, atol=1e-12 * float(jnp.abs(b).max(initial=0.0)))
    # Nothing the new joint models can be toleranced: it lists no design features.
    assert tx.design_names(new) == ()


@pytest.mark.slow
def test_fourth_fidelity_run_equals_lumped():
    """Enlarges `test_fourth_fidelity_equals_lumped_on_a_clearance_free_stage` (the vector field
    at random states) to the azimuth scan: the same motion to the solver's tolerance, as the two
    write the same forces in a different order and the adaptive steps follow the rounding
    (measured: 1e-8 of the peak pointing error, 1.4e-6 of the peak tracking speed error)."""
    _, mechs = _new_and_lumped()
    new, ref = (tx.simulate(mech, 0.3, n_save=31) for mech in mechs)
    assert new.success and ref.success and float(np.max(np.asarray(ref.pointing_error))) > 0.0
    for name in ("pointing_error", "joint_angle", "tracking_speed_error"):
        a, b = np.asarray(getattr(new, name)), np.asarray(getattr(ref, name))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-5 * np.abs(b).max())


def test_registered_fidelity_is_a_name_for_the_builders(monkeypatch):
    # The recipe's last, optional step: an entry in `tx.FIDELITIES` makes the class a fidelity
    # name for `tx.antenna`/`tx.scan` (and so for scene files, which call them).
    monkeypatch.setitem(tx.FIDELITIES, "torsional", TorsionalJoint)
    mech = tx.antenna("dual", fidelity=("torsional", "lumped"))
    assert isinstance(mech.azimuth, TorsionalJoint) and isinstance(mech.pitch, tx.LumpedJoint)
    assert mech.layout.size_u == 6 + 2 + 4  # free base; the torsional joint's 2; lumped with its output bearing
