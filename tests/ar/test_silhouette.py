"""The device's silhouette from joint state + calibration covers the rendered device (label 2)."""
from __future__ import annotations

import numpy as np
import pytest

from vishap.ar import ViewCamera, device_geometry, device_silhouette
from vishap.ar.device_geometry import Part, part_hull_points_cam
from vishap._core.errors import ConfigError
from vishap.registration.sim import scaled_rig


@pytest.mark.render
@pytest.mark.parametrize("distorted", [False, True])
def test_silhouette_covers_the_rendered_device_in_both_views(frames_factory, distorted_rig, distorted):
    rig = scaled_rig(distorted_rig, (160, 120)) if distorted else None
    f = frames_factory("button", rig=rig)
    cams = {s: ViewCamera(f.prep.rig, f.prep.T_robot_cam, s) for s in ("left", "right")}
    for t in (0.2, 2.0, 3.1):
        s = f.state(t)
        pair = f.render.render(s)
        for side, cam in cams.items():
            labels = getattr(pair, f"labels_{side}")
            dev = labels == 2
            mask = device_silhouette(f.geometry, f.q(s), cam, margin_px=0) > 0
            assert dev.sum() > 200
            assert np.count_nonzero(dev & ~mask) / dev.sum() < 0.01          # < 1 % of device pixels left
            assert np.count_nonzero(mask & ~dev & (labels != 1)) / dev.sum() < 0.35  # and not a blanket


@pytest.mark.render
def test_silhouette_follows_the_joint_state(frames_factory):
    f = frames_factory("wall")
    cam = ViewCamera(f.prep.rig, f.prep.T_robot_cam)
    s = f.state(2.0)
    dev = f.render.render(s).labels_left == 2
    q = f.q(s) + np.array([0.25, 0.0, 0.0])  # the arm turned away: its links must leave the silhouette
    mask = device_silhouette(f.geometry, q, cam, margin_px=1) > 0
    assert np.count_nonzero(dev & ~mask) / dev.sum() > 0.05


def test_hull_points_contain_the_part_outline(rng):
    T = np.eye(4)
    T[:3, 3] = [0.0, 0.0, 0.5]
    for part in (Part("sphere", np.array([0.03, -0.02, 0.0]), radius=0.011),
                 Part("cylinder", np.array([-0.05, 0.0, 0.02]), np.array([0.08, 0.03, -0.04]), 0.007)):
        hull = np.vstack(part_hull_points_cam(part, T))
        # random points on the part's surface project inside the hull of the projected outline points
        d = rng.normal(size=(400, 3))
        d /= np.linalg.norm(d, axis=1, keepdims=True)
        if part.kind == "sphere":
            surf = part.a + part.radius * d
        else:
            axis = part.b - part.a
            u = np.cross(axis, [0, 0, 1.0])
            u /= np.linalg.norm(u)
            v = np.cross(axis / np.linalg.norm(axis), u)
            a = rng.uniform(0, 2 * np.pi, 400)[:, None]
            surf = part.a + rng.uniform(0, 1, (400, 1)) * axis + part.radius * (np.cos(a) * u + np.sin(a) * v)
        surf = surf + T[:3, 3]
        import cv2

        hull_uv = (hull[:, :2] / hull[:, 2:]).astype(np.float32)
        pts = surf[:, :2] / surf[:, 2:]
        h = cv2.convexHull(hull_uv)
        inside = [cv2.pointPolygonTest(h, (float(x), float(y)), True) >= -1e-7 for x, y in pts]
        assert all(inside)


def test_unknown_device_geometry_is_a_config_error():
    with pytest.raises(ConfigError, match="no_such_arm"):
        device_geometry("no_such_arm")
    with pytest.raises(ConfigError, match="passive_size_m"):
        device_geometry("phantom_premium_1_0", passive_size_m=(0.04, -1.0, 0.003))
