"""``vishap calibrate stereo``: stereo calibration (VisHap §2.2)."""
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


def _stereo(args: argparse.Namespace) -> int:
    from vishap.registration.stereo_calib import calibrate_stereo_files, parse_board

    board = parse_board(args.board, args.square, charuco=args.charuco, marker_m=args.marker, dictionary=args.dictionary)
    cal = calibrate_stereo_files(args.left, args.right, board, model=args.model)
    cal.rig.save(args.out)
    print(json.dumps({"out": str(args.out), "board": f"{board.cols}x{board.rows} {board.kind}", **cal.summary()}))
    return 0
