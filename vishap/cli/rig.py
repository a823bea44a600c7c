"""``vishap rig``: make an ideal stereo rig file or describe an existing one."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_overwrite_flag, report


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("rig", help="create or inspect a stereo rig file (OpenCV FileStorage YAML)")
    rs = p.add_subparsers(dest="rig_command", metavar="ACTION", required=True)

    new = rs.add_parser("new", help="write an ideal parallel rig (no distortion)")
    new.add_argument("--out", required=True, help="rig file to write (.yaml)")
    new.add_argument("--width", type=int, default=640, help="image width, pixels (default 640)")
    new.add_argument("--height", type=int, default=480, help="image height, pixels (default 480)")
    new.add_argument("--hfov", type=float, default=60.0, help="horizontal field of view, degrees (default 60)")
    new.add_argument("--baseline", type=float, default=0.06, help="baseline, metres (default 0.06)")
    add_overwrite_flag(new)
    add_json_flag(new)
    new.set_defaults(func=_new)

    show = rs.add_parser("show", help="summarise a rig file (JSON with --json)")
    show.add_argument("file", help="rig file (.yaml)")
    add_json_flag(show)
    show.set_defaults(func=_show)


def _lines(verb: str, file, s: dict) -> list[str]:
    w, h = s["image_size"]
    lines = [f"{verb} {file}: {w}x{h} px, fx {s['fx_px']:.1f} px ({s['hfov_deg']:.1f}° horizontal), "
             f"baseline {s['baseline_m'] * 1e3:.1f} mm, {'with' if s['distortion'] else 'no'} distortion"]
    if s.get("rms_px") is not None or s.get("board"):
        lines.append(f"  calibrated on {s.get('board') or 'an unnamed board'}, RMS "
                     f"{'?' if s.get('rms_px') is None else format(s['rms_px'], '.3f')} px")
    return lines


def _new(args: argparse.Namespace) -> int:
    from vishap._core.output import check_output_file
    from vishap.vision.rig import StereoRig

    check_output_file(args.out, overwrite=args.overwrite)
    rig = StereoRig.from_fov(args.width, args.height, args.hfov, args.baseline)
    rig.save(args.out)
    s = rig.summary()
    report(args, {"file": str(args.out), **s}, _lines("wrote", args.out, s))
    return 0


def _show(args: argparse.Namespace) -> int:
    from vishap.vision.rig import StereoRig

    s = StereoRig.load(args.file).summary()
    report(args, {"file": str(args.file), **s}, _lines("rig", args.file, s))
    return 0
