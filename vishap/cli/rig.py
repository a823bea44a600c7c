"""``vishap rig``: make an ideal stereo rig file or describe an existing one."""
from __future__ import annotations

import argparse
import json


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("rig", help="create or inspect a stereo rig file (OpenCV FileStorage YAML)")
    rs = p.add_subparsers(dest="rig_command", metavar="ACTION", required=True)

    new = rs.add_parser("new", help="write an ideal parallel rig (no distortion)")
    new.add_argument("--out", required=True, help="rig file to write (.yaml)")
    new.add_argument("--width", type=int, default=640, help="image width, pixels (default 640)")
    new.add_argument("--height", type=int, default=480, help="image height, pixels (default 480)")
    new.add_argument("--hfov", type=float, default=60.0, help="horizontal field of view, degrees (default 60)")
    new.add_argument("--baseline", type=float, default=0.06, help="baseline, metres (default 0.06)")
    new.set_defaults(func=_new)

    show = rs.add_parser("show", help="print a rig file's summary as JSON")
    show.add_argument("file", help="rig file (.yaml)")
    show.set_defaults(func=_show)


def _new(args: argparse.Namespace) -> int:
    from vishap.vision.rig import StereoRig

    rig = StereoRig.from_fov(args.width, args.height, args.hfov, args.baseline)
    rig.save(args.out)
    print(json.dumps({"file": str(args.out), **rig.summary()}))
    return 0


def _show(args: argparse.Namespace) -> int:
    from vishap.vision.rig import StereoRig

    print(json.dumps({"file": str(args.file), **StereoRig.load(args.file).summary()}))
    return 0
