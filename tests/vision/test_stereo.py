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


def test_covariance_added_later_is_the_same(distorted_rig):
    """A pair checked without its covariance gets, from with_covariance, the floats a plain
    triangulation gives; a point with one, or a failed one, is returned as it is."""
    from vishap.vision.stereo import triangulate_rectified_tip, with_covariance

    rl, rr = np.array([352.25, 261.125]), np.array([301.5, 261.5])
    full = triangulate_rectified_tip(distorted_rig, rl, rr)
    bare = triangulate_rectified_tip(distorted_rig, rl, rr, covariance=False)
    assert bare.ok and bare.cov_cam is None and np.array_equal(bare.p_cam, full.p_cam)
    later = with_covariance(distorted_rig, bare)
    assert np.array_equal(later.p_cam, full.p_cam) and np.array_equal(later.cov_cam, full.cov_cam)
    assert with_covariance(distorted_rig, full) is full
    bad = triangulate_rectified_tip(distorted_rig, rl, rr + (0, 9.0), covariance=False)
    assert not bad.ok and with_covariance(distorted_rig, bad) is bad


def test_epipolar_and_disparity_checks(ideal_rig):
    p = np.array([0.0, 0.0, 0.6])
    uv_l, uv_r = ideal_rig.project(p)
    bad = triangulate_tip(ideal_rig, uv_l[0], uv_r[0] + (0, 5.0))
    assert not bad and "epipolar" in bad.reason
    far = triangulate_tip(ideal_rig, uv_l[0], uv_l[0] + (0.5, 0))  # negative disparity
    assert not far and "disparity" in far.reason
    assert not triangulate_tip(ideal_rig, None, uv_r[0])


def test_a_disparity_at_infinity_is_refused(ideal_rig):
    # a rectification whose zero disparity lies elsewhere (Q[3, 3] ≠ 0): a pair at that disparity has no point
    from vishap.vision.stereo import triangulate_rectified_tip

    Q = ideal_rig.Q.copy()
    Q[3, 3] = -20.0 * Q[3, 2]  # h = Q[3, 2]·d + Q[3, 3] = 0 at d = 20 px
    ideal_rig.Q = Q
    sp = triangulate_rectified_tip(ideal_rig, (320.0, 240.0), (300.0, 240.0))
    assert not sp.ok and "infinity" in sp.reason
    assert triangulate_rectified_tip(ideal_rig, (330.0, 240.0), (300.0, 240.0)).ok


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


# --------------------------------------------------------------------- stereo refinement of the cap centres

def _cap_pair(rig, p, seed):
    """A toy stereo pair (anti-aliased) with the fingertip's cap centre at ``p`` and the cap fits of
    its binary skin masks in both views (the pipeline's input to the refinement)."""
    from vishap.vision.fingertip import detect_fingertips
    from vishap.vision.toy import ToyScene

    f = ToyScene(rig, seed=seed, ss=8, noise=2.0).frame(0.0, p, direction_cam=(0.25, 0.7, 0.3))
    tips = []
    for lab, gt in ((f.labels_left, f.tip_uv_left), (f.labels_right, f.tip_uv_right)):
        cands = detect_fingertips(((lab == 1) * 255).astype(np.uint8), rig.fx_px * 0.0048 / p[2], max_tips=4)
        tips.append(min(cands, key=lambda t: np.hypot(*(t.uv - gt))))
    return f, tips


def _disparity_error(rig, uv_l, uv_r, f):
    rl = rig.rectify_points(np.vstack([uv_l, f.tip_uv_left]), "left")
    rr = rig.rectify_points(np.vstack([uv_r, f.tip_uv_right]), "right")
    return (rl[0, 0] - rr[0, 0]) - (rl[1, 0] - rr[1, 0]), rl[0, 1] - rr[0, 1]


POSITIONS = [(-0.03, 0.01, 0.45), (0.02, -0.02, 0.55), (0.05, 0.02, 0.62), (-0.06, -0.03, 0.7), (0.0, 0.04, 0.78),
             (0.04, 0.0, 0.5)]


