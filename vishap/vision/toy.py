"""A tiny analytic stereo scene for tests: a finger (capsule with a hemispherical cap) and palm over
a textured table, with a grey arm, drawn anti-aliased through a :class:`StereoRig`.

Not a renderer (that is :mod:`vishap.sim`): shapes are projected spheres/capsules drawn in 2-D with
4× supersampling, colours are flat with mild shading and noise. Ground truth: ``labels`` (0
background, 1 skin, 2 device) and ``tip_uv`` = projection of the centre of the fingertip's cap.
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from vishap.vision.rig import StereoRig
from vishap.world.finger import TIP_RADIUS_M

__all__ = ["ToyScene", "ToyFrame", "write_sequence"]

SKIN_BGR = (120, 150, 215)     # hue ≈ 10 (OpenCV), a light skin tone
TABLE_BGR = (95, 140, 80)      # greenish table
SKINLIKE_TABLE_BGR = (110, 140, 200)


@dataclass
class ToyFrame:
    t: float
    left: np.ndarray
    right: np.ndarray
    labels_left: np.ndarray
    labels_right: np.ndarray
    tip_cam: np.ndarray
    tip_uv_left: np.ndarray
    tip_uv_right: np.ndarray


class ToyScene:
    """Draw frames with the fingertip cap centre at ``tip_cam`` (left camera frame, metres)."""

    def __init__(self, rig: StereoRig, *, seed: int = 0, finger_radius_m: float = TIP_RADIUS_M,
                 skinlike_table: bool = False, noise: float = 2.0, ss: int = 4, table_bgr=None):
        self.rig, self.R, self.noise, self.ss = rig, finger_radius_m, noise, ss
        self.rng = np.random.default_rng(seed)
        w, h = rig.image_size
        if table_bgr is None:
            table_bgr = SKINLIKE_TABLE_BGR if skinlike_table else TABLE_BGR
        base = np.array(table_bgr, np.float32)
        tex = self.rng.normal(0, 6, (h // 8 + 1, w // 8 + 1, 3)).astype(np.float32)
        tex = cv2.resize(tex, (w, h), interpolation=cv2.INTER_LINEAR)
        self.table = {s: np.clip(base + tex, 0, 255) for s in ("left", "right")}

    def _draw(self, side: str, tip_cam, direction_cam, light: float, device_uv, hand: bool):
        rig, ss = self.rig, self.ss
        w, h = rig.image_size
        img = self.table[side] * light
        lab = np.zeros((h, w), np.uint8)
        cover_dev = np.zeros((h * ss, w * ss), np.uint8)
        if device_uv is not None:
            pts = (np.asarray(device_uv[side]) * ss + (ss - 1) / 2).astype(np.int32)
            cv2.polylines(cover_dev, [pts.reshape(-1, 1, 2)], False, 255, thickness=6 * ss, lineType=cv2.LINE_8)
        cover_skin = np.zeros((h * ss, w * ss), np.uint8)
        if hand:
            p0 = np.asarray(tip_cam, float)
            d = np.asarray(direction_cam, float)
            d = d / np.linalg.norm(d)
            p1 = p0 + 0.07 * d  # finger base
            pc = p0 + 0.11 * d  # palm centre
            proj = {}
            for name, p in (("tip", p0), ("base", p1), ("palm", pc)):
                uvl, uvr = rig.project(p[None])
                proj[name] = (uvl if side == "left" else uvr)[0]
            f = rig.K_left[0, 0]
            rt = f * self.R / p0[2] * ss
            rp = f * 0.04 / pc[2] * ss
            q = lambda uv: tuple(int(round(x)) for x in (uv * ss + (ss - 1) / 2))
            cv2.circle(cover_skin, q(proj["palm"]), int(round(rp)), 255, -1)
            cv2.line(cover_skin, q(proj["tip"]), q(proj["base"]), 255, thickness=int(round(2 * rt)))
            cv2.circle(cover_skin, q(proj["tip"]), int(round(rt)), 255, -1)
            cv2.circle(cover_skin, q(proj["base"]), int(round(rt)), 255, -1)
        a_dev = cv2.resize(cover_dev, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)[..., None] / 255
        a_skin = cv2.resize(cover_skin, (w, h), interpolation=cv2.INTER_AREA).astype(np.float32)[..., None] / 255
        dev_col = np.array((60, 60, 62), np.float32) * light
        skin_col = np.array(SKIN_BGR, np.float32) * light
        img = img * (1 - a_dev) + dev_col * a_dev
        img = img * (1 - a_skin) + skin_col * a_skin
        lab[a_dev[..., 0] >= 0.5] = 2
        lab[a_skin[..., 0] >= 0.5] = 1
        img = img + self.rng.normal(0, self.noise, img.shape)
        return np.clip(img + 0.5, 0, 255).astype(np.uint8), lab

    def frame(self, t: float, tip_cam, *, direction_cam=(0.3, 0.6, 0.3), light: float = 1.0,
              device_cam=None, hand: bool = True) -> ToyFrame:
        """Render one stereo pair. ``device_cam``: (K, 3) polyline of the grey arm (camera frame)."""
        device_uv = None
        if device_cam is not None:
            l, r = self.rig.project(np.asarray(device_cam, float))
            device_uv = {"left": l, "right": r}
        left, ll = self._draw("left", tip_cam, direction_cam, light, device_uv, hand)
        right, lr = self._draw("right", tip_cam, direction_cam, light, device_uv, hand)
        uvl, uvr = self.rig.project(np.asarray(tip_cam, float)[None])
        return ToyFrame(t, left, right, ll, lr, np.asarray(tip_cam, float), uvl[0], uvr[0])


def write_sequence(folder, *, seed: int = 0, frames: int = 16, learn: int = 4, size=(320, 240),
                   skinlike_table: bool = False, light_drop: float = 0.0, speed_m_s: float = 0.09) -> None:
    """Write a labelled toy sequence in the folder layout ``vishap synth`` uses (tests, benchmarks)."""
    from pathlib import Path

    folder = Path(folder)
    rig = StereoRig.from_fov(size[0], size[1], 60.0, 0.06)
    scene = ToyScene(rig, seed=seed, skinlike_table=skinlike_table)
    for d in ("left", "right", "labels/left", "labels/right"):
        (folder / d).mkdir(parents=True, exist_ok=True)
    rig.save(folder / "rig.yaml")
    gt = {k: [] for k in ("t", "tip_cam", "tip_uv_left", "tip_uv_right", "tip_visible_left", "tip_visible_right")}
    for i in range(frames):
        t = i / 30
        p = np.array([-0.03 + speed_m_s * t, 0.15 * speed_m_s * t, 0.45 + 0.1 * speed_m_s * t])
        f = scene.frame(t, p, hand=i >= learn, light=1.0 - light_drop * (i >= learn))
        name = f"{i:06d}.png"
        for sub, img in (("left", f.left), ("right", f.right), ("labels/left", f.labels_left),
                         ("labels/right", f.labels_right)):
            cv2.imwrite(str(folder / sub / name), img)
        for k, v in (("t", t), ("tip_cam", p), ("tip_uv_left", f.tip_uv_left), ("tip_uv_right", f.tip_uv_right),
                     ("tip_visible_left", i >= learn), ("tip_visible_right", i >= learn)):
            gt[k].append(v)
    np.savez(folder / "gt.npz", **{k: np.array(v) for k, v in gt.items()})
