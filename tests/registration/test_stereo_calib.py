import json

import cv2
import numpy as np
import pytest

from vishap._core.errors import CalibrationError, ConfigError
from vishap.cli import main
from vishap.registration.stereo_calib import (
    Board,
    calibrate_stereo,
    detect_board,
    opencv_sample_stereo_calib,
    parse_board,
)
from vishap.vision.rig import StereoRig


def _render_pairs(rig, board_tex, metres_per_px, views, render):
    T_right_left = np.eye(4)
    T_right_left[:3, :3], T_right_left[:3, 3] = rig.R, rig.T
    lefts, rights = [], []
    for T in views:
        lefts.append(render(board_tex, metres_per_px, T, rig.K_left, rig.dist_left, rig.image_size))
        rights.append(render(board_tex, metres_per_px, T_right_left @ T, rig.K_right, rig.dist_right, rig.image_size))
    return lefts, rights


def _check_recovers(rig_true, cal, held_out, board):
    """Intrinsics and baseline close to the truth; a held-out view triangulates to the metric board."""
    rig = cal.rig
    assert rig.fx_px == pytest.approx(rig_true.fx_px, rel=0.01)
    assert rig.K_left[:2, 2] == pytest.approx(rig_true.K_left[:2, 2], abs=5.0)  # weakly observable
    assert rig.baseline_m == pytest.approx(rig_true.baseline_m, rel=0.01)
    assert np.degrees(np.arccos(np.clip((np.trace(rig.R.T @ rig_true.R) - 1) / 2, -1, 1))) < 0.3
    (ids_l, uv_l), (ids_r, uv_r) = detect_board(held_out[0], board), detect_board(held_out[1], board)
    common, ia, ib = np.intersect1d(ids_l, ids_r, return_indices=True)
    p_cam = rig.triangulate(uv_l[ia], uv_r[ib])
    obj = board.object_points[common].astype(np.float64)
    d_true = np.linalg.norm(obj[:, None] - obj[None], axis=-1)
    d_est = np.linalg.norm(p_cam[:, None] - p_cam[None], axis=-1)
    far = d_true > 2.5 * board.square_m
    assert np.median(np.abs(d_est[far] / d_true[far] - 1.0)) < 0.005  # metric to 0.5 %
    dv = rig.rectify_points(uv_l[ia], "left")[:, 1] - rig.rectify_points(uv_r[ib], "right")[:, 1]
    assert np.mean(np.abs(dv)) < 0.3  # rectified rows agree


def test_synthetic_chessboard_recovers_distorted_rig(distorted_rig, board_tools, rng):
    tex, _ = board_tools.chessboard_texture(9, 6, 40)
    square = 0.025
    views = board_tools.board_views(rng, 9, centre_m=(11 * square / 2, 8 * square / 2))
    lefts, rights = _render_pairs(distorted_rig, tex, square / 40, views, board_tools.render_board)
    board = Board(9, 6, square)
    cal = calibrate_stereo(lefts[:-1], rights[:-1], board)
    assert cal.pairs_used >= 7
    assert cal.rms_px < 0.3
    _check_recovers(distorted_rig, cal, (lefts[-1], rights[-1]), board)


def test_calibrate_stereo_writes_image_size_rms_and_board_into_a_group_readable_rig_file(
        distorted_rig, board_tools, rng, tmp_path, capsys):
    import os
    import stat

    tex, _ = board_tools.chessboard_texture(9, 6, 40)
    square = 0.025
    views = board_tools.board_views(rng, 6, centre_m=(11 * square / 2, 8 * square / 2))
    lefts, rights = _render_pairs(distorted_rig, tex, square / 40, views, board_tools.render_board)
    for k, (a, b) in enumerate(zip(lefts, rights)):
        cv2.imwrite(str(tmp_path / f"l{k:02d}.png"), a)
        cv2.imwrite(str(tmp_path / f"r{k:02d}.png"), b)
    out = tmp_path / "calib" / "rig.yaml"
    old = os.umask(0o022)
    try:
        assert main(["calibrate", "stereo", "--left", str(tmp_path / "l*.png"), "--right", str(tmp_path / "r*.png"),
                     "--board", "9x6", "--square", str(square), "--out", str(out), "--json"]) == 0
    finally:
        os.umask(old)
    rec = json.loads(capsys.readouterr().out)
    assert stat.S_IMODE(out.stat().st_mode) == 0o644  # the umask's mode, not mkstemp's 0600
    text = out.read_text()
    for node in ("image_size:", "rms_px:", "board: chessboard", "board_width: 9", "board_height: 6", "square_size:"):
        assert node in text, node
    rig = StereoRig.load(out)
    assert rig.image_size == distorted_rig.image_size
    assert rig.rms_px == pytest.approx(rec["rms_px"], rel=1e-12) and 0 < rig.rms_px < 0.5
    assert (rig.board, rig.board_size, rig.square_m) == ("chessboard", (9, 6), square)
    assert rig.summary()["board_size"] == [9, 6]


