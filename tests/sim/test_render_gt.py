"""Rendered ground truth is self-consistent: projections, visibility, labels (tiny 160×120 renders)."""
from __future__ import annotations

import numpy as np
import pytest

from vishap._core.pose import invert, transform_points
from vishap.sim.sequence import SequenceSpec, generate, tip_visible
from vishap.vision.rig import StereoRig

pytestmark = pytest.mark.render


def _small_distorted_rig() -> StereoRig:
    from vishap._core.pose import rotvec_to_matrix

    K1 = np.array([[140.0, 0.0, 80.5], [0.0, 139.5, 60.4], [0.0, 0.0, 1.0]])
    K2 = np.array([[138.0, 0.0, 79.2], [0.0, 138.4, 59.5], [0.0, 0.0, 1.0]])
    return StereoRig(image_size=(160, 120), K_left=K1, dist_left=np.array([-0.21, 0.08, 0.0012, -0.0007, -0.012]),
                     K_right=K2, dist_right=np.array([-0.19, 0.05, -0.0004, 0.0009, 0.0]),
                     R=rotvec_to_matrix([0.004, -0.03, 0.002]), T=np.array([-0.0601, 0.0007, 0.0012]))


@pytest.mark.parametrize("scene,seed,start_s", [("wall", 0, 2.0), ("button", 1, 1.8), ("fabric", 2, 2.6),
                                                ("wall", 7, 5.0)])
def test_tip_projection_visibility_and_skin_label(scene, seed, start_s):
    spec = SequenceSpec(scene=scene, frames=3, seed=seed, width=160, height=120, start_s=start_s, effects=False)
    n_vis = 0
    for state, pair, row in generate(spec):
        T = np.asarray(row["tip_cam"])
        np.testing.assert_allclose(transform_points(invert(_T(spec)), state.tip_robot), T, atol=1e-12)
        rig = StereoRig.from_fov(160, 120, 60.0, 0.06)
        uvl, uvr = rig.project(T)
        assert np.abs(uvl[0] - row["tip_uv_left"]).max() < 0.01
        assert np.abs(uvr[0] - row["tip_uv_right"]).max() < 0.01
        for side in ("left", "right"):
            if row[f"tip_visible_{side}"]:
                n_vis += 1
                u, v = (int(np.floor(c + 0.5)) for c in row[f"tip_uv_{side}"])
                assert getattr(pair, f"labels_{side}")[v, u] == 1
        assert pair.left.shape == (120, 160, 3) and pair.labels_left.dtype == np.uint8
    assert n_vis >= 4  # the camera placement keeps the fingertip in view while it works


def _T(spec):
    from vishap.sim.camera_placement import default_T_robot_cam

    return default_T_robot_cam()


def test_distorted_rig_tip_pixel_is_skin():
    rig = _small_distorted_rig()
    spec = SequenceSpec(scene="wall", frames=2, seed=4, rig=rig, start_s=3.0, effects=False)
    n_vis = 0
    for _, pair, row in generate(spec):
        uvl, uvr = rig.project(row["tip_cam"])
        assert np.abs(uvl[0] - row["tip_uv_left"]).max() < 0.01
        for side in ("left", "right"):
            if row[f"tip_visible_{side}"]:
                n_vis += 1
                u, v = (int(np.floor(c + 0.5)) for c in row[f"tip_uv_{side}"])
                assert getattr(pair, f"labels_{side}")[v, u] == 1
    assert n_vis >= 2


def test_hidden_tip_is_not_visible():
    """Hand-free frames and a tip outside the image are never marked visible."""
    spec = SequenceSpec(scene="wall", frames=2, seed=0, width=160, height=120, effects=False)
    for state, pair, row in generate(spec):
        assert not state.hand_visible
        assert not row["tip_visible_left"] and not row["tip_visible_right"]
        assert not np.any(pair.labels_left == 1)
    depth = np.full((120, 160), 0.5, np.float32)
    assert not tip_visible(np.array([-3.0, 50.0]), 0.5, depth)
    assert tip_visible(np.array([10.0, 50.0]), 0.505, depth)
    assert not tip_visible(np.array([10.0, 50.0]), 0.6, depth)  # something 10 cm in front of it


def test_alpha_labels_equal_the_flat_label_pass_with_an_occluder():
    """Labels from the colour pass's alpha equal a flat segmentation pass (rod in front of the finger)."""
    from vishap.sim.sequence import frame_state, make_renderer, prepare

    p = prepare(SequenceSpec(scene="wall", frames=330, seed=1, width=160, height=120, effects=False))
    t = next(float(t) for t in p.times if frame_state(p, float(t))[1]["occluder_present"]) + 0.4
    state, _ = frame_state(p, t)
    assert state.occluder is not None
    r = make_renderer(p)
    try:
        a, b = r.render(state, labels="alpha"), r.render(state, labels="seg")
        c = r.render(state, labels="none")
    finally:
        r.close()
    np.testing.assert_array_equal(a.labels_left, b.labels_left)
    np.testing.assert_array_equal(a.labels_right, b.labels_right)
    assert (a.labels_left == 1).sum() > 20 and not c.labels_left.any()
    np.testing.assert_array_equal(a.left, c.left)
