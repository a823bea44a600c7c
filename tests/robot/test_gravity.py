"""Eq. 7 against MuJoCo's bias forces for the same parameters; Eq. 6 compensation force."""
import mujoco
from dataclasses import replace

import numpy as np

from vishap.robot import gravity, kinematics as kin
from vishap.robot.mjcf import PassiveObject, build_model
from vishap.robot.params import DEFAULT
from vishap.world.scene import demo_passive_object

E_INV = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 1.0]])


def test_coefficients_are_the_papers():
    p = DEFAULT
    c2, c3 = gravity.coefficients(p)
    assert c2 == p.g * (p.l1 * p.m_a + 0.5 * p.l1 * p.m_c + p.m_be * p.l5)
    assert c3 == p.g * (0.5 * p.m_a * p.l2 + p.m_c * p.l3 - p.m_df * p.l6)
    np.testing.assert_allclose(gravity.gravity_torque([0.3, 0.0, np.pi / 2]), [0.0, c2, c3])


def test_adjusted_m_a_changes_both_coefficients():
    p = DEFAULT.with_adjusted_m_a(0.01)
    c2, c3 = gravity.coefficients(p)
    c2_0, c3_0 = gravity.coefficients(DEFAULT)
    np.testing.assert_allclose([c2 - c2_0, c3 - c3_0], [DEFAULT.g * 0.01 * DEFAULT.l1, DEFAULT.g * 0.005 * DEFAULT.l2])
    model = gravity.GravityModel()
    model.set_m_a(DEFAULT.m_a + 0.01)
    assert (model.c2, model.c3) == (c2, c3)


def _bias_torque(m, d, q, params):
    """MuJoCo's gravity generalized force at rest, mapped to motor torques: τ = E⁻ᵀ qfrc_bias, plus
    the crank's gravity torque on θ3 that the plant applies (the crank is carried by motor 3's tendon)."""
    d.qpos[:] = E_INV @ q
    d.qvel[:] = 0.0
    mujoco.mj_forward(m, d)
    return E_INV.T @ d.qfrc_bias + np.array([0.0, 0.0, params.crank_gravity_nm * np.sin(q[2])])


def test_gravity_matches_mujoco_bias(rng):
    for obj in (None, replace(demo_passive_object(), mass_kg=0.012), PassiveObject(shape="sphere", size_m=(0.01,), mass_kg=0.05)):
        params = DEFAULT.with_tip_mass(0.0 if obj is None else obj.mass_kg)
        m = build_model(params, passive_object=obj)
        d = mujoco.MjData(m)
        for _ in range(30):
            q = np.array([rng.uniform(-0.9, 0.9), rng.uniform(-0.45, 0.85), rng.uniform(-0.9, 0.9)])
            np.testing.assert_allclose(gravity.gravity_torque(q, params), _bias_torque(m, d, q, params), rtol=0, atol=1e-14)


def test_compensation_force_balances_gravity(rng):
    for _ in range(10):
        q = np.array([rng.uniform(-0.5, 0.5), rng.uniform(-0.3, 0.6), rng.uniform(-0.7, 0.7)])
        F = gravity.gravity_force(q)
        np.testing.assert_allclose(kin.force_to_torque(q, F), gravity.gravity_torque(q), atol=1e-14)
