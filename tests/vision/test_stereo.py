import numpy as np
import pytest

from vishap.vision.stereo import DenseMatcher, StereoConfig, dense_tip, triangulate_tip


@pytest.mark.parametrize("rig_name", ["ideal_rig", "distorted_rig"])
def test_sparse_triangulation_recovers_the_point(rig_name, request):
    rig = request.getfixturevalue(rig_name)
    p = np.array([0.03, -0.02, 0.6])
    uv_l, uv_r = rig.project(p)
    sp = triangulate_tip(rig, uv_l[0], uv_r[0])
    assert sp.ok and np.allclose(sp.p_cam, p, atol=1e-7)
    assert sp.cov_cam.shape == (3, 3) and np.all(np.linalg.eigvalsh(sp.cov_cam) > 0)


def test_covariance_matches_monte_carlo(ideal_rig, rng):
    p = np.array([0.02, 0.01, 0.7])
    uv_l, uv_r = ideal_rig.project(p)
    cfg = StereoConfig(sigma_px=0.3)
    samples = []
    for _ in range(2000):
        sp = triangulate_tip(ideal_rig, uv_l[0] + rng.normal(0, 0.3, 2), uv_r[0] + rng.normal(0, 0.3, 2), cfg)
        samples.append(sp.p_cam)
    emp = np.cov(np.array(samples).T)
    model = triangulate_tip(ideal_rig, uv_l[0], uv_r[0], cfg).cov_cam
    assert np.allclose(np.sqrt(np.diag(emp)), np.sqrt(np.diag(model)), rtol=0.1)


def test_epipolar_and_disparity_checks(ideal_rig):
    p = np.array([0.0, 0.0, 0.6])
    uv_l, uv_r = ideal_rig.project(p)
    bad = triangulate_tip(ideal_rig, uv_l[0], uv_r[0] + (0, 5.0))
    assert not bad and "epipolar" in bad.reason
    far = triangulate_tip(ideal_rig, uv_l[0], uv_l[0] + (0.5, 0))  # negative disparity
    assert not far and "disparity" in far.reason
    assert not triangulate_tip(ideal_rig, None, uv_r[0])


def test_dense_sgbm_depth_of_a_textured_plane(ideal_rig, rng):
    import cv2

    rig = ideal_rig
    z = 0.5
    w, h = rig.image_size
    d = rig.rectified_fx_px * rig.rectified_baseline_m / z
    tex = cv2.resize(rng.integers(0, 255, (h // 4, w // 4 + 40, 3)).astype(np.uint8), (w + 160, h),
                     interpolation=cv2.INTER_LINEAR)
    left = np.ascontiguousarray(tex[:, 80:80 + w])
    M = np.float32([[1, 0, -(80 + d)], [0, 1, 0]])
    right = cv2.warpAffine(tex, M, (w, h), flags=cv2.INTER_LINEAR)
    sp = dense_tip(DenseMatcher(rig, "sgbm"), left, right, (320.0, 240.0))
    assert sp.ok and abs(sp.p_cam[2] - z) < 0.01
