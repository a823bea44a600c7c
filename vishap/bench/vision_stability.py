"""``vishap bench vision_stability``: where each vision method fails (VisHap §2.1 under stress).

One factor at a time is swept on a controlled toy stereo scene (:mod:`vishap.vision.toy`, 320×240,
the finger moving along a straight line): finger speed, occlusion length (frames the hand is out
of view, then back), size of a lighting drop after the background was learned, hue distance of a
skin-like table from the skin, and pixel noise. Methods: this pipeline with its tracking window,
the same pipeline searching the full frame every frame, and the same detector on masks from
OpenCV's MOG2 background subtractor (with the same skin model and median). Per point: detection
rate on frames where the tip is visible, tip 2-D/3-D RMS, track losses and the frames needed to
recover after the finger returns.
"""
from __future__ import annotations

import argparse

import cv2
import numpy as np

from vishap.bench._common import machine_info, new_figure, save_figure

HELP = "vision stability: sweep speed, occlusion, lighting, skin-like background, noise; chart failures"

SWEEPS = {
    "speed_m_s": [0.05, 0.2, 0.5, 1.0, 2.0, 3.0],
    "occlusion_frames": [0, 3, 10, 30],
    "light_drop": [0.0, 0.15, 0.3, 0.5, 0.7],
    "table_hue_offset": [60, 30, 15, 8, 4, 0],
    "noise_sigma": [0.0, 3.0, 8.0, 15.0, 25.0],
}
NOMINAL = {"speed_m_s": 0.2, "occlusion_frames": 0, "light_drop": 0.0, "table_hue_offset": 60, "noise_sigma": 2.0}


def add_arguments(p: argparse.ArgumentParser) -> None:
    p.add_argument("--frames", type=int, default=36, help="frames after the background frames (default 36)")
    p.add_argument("--quick", action="store_true", help="two values per factor (smoke run)")
    from vishap.scale.cli import add_engine_options

    add_engine_options(p, sweep=True)


def _table_bgr(offset):
    from vishap.vision.toy import SKIN_BGR

    skin_hsv = cv2.cvtColor(np.uint8([[SKIN_BGR]]), cv2.COLOR_BGR2HSV)[0, 0].astype(int)
    hsv = np.uint8([[[(skin_hsv[0] + offset) % 180, skin_hsv[1], min(255, skin_hsv[2] - 20)]]])
    return tuple(int(v) for v in cv2.cvtColor(hsv, cv2.COLOR_HSV2BGR)[0, 0])


def _frames(p: dict, n: int, learn: int = 10):
    """Render one sweep point: (frames, ground truth)."""
    from vishap.vision.rig import StereoRig
    from vishap.vision.toy import ToyScene

    rig = StereoRig.from_fov(320, 240, 60.0, 0.06)
    scene = ToyScene(rig, seed=7, noise=p["noise_sigma"], table_bgr=_table_bgr(p["table_hue_offset"]), ss=3)
    occ0 = learn + 6
    n = max(n, 6 + p["occlusion_frames"] + 18)  # enough frames after the finger returns
    frames, gt = [], []
    for i in range(learn + n):
        t = i / 30
        tau = max(0.0, t - learn / 30)
        # back-and-forth along a line across the view: speed is the finger's speed, m/s
        span = 0.14
        s = (p["speed_m_s"] * tau) % (2 * span)
        s = s if s <= span else 2 * span - s
        tip = np.array([-0.07 + s, -0.02 + 0.3 * s, 0.45])
        hand = i >= learn and not (occ0 <= i < occ0 + p["occlusion_frames"])
        light = 1.0 - (p["light_drop"] if i >= learn else 0.0)
        f = scene.frame(t, tip, hand=hand, light=light)
        frames.append((t, f.left, f.right))
        gt.append((hand, f.tip_uv_left, f.tip_uv_right, tip, f.labels_left))
    return rig, frames, gt, occ0


class _MOG2Segmenter:
    """Adapter: MOG2 foreground ∧ skin model ∧ median, with the Segmenter interface the pipeline uses."""

    def __init__(self, skin, config):
        self.skin, self.config, self.median = skin, config, config.median
        self.sub = cv2.createBackgroundSubtractorMOG2()
        self.learned = False
        self._last = None

    def learn(self, frames):
        for f in frames:
            self.sub.apply(f)
        # the pipeline checks the learned background for a hand, as it does with its own model's mean
        self.mean_image = self.sub.getBackgroundImage()
        self.learned = True

    def segment(self, image, roi=None):
        fg = self.sub.apply(image)
        m = cv2.bitwise_and(self.skin.mask(image), self.skin.mask(image), mask=(fg == 255).view(np.uint8))
        m = cv2.medianBlur(m, self.median)
        if roi is not None:
            x0, y0, x1, y1 = roi
            m = np.ascontiguousarray(m[y0:y1, x0:x1])
        return m

    def segment_region(self, image, roi=None, *, pad=0):
        """The mask over all of ``roi`` and its origin (MOG2 has no cheaper region; ``pad`` is moot)."""
        return self.segment(image, roi), (0, 0) if roi is None else tuple(roi[:2])