@pytest.mark.parametrize("rig_name, method", [("ideal_rig", "edges"), ("ideal_rig", "edges_separate"),
                                              ("distorted_rig", "edges_separate")])
def test_edge_refinement_recovers_the_known_disparity(rig_name, method, request):
    """On anti-aliased images the sub-pixel edges put the disparity within a few hundredths of a
    pixel of the truth (depth 0.45–0.78 m), where the binary masks' cap fits are off by tenths;
    the joint fit also puts both centres on one rectified row. (The joint fit's shared radius is
    not checked on the distorted rig: the toy scene draws both views' caps with the left focal
    length, so their rectified radii differ there.)"""
    from vishap.vision.stereo import RefineConfig, refine_tip_pair

    rig = request.getfixturevalue(rig_name)
    before, after = [], []
    for k, p in enumerate(POSITIONS):
        f, (tl, tr) = _cap_pair(rig, np.array(p), seed=k)
        before.append(_disparity_error(rig, tl.uv, tr.uv, f)[0])
        ref = refine_tip_pair(rig, f.left, f.right, tl, tr, RefineConfig(method=method))
        assert ref.ok, ref.reason
        d_err, row_gap = _disparity_error(rig, ref.uv_left, ref.uv_right, f)
        after.append(d_err)
        if method == "edges":
            assert abs(row_gap) < 1e-6
    rms = lambda x: float(np.sqrt(np.mean(np.square(x))))
    assert rms(after) < 0.06 and rms(after) < 0.5 * rms(before), (rms(before), rms(after))


def test_match_refinement_finds_the_disparity_of_a_textured_patch(ideal_rig, rng):
    """ZNCC along the rectified row: a textured plane at a known depth, the right tip given 1.3 px
    off; the refined right tip lands on the plane's disparity."""
    import cv2

    from vishap.vision.fingertip import Fingertip
    from vishap.vision.stereo import RefineConfig, refine_tip_pair

    rig = ideal_rig
    w, h = rig.image_size
    d = rig.rectified_fx_px * rig.rectified_baseline_m / 0.55
    tex = cv2.GaussianBlur(rng.integers(0, 255, (h, w + 160, 3)).astype(np.uint8), (0, 0), 1.5)
    left = np.ascontiguousarray(tex[:, 80:80 + w])
    right = cv2.warpAffine(tex, np.float32([[1, 0, -(80 + d)], [0, 1, 0]]), (w, h), flags=cv2.INTER_LINEAR)
    uv = np.array([300.0, 240.0])
    tl = Fingertip(True, uv=uv, direction=np.array([0.0, 1.0]), radius_px=5.0, cap_radius_px=8.0)
    tr = Fingertip(True, uv=uv - (d + 1.3, 0.0), direction=np.array([0.0, 1.0]), radius_px=5.0, cap_radius_px=8.0)
    ref = refine_tip_pair(rig, left, right, tl, tr, RefineConfig(method="match"))
    assert ref.ok, ref.reason
    assert np.allclose(ref.uv_left, uv)
    assert abs((ref.uv_left[0] - ref.uv_right[0]) - d) < 0.1


def test_refinement_refuses_what_it_cannot_measure(ideal_rig):
    from vishap import VisionError
    from vishap.vision.fingertip import Fingertip
    from vishap.vision.stereo import RefineConfig, refine_tip_pair

    flat = np.full((480, 640, 3), 128, np.uint8)  # no edge anywhere
    tip = Fingertip(True, uv=np.array([320.0, 240.0]), direction=np.array([0.0, 1.0]), radius_px=5.0, cap_radius_px=8.0)
    tip_r = Fingertip(True, uv=np.array([280.0, 240.0]), direction=np.array([0.0, 1.0]), radius_px=5.0, cap_radius_px=8.0)
    ref = refine_tip_pair(ideal_rig, flat, flat, tip, tip_r, RefineConfig(method="edges"))
    assert not ref.ok and "edge points" in ref.reason
    with pytest.raises(VisionError, match="refine method"):
        RefineConfig(method="dense")
