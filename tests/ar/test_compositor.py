"""The augmented view: deletion against a render without the device, the hand kept in front, the
objects registered through the calibration, contact shown, bad input as plain video with a note."""
from __future__ import annotations

import cv2
import numpy as np
import pytest

from vishap.ar import ARCompositor, Contact, ObjectLayer, ViewCamera, object_corners_robot
from vishap.sim.camera_placement import default_T_robot_cam
from vishap.sim.device import device_links
from vishap.sim.state import FrameState
from vishap.vision.rig import StereoRig
from vishap.world.scene import load_scene


def _psnr(a, b):
    return 10 * np.log10(255.0 ** 2 / np.mean((a.astype(float) - b.astype(float)) ** 2))


def _rig():
    return StereoRig.from_fov(160, 120, 60.0, 0.06)


@pytest.mark.render
def test_device_deleted_and_hand_kept_in_front_of_the_objects(frames_factory):
    f = frames_factory("wall")
    p = f.prep
    ar = ARCompositor(p.rig, p.T_robot_cam, load_scene("wall"), f.geometry)
    no_hand = np.zeros((120, 160), np.uint8)
    # the arm visits a few poses hand-free first (as in the calibration sweep)
    for k, ee in enumerate([(0.14, -0.05, -0.08), (0.26, 0.05, -0.06), (0.20, -0.04, -0.16), (0.28, 0.0, -0.12)]):
        ee = np.asarray(ee)
        s = FrameState(t=0.5 * k, tip_robot=np.array([0.3, 0, 0]), hand_visible=False,
                       device_points_robot=device_links(ee), ee_robot=ee, passive_object=p.passive)
        ar.compose(f.render.render(s).left, no_hand, f.q(s), 0.5 * k)
    t0 = 2.0
    for k, t in enumerate(p.times[:10]):  # hand-free frames: the compositor's own skin segmenter learns
        s = f.state(t)
        left = f.render.render(s).left
        out = ar.compose(left, None, f.q(s), t0 + t)
        if k < 9:
            rows = np.nonzero(np.any(out != left, axis=(1, 2)))[0]
            assert rows.size and rows.max() < 40  # a note only
    contact_times = [t for t in p.times[10:] if p.trajectory.sample(float(t)).in_contact][:6]
    assert contact_times
    for t in contact_times:
        s = f.state(t)
        pair = f.render.render(s)
        out = ar.compose(pair.left, None, f.q(s), t0 + t)
    truth = f.render_free.render(f.without_device(s)).left
    dev = pair.labels_left == 2
    region = ar.last["region"] > 0
    assert np.count_nonzero(dev & ~region) / dev.sum() < 0.01
    deleted = ar.last["deleted"]
    assert _psnr(deleted[dev], truth[dev]) > 24.0
    assert _psnr(deleted[dev], truth[dev]) > _psnr(pair.left[dev], truth[dev]) + 12.0
    # the hand in front: skin pixels are the camera's own; object pixels elsewhere are drawn
    skin = ar.last["skin"] > 0
    cover = ar.last["cover"] > 0
    assert np.count_nonzero(skin & cover) > 10
    assert np.array_equal(out[skin], pair.left[skin])
    inner = cv2.erode(ar.last["cover"], np.ones((3, 3), np.uint8)) > 0
    drawn = inner & ~cv2.dilate(ar.last["skin"], np.ones((3, 3), np.uint8)).astype(bool)
    assert np.mean(np.any(out[drawn] != deleted[drawn], axis=1)) > 0.95
    # and the hand really is where the labels say, inside the objects' cover
    hand = pair.labels_left[cover] == 1
    assert np.mean(skin[cover] == hand) > 0.95


@pytest.mark.parametrize("scene", ["wall", "button", "fabric"])
def test_overlay_is_registered_through_the_calibration(scene):
    rig = _rig()
    T = default_T_robot_cam(baseline_m=0.06)
    sc = load_scene(scene)
    cam = ViewCamera(rig, T)
    _, cover = ObjectLayer(sc, cam).draw()
    for obj in sc.objects:
        uv = cam.project_robot(object_corners_robot(obj))
        # the corners as the rig projects them (the renderer's convention, pixel centres at integers)
        poly = np.zeros((120, 160), np.uint8)
        cv2.fillConvexPoly(poly, np.round(uv * 16).astype(np.int32), 255, cv2.LINE_8, 4)
        inside = cv2.erode(poly, np.ones((3, 3), np.uint8)) > 0
        assert inside.sum() > 30 and (cover[inside] > 0).all()
        # the top face is the object's upper outline: nothing is drawn above its far edge
        top_row = int(np.floor(uv[:, 1].min())) - 2
        assert not cover[: max(0, top_row)].any()


def test_registration_moves_with_the_calibration():
    rig = _rig()
    T = default_T_robot_cam(baseline_m=0.06)
    T2 = T.copy()
    T2[:3, 3] += [0.0, 0.0, 0.01]  # a calibration 1 cm off moves the drawn object
    sc = load_scene("wall")
    _, c1 = ObjectLayer(sc, ViewCamera(rig, T)).draw()
    _, c2 = ObjectLayer(sc, ViewCamera(rig, T2)).draw()
    assert np.count_nonzero(c1 != c2) > 50


