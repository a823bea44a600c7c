"""``vishap calibrate stereo|robot``: stereo calibration and camera-to-robot registration (VisHap §2.2)."""
from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("calibrate", help="calibrate the stereo rig or the camera-to-robot transform")
    cs = p.add_subparsers(dest="calibrate_command", metavar="WHAT", required=True)

    st = cs.add_parser("stereo", help="stereo calibration from chessboard/ChArUco image pairs; writes a rig file")
    st.add_argument("--left", required=True, help="glob of left images (paired with --right in sorted order)")
    st.add_argument("--right", required=True, help="glob of right images")
    st.add_argument("--board", required=True, help="COLSxROWS: inner corners (chessboard) or squares (ChArUco)")
    st.add_argument("--square", type=float, required=True, help="square side, metres")
    st.add_argument("--charuco", action="store_true", help="the board is ChArUco (needs --marker)")
    st.add_argument("--marker", type=float, default=None, help="ChArUco marker side, metres")
    st.add_argument("--dictionary", default="DICT_4X4_50", help="ChArUco ArUco dictionary (default DICT_4X4_50)")
    st.add_argument("--model", default="k5", choices=["k4", "k5", "rational"], help="distortion model (default k5)")
    st.add_argument("--out", required=True, help="rig file to write (OpenCV FileStorage YAML)")
    st.set_defaults(func=_stereo)

    rb = cs.add_parser("robot", help="camera-to-robot transform from end-effector marker views (Eq. 3)")
    rb.add_argument("--sim", action="store_true", help="use the simulated arm and the synthetic renderer")
    rb.add_argument("--poses", type=int, default=12, help="number of end-effector poses (default 12)")
    rb.add_argument("--seed", type=int, default=0, help="random seed (pose jitter, render noise)")
    rb.add_argument("--rig", default=None, help="rig file (default: the synthetic renderer's default rig)")
    rb.add_argument("--size", default=None, help="render size WxH (default: the rig's)")
    rb.add_argument("--robust", action="store_true", help="robust (LMedS) fit instead of plain least squares")
    rb.add_argument("--out", required=True, help="calibration file to write (YAML)")
    rb.add_argument("--poses-out", default=None, help="also write the pose set and measurements here (.npz)")
    rb.set_defaults(func=_robot)


def _stereo(args: argparse.Namespace) -> int:
    from vishap.registration.stereo_calib import calibrate_stereo_files, parse_board

    board = parse_board(args.board, args.square, charuco=args.charuco, marker_m=args.marker, dictionary=args.dictionary)
    cal = calibrate_stereo_files(args.left, args.right, board, model=args.model)
    cal.rig.save(args.out)
    print(json.dumps({"out": str(args.out), "board": f"{board.cols}x{board.rows} {board.kind}", **cal.summary()}))
    return 0


def _robot(args: argparse.Namespace) -> int:
    from vishap._core.errors import ConfigError
    from vishap.registration.sim import calibrate_sim

    if not args.sim:
        raise ConfigError("only --sim is available: a real device driver is not part of this build", field="--sim")
    size = None
    if args.size:
        try:
            size = tuple(int(s) for s in args.size.lower().split("x"))
        except ValueError:
            raise ConfigError(f"expected WxH such as 320x240, got {args.size!r}", field="--size") from None
    result = calibrate_sim(n_poses=args.poses, seed=args.seed, rig_path=args.rig, size=size, robust=args.robust,
                           out=args.out, poses_out=args.poses_out)
    print(json.dumps(result))
    return 0
