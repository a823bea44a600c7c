"""Live mode: the demo's core on a real clock, fed by cameras or a recording (issue 9 part 3).

``--cameras`` takes the source specs ``vishap track`` takes (:func:`vishap.vision.capture.open_source`):
``cam:0,1``, ``cam:0`` (side by side), ``LEFT.mp4,RIGHT.mp4``, ``sbs:VIDEO`` or a recorded folder
such as a ``vishap synth`` output; bare indices ``0,1`` still mean cameras. ``--device sim`` runs the
MuJoCo PHANToM behind it, its finger pad pressed by the recording's ground-truth finger where the
source has one (``gt.npz``) and by the tracked finger otherwise; ``--device module:Class`` loads a
driver. Without ``--calib`` (a recorded synthetic folder on the ``sim`` device) the simulated
camera-to-robot calibration runs first, as in the batch demo; cameras, videos and real devices need
a calibration file.

Before anything starts, every piece the run needs is checked and whatever is missing is reported in
one error: each camera that cannot be opened, the source, the rig and calibration files, the driver.
"""
from __future__ import annotations

from pathlib import Path

from vishap._core.errors import ConfigError, DeviceError

__all__ = ["source_spec", "check_cameras", "check_live", "run_live"]


def source_spec(spec: str) -> str:
    """Bare camera indices (``0,1`` or ``0``) → ``cam:0,1``; every other spec is ``open_source``'s."""
    s = str(spec).strip()
    parts = [p.strip() for p in s.split(",")]
    if parts and all(p.isdigit() for p in parts):
        if len(parts) > 2:
            raise DeviceError(f"--cameras: expected one (side-by-side) or two camera indices, got {spec!r}")
        return "cam:" + ",".join(parts)
    return s


def check_cameras(indices: list[int]) -> list[str]:
    """Open each camera once and grab a frame; return one line per camera that is not usable."""
    import cv2

    problems = []
    for i in indices:
        node = Path(f"/dev/video{i}")
        if not node.exists():
            problems.append(f"camera index {i}: no device node {node}")
            continue
        cap = cv2.VideoCapture(i)
        try:
            if not cap.isOpened():
                problems.append(f"camera index {i}: {node} exists but cv2.VideoCapture({i}) cannot open it")
            elif not cap.read()[0]:
                problems.append(f"camera index {i}: opened but returned no frame")
        finally:
            cap.release()
    return problems


def check_live(*, cameras: str, rig: str | None, calib: str | None, device: str | None):
    """Collect every missing piece; return ``(source spec, rig path or None, calib path or None, device spec)``.

    A recorded folder brings its own rig; ``calib`` None means "calibrate in simulation" (a recorded
    synthetic folder on the ``sim`` device only).
    """
    problems = []
    spec = source_spec(cameras)
    folder = Path(spec) if "," not in spec and not spec.startswith(("cam:", "sbs")) else None
    if spec.startswith(("cam:", "sbs-cam:")):
        idx = [d.strip() for d in spec.split(":", 1)[1].split(",")]
        problems += check_cameras([int(i) for i in idx if i.isdigit()])
    elif folder is None or not folder.is_dir():
        for f in spec.removeprefix("sbs:").split(","):
            if not Path(f).is_file():
                problems.append(f"source {f}: file not found")
    elif not (folder / "rig.yaml").is_file():
        problems.append(f"source {folder}: not a recorded stereo folder (no rig.yaml)")
    rig_path = Path(rig) if rig else (folder / "rig.yaml" if folder is not None and folder.is_dir() else Path("calib/rig.yaml"))
    if not rig_path.is_file():
        problems.append(f"stereo rig file {rig_path} not found (make it with 'vishap calibrate stereo')")
    device = device or "sim"
    if calib is not None and not Path(calib).is_file():
        problems.append(f"camera-robot calibration {calib} not found (make it with 'vishap calibrate robot')")
    elif calib is None and (device != "sim" or folder is None or not folder.is_dir()):
        problems.append("camera-robot calibration: --calib is needed for cameras, videos or a real device "
                        "(the simulated calibration calibrates only the simulated cameras and device of a "
                        "recorded synthetic folder; make one with 'vishap calibrate robot')")
    if device != "sim":
        from vishap.robot.drivers import resolve

        try:
            resolve(device)
        except ConfigError as exc:
            problems.append(f"haptic device: {exc}")
    if problems:
        raise DeviceError("live mode cannot start, missing: " + "; ".join(problems))
    return spec, rig_path, None if calib is None else Path(calib), device


def run_live(scene: str, *, out, cameras: str, calib: str | None, rig: str | None, device: str | None,
             duration_s: float, realtime: bool = True, progress: bool = False, **fields) -> dict:
    """``vishap demo SCENE --live``: check, calibrate if needed, run :func:`run_live_loop`."""
    import numpy as np

    from vishap.apps.assemble import calibrate
    from vishap.apps.config import DemoConfig
    from vishap.apps.live_loop import run_live_loop
    from vishap.registration.camera_robot import load
    from vishap.vision.capture import open_source
    from vishap.vision.rig import StereoRig

    spec, rig_path, calib_path, device = check_live(cameras=cameras, rig=rig, calib=calib, device=device)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stereo = StereoRig.load(rig_path)
    cfg = DemoConfig(scene=scene, width=stereo.image_size[0], height=stereo.image_size[1], video=False, **fields)
    if calib_path is not None:
        T, report = load(calib_path, rig=stereo), {"source": str(calib_path)}
    else:
        T, report = calibrate(cfg, stereo, out)
    gt = None
    folder = Path(spec)
    if folder.is_dir() and (folder / "gt.npz").is_file():
        with np.load(folder / "gt.npz", allow_pickle=False) as z:
            gt = {k: z[k] for k in z.files}
    source = open_source(spec)
    return run_live_loop(cfg, out=out, source=source, rig=stereo, T_robot_cam=T, calib_report=report, device=device,
                         gt=gt, duration_s=duration_s, realtime=realtime, source_name=spec, progress=progress)
