import numpy as np
import pytest
from hypothesis import assume, given, settings
from hypothesis import strategies as st
from scipy.spatial.transform import Rotation

from vishap._core.errors import CalibrationError, ShapeError
from vishap._core.pose import from_rt, is_rotation, rotvec_to_matrix
from vishap.registration import RigidTransform

coord = st.floats(-1.0, 1.0, allow_nan=False, allow_infinity=False)


def _random_T(rng):
    return from_rt(Rotation.random(random_state=rng.integers(1 << 31)).as_matrix(), rng.uniform(-1, 1, 3))


@settings(max_examples=60, deadline=None)
@given(
    st.lists(st.tuples(coord, coord, coord), min_size=3, max_size=25),
    st.tuples(st.floats(-4, 4), st.floats(-4, 4), st.floats(-4, 4)),
    st.tuples(coord, coord, coord),
)
def test_recovers_exact_transform(points, rotvec, t):
    p_src = np.array(points)
    q = p_src - p_src.mean(axis=0)
    s = np.linalg.svd(q, compute_uv=False)
    assume(s[1] > 1e-3 * max(s[0], 1e-9) and s[0] > 1e-6)  # well-conditioned (not near-collinear)
    T_true = from_rt(rotvec_to_matrix(rotvec), t)
    p_dst = p_src @ T_true[:3, :3].T + T_true[:3, 3]
    est = RigidTransform.from_estimate(p_src, p_dst)
    assert est, est.reason
    assert is_rotation(est.R)
    assert np.allclose(est.T, T_true, atol=1e-7)
    assert np.max(est.residuals()) < 1e-7


@settings(max_examples=40, deadline=None)
@given(st.lists(st.tuples(coord, coord, coord), min_size=0, max_size=12), st.integers(0, 4))
def test_never_raises_and_always_proper(points, nan_at):
    """Arbitrary (possibly degenerate) input: either a proper rotation or a falsy estimate."""
    p_src = np.array(points, dtype=float).reshape(-1, 3)
    p_dst = p_src[:, ::-1] * 2.0 + 0.1  # a reflection and a scale: no rigid transform fits exactly
    if nan_at < len(p_src) and nan_at == 2:
        p_dst[nan_at, 1] = np.nan
    est = RigidTransform.from_estimate(p_src, p_dst)
    if est:
        assert is_rotation(est.R)
        assert np.all(np.isfinite(est.T))
    else:
        assert est.reason
        with pytest.raises(CalibrationError):
            est.T


def test_reflection_never_returned(rng):
    p_src = rng.normal(size=(10, 3))
    p_dst = p_src * np.array([1.0, 1.0, -1.0])  # a mirror image
    est = RigidTransform.from_estimate(p_src, p_dst)
    assert est and is_rotation(est.R)
    assert np.linalg.det(est.R) == pytest.approx(1.0)


def test_agrees_with_scipy_align_vectors(rng):
    T = _random_T(rng)
    p_src = rng.normal(size=(40, 3)) * 0.1
    p_dst = p_src @ T[:3, :3].T + T[:3, 3] + rng.normal(scale=1e-3, size=(40, 3))
    w = rng.uniform(0.2, 3.0, 40)
    est = RigidTransform.from_estimate(p_src, p_dst, weights=w)
    # scipy's Kabsch on weighted, centred vectors gives the same rotation
    mu_s = np.average(p_src, axis=0, weights=w)
    mu_d = np.average(p_dst, axis=0, weights=w)
    rot, _ = Rotation.align_vectors(p_dst - mu_d, p_src - mu_s, weights=w)
    assert np.allclose(est.R, rot.as_matrix(), atol=1e-10)
    assert np.allclose(est.t, mu_d - est.R @ mu_s, atol=1e-12)


def test_weights_zero_ignores_pair_and_integer_weights_equal_duplicates(rng):
    T = _random_T(rng)
    p_src = rng.normal(size=(8, 3))
    p_dst = p_src @ T[:3, :3].T + T[:3, 3] + rng.normal(scale=0.01, size=(8, 3))
    bad = p_dst.copy()
    bad[0] += 5.0
    w = np.ones(8)
    w[0] = 0.0
    a = RigidTransform.from_estimate(p_src, bad, weights=w)
    b = RigidTransform.from_estimate(p_src[1:], p_dst[1:])
    assert np.allclose(a.T, b.T, atol=1e-12)
    w2 = np.array([2, 1, 1, 3, 1, 1, 1, 1], dtype=float)
    c = RigidTransform.from_estimate(p_src, p_dst, weights=w2)
    d = RigidTransform.from_estimate(np.repeat(p_src, w2.astype(int), axis=0), np.repeat(p_dst, w2.astype(int), axis=0))
    assert np.allclose(c.T, d.T, atol=1e-12)


