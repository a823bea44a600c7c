"""``vishap demo {wall,button,fabric}``: the closed-loop demos (issue 9 parts 2, 3 and 5).

Batch mode (default) simulates the whole system on a simulated clock: pyrender stereo frames of a
scripted finger → vision → registration → world → MuJoCo device → tactile layer, writing the
video, plots, ``log.npz`` and ``summary.json`` into ``--out``. ``--live`` runs the same core on a real
clock, fed by cameras or a recording, with the simulated or a real device, and says what is missing
when something is not there; it writes the same outputs (but the video).
"""
from __future__ import annotations

import argparse

from vishap.apps.config import FAULT_KINDS, SCENES
from vishap.cli import add_json_flag, add_overwrite_flag, add_quiet_flag, report, show_progress

__all__ = ["register", "parse_fault", "parse_travel"]


def parse_fault(text: str) -> dict:
    """``KIND:T_START:T_END`` (seconds of simulated time) → a fault record."""
    parts = text.split(":")
    if len(parts) != 3 or parts[0] not in FAULT_KINDS:
        raise argparse.ArgumentTypeError(
            f"expected KIND:T_START:T_END with KIND one of {', '.join(FAULT_KINDS)}, got {text!r}")
    try:
        return {"kind": parts[0], "t_start": float(parts[1]), "t_end": float(parts[2])}
    except ValueError:
        raise argparse.ArgumentTypeError(f"times must be seconds, got {text!r}") from None


def parse_travel(text: str) -> dict:
    """``SPEED,ACCEL`` (m/s, m/s²) or ``off`` → the demo's travel-limit fields."""
    if text.strip().lower() == "off":
        return {"travel_speed_m_s": None}
    try:
        speed, accel = (float(v) for v in text.split(","))
    except ValueError:
        raise argparse.ArgumentTypeError(f"expected SPEED,ACCEL (m/s, m/s²) or 'off', got {text!r}") from None
    return {"travel_speed_m_s": speed, "travel_accel_m_s2": accel}


def register(sub: argparse._SubParsersAction) -> None:
    p = sub.add_parser("demo", help="run the wall / button / fabric closed-loop demo (simulated or live)")
    p.add_argument("scene", choices=SCENES, help="which demo")
    p.add_argument("--out", required=True,
                   help="output folder (video, plots, log.npz, summary.json), written whole at the end; "
                        "must not exist or be empty")
    add_overwrite_flag(p)
    p.add_argument("--frames", type=int, default=None, help="camera frames (default: the scene's script length)")
    p.add_argument("--seed", type=int, default=0, help="random seed (default 0)")
    p.add_argument("--width", type=int, default=480, help="image width, pixels (default 480)")
    p.add_argument("--height", type=int, default=360, help="image height, pixels (default 360)")
    p.add_argument("--camera-hz", type=float, default=30.0, help="camera rate (default 30)")
    p.add_argument("--scene-hz", type=float, default=60.0,
                   help="scene (world update) rate; 1000 runs the world as soon as vision returns (default 60)")
    p.add_argument("--calib", default=None,
                   help="camera_robot.yaml (default: run the camera-robot calibration in simulation first)")
    p.add_argument("--fault", action="append", type=parse_fault, default=[], metavar="KIND:T0:T1",
                   help=f"inject a fault in [T0, T1) s; KIND one of {', '.join(FAULT_KINDS)} (repeatable)")
    p.add_argument("--travel", type=parse_travel, default={}, metavar="SPEED,ACCEL",
                   help="device travel limits in m/s and m/s² (default 0.6,40; docs/robot.md); 'off' for none")
    p.add_argument("--contact-model", default=None, choices=("ray", "path", "both", "reach", "all"),
                   help="the world's meeting-point prediction (default: the demo configuration's)")
    p.add_argument("--no-video", action="store_true", help="skip the MP4 (faster)")
    p.add_argument("--no-frames", action="store_true",
                   help="do not keep the lossless frames (≈ 0.3 MB per pair at 480x360; replay needs them)")
    p.add_argument("--live", action="store_true",
                   help="run the same core on a real clock, fed by cameras or a recording (--cameras)")
    p.add_argument("--cameras", default="cam:0,1",
                   help="live: a source spec as 'vishap track' takes it: cam:0,1 | cam:0 | LEFT,RIGHT videos | "
                        "sbs:VIDEO | a recorded folder (e.g. a 'vishap synth' output); bare indices 0,1 mean cameras")
    p.add_argument("--rig", default=None, help="live: stereo rig file (default: the recorded folder's, else calib/rig.yaml)")
    p.add_argument("--device", default="sim",
                   help="live: 'sim' (the MuJoCo PHANToM; its finger pad follows the source's ground truth or the "
                        "tracked finger), a driver registered in the entry-point group 'vishap.devices' "
                        "('vishap devices' lists them) or 'module:Class' (default sim)")
    p.add_argument("--duration", type=float, default=30.0, help="live: seconds to run (default 30)")
    add_quiet_flag(p)
    add_json_flag(p)
    p.set_defaults(func=_run)


def _run(args: argparse.Namespace) -> int:
    from vishap._core.output import output_dir
    from vishap.apps.summary import summary_lines

    with output_dir(args.out, overwrite=args.overwrite) as o:
        summary = _demo(args, o.path)
    report(args, summary, summary_lines(summary, o.final))
    return 0


def _demo(args: argparse.Namespace, out) -> dict:
    if args.live:
        from vishap.apps.live import run_live

        fields = {"seed": args.seed, "scene_hz": args.scene_hz, "save_frames": not args.no_frames, **args.travel}
        if args.contact_model is not None:
            fields["contact_model"] = args.contact_model
        return run_live(args.scene, out=out, cameras=args.cameras, calib=args.calib, rig=args.rig,
                        device=args.device, duration_s=args.duration, progress=show_progress(args), **fields)
    from vishap.apps import run_demo
    from vishap.apps.config import DemoConfig
    from vishap._core.config import validate

    fields = {"scene": args.scene, "seed": args.seed, "width": args.width, "height": args.height,
              "camera_hz": args.camera_hz, "scene_hz": args.scene_hz, "calib": args.calib, "faults": args.fault,
              "video": not args.no_video, "save_frames": not args.no_frames}
    if args.frames is not None:
        fields["frames"] = args.frames
    fields.update(args.travel)
    if args.contact_model is not None:
        fields["contact_model"] = args.contact_model
    cfg = validate(DemoConfig, fields, file=None)
    return run_demo(cfg, out, progress=show_progress(args))
