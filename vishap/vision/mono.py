"""The paper's fingertip detector in one camera: skin segmentation → cap test → Kalman tracker.

:class:`GeometricDetector` implements :class:`vishap.vision.detector.MonoDetector` with the same
per-view pieces the stereo pipeline uses (:class:`~vishap.vision.segment.Segmenter`,
:func:`~vishap.vision.view.search_tips`, :class:`~vishap.vision.track.TipTracker`); no rig is
needed. Depth is unknown in one camera, so the cap test runs at the radii of several depths
(``z_search_m``) unless the caller gives one (``set_depth``, e.g. from stereo).

Two variants are registered:

``paper``      as shipped: the Gaussian hue skin model with its saturation gate; candidates ranked by
               distance from the centroid of all skin; depths 0.6/0.45/0.8 m; the background learned
               from the first frames whatever they hold (skin only until then).
``geometric``  for real scenes (the default): the skin model fitted on real skin
               (:mod:`vishap.vision.skin_hist`); the finger of the hand (:func:`vishap.vision.view.hand_tip`)
               with the cap test at several scales near it; the background learned only from frames
               with no hand found (:mod:`vishap.vision.background`).

Both report ``cap_uv`` (the fitted cap centre, what stereo triangulates) and ``tip_end_uv``
(the cap's outermost point along the finger: the centre moved by the cap radius away from the
finger; the hand's extreme point where no cap fits).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np

from vishap.vision.detector import MonoDetection, register_detector
from vishap.vision.fingertip import FingertipConfig
from vishap.vision.segment import SegmentConfig, Segmenter, snap_roi
from vishap.vision.track import TipTracker, TrackerConfig
from vishap.vision.view import hand_region, hand_tip, search_tips

__all__ = ["GeometricConfig", "GeometricDetector", "focal_from_fov"]


def focal_from_fov(width_px: int, hfov_deg: float = 60.0) -> float:
    """Focal length in pixels of a pinhole camera of horizontal field of view ``hfov_deg``."""
    return 0.5 * width_px / np.tan(np.radians(hfov_deg) / 2)


@dataclass(frozen=True)
class GeometricConfig:
    skin: str = "adaptive"          # "adaptive" (hue seed + this image's hand colours, hand_mask.py) |
    #                                 "gaussian" (the paper's hue model) | "real" (histogram fitted on real skin)
    candidates: str = "hand"        # "hand" (finger of the hand) | "centroid" (distance from the skin centroid)
    background: str = "hand_free"   # "hand_free" | "first_frames" (as shipped) | "none" (skin only)
    hfov_deg: float = 60.0          # field of view used for r = K/z when no focal length is given
    focal_px: float | None = None
    tip_circle_m: float = 0.0048    # as the stereo pipeline: test circle radius at the fingertip
    z_search_m: tuple[float, ...] = (0.25, 0.35, 0.5, 0.7)  # depths tried when the depth is unknown
    hand_window_frac: float = 2.5   # cap test near the hand's extreme point: window half-side in cap radii
    tip_end_frac: float = -0.4      # tip end = cap centre moved this many cap radii out along the finger
    #   (negative: into it). Fitted on the fit split of the real photos (TI1K 1-600, every 3rd):
    #   annotators mark the finger's pad, 0.4 cap radii behind the fitted cap centre
    #   (PCK@10 1.0: 0.005, 0.0: 0.50, -0.4: 0.625, -0.7: 0.53)
    learn_frames: int = 10
    tracking: bool = True
    recheck_frames: int = 15        # while tracking, search the full frame every this many frames …
    recheck_young_frames: int = 3   # … every this many while the track is younger than recheck_frames
    recheck_jump_px: float = 12.0   # a recheck this far from the track restarts it there
    segment: SegmentConfig = field(default_factory=SegmentConfig)
    fingertip: FingertipConfig = field(default_factory=FingertipConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    max_candidates: int = 4


PAPER = GeometricConfig(skin="gaussian", candidates="centroid", background="first_frames",
                        z_search_m=(0.6, 0.45, 0.8), tracking=True)


class GeometricDetector:
    """One camera's paper-style fingertip detector and tracker (see the module docstring)."""

    def __init__(self, config: GeometricConfig | None = None, *, skin_model=None, name: str = "geometric"):
        self.config = config or GeometricConfig()
        self.name = name
        self.skin = skin_model if skin_model is not None else _load_skin(self.config.skin)
        self.reset()

    def reset(self) -> None:
        self.seg = Segmenter(self.skin, self.config.segment)
        self.tracker = TipTracker(self.config.tracker)
        self._bg = None
        if self.config.background == "hand_free":
            from vishap.vision.background import HandFreeBackground

            self._bg = HandFreeBackground(self.seg, learn_frames=self.config.learn_frames)
        self._frames: list = []
        self._since_full = 0
        self._track_age = 0
        self._r_track: float | None = None  # test-circle radius of the last detection
        self._z: float | None = None
        self._f: float | None = self.config.focal_px

    def set_depth(self, z_m: float | None) -> None:
        """Depth of the fingertip when known (stereo): one radius instead of several."""
        self._z = None if z_m is None else float(z_m)

    # ------------------------------------------------------------------ per frame
    def process(self, image: np.ndarray, t: float) -> MonoDetection:
        t0 = time.perf_counter()
        cfg = self.config
        h, w = image.shape[:2]
        if self._f is None:
            self._f = focal_from_fov(w, cfg.hfov_deg)
        K = self._f * cfg.tip_circle_m
        radii = [K / self._z] if self._z else [K / z for z in cfg.z_search_m]
        # a held track keeps the scale it was found at: one radius in its window
        track_r = [self._r_track] if self._r_track and not self._z else radii
        pred = self.tracker.predict(t) if cfg.tracking else None
        roi = None
        if pred is not None:
            roi = self.tracker.window((w, h), extra_px=2 * max(track_r) * (1 + cfg.fingertip.delta_r_frac))
        mode = "tracked" if roi is not None else "full"
        period = cfg.recheck_young_frames if self._track_age < cfg.recheck_frames else cfg.recheck_frames
        if mode == "tracked" and period and self._since_full >= period:
            roi, mode = None, "recheck"  # as the stereo pipeline: escape a lock on a knuckle taken at the entry
        det = self._search(image, roi, track_r if mode == "tracked" else radii, pred if mode == "tracked" else None)
        if det is None and mode == "tracked":
            mode = "full"
            det = self._search(image, None, radii, None)
        self._since_full = self._since_full + 1 if mode == "tracked" else 0
        self._track_age = self._track_age + 1 if det is not None else 0
        if self._bg is not None:
            self._bg.observe(image, t, hand_uv=None if det is None else det[1])
        status = self._background_status(image)  # after this frame was seen: "hand in view" from the first one
        if self.config.background == "first_frames" and not self.seg.learned:
            self._frames.append(image)
            if len(self._frames) >= cfg.learn_frames:
                self.seg.learn(self._frames)
                self._frames = []
        timings = {"total_ms": (time.perf_counter() - t0) * 1e3}
        if det is None:
            self._r_track = None
            self.tracker.update(t, None)
            return MonoDetection(t, False, mode=mode, reason=f"no fingertip ({status})", timings=timings)
        tip, end, cap = det
        self._r_track = None if tip is None else tip.radius_px
        if mode == "recheck" and self.tracker.tracking and np.hypot(*(end - self.tracker.kf.position)) > cfg.recheck_jump_px:
            self.tracker.restart(t, end)
        else:
            self.tracker.update(t, end)
        return MonoDetection(t, True, tip_end_uv=end, cap_uv=cap, radius_px=float(tip.cap_radius_px if tip else 0.0),
                             direction=None if tip is None else tip.direction, confidence=self.tracker.confidence,
                             mode=f"{mode}/{status}", timings=timings)

    def _background_status(self, image) -> str:
        if self._bg is not None:
            return self._bg.status
        return "background" if self.seg.learned else "skin only"

    def _mask(self, image, roi, full: bool = False):
        """Skin mask of the ROI: with the background model when one is learned, else the skin test
        alone (over the full frame with the adaptive model: the hand's own colours)."""
        import cv2

        from vishap.vision.segment import binary_median

        if self.seg.learned and (self._bg is None or self._bg.usable):
            return self.seg.segment(image, roi)
        x0, y0, x1, y1 = roi
        if self.config.skin == "adaptive":
            from vishap.vision.hand_mask import WINDOW, adaptive_hand_mask

            if full:
                return adaptive_hand_mask(image, self.skin)
            # a tracking window: the finger enters it from any side
            return adaptive_hand_mask(np.ascontiguousarray(image[y0:y1, x0:x1]), self.skin, WINDOW)
        mask = self.skin.mask_hsv(cv2.cvtColor(image[y0:y1, x0:x1], cv2.COLOR_BGR2HSV))
        k = self.config.segment.median
        return binary_median(mask, k) if k > 1 else mask

    def _search(self, image, roi, radii, prior):
        """(Fingertip or None, tip end uv, cap uv) of the best candidate in ``roi`` (None: full frame)."""
        cfg = self.config
        h, w = image.shape[:2]
        full = roi is None
        roi = snap_roi((0, 0, w, h) if full else roi, cfg.segment.tile, (w, h))
        mask = self._mask(image, roi, full)
        if cfg.candidates == "hand" and full:
            return self._hand_candidate(mask, roi, radii)
        if prior is not None:
            tips = search_tips(mask, radii, cfg.fingertip, origin=roi[:2], prior_uv=prior,
                               max_tips=1)
        else:
            tips = search_tips(mask, radii, cfg.fingertip, origin=roi[:2], max_tips=cfg.max_candidates)
        if not tips:
            return None
        tip = tips[0]
        return tip, _tip_end(tip, cfg.tip_end_frac), tip.uv.copy()

    def _hand_candidate(self, mask, roi, radii):
        region = hand_region(mask)
        if region is None:
            return None
        extreme = hand_tip(region)
        cfg = self.config
        m = region.label_mask
        caps = []
        for r in radii:
            half = int(np.ceil(cfg.hand_window_frac * 2 * r * (1 + cfg.fingertip.delta_r_frac)))
            x0, y0 = max(0, int(extreme[0]) - half), max(0, int(extreme[1]) - half)
            x1, y1 = min(m.shape[1], int(extreme[0]) + half + 1), min(m.shape[0], int(extreme[1]) + half + 1)
            tips = search_tips(np.ascontiguousarray(m[y0:y1, x0:x1]), [r], cfg.fingertip, origin=(x0, y0),
                               prior_uv=extreme, max_tips=1)
            if tips and tips[0].cap_radius_px > 0:
                caps.append(tips[0])
        # the largest cap whose circle reaches the extreme point (a smaller test circle also fits
        # deeper inside a wide fingertip); else the cap nearest it (a knuckle passes at a larger scale)
        gap = [float(np.hypot(*(tp.uv - extreme))) - tp.cap_radius_px for tp in caps]
        touching = [tp for tp, g in zip(caps, gap) if g <= 0.35 * tp.cap_radius_px + 2.0]
        best = max(touching, key=lambda tp: tp.cap_radius_px) if touching else \
            (caps[int(np.argmin(gap))] if caps else None)
        origin = np.asarray(roi[:2], dtype=np.float64)
        if best is None:
            return None, extreme + origin, None
        best.uv = best.uv + origin
        return best, _tip_end(best, cfg.tip_end_frac), best.uv.copy()


def _tip_end(tip, frac: float = 1.0) -> np.ndarray:
    """The fingertip's end: the cap centre moved ``frac`` cap radii (the test circle's when no cap
    was fitted) out along the finger (1: the cap's outermost point)."""
    rad = tip.cap_radius_px if tip.cap_radius_px > 0 else tip.radius_px
    return tip.uv - frac * rad * np.asarray(tip.direction, dtype=np.float64)


def _load_skin(kind: str):
    if kind in ("gaussian", "adaptive"):
        from vishap.vision.skin_model import SkinModel

        return SkinModel.load()
    if kind == "real":
        from vishap.vision.skin_hist import HistogramSkinModel

        return HistogramSkinModel.load()
    from vishap._core.errors import ConfigError

    raise ConfigError(f"skin {kind!r}: expected 'adaptive', 'gaussian' or 'real'", field="skin")


register_detector("paper", lambda **kw: GeometricDetector(PAPER, name="paper", **kw),
                  "the paper's method as shipped: Gaussian hue skin, centroid ranking, background from the first frames")
register_detector("geometric", lambda **kw: GeometricDetector(GeometricConfig(), name="geometric", **kw),
                  "skin fitted on real hands, finger of the hand, cap test at several scales, hand-free background")
