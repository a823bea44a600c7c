import numpy as np
import pytest
import yaml

from vishap._core.errors import CalibrationError
from vishap._core.pose import from_rt, rotvec_to_matrix
from vishap.registration import camera_robot
from vishap.vision.rig import StereoRig

T_TRUE = from_rt(rotvec_to_matrix([0.3, -1.2, 0.4]), [0.41, -0.05, 0.22])


def test_round_trip_with_rig_check(tmp_path, ideal_rig):
    path = tmp_path / "camera_robot.yaml"
    camera_robot.save(path, T_TRUE, {"rms_mm": np.float64(0.21), "per_axis_error_mm": np.array([0.1, 0.2, 0.1])},
                      rig=ideal_rig)
    assert np.array_equal(camera_robot.load(path), T_TRUE)
    assert np.array_equal(camera_robot.load(path, rig=ideal_rig), T_TRUE)
    # the same rig after a file round trip still matches
    ideal_rig.save(tmp_path / "rig.yaml")
    assert np.array_equal(camera_robot.load(path, rig=StereoRig.load(tmp_path / "rig.yaml")), T_TRUE)
    doc = camera_robot.load_file(path)
    assert doc.report["rms_mm"] == pytest.approx(0.21)


def _write(path, data):
    path.write_text(data if isinstance(data, str) else yaml.safe_dump(data))
    return path


def _valid(rig):
    return {"format": camera_robot.FORMAT, "T_robot_cam": T_TRUE.tolist(), "rig": camera_robot.rig_identity(rig)}


@pytest.mark.parametrize(
    "edit, field, message",
    [
        (lambda d: "", None, "empty"),
        (lambda d: "T_robot_cam: [[1, 2]\n  bad: {", None, "not valid YAML"),
        (lambda d: "- just\n- a list\n", None, "mapping"),
        (lambda d: {k: v for k, v in d.items() if k != "T_robot_cam"}, "T_robot_cam", "required"),
        (lambda d: {**d, "format": "something/2"}, "format", "expected format"),
        (lambda d: {**d, "T_robot_cam": T_TRUE[:3].tolist()}, "T_robot_cam", "4x4"),
        (lambda d: {**d, "T_robot_cam": [["a"] * 4] * 4}, "T_robot_cam", "valid number"),
        (lambda d: {**d, "T_robot_cam": (T_TRUE * np.array([[1.01], [1], [1], [1]])).tolist()}, "T_robot_cam",
         "not a proper rotation"),
        (lambda d: {**d, "T_robot_cam": (T_TRUE @ np.diag([1.0, 1.0, -1.0, 1.0])).tolist()}, "T_robot_cam",
         "det = -1"),
        (lambda d: {**d, "T_robot_cam": np.vstack([T_TRUE[:3], [0, 0, 1, 1]]).tolist()}, "T_robot_cam", "last row"),
        (lambda d: {**d, "T_robot_cam": np.where(np.eye(4) > 0, np.nan, T_TRUE).tolist()}, "T_robot_cam", "NaN"),
        (lambda d: {**d, "extra": 1}, "extra", "Extra inputs"),
    ],
)
def test_malformed_files_give_one_calibration_error(tmp_path, ideal_rig, edit, field, message):
    path = _write(tmp_path / "c.yaml", edit(_valid(ideal_rig)))
    with pytest.raises(CalibrationError, match=message) as info:
        camera_robot.load(path)
    assert str(path) in str(info.value)
    if field is not None:
        assert info.value.field is not None and info.value.field.startswith(field)


def test_missing_file(tmp_path):
    with pytest.raises(CalibrationError, match="not found"):
        camera_robot.load(tmp_path / "nope.yaml")


def test_another_rig_is_refused(tmp_path, ideal_rig, distorted_rig):
    path = tmp_path / "c.yaml"
    camera_robot.save(path, T_TRUE, rig=ideal_rig)
    with pytest.raises(CalibrationError, match="another rig") as info:
        camera_robot.load(path, rig=distorted_rig)
    assert info.value.field == "rig.fingerprint"
    # a file without a rig identity cannot be checked against a rig
    camera_robot.save(path, T_TRUE)
    assert np.array_equal(camera_robot.load(path), T_TRUE)
    with pytest.raises(CalibrationError, match="which rig"):
        camera_robot.load(path, rig=ideal_rig)


def test_save_refuses_a_non_rigid_transform(tmp_path):
    with pytest.raises(CalibrationError, match="proper rotation"):
        camera_robot.save(tmp_path / "c.yaml", np.diag([2.0, 1.0, 1.0, 1.0]))