def test_synthetic_charuco_recovers_rig(distorted_rig, board_tools, rng):
    board = parse_board("7x5", 0.035, charuco=True, marker_m=0.026)
    tex = board.charuco_board().generateImage((7 * 50, 5 * 50), marginSize=0)
    views = board_tools.board_views(rng, 9, centre_m=(7 * 0.035 / 2, 5 * 0.035 / 2))
    lefts, rights = _render_pairs(distorted_rig, tex, 0.035 / 50, views, board_tools.render_board)
    ids = detect_board(lefts[0], board)
    assert ids is not None and len(ids[0]) >= 6
    cal = calibrate_stereo(lefts[:-1], rights[:-1], board)
    assert cal.pairs_used >= 7
    assert cal.rms_px < 0.5
    assert (cal.rig.board, cal.rig.board_size, cal.rig.rms_px) == ("charuco", (7, 5), cal.rms_px)
    _check_recovers(distorted_rig, cal, (lefts[-1], rights[-1]), board)


def test_opencv_sample_pairs_reach_the_sample_rms(opencv_stereo_dir, tmp_path, capsys):
    """OpenCV's own stereo pairs: the CLI must reach (at most) the RMS of OpenCV's stereo_calib sample."""
    out = tmp_path / "rig.yaml"
    code = main(["calibrate", "stereo", "--left", str(opencv_stereo_dir / "left*.jpg"), "--right",
                 str(opencv_stereo_dir / "right*.jpg"), "--board", "9x6", "--square", "0.025", "--out", str(out), "--json"])
    assert code == 0
    rec = json.loads(capsys.readouterr().out)
    assert {"pairs_used", "rms_px", "baseline_m", "fx_px"} <= set(rec)
    left = sorted(opencv_stereo_dir.glob("left*.jpg"))
    right = sorted(opencv_stereo_dir.glob("right*.jpg"))
    ref = opencv_sample_stereo_calib(left, right, Board(9, 6, 0.025))
    assert rec["pairs_used"] == ref["pairs_used"] == 13
    assert rec["rms_px"] <= ref["rms_px"]
    assert rec["baseline_m"] == pytest.approx(ref["baseline_m"], rel=0.02)
    # the written file loads with the calibration's RMS and board, and rectification puts matching
    # corners on the same row
    rig = StereoRig.load(out)
    assert rig.rms_px == rec["rms_px"] and rig.board_size == (9, 6) and rig.square_m == 0.025
    ids_l, uv_l = detect_board(left[0], Board(9, 6, 0.025))
    ids_r, uv_r = detect_board(right[0], Board(9, 6, 0.025))
    dv = rig.rectify_points(uv_l, "left")[:, 1] - rig.rectify_points(uv_r, "right")[:, 1]
    assert np.mean(np.abs(dv)) < 0.5


def test_bad_inputs_give_clear_errors(tmp_path, board_tools):
    with pytest.raises(ConfigError, match="COLSxROWS"):
        parse_board("9by6", 0.02)
    with pytest.raises(ConfigError, match="marker"):
        parse_board("7x5", 0.03, charuco=True)
    with pytest.raises(ConfigError, match="positive"):
        Board(9, 6, 0.0)
    blank = np.full((120, 160), 128, np.uint8)
    with pytest.raises(CalibrationError, match="only 0 of 4 pairs"):
        calibrate_stereo([blank] * 4, [blank] * 4, Board(9, 6, 0.02))
    with pytest.raises(CalibrationError, match="3 left images but 2"):
        calibrate_stereo([blank] * 3, [blank] * 2, Board(9, 6, 0.02))
    assert main(["calibrate", "stereo", "--left", str(tmp_path / "none*.png"), "--right", str(tmp_path / "x*.png"),
                 "--board", "9x6", "--square", "0.02", "--out", str(tmp_path / "r.yaml")]) == 2
