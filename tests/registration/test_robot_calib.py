"""The camera-to-robot procedure on a stand-in: analytic sphere images and ideal kinematics."""
import numpy as np
import pytest

from vishap._core.errors import CalibrationError
from vishap._core.pose import from_rt, invert
from vishap.registration.robot_calib import REACHABLE_BOX, measure, report, select_poses, solve
from vishap.vision.rig import StereoRig


def look_at(eye, target):
    """T_robot_cam of a camera at ``eye`` looking at ``target`` (robot z up → image y down)."""
    z = np.asarray(target, float) - eye
    z /= np.linalg.norm(z)
    x = np.cross(z, [0.0, 0.0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    return from_rt(np.column_stack([x, y, z]), eye)


def sphere_pair(rig, T_robot_cam, p_robot, radius_m=0.005, ss=4, noise=0.0, rng=None, hide=0.0):
    """Anti-aliased, shaded green sphere images of the marker at ``p_robot`` (grey background)."""
    T_cam_robot = invert(T_robot_cam)
    p_cam = T_cam_robot[:3, :3] @ p_robot + T_cam_robot[:3, 3]
    imgs = []
    for uv, K, z in zip(rig.project(p_cam), (rig.K_left, rig.K_right), (p_cam[2], (rig.R @ p_cam + rig.T)[2])):
        w, h = rig.image_size
        img = np.full((h, w, 3), (105.0, 118.0, 126.0))
        c = uv[0]
        r = K[0, 0] * radius_m / z
        x0, y0 = int(c[0] - r - 3), int(c[1] - r - 3)
        n = int(2 * r + 7)
        yy, xx = np.mgrid[0 : n * ss, 0 : n * ss]
        u = x0 + (xx + 0.5) / ss - 0.5
        v = y0 + (yy + 0.5) / ss - 0.5
        dx, dy = (u - c[0]) / r, (v - c[1]) / r
        inside = dx * dx + dy * dy <= 1
        nz = np.sqrt(np.clip(1 - dx * dx - dy * dy, 0, 1))
        lam = np.clip(0.3 * dx - 0.4 * dy + 0.87 * nz, 0, 1)
        patch = np.where(inside[..., None], np.stack([0 * lam, 30 + 225 * lam, 0 * lam], -1), img[0, 0])
        patch = patch.reshape(n, ss, n, ss, 3).mean(axis=(1, 3))
        img[y0 : y0 + n, x0 : x0 + n] = patch
        if hide and len(imgs) == 0:  # a dark link in front of the left edge of the marker (left image)
            img[:, : int(round(c[0] - r + 2 * r * hide))] = (40.0, 40.0, 40.0)
        if noise:
            img += rng.normal(0, noise, img.shape)
        imgs.append(np.clip(np.round(img), 0, 255).astype(np.uint8))
    return imgs


@pytest.fixture
def setup():
    rig = StereoRig.from_fov(320, 240, 60.0, 0.06)
    T_true = look_at(np.array([0.2, -0.5, 0.15]), np.array([0.2, 0.0, -0.12]))
    return rig, T_true


def test_select_poses_span_the_box():
    p = select_poses(12, seed=3)
    assert p.shape == (12, 3)
    lo, hi = REACHABLE_BOX[:, 0] + 0.01, REACHABLE_BOX[:, 1] - 0.01
    assert np.all(p >= lo - 1e-12) and np.all(p <= hi + 1e-12)
    # the extremes of the box are used: each coordinate reaches both ends
    assert np.allclose(p.min(axis=0), lo) and np.allclose(p.max(axis=0), hi)
    # no two poses close together (maximin design)
    d = np.linalg.norm(p[:, None] - p[None], axis=-1) + np.eye(12)
    assert d.min() > 0.04
    # a reachability filter is honoured
    q = select_poses(6, seed=3, reachable=lambda x: x[0] < 0.2)
    assert np.all(q[:, 0] < 0.2)
    with pytest.raises(CalibrationError, match="at least 3"):
        select_poses(2)


def test_procedure_recovers_transform(setup, rng):
    rig, T_true = setup
    targets = select_poses(10, seed=1)
    obs = measure(targets, rig, move_to=lambda t: t.copy(),
                  grab=lambda p, t: sphere_pair(rig, T_true, p, noise=1.0, rng=rng))
    assert obs.ok.all(), obs.reasons
    for kw in ({}, {"robust": True}, {"refine": True}):
        fit = solve(obs, rig, **kw)
        rep = report(fit, obs, T_true, rig=rig)
        assert rep["poses_used"] == 10
        assert max(rep["per_axis_error_mm"]) < 0.5, (kw, rep)
        assert rep["rotation_error_deg"] < 0.3 and rep["translation_error_mm"] < 1.5, (kw, rep)
        assert rep["reprojection_rms_px"] < 0.3


def test_occluded_or_unreachable_poses_are_dropped_and_reported(setup, rng):
    _, T_true = setup
    rig = StereoRig.from_fov(640, 480, 60.0, 0.06)  # marker radius ≈ 5 px
    targets = select_poses(6, seed=2)
    blank = np.full((480, 640, 3), 120, np.uint8)

    def grab(p, t):
        if np.array_equal(t, targets[1]):
            return blank, blank
        return sphere_pair(rig, T_true, p, hide=0.2 if np.array_equal(t, targets[2]) else 0.0)  # 16 % of it

    obs = measure(targets, rig, move_to=lambda t: None if np.array_equal(t, targets[0]) else t.copy(), grab=grab)
    assert obs.ok.tolist() == [False, False, False, True, True, True]
    rep = report(solve(obs, rig), obs, T_true)
    assert rep["poses_used"] == 3
    assert [d["index"] for d in rep["poses_dropped"]] == [0, 1, 2]
    assert "reachable" in rep["poses_dropped"][0]["reason"] and "green" in rep["poses_dropped"][1]["reason"]
    assert "left: marker area" in rep["poses_dropped"][2]["reason"]
    # fewer than 3 measured poses: a failed fit, and report refuses it
    obs.p_cam[4:] = np.nan
    fit = solve(obs, rig)
    assert not fit and "only 1 pose" in fit.reason
    with pytest.raises(CalibrationError, match="failed"):
        report(fit, obs)


def test_a_dropped_pose_and_a_stop_end_the_visit_as_told(setup, rng):
    """move_to/grab raise PoseDropped (that pose is lost, with its reason) or StopMeasuring (no more poses)."""
    from vishap.registration.robot_calib import PoseDropped, StopMeasuring

    rig, T_true = setup
    targets = select_poses(8, seed=4)

    def move_to(t):
        if np.array_equal(t, targets[1]):
            raise PoseDropped("did not settle")
        if np.array_equal(t, targets[6]):
            raise StopMeasuring("source ended")
        return t.copy()

    obs = measure(targets, rig, move_to=move_to, grab=lambda p, t: sphere_pair(rig, T_true, p, noise=1.0, rng=rng))
    assert len(obs.targets_robot) == 6 and obs.ok.tolist() == [True, False, True, True, True, True]
    assert obs.reasons[1] == "did not settle" and np.isnan(obs.p_robot[1]).all()
    assert max(report(solve(obs, rig), obs, T_true)["per_axis_error_mm"]) < 0.5
