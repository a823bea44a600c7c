"""The core's scene step, contact renderer and servo step (vishap.runtime.core)."""
import numpy as np
import pytest

from vishap.runtime.core import ContactRenderer, SceneStep, TargetRecord
from vishap.world.scene import load_scene
from vishap.world.world import World


def test_record_packs_and_unpacks_every_field():
    r = TargetRecord(7, (0.1, 0.2, -0.3), 1.5, 0.8, False, True, 2, True, False, (1.0, 2.0, 3.0), (0.1, 0.0, -0.2), 1.52)
    a = r.pack()
    assert a.dtype == np.float64 and a.shape == (18,)
    assert TargetRecord.unpack(a) == r
    p, v = r.finger_at(1.62)
    assert np.allclose(p, [1.01, 2.0, 2.98]) and np.allclose(v, [0.1, 0.0, -0.2])


def test_scene_step_maps_the_cap_centre_to_the_pad_and_the_target_to_the_end_effector():
    scene = load_scene("wall")
    T = np.eye(4)
    T[:3, 3] = [0.1, 0.0, 0.0]
    step = SceneStep(World(scene, predictor="none"), T, tip_radius_m=0.008, mount_offset=(0.03, 0.0, 0.0))
    rec, inter, pad = step.step(0.0, False, np.full(3, np.nan), 0.0, None)
    assert not rec.armed and inter is None  # nothing seen yet: the servo holds
    rec, inter, pad = step.step(0.1, True, [0.1, 0.0, -0.142], 0.9, None)
    assert np.allclose(pad, [0.2, 0.0, -0.150])
    assert rec.armed and rec.seq == 2 and rec.made_at == 0.1 and rec.confidence == 0.9
    assert np.allclose(rec.X_ee, inter.X_d - [0.03, 0.0, 0.0])
    assert rec.subject == 0 and rec.in_contact and rec.imminent
    # no calibration: the record says so and carries no target
    lost = SceneStep(World(scene, predictor="none"), None, tip_radius_m=0.008, mount_offset=(0.03, 0.0, 0.0))
    rec, inter, _ = lost.step(0.0, True, [0.1, 0.0, -0.142], 0.9, None)
    assert not rec.calibrated and rec.armed and inter is None and not np.isfinite(rec.X_ee).any()


def test_contact_renderer_gates_the_law_and_the_object_gain():
    scene = load_scene("wall")
    c = ContactRenderer(scene.objects, max_force_n=8.5, engage_m=0.0003)
    assert c.update(np.array([0.2, 0.0, -0.151]), np.zeros(3), 0, False)[0] is None  # nothing announced
    F, lam, R, changed = c.update(np.array([0.2, 0.0, -0.1501]), np.zeros(3), 0, True)
    assert F[2] == pytest.approx(800.0 * 0.0001) and lam == (1.0, 1.0, 0.0) and changed  # sagging: lateral servo
    F, lam, R, changed = c.update(np.array([0.2, 0.0, -0.152]), np.zeros(3), 0, True)
    assert F[2] == pytest.approx(1.6) and lam == (0.0, 0.0, 0.0) and np.allclose(R, np.eye(3))  # pressed: slide
    F, lam, _, changed = c.update(np.array([0.2, 0.0, -0.149]), np.zeros(3), 0, True)
    assert F is None and lam is None and changed  # above the surface: free motion again
    panel = load_scene("panel")
    k = [o.name for o in panel.objects].index("key_b")
    kb = ContactRenderer(panel.objects, max_force_n=8.5)
    F, lam, _, _ = kb.update(np.array([0.23, 0.04, -0.152]), np.zeros(3), k, True)
    assert lam == (1.0, 1.0, 0.0) and F[2] > 0  # a key stays put laterally
    # the subject's own law, saturated at the device's force limit
    F, _, _, _ = kb.update(np.array([0.23, 0.04, -0.151]), np.zeros(3), k, True)
    assert F[2] == pytest.approx(500.0 * 0.001)
    small = ContactRenderer(scene.objects, max_force_n=1.0)
    assert np.linalg.norm(small.update(np.array([0.2, 0.0, -0.160]), np.zeros(3), 0, True)[0]) == pytest.approx(1.0)


def test_servo_step_renders_the_law_only_while_announced_and_tracking_or_holding():
    from vishap.robot import kinematics
    from vishap.runtime.assembly import make_servo_step, open_device

    scene = load_scene("wall")
    dev = open_device("sim", passive_object=scene.passive_object.for_mujoco())
    step = make_servo_step(dev, scene)
    p_in = scene.objects[0].centre - np.array([0.0, 0.0, 0.002])  # contact point 2 mm under the wall
    X_ee = tuple(p_in - step.mount)
    dev.reset(kinematics.ik(np.asarray(X_ee)))
    on = TargetRecord(1, X_ee, 0.0, 1.0, True, True, 0, True, True)
    tk = step.tick(0.0, on)
    assert tk.action == "track" and tk.F_law is not None and tk.F_law[2] > 0
    assert np.allclose(step.controller.lambda_robot, np.diag([0.0, 0.0, 0.0]))  # the wall's Λ is set
    bad = TargetRecord(2, (np.nan,) * 3, 0.001, 1.0, True, True, 0, True, True)
    tk = step.tick(0.001, bad)
    assert tk.action == "hold" and tk.F_law is not None  # holding keeps rendering the wall
    off = TargetRecord(3, X_ee, 0.002, 1.0, False, True, 0, True, True)
    tk = step.tick(0.002, off)
    assert tk.action == "retreat" and tk.F_law is None and np.allclose(step.controller.lambda_robot, np.eye(3))