def test_key_sinks_by_its_travel_and_fabric_dents_at_the_contact():
    rig = StereoRig.from_fov(320, 240, 60.0, 0.06)
    T = default_T_robot_cam(baseline_m=0.06)
    cam = ViewCamera(rig, T)
    key = load_scene("button")
    layer = ObjectLayer(key, cam)
    up, _ = layer.draw()
    down, _ = layer.draw(travel={"key": 0.004})
    changed = np.any(up != down, axis=2)
    assert changed.sum() > 20
    obj = key.objects[0]
    box = cam.project_robot(object_corners_robot(obj))
    ys, xs = np.nonzero(changed)
    assert xs.min() >= box[:, 0].min() - 1 and xs.max() <= box[:, 0].max() + 1  # only inside the bezel
    over, _ = layer.draw(travel={"key": 0.02})  # clipped to the key's travel
    assert np.array_equal(over, down)

    fab = load_scene("fabric")
    flat_layer = ObjectLayer(fab, cam)
    flat, _ = flat_layer.draw()
    p = np.array([0.21, 0.01, -0.150])
    dented, _ = flat_layer.draw(dent=("fabric", p, 0.004))
    diff = np.any(flat != dented, axis=2)
    assert diff.sum() > 30
    ys, xs = np.nonzero(diff)
    uv = cam.project_robot(p)[0]
    assert np.hypot(xs - uv[0], ys - uv[1]).max() < 3 * 0.008 / 0.0025 * 2  # within the dent's reach


def test_contact_is_routed_to_the_object_under_it():
    rig = StereoRig.from_fov(320, 240, 60.0, 0.06)
    sc = load_scene("button")
    ar = ARCompositor(rig, default_T_robot_cam(baseline_m=0.06), sc, "phantom_premium_1_0")
    img = np.full((240, 320, 3), 120, np.uint8)
    q = np.array([0.0, 0.2, 0.3])
    no_skin = np.zeros((240, 320), np.uint8)
    rest = ar.compose(img, no_skin, q, 0.0)
    pressed = ar.compose(img, no_skin, q, 0.1, contact=Contact((0.2, 0.0, -0.152), 0.002))
    away = ar.compose(img, no_skin, q, 0.2, contact=Contact((0.0, 0.3, -0.152), 0.002))
    assert not np.array_equal(rest, pressed) and np.array_equal(rest, away)


@pytest.mark.parametrize("case", ["no_calibration", "bad_calibration", "unknown_device", "no_joint_state"])
def test_bad_input_gives_the_plain_video_with_a_note(case, rng):
    rig = _rig()
    T = default_T_robot_cam(baseline_m=0.06)
    sc = load_scene("wall")
    device, q = "phantom_premium_1_0", np.array([0.0, 0.2, 0.3])
    if case == "no_calibration":
        T = None
    elif case == "bad_calibration":
        T = T.copy()
        T[:3, :3] *= 1.5  # not a rotation
    elif case == "unknown_device":
        device = "omega_7"
    else:
        q = np.array([np.nan, 0.2, 0.3])
    ar = ARCompositor(rig, T, sc, device)
    img = rng.integers(0, 256, (120, 160, 3), dtype=np.uint8)
    out = ar.compose(img, np.zeros((120, 160), np.uint8), q, 0.0)
    rows = np.nonzero(np.any(out != img, axis=(1, 2)))[0]
    assert rows.size and rows.max() < 40           # only the note's band at the top differs
    assert np.array_equal(out[40:], img[40:])      # no overlay, no deletion
    word = {"no_calibration": "calibration", "bad_calibration": "calibration unusable",
            "unknown_device": "omega_7", "no_joint_state": None}[case]
    if word:
        assert not ar.enabled and word in ar.reason


def test_right_camera_projects_like_the_rig(distorted_rig, rng):
    T = default_T_robot_cam(baseline_m=0.06)
    cam = ViewCamera(distorted_rig, T, "right")
    p_robot = np.array([0.2, 0.0, -0.15]) + rng.normal(0, 0.03, (20, 3))
    from vishap._core.pose import invert, transform_points

    _, uv_r = distorted_rig.project(transform_points(invert(T), p_robot))
    np.testing.assert_allclose(cam.project_robot(p_robot), uv_r, atol=1e-9)
    # the per-pixel rays of the right camera reproject onto their pixels
    rays = cam.rays()
    for v, u in rng.integers(0, [480, 640], (10, 2)):
        uv = cam.project_cam(rays[v, u].astype(np.float64) * 0.4)
        np.testing.assert_allclose(uv[0], [u, v], atol=1e-3)


def test_a_shared_segmenter_is_left_to_the_vision_to_learn(rng):
    from vishap.vision.segment import Segmenter
    from vishap.vision.skin_model import SkinModel

    rig = _rig()
    seg = Segmenter(SkinModel.load())
    ar = ARCompositor(rig, default_T_robot_cam(baseline_m=0.06), load_scene("wall"), "phantom_premium_1_0",
                      segmenter=seg)
    img = rng.integers(90, 140, (120, 160, 3), dtype=np.uint8)
    q = np.array([0.0, 0.2, 0.3])
    for k in range(12):
        out = ar.compose(img, None, q, 0.1 * k)
        assert np.array_equal(out[40:], img[40:])   # passed through with a note
    assert not seg.learned                          # the compositor did not learn the vision's model
    seg.learn([img] * 3)
    out = ar.compose(img, None, q, 2.0)
    assert not np.array_equal(out[40:], img[40:])   # now the augmented view
