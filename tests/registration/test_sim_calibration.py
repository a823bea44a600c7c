"""Camera-to-robot calibration end to end on rendered images (real renderer and kinematics)."""
import json

import numpy as np
import pytest

from vishap._core.errors import CalibrationError
from vishap.cli import main
from vishap.registration import camera_robot


@pytest.mark.render
def test_calibrate_robot_sim_cli(tmp_path, capsys):
    out = tmp_path / "camera_robot.yaml"
    poses = tmp_path / "poses.npz"
    code = main(["calibrate", "robot", "--sim", "--poses", "8", "--seed", "1", "--size", "480x360",
                 "--out", str(out), "--poses-out", str(poses), "--json"])
    assert code == 0
    rec = json.loads(capsys.readouterr().out)
    for key in ("poses_used", "per_axis_error_mm", "rms_mm", "rotation_error_deg", "translation_error_mm"):
        assert key in rec
    # poses where the arm hides the marker are replaced by the next of the sequence
    assert rec["poses_used"] == 8 and rec["poses_visited"] >= 8
    assert len(rec["per_axis_error_mm"]) == 3
    # the shared procedure on the sim device: VisHap's figure (mean per-axis residual) under 0.5 mm
    assert rec["device"] == "sim" and rec["cameras"] == "render"
    assert max(rec["per_axis_error_mm"]) < 0.5
    # against the true transform of the renderer: the map is right to a fraction of a millimetre
    assert max(rec["workspace_per_axis_error_mm"]) < 0.5
    assert rec["rotation_error_deg"] < 0.5
    assert rec["marker_error_px"]["median"] < 0.3
    # the file loads, is tied to the rig it was made with, and equals the truth closely
    from vishap.registration.sim import default_rig, scaled_rig
    from vishap.sim.camera_placement import default_T_robot_cam

    rig = scaled_rig(default_rig(), (480, 360))
    T = camera_robot.load(out, rig=rig)
    T_true = default_T_robot_cam()
    p_robot = np.array([[0.2, 0.0, -0.12], [0.12, 0.05, -0.06], [0.28, -0.05, -0.18]])
    p_cam = (p_robot - T_true[:3, 3]) @ T_true[:3, :3]
    assert np.max(np.abs(p_cam @ T[:3, :3].T + T[:3, 3] - p_robot)) < 1e-3
    with pytest.raises(CalibrationError, match="another rig"):
        camera_robot.load(out, rig=default_rig())
    data = np.load(poses)
    assert data["targets_robot"].shape == (rec["poses_visited"], 3) and data["ok"].sum() == rec["poses_used"]
