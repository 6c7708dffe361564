"""The recipes of docs/architecture.md followed literally: a new contact law and a fourth joint
fidelity, each written outside the package from what the page says and run through `simulate`.
If these tests need a change to `src/` to pass, the page is wrong."""

import jax.numpy as jnp
import numpy as np
from jaxtyping import Array, Float

import tolerax as tx
from tolerax.mechanism.joints import JointLayout, disc_tensors, planet_spin_ratio


# -- Recipe 1: a contact law ------------------------------------------------------------------


class LinearSpring(tx.AbstractContactLaw):
    """A linear, undamped contact: $F = k\\delta$ (N), $k$ in N/m."""

    stiffness: Float[Array, ""]

    def __init__(self, stiffness=1e8):
        self.stiffness = jnp.asarray(stiffness, dtype=float)

    def elastic(self, bearing, penetration):
        return self.stiffness * penetration

    def damped(self, bearing, penetration, rate, impact_rate, elastic):
        return elastic

    def potential(self, bearing, penetration):
        return 0.5 * self.stiffness * penetration**2


def test_new_contact_law_force_and_simulation():
    law = LinearSpring(2e8)
    bearing = tx.contact.JournalBearing(journal_radius=5e-3, clearance=10e-6, length=8e-3)
    # 3 um into a 10 um clearance, at rest: the force is k * delta, exactly at width 0 (the
    # clip's ramp is exact there), within the smoothing's error at the default 1 nm.
    e = jnp.array([13e-6, 0.0])
    for width, rtol in ((0.0, 1e-12), (1e-9, 1e-3)):
        state = tx.contact.contact_kinematics(bearing, e, jnp.zeros(2), width)
        force = tx.contact.normal_force(law, bearing, state, jnp.asarray(0.0), width)
        np.testing.assert_allclose(float(force), 2e8 * 3e-6, rtol=rtol)
    # The law drives every clearance of a joint on its bench: the run succeeds, the planet pins
    # land and carry load, and no contact pulls.
    bench = tx.TestBench(tx.default_stage(contact_law=law))
    res = tx.simulate(bench, 0.3, n_save=31)
    assert res.success
    forces = np.asarray(res.contact_force)
    assert forces.min() >= 0.0 and forces.max() > 0.1


# -- Recipe 2: a joint fidelity ---------------------------------------------------------------


class TorsionalJoint(tx.AbstractJoint):
    """Sun and output coupled by the stage's equivalent torsional mesh (`tx.lumped_mesh`),
    linear: no backlash, no bearing clearance, planets rolling rigidly."""

    @property
    def layout(self):
        return JointLayout(2, 0, 1, None, ("theta_s", "theta_c"))

    def planar(self, qj, t):
        theta_s, theta_c = qj[0], qj[1]
        psi = self.stage.planet_angles + theta_c
        planets = self.stage.carrier_radius * jnp.stack([jnp.cos(psi), jnp.sin(psi)], axis=-1)
        centres = jnp.concatenate([jnp.zeros((2, 2)), planets])
        spins = jnp.broadcast_to(planet_spin_ratio(self.stage) * theta_c, psi.shape)
        return centres, jnp.concatenate([jnp.stack([theta_s, theta_c]), spins]), jnp.zeros(2), theta_c

    def body_inertia(self):
        return disc_tensors(self.stage, self.motor_inertia, 2 + self.stage.n_planets)

    def forces(self, qj, uj, vj, t):
        mesh, ratio = tx.lumped_mesh(self.stage, self.motor_inertia), self.stage.ratio
        deflection = mesh.lever * (qj[0] / ratio - qj[1])
        rate = mesh.lever * (uj[0] / ratio - uj[1])
        tooth = mesh.stiffness * deflection + mesh.damping * rate
        force = self.drive_forces(qj, uj, t).at[0].add(-tooth * mesh.lever / ratio).at[1].add(tooth * mesh.lever)
        return force, jnp.zeros(0)


def test_fourth_joint_fidelity_equals_lumped_on_a_linear_stage():
    # Independent of the library's LumpedJoint (written here from the page): on a stage with
    # linear meshes and rigid supports, the lumped joint is exactly this torsional joint, so the
    # dual-axis antenna scanning with either gives the same motion to the solver's rounding.
    stage = tx.default_stage(mesh="linear", sun_support="rigid", carrier_support="rigid", planet_support="rigid")
    drive = tx.ScanServo(amplitude=np.radians(0.5), period=1.0)
    runs = []
    for cls in (TorsionalJoint, tx.LumpedJoint):
        mech = tx.Mechanism(cls(stage, drive), cls(stage, drive), base="fixed")
        res = tx.simulate(mech, 0.3, n_save=31)
        assert res.success
        runs.append(res)
    new, ref = runs
    assert float(np.abs(np.asarray(ref.pointing_error)).max()) > 0.0
    for name in ("pointing_error", "joint_angle", "tracking_speed_error"):
        a, b = np.asarray(getattr(new, name)), np.asarray(getattr(ref, name))
        np.testing.assert_allclose(a, b, rtol=0, atol=1e-9 * np.abs(b).max())
    # The mechanism reads the new joint's structure (no fidelity switch anywhere): its
    # coordinates and no design features (nothing it models can be toleranced).
    assert tx.design_names(tx.Mechanism(TorsionalJoint(stage, drive), TorsionalJoint(stage, drive))) == ()


def test_registered_fidelity_is_a_name_for_the_builders(monkeypatch):
    # The recipe's last, optional step: an entry in `tx.FIDELITIES` makes the class a fidelity
    # name for `tx.antenna`/`tx.scan` (and the scene files, which call them).
    monkeypatch.setitem(tx.FIDELITIES, "torsional", TorsionalJoint)
    mech = tx.antenna("dual", fidelity=("torsional", "lumped"))
    assert isinstance(mech.azimuth, TorsionalJoint) and isinstance(mech.pitch, tx.LumpedJoint)
    assert mech.layout.size_u == 6 + 2 + 4  # free base, the torsional joint's 2, lumped with its output bearing
