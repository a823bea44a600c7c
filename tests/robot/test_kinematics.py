"""Kinematics against finite differences and MuJoCo; Eq. 6 both ways; workspace and limits."""
import mujoco
import numpy as np
import pytest

from vishap._core.errors import ShapeError
from vishap.robot import kinematics as kin
from vishap.robot.mjcf import build_model
from vishap.robot.params import DEFAULT

# θ = E · q_mujoco (the third motor drives θ3 = θ2 + elbow)
E_INV = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 1.0]])


def box_points(n=5):
    lo, hi = np.array(DEFAULT.workspace_min), np.array(DEFAULT.workspace_max)
    g = [np.linspace(lo[i], hi[i], n) for i in range(3)]
    return np.stack(np.meshgrid(*g, indexing="ij"), -1).reshape(-1, 3)


def random_q(rng, n):
    return np.stack([rng.uniform(-0.5, 0.5, n), rng.uniform(-0.3, 0.6, n), rng.uniform(-0.7, 0.7, n)], -1)


def test_home_tip():
    np.testing.assert_allclose(kin.fk([0, 0, 0]), [0.215, 0.0, -0.170], atol=1e-12)


def test_fk_batch_matches_single(rng):
    q = random_q(rng, 20)
    np.testing.assert_allclose(kin.fk(q), np.stack([kin.fk(x) for x in q]), atol=1e-15)


def test_ik_round_trip_over_box():
    for p in box_points(6):
        q = kin.ik(p)
        np.testing.assert_allclose(kin.fk(q), p, atol=1e-12)
        assert kin.within_joint_limits(q, margin=0.05), (p, q)


def test_ik_out_of_reach():
    with pytest.raises(ShapeError, match="reach"):
        kin.ik([1.0, 0.0, 0.0])
    with pytest.raises(ShapeError):
        kin.ik([np.nan, 0.0, 0.0])


def test_jacobian_vs_finite_differences(rng):
    h = 1e-6
    for q in random_q(rng, 25):
        J = kin.jacobian(q)
        Jn = np.stack([(kin.fk(q + h * e) - kin.fk(q - h * e)) / (2 * h) for e in np.eye(3)], -1)
        np.testing.assert_allclose(J, Jn, atol=1e-9)


def test_fk_and_jacobian_vs_mujoco(rng):
    m = build_model()
    d = mujoco.MjData(m)
    site = mujoco.mj_name2id(m, mujoco.mjtObj.mjOBJ_SITE, "tip")
    jacp = np.zeros((3, m.nv))
    for q in random_q(rng, 25):
        d.qpos[:] = E_INV @ q
        mujoco.mj_forward(m, d)
        np.testing.assert_allclose(d.site_xpos[site], kin.fk(q), atol=1e-12)
        mujoco.mj_jacSite(m, d, jacp, None, site)
        np.testing.assert_allclose(jacp @ E_INV, kin.jacobian(q), atol=1e-12)


def test_eq6_both_ways(rng):
    for q in random_q(rng, 25):
        F = rng.normal(size=3)
        tau = kin.force_to_torque(q, F)
        np.testing.assert_allclose(tau, kin.jacobian(q).T @ F)
        np.testing.assert_allclose(kin.torque_to_force(q, tau), F, atol=1e-10)


def test_torque_to_force_singular():
    # θ3 − θ2 = −π/2: upper arm and forearm in line (stretched)
    with pytest.raises(ShapeError, match="singular"):
        kin.torque_to_force([0.0, 0.0, -np.pi / 2], [0.0, 0.1, 0.1])


def test_link_points_polyline(rng):
    q = random_q(rng, 1)[0]
    pts = kin.link_points(q)
    assert pts.shape == (4, 3)
    np.testing.assert_allclose(pts[-1], kin.fk(q))
    np.testing.assert_allclose(np.linalg.norm(pts[2] - pts[1]), DEFAULT.l1)
    np.testing.assert_allclose(np.linalg.norm(pts[3] - pts[2]), DEFAULT.l2)


def test_clamp_to_workspace():
    p, moved = kin.clamp_to_workspace([0.5, -0.2, -0.1])
    assert moved and np.allclose(p, [0.30, -0.065, -0.1])
    p, moved = kin.clamp_to_workspace([0.2, 0.0, -0.1])
    assert not moved and np.allclose(p, [0.2, 0.0, -0.1])
    p, moved = kin.clamp_to_workspace([np.nan, np.inf, -np.inf])
    assert moved and np.all(np.isfinite(p)) and kin.in_workspace(p)
