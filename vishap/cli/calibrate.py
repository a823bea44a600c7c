"""``vishap calibrate stereo|robot``: stereo calibration and camera-to-robot registration (VisHap §2.2)."""
from __future__ import annotations

import argparse

from vishap.cli import add_json_flag, add_overwrite_flag, add_quiet_flag, report, show_progress


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
    st.add_argument("--out", required=True, help="rig file to write (OpenCV FileStorage YAML); must not exist")
    _add_common(st)
    st.set_defaults(func=_stereo)

    rb = cs.add_parser("robot", help="camera-to-robot transform from end-effector marker views (Eq. 3)",
                       description="Move the device through N poses (or ask you to place a device that cannot move "
                                   "itself), find its green end-effector marker in both cameras, solve T_robot_cam.")
    rb.add_argument("--device", default=None, help="device: sim | a registered name (vishap devices) | module:Class")
    rb.add_argument("--cameras", default=None,
                    help="stereo source: cam:L,R | cam:SBS | L.mp4,R.mp4 | sbs:VIDEO | a recorded folder | "
                         "render (the synthetic renderer watching the sim device)")
    rb.add_argument("--sim", action="store_true", help="same as --device sim --cameras render")
    rb.add_argument("--poses", type=int, default=12, help="number of usable end-effector poses (default 12)")
    rb.add_argument("--seed", type=int, default=0, help="random seed (pose sequence, render noise)")
    rb.add_argument("--rig", default=None, help="rig file (required with real cameras; default for render: the "
                                               "synthetic renderer's rig)")
    rb.add_argument("--size", default=None, help="render size WxH (render only; default: the rig's)")
    rb.add_argument("--frames-per-pose", type=int, default=None,
                    help="frames pulled per pose, the last one used (default 3 for live cameras, else 1)")
    rb.add_argument("--robust", action="store_true", help="robust (LMedS) fit instead of plain least squares")
    rb.add_argument("--out", required=True, help="calibration file to write (YAML); must not exist")
    rb.add_argument("--poses-out", default=None, help="also write the pose set and measurements here (.npz)")
    _add_common(rb)
    rb.set_defaults(func=_robot)


def _add_common(p: argparse.ArgumentParser) -> None:
    add_overwrite_flag(p, "--out file")
    add_quiet_flag(p)
    add_json_flag(p)


def _check_outputs(args: argparse.Namespace) -> None:
    """Refuse a bad --out (or --poses-out) before the calibration runs, not after."""
    from vishap._core.output import check_output_file

    for path in (args.out, getattr(args, "poses_out", None)):
        if path is not None:
            check_output_file(path, overwrite=args.overwrite)


def _stereo(args: argparse.Namespace) -> int:
    from vishap.registration.stereo_calib import calibrate_stereo_files, parse_board

    _check_outputs(args)
    board = parse_board(args.board, args.square, charuco=args.charuco, marker_m=args.marker, dictionary=args.dictionary)
    cal = calibrate_stereo_files(args.left, args.right, board, model=args.model, progress=show_progress(args))
    cal.rig.save(args.out)
    rec = {"out": str(args.out), "board": f"{board.cols}x{board.rows} {board.kind}", **cal.summary()}
    report(args, rec, [f"stereo calibration from {rec['pairs_used']} of {rec['pairs_total']} pairs ({rec['board']}): "
                       f"RMS {rec['rms_px']:.3f} px (worst view {rec['worst_view_rms_px']:.3f} px)",
                       f"  baseline {rec['baseline_m'] * 1e3:.1f} mm, fx {rec['fx_px']:.1f} px, "
                       f"{rec['image_size'][0]}x{rec['image_size'][1]} px",
                       f"  rig file: {args.out}"])
    return 0


def _robot(args: argparse.Namespace) -> int:
    from vishap._core.errors import ConfigError

    device_spec, cameras = args.device, args.cameras
    if args.sim:
        if (device_spec or "sim") != "sim" or (cameras or "render") != "render":
            raise ConfigError("--sim is --device sim --cameras render; drop --sim to use another device or cameras",
                              field="--sim")
        device_spec, cameras = "sim", "render"
    if device_spec is None or cameras is None:
        raise ConfigError("give --device NAME and --cameras SPEC (or --sim for the simulated set-up)", field="--device")
    _check_outputs(args)
    size = None
    if args.size:
        try:
            size = tuple(int(s) for s in args.size.lower().split("x"))
        except ValueError:
            raise ConfigError(f"expected WxH such as 320x240, got {args.size!r}", field="--size") from None
    if cameras == "render":
        if device_spec != "sim":
            raise ConfigError(f"rendered cameras watch the simulated device only, not {device_spec!r}",
                              field="--cameras")
        from vishap.registration.sim import calibrate_sim

        result = calibrate_sim(n_poses=args.poses, seed=args.seed, rig_path=args.rig, size=size, robust=args.robust,
                               out=args.out, poses_out=args.poses_out, progress=show_progress(args))
    else:
        if size is not None:
            raise ConfigError("--size applies to rendered cameras only", field="--size")
        result = _robot_real(args, device_spec, cameras)
    report(args, result, _robot_lines(result, args.out))
    return 0


def _robot_lines(rec: dict, out) -> list[str]:
    def mm(k):
        v = rec.get(k)
        return "n/a" if v is None else (f"{v:.3f} mm" if not isinstance(v, list) else
                                        " / ".join(f"{x:.3f}" for x in v) + " mm")

    lines = [f"camera-to-robot calibration from {rec.get('poses_used')} of {rec.get('poses')} poses: "
             f"RMS {mm('rms_mm')}, per axis {mm('per_axis_error_mm')}"]
    if rec.get("workspace_per_axis_error_mm") is not None:
        lines.append(f"  against the simulation's truth: workspace per axis {mm('workspace_per_axis_error_mm')}, "
                     f"rotation {rec.get('rotation_error_deg', float('nan')):.3f}°")
    lines.append(f"  calibration file: {out}")
    return lines


def _robot_real(args: argparse.Namespace, device_spec: str, cameras: str) -> dict:
    """The shared procedure on a driver and real (or recorded) cameras."""
    from vishap._core.errors import ConfigError
    from vishap.registration.procedure import console_prompt, run_calibration
    from vishap.robot.drivers import open_device, resolve
    from vishap.vision.capture import open_source
    from vishap.vision.rig import StereoRig

    resolve(device_spec)  # an unknown driver is reported before any camera is opened
    source = open_source(cameras)
    rig = getattr(source, "rig", None)
    if args.rig is not None:
        rig = StereoRig.load(args.rig)
    if rig is None:
        source.close()
        raise ConfigError("the cameras' stereo calibration is needed (make it with 'vishap calibrate stereo')",
                          field="--rig")
    frames = args.frames_per_pose or (3 if cameras.startswith(("cam:", "sbs-cam:")) else 1)
    try:
        device = open_device(device_spec)
        try:
            prompt = None if device.moves_itself else console_prompt(args.poses)
            return run_calibration(device, source, rig, n_poses=args.poses, seed=args.seed, prompt=prompt,
                                   robust=args.robust, frames_per_pose=frames, out=args.out, poses_out=args.poses_out,
                                   describe={"device": device_spec, "cameras": cameras},
                                   progress=prompt is None and show_progress(args))  # a bar would garble the prompt
        finally:
            device.close()
    finally:
        source.close()