@pytest.mark.parametrize(
    "p_src, weights, expect",
    [
        (np.zeros((0, 3)), None, "at least 3"),
        (np.array([[0, 0, 0], [1, 0, 0.0]]), None, "at least 3"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), [1, 1, 0], "at least 3"),
        (np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2], [3, 3, 3.0]]), None, "collinear"),
        (np.ones((5, 3)), None, "coincide"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, np.nan, 0]]), None, "NaN"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, np.inf, 0]]), None, "NaN or inf"),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0.0]]), [1, -1, 1], "non-negative"),
    ],
)
def test_degenerate_input_is_a_falsy_estimate(p_src, weights, expect):
    p_dst = np.nan_to_num(p_src, nan=0.0, posinf=0.0) + 1.0
    est = RigidTransform.from_estimate(p_src, p_dst, weights=weights)
    assert not est
    assert expect in est.reason
    with pytest.raises(CalibrationError, match="failed"):
        est.apply([0.0, 0.0, 0.0])


def test_nan_in_destination_and_shape_errors():
    p = np.eye(3)
    q = p.copy()
    q[1, 2] = np.nan
    est = RigidTransform.from_estimate(p, q)
    assert not est and "p_dst" in est.reason
    with pytest.raises(ShapeError):
        RigidTransform.from_estimate(np.zeros((4, 2)), np.zeros((4, 2)))
    with pytest.raises(ShapeError):
        RigidTransform.from_estimate(np.zeros((4, 3)), np.zeros((5, 3)))


def test_apply_inverse_residuals_and_report(rng):
    T = _random_T(rng)
    p_cam = rng.uniform(-0.1, 0.1, size=(20, 3)) + [0, 0, 0.6]
    noise = rng.normal(scale=0.5e-3, size=(20, 3))
    p_robot = p_cam @ T[:3, :3].T + T[:3, 3] + noise
    est = RigidTransform.from_estimate(p_cam, p_robot)
    assert np.allclose(est.apply(p_cam[0]), est.apply(p_cam)[0])
    inv = est.inverse()
    assert np.allclose(inv.T @ est.T, np.eye(4), atol=1e-12)
    assert np.allclose(inv.apply(est.apply(p_cam)), p_cam, atol=1e-12)
    assert np.allclose(inv.residuals(), est.residuals(), atol=1e-12)  # a rigid map keeps distances
    r = est.residuals()
    assert r.shape == (20,)
    assert np.allclose(r, np.linalg.norm(est.apply(p_cam) - p_robot, axis=1))
    rep = est.error_report()
    assert rep["pairs"] == 20 and len(rep["per_axis_error_mm"]) == 3
    assert rep["rms_mm"] == pytest.approx(np.sqrt(np.mean(r**2)) * 1e3)
    # a least-squares fit on 20 pairs leaves less error than the noise it was fitted to
    assert rep["rms_mm"] < np.sqrt(np.mean(np.sum(noise**2, axis=1))) * 1e3
    cmp = est.compare(T)
    assert cmp["rotation_error_deg"] < 0.5 and cmp["translation_error_mm"] < 2.0


@pytest.mark.parametrize("threshold", [None, 2e-3])
def test_robust_mode_rejects_30_percent_outliers(rng, threshold):
    T = _random_T(rng)
    n = 60
    p_src = rng.uniform(-0.1, 0.1, size=(n, 3))
    p_dst = p_src @ T[:3, :3].T + T[:3, 3] + rng.normal(scale=0.3e-3, size=(n, 3))
    out = rng.choice(n, int(0.3 * n), replace=False)
    p_dst[out] += rng.uniform(-0.05, 0.05, size=(len(out), 3))
    plain = RigidTransform.from_estimate(p_src, p_dst)
    robust = RigidTransform.from_estimate_robust(p_src, p_dst, threshold=threshold, seed=3)
    assert robust, robust.reason
    truth = np.ones(n, bool)
    truth[out] = False
    big = np.linalg.norm(p_dst - (p_src @ T[:3, :3].T + T[:3, 3]), axis=1) > 3e-3
    assert not np.any(robust.inliers & big)  # no gross outlier kept
    assert np.sum(robust.inliers & truth) >= 0.95 * truth.sum()
    assert robust.compare(T)["translation_error_mm"] < 0.5
    assert robust.compare(T)["rotation_error_deg"] < 0.5
    assert plain.compare(T)["translation_error_mm"] > 3 * robust.compare(T)["translation_error_mm"]


def test_robust_mode_on_clean_data_equals_closed_form(rng):
    T = _random_T(rng)
    p_src = rng.uniform(-0.1, 0.1, size=(30, 3))
    p_dst = p_src @ T[:3, :3].T + T[:3, 3] + rng.normal(scale=0.2e-3, size=(30, 3))
    a = RigidTransform.from_estimate(p_src, p_dst)
    b = RigidTransform.from_estimate_robust(p_src, p_dst)
    assert b.inliers.sum() >= 29
    if b.inliers.all():
        assert np.allclose(a.T, b.T, atol=1e-12)
    assert not RigidTransform.from_estimate_robust(np.eye(3)[:2], np.eye(3)[:2])
