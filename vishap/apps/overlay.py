"""The demo video: both views side by side with the detected tip, the device and the object drawn
over the camera pixels (VisHap Fig. 3 style), written as H.264 MP4 through imageio-ffmpeg."""
from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from vishap._core.pose import transform_points

__all__ = ["object_outline_robot", "draw_overlay", "VideoWriter"]

TIP_COLOUR = (0, 0, 255)       # BGR red: detected tip
DEVICE_COLOUR = (255, 160, 0)  # blue-ish: device links from the plant state
OBJECT_COLOUR = (0, 220, 255)  # yellow: the scene object
TARGET_COLOUR = (0, 200, 0)    # green: device target X_d


def object_outline_robot(centre, normal, extent_m, *, n: int = 5) -> np.ndarray:
    """Closed rectangle (n points per side) of a patch of size ``extent_m`` on its plane, robot frame."""
    c = np.asarray(centre, float)
    nz = np.asarray(normal, float) / np.linalg.norm(normal)
    ref = np.array([1.0, 0.0, 0.0]) if abs(nz[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    ex = ref - nz * (ref @ nz)
    ex /= np.linalg.norm(ex)
    ey = np.cross(nz, ex)
    hx, hy = 0.5 * float(extent_m[0]), 0.5 * float(extent_m[1])
    corners = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy), (-hx, -hy)]
    pts = []
    for (a0, b0), (a1, b1) in zip(corners[:-1], corners[1:]):
        for s in np.linspace(0.0, 1.0, n, endpoint=False):
            pts.append(c + ex * (a0 + s * (a1 - a0)) + ey * (b0 + s * (b1 - b0)))
    pts.append(pts[0])
    return np.asarray(pts)


def _poly(img, uv, colour, thickness=1):
    uv = np.asarray(uv, float)
    ok = np.all(np.isfinite(uv), 1)
    if ok.sum() < 2:
        return
    pts = np.round(uv[ok] * 4).astype(np.int32)  # 2 fractional bits
    cv2.polylines(img, [pts.reshape(-1, 1, 2)], False, colour, thickness, cv2.LINE_AA, shift=2)


def _dot(img, uv, colour, r):
    if uv is None or not np.all(np.isfinite(uv)):
        return
    c = tuple(int(round(v * 4)) for v in np.asarray(uv, float).reshape(2))
    cv2.circle(img, c, int(r * 4), colour, 1, cv2.LINE_AA, shift=2)


def draw_overlay(left, right, *, rig, T_cam_robot, tip_uv=(None, None), device_points_robot=None,
                 object_outlines_robot=(), target_robot=None, lines=()) -> np.ndarray:
    """Return the side-by-side BGR image (H, 2W, 3) with the overlays drawn."""
    views = [left.copy(), right.copy()]
    scale = max(1.0, left.shape[1] / 320.0)
    projected = {}
    for name, pts in [("device", device_points_robot), ("target", target_robot)] + [
        (f"obj{i}", o) for i, o in enumerate(object_outlines_robot)
    ]:
        if pts is None:
            continue
        p_cam = transform_points(T_cam_robot, np.asarray(pts, float).reshape(-1, 3))
        projected[name] = rig.project(p_cam)
    for side, img in enumerate(views):
        for name, uv in projected.items():
            if name.startswith("obj"):
                _poly(img, uv[side], OBJECT_COLOUR, 1)
        if "device" in projected:
            _poly(img, projected["device"][side], DEVICE_COLOUR, max(1, int(scale)))
        if "target" in projected:
            _dot(img, projected["target"][side][0], TARGET_COLOUR, 3 * scale)
        uv = tip_uv[side]
        if uv is not None and np.all(np.isfinite(uv)):
            _dot(img, uv, TIP_COLOUR, 5 * scale)
            u, v = (int(round(x)) for x in np.asarray(uv).reshape(2))
            cv2.line(img, (u - int(8 * scale), v), (u + int(8 * scale), v), TIP_COLOUR, 1)
            cv2.line(img, (u, v - int(8 * scale)), (u, v + int(8 * scale)), TIP_COLOUR, 1)
    out = np.concatenate(views, axis=1)
    fs = 0.35 * scale
    for k, text in enumerate(lines):
        y = int((12 + 12 * k) * scale)
        (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, fs, 1)
        cv2.rectangle(out, (2, y - h - 2), (6 + w, y + base), (0, 0, 0), -1)
        cv2.putText(out, text, (4, y), cv2.FONT_HERSHEY_SIMPLEX, fs, (255, 255, 255), 1, cv2.LINE_AA)
    return out


class VideoWriter:
    """H.264 MP4 writer for BGR frames (opened lazily on the first frame)."""

    def __init__(self, path: str | Path, fps: float) -> None:
        self.path = Path(path)
        self.fps = float(fps)
        self._w = None
        self.frames = 0

    def write(self, image_bgr: np.ndarray) -> None:
        import imageio.v2 as imageio

        if self._w is None:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._w = imageio.get_writer(str(self.path), fps=self.fps, codec="libx264", quality=7,
                                         macro_block_size=2, ffmpeg_log_level="error")
        self._w.append_data(np.ascontiguousarray(image_bgr[:, :, ::-1]))
        self.frames += 1

    def close(self) -> None:
        if self._w is not None:
            self._w.close()
            self._w = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()