def _run_method(method, rig, frames, gt, occ0, n_occ):
    from vishap.vision.capture import StereoFrame
    from vishap.vision.pipeline import PipelineConfig, VisionPipeline
    from vishap.vision.skin_model import SkinModel

    skin = SkinModel.load()
    cfg = PipelineConfig(tracking=(method == "tracked window"))
    pipe = VisionPipeline(rig, skin_model=skin, config=cfg)
    if method.startswith("MOG2"):
        pipe.segmenters = {s: _MOG2Segmenter(skin, cfg.segment) for s in ("left", "right")}
    e2, e3, det, vis = [], [], 0, 0
    losses, was = 0, False
    recover = None
    for i, (t, l, r) in enumerate(frames):
        est = pipe.process(StereoFrame(i, t, l, r))
        hand, uvl, uvr, tip, _ = gt[i]
        if est.mode == "learning":
            continue
        now = est.confidence > 0
        if was and not now and hand:
            losses += 1
        was = now
        if not hand:
            continue
        vis += 1
        if est.found:
            det += 1
            e2.append(np.r_[est.uv_left - uvl, est.uv_right - uvr])
            e3.append(np.linalg.norm(est.p_cam - tip))
            if n_occ and recover is None and i >= occ0 + n_occ:
                recover = i - (occ0 + n_occ)
    return {"detection_rate": det / vis if vis else None,
            "tip2d_rms_px": float(np.sqrt(np.mean(np.square(e2)))) if e2 else None,
            "tip3d_rms_mm": float(np.sqrt(np.mean(np.square(e3))) * 1e3) if e3 else None,
            "track_losses": losses, "recovery_frames": recover if n_occ else None}


METHODS = ("tracked window", "full frame", "MOG2 + same detector")


def _point(case: tuple) -> dict:
    """One sweep point, every method (a Ray task under ``--workers``): a pure function of
    ``(factor, value, frames)`` (the toy scene's noise has a fixed seed)."""
    factor, v, n = case
    p = dict(NOMINAL, **{factor: v})
    rig, frames, gt, occ0 = _frames(p, n)
    row = {"value": v}
    for m in METHODS:
        row[m] = _run_method(m, rig, frames, gt, occ0, p["occlusion_frames"])
    return row


def run(args: argparse.Namespace) -> dict:
    from vishap.scale import map_cases
    from vishap.scale.cli import engine_args

    rec = {"machine": machine_info(), "nominal": NOMINAL, "sweeps": {}}
    cases = [(factor, v, args.frames) for factor, values in SWEEPS.items()
             for v in ([values[0], values[-1]] if args.quick else values)]
    rows = map_cases(_point, cases, desc="vision_stability", **engine_args(args))
    for (factor, _, _), row in zip(cases, rows):
        rec["sweeps"].setdefault(factor, []).append(row)
    rec["chart"] = str(_chart(rec, f"{args.out}/vision_stability.png"))
    return rec


def _chart(rec, path):
    sweeps = rec["sweeps"]
    fig, axes = new_figure(2, len(sweeps), figsize=(4 * len(sweeps), 7), squeeze=False)
    for j, (factor, rows) in enumerate(sweeps.items()):
        x = [r["value"] for r in rows]
        for m in METHODS:
            axes[0, j].plot(x, [r[m]["detection_rate"] for r in rows], "o-", label=m)
            y = [r[m]["tip3d_rms_mm"] if r[m]["tip3d_rms_mm"] is not None else np.nan for r in rows]
            axes[1, j].plot(x, y, "o-", label=m)
        axes[0, j].set(title=factor, ylabel="detection rate (tip visible)", ylim=(-0.05, 1.05))
        axes[1, j].set(xlabel=factor, ylabel="tip 3-D RMS, mm", yscale="log")
        for a in axes[:, j]:
            a.grid(alpha=0.3)
    axes[0, 0].legend(fontsize=8)
    return save_figure(fig, path)
