"""Live mode: the demo on real cameras and a real haptic device (issue 9 part 3).

Before anything starts, every piece of hardware and every file the live loop needs is checked, and
whatever is missing is reported in one error: each camera index that cannot be opened (and whether
its ``/dev/videoN`` node exists), the stereo rig and camera-to-robot calibration files, and the
haptic device driver (vishap ships the MuJoCo plant; a real arm needs a :class:`Device` driver).
"""
from __future__ import annotations

import ctypes.util
import os
from pathlib import Path

from vishap._core.errors import DeviceError

__all__ = ["parse_cameras", "check_cameras", "find_device_driver", "check_live", "run_live"]

#: Real-device drivers: name → (module, class). A driver module implements ``vishap.robot.device.Device``.
DEVICE_DRIVERS = {"phantom": ("vishap.robot.phantom", "PhantomDevice")}


def parse_cameras(spec: str) -> list[int]:
    try:
        idx = [int(s) for s in str(spec).split(",") if s.strip() != ""]
    except ValueError:
        raise DeviceError(f"--cameras: expected camera indices like '0,1' or '0', got {spec!r}") from None
    if not 1 <= len(idx) <= 2 or any(i < 0 for i in idx):
        raise DeviceError(f"--cameras: expected one (side-by-side) or two non-negative indices, got {spec!r}")
    return idx


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


def find_device_driver(name: str | None):
    """Return the driver class for ``name`` (default ``phantom``), or a string saying what is missing."""
    import importlib

    name = name or "phantom"
    if name not in DEVICE_DRIVERS:
        return f"haptic device: unknown driver {name!r} (known: {', '.join(DEVICE_DRIVERS)})"
    mod_name, cls_name = DEVICE_DRIVERS[name]
    try:
        mod = importlib.import_module(mod_name)
    except ImportError:
        lib = ctypes.util.find_library("HD")
        why = "OpenHaptics libHD found" if lib else "OpenHaptics libHD not installed"
        return (f"haptic device: no {name!r} driver ({mod_name} is not part of this installation; {why}); "
                f"vishap ships only the simulated MuJoCo plant")
    return getattr(mod, cls_name)


def check_live(*, cameras: str, rig: str | None, calib: str | None, device: str | None):
    """Collect every missing piece; return ``(camera_indices, rig_path, calib_path, driver_class)``."""
    problems = []
    idx = parse_cameras(cameras)
    problems += check_cameras(idx)
    rig_path = Path(rig or "calib/rig.yaml")
    if not rig_path.is_file():
        problems.append(f"stereo rig file {rig_path} not found (make it with 'vishap calibrate stereo')")
    calib_path = Path(calib or "calib/camera_robot.yaml")
    if not calib_path.is_file():
        problems.append(f"camera-robot calibration {calib_path} not found (make it with 'vishap calibrate robot')")
    driver = find_device_driver(device)
    if isinstance(driver, str):
        problems.append(driver)
    if problems:
        raise DeviceError("live mode cannot start, missing: " + "; ".join(problems))
    return idx, rig_path, calib_path, driver


def run_live(scene: str, *, out, cameras: str, calib: str | None, rig: str | None, device: str | None,
             duration_s: float) -> dict:
    idx, rig_path, calib_path, driver = check_live(cameras=cameras, rig=rig, calib=calib, device=device)
    from vishap.apps.live_loop import run_live_loop
    from vishap.registration.camera_robot import load
    from vishap.vision.capture import CameraSource
    from vishap.vision.rig import StereoRig

    os.makedirs(out, exist_ok=True)
    stereo = StereoRig.load(rig_path)
    source = CameraSource(idx[0], idx[1] if len(idx) == 2 else None)
    return run_live_loop(scene, out=out, source=source, rig=stereo, T_robot_cam=load(calib_path, rig=stereo),
                         device_path=f"{driver.__module__}:{driver.__name__}", duration_s=duration_s)
