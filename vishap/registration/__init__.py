"""Registration (VisHap §2.2, Eq. 3): the rigid transform ``T_robot_cam`` and the calibrations behind it.

* :mod:`~vishap.registration.rigid` — absolute orientation (closed form, robust);
* :mod:`~vishap.registration.stereo_calib` — stereo calibration from a chessboard / ChArUco board;
* :mod:`~vishap.registration.marker` — the end-effector marker in an image;
* :mod:`~vishap.registration.robot_calib` — the camera-to-robot procedure;
* :mod:`~vishap.registration.camera_robot` — its calibration files;
* :mod:`~vishap.registration.sim` — the procedure on the simulated arm and renderer (imports pyrender).
"""
from vishap.registration import camera_robot
from vishap.registration.marker import MarkerDetection, detect_marker
from vishap.registration.rigid import RigidTransform, degeneracy, kabsch_umeyama
from vishap.registration.robot_calib import Observations, measure, refine_reprojection, report, select_poses, solve
from vishap.registration.stereo_calib import Board, StereoCalibration, calibrate_stereo, detect_board, parse_board

__all__ = [
    "RigidTransform",
    "degeneracy",
    "kabsch_umeyama",
    "camera_robot",
    "MarkerDetection",
    "detect_marker",
    "Observations",
    "select_poses",
    "measure",
    "solve",
    "refine_reprojection",
    "report",
    "Board",
    "StereoCalibration",
    "calibrate_stereo",
    "detect_board",
    "parse_board",
]
