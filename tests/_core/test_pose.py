import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from vishap._core import pose
from vishap._core.check import as_points, as_transform, check_shape
from vishap._core.errors import ShapeError

angles = st.floats(-np.pi, np.pi, allow_nan=False)


@settings(max_examples=50, deadline=None)
@given(angles, angles, angles, st.lists(st.floats(-2, 2, allow_nan=False), min_size=3, max_size=3))
def test_invert_composes_to_identity(a, b, c, t):
    R = pose.rot_z(a) @ pose.rot_y(b) @ pose.rot_x(c)
    T = pose.from_rt(R, t)
    assert pose.is_rotation(R)
    assert np.allclose(pose.invert(T) @ T, np.eye(4), atol=1e-12)
    assert np.allclose(T @ pose.invert(T), np.eye(4), atol=1e-12)


def test_transform_points_and_vectors():
    T_robot_cam = pose.from_rt(pose.rot_z(np.pi / 2), [1.0, 2.0, 3.0])
    p_cam = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])
    p_robot = pose.transform_points(T_robot_cam, p_cam)
    assert np.allclose(p_robot, [[1.0, 3.0, 3.0], [0.0, 2.0, 3.0]])
    assert np.allclose(pose.transform_vectors(T_robot_cam, [1.0, 0.0, 0.0]), [0.0, 1.0, 0.0])
    assert np.allclose(pose.transform_points(pose.invert(T_robot_cam), p_robot), p_cam)


def test_rotvec_round_trip(rng):
    for _ in range(20):
        rv = rng.normal(size=3)
        rv *= min(1.0, 3.0 / np.linalg.norm(rv))
        R = pose.rotvec_to_matrix(rv)
        assert pose.is_rotation(R)
        assert np.allclose(pose.matrix_to_rotvec(R), rv, atol=1e-9)
        assert pose.rotation_angle(R) == pytest.approx(np.linalg.norm(rv), abs=1e-9)


def test_reflection_is_not_a_rotation():
    assert not pose.is_rotation(np.diag([1.0, 1.0, -1.0]))
    assert not pose.is_rotation(np.full((3, 3), np.nan))


def test_checks_name_the_argument():
    with pytest.raises(ShapeError, match="p_cam"):
        as_points(np.zeros((4, 2)), "p_cam")
    with pytest.raises(ShapeError, match="p_cam.*NaN"):
        as_points([[0.0, np.nan, 1.0]], "p_cam")
    assert as_points([1.0, 2.0, 3.0], "p").shape == (1, 3)
    with pytest.raises(ShapeError, match=r"expected shape \(N, 3\)"):
        check_shape(np.zeros((2, 2)), (None, 3), "x")
    with pytest.raises(ShapeError, match="T_robot_cam.*rotation"):
        as_transform(np.diag([1.0, 1.0, -1.0, 1.0]), "T_robot_cam")
