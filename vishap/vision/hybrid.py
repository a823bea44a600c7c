"""Hybrid fingertip detector: the learned model finds the hand, the geometric cap fit follows it.

The learned hand-landmark model (:mod:`vishap.vision.learned`) is accurate on real frames but
costs a full network per frame; the paper's cap test and circle fit (:mod:`vishap.vision.fingertip`)
with the Kalman tracker (:mod:`vishap.vision.track`) cost a small window per frame but need a
skin mask that holds and a start. The hybrid gives each the part it is good at:

1. **find** (slow, every ``recheck_every`` frames or when the window loses the tip): the landmark
   model, in video mode (its hand region moved by the motion tracked since it last ran; the palm
   detector only when that region holds no hand), gives the index finger's landmarks, its cap
   centre and radius (:func:`~vishap.vision.learned.cap_from_landmarks`) and the finger's
   direction. From the same frame it learns this hand's colour against its surroundings
   (:class:`LocalSkin`), since with a camera that moves there is no hand-free background to learn.
2. **refine** (that frame): the cap test and circle fit (:func:`~vishap.vision.fingertip.detect_fingertips`)
   on the skin mask of a window around the learned cap give a sub-pixel cap centre and radius;
   they replace the landmark estimate when they agree with it (within ``gate_radii`` cap radii).
3. **follow** (fast, the frames between): the tracker predicts the cap, the window around the
   prediction is segmented with the learned colour model, the cap fit measures it, the tracker
   updates. Where the colour model cannot separate the finger from what lies behind it (pale
   skin on a pale wall, motion blur) the fit fails; the fingertip's patch from the last *find*,
   matched by normalised cross-correlation in the same window (sub-pixel peak), measures the cap
   instead (mode ``tracked_template``), for at most ``max_template_run`` frames in a row and
   at NCC ≥ ``min_ncc``: the patch is mostly background around a thin finger, so a run of
   matches can follow the scene instead of the finger (on the train photos in file order a
   7-frame run drifted 46 → 108 px). Photos 1–600 in file order, PCK@30 / finds in 600 frames,
   and finds in 5 × 60 frames of moving fit photos (the tracking-mode time): no limit, NCC 0.9:
   0.975 / 161 / 30; runs of 1: 0.988 / 176 / 47; runs of 3: 0.983 / 161 / 36; runs of 3 at
   NCC 0.95: 0.988 / 189 / 36 (the default: the accuracy of the tightest limit at the tracking
   cost of a loose one).
   A frame where neither holds (no fit near the prediction pointing the right way, no match
   above ``min_ncc``, the patch's run used up) is a miss; ``max_misses`` misses in a row hand
   the frame back to the learned model.
4. **checks** on what the window measures, each of which hands the frame to the learned model at
   once (found on photos 1–600 played in file order, every 2nd and 3rd photo, and backwards:
   faster motion and more cuts than the file order alone):

   * a patch match must land on skin: at least ``template_min_skin`` of the colour mask within
     half a cap radius of the matched cap centre. Where the finger and the scene move apart (a
     camera panning while the finger moves), the patch, mostly background, matched the scene at
     NCC ≥ 0.95 and walked off the finger (every 3rd photo: 40 → 69 → 104 px in three frames);
   * a cap fit that disagrees with the track in all three ways at once — its radius off the
     tracked one by more than a factor ``1/disagree_radius_ratio``, its centre more than
     ``disagree_jump_radii`` radii from the prediction, its direction turned by more than
     acos(``disagree_cos``) — is a cap of something else (backwards: after a cut the thumbnail
     test missed, a cap of half the radius 1.8 radii away, turned 57°, followed 60 px off the tip).
     Any one of the three alone is common on good frames (of 1212 fits there 5 % lie farther than
     1.65 radii, 5 % turn more than 46°); two of them flag 28 good fits, all three none;
   * a cap fit farther than ``recheck_jump_radii`` radii from the prediction, whatever its radius and
     direction, is looked at again by the learned model (not rejected: a fast finger is confirmed by
     the find). The window's fit can move to a neighbouring cap of the same size and direction (the
     thumb under a pinching index, a knuckle) and the track then follows it until the next re-check.
     Photos 1–600 in file order, every 2nd (twice), every 3rd and backwards, 1198 followed fits: 4
     jumped onto something else (the error rose by more than 12 px to over 25 px), all 1.65–2.03
     radii from the prediction; 74 fits (6 %) lie beyond 1.6, the default.

5. **an unconfirmed find** (no cap fit agrees with the landmarks' cap) is read again: the landmark
   model on the region its own landmarks give (:meth:`~vishap.vision.learned.LearnedDetector.reread`,
   what video mode looks at on the next frame), up to ``max_rereads`` times, until two readings'
   index tips agree within ``reread_agree_radii`` cap radii. The first reading comes from a palm box
   or a followed region sized for another moment, and the model can read a near hand framed that way
   as a curled finger (fit photo 117: 240 px off, 9 px on the second reading, 4 on the third). A find
   whose readings never agree (the model flips between a curled and a stretched finger) is not
   followed: the next frame goes to the learned model again (``recheck_unsettled``), instead of its
   patch being followed. Chosen on photos 1–600 (the five orders above, 2000 frames, with the
   jump re-check): PCK@30 0.9895 (none) → 0.9925 (one re-read, always taken) → 0.9960 (up to two, to
   agreement); agreement within 0.5 / 1 / 2 radii: 0.9970 / 0.9960 / 0.9940; as independent photos
   0.990 → 0.990 → 0.993 (PCK@20 0.963 → 0.980 → 0.983).
   A find in a running track (not after a scene cut) whose landmark cap agrees with the track —
   within the window's gate of the prediction, its radius within ``disagree_radius_ratio`` of the
   track's — is confirmed by the track and not read again (``reread_trusts_track``): on the moving
   photos each re-check of a finger the cap fit misses paid two more landmark runs for the same
   output (tracking-mode time 0.25 → 0.31 of MediaPipe's video mode in one run). The five orders:
   PCK@30 0.9960 → 0.9950, PCK@20 0.9735 → 0.9770, PCK@10 0.842 → 0.857.

A **scene cut** (a frame unrelated to the last: another clip, a new moment of a video cut
together) is seen before the window is looked at: a 40×30 thumbnail of the frame that correlates
less than ``cut_ncc`` with the last frame's sends the frame straight to the learned model, whose
followed hand region is then verified by its presence score (the palm detector runs when it
fails). Otherwise a window that still holds skin within the gate after a cut keeps a stale track
until the next re-check.

On independent photos (``reset()`` before each) every frame is a *find* + *refine*.

``tip_end_uv`` is the point annotators mark as the fingertip, placed along the finger from the cap
centre: ``cap − k·radius·direction`` (direction into the finger), with ``k`` =
``tip_end_frac`` for a fitted cap and ``landmark_tip_end_frac`` for the cap the landmarks give
(``k`` = 1 is the cap's outermost point; ``landmark_tip_end_frac=None`` reports landmark 8). On the real
train photos (TI1K, fit split 1–600 only) the annotation lies a median 0.17 radii *behind* the
fitted cap centre (the pad, not the end; 455 photos) and 0.53 radii out from the landmark cap
centre (144 photos where the cap fit failed): the defaults. ``cap_uv`` (what stereo triangulates)
does not depend on them.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import cv2
import numpy as np

from vishap._core.errors import ConfigError
from vishap.vision.detector import MonoDetection, register_detector
from vishap.vision.fingertip import detect_fingertips
from vishap.vision.learned import (
    INDEX_DIP, INDEX_MCP, INDEX_PIP, INDEX_TIP, INSTALL_HINT, HandLandmarks, LearnedConfig, LearnedDetector,
    cap_from_landmarks,
)
from vishap.vision.segment import binary_median
from vishap.vision.skin_model import SkinModel
from vishap.vision.track import TipTracker, TrackerConfig

__all__ = ["HybridConfig", "LocalSkin", "HybridDetector"]


@dataclass(frozen=True)
class HybridConfig:
    recheck_every: int = 10        # tracked frames between two runs of the learned model
    max_misses: int = 0            # window misses in a row before the learned model takes over (0: at once)
    window_radii: float = 3.0      # window half-side: this many cap radii beyond the tracker's prediction
    gate_radii: float = 1.5        # a fit farther than this many radii from the prediction is a miss
    min_direction_cos: float = 0.5  # a fit whose finger direction turns more than 60° is a miss
    fit_radius_frac: float = 0.7   # radius given to the cap test, as a fraction of the estimated cap radius
    skin: str = "local"            # "local": colour model learned from the hand in the found frame;
    #                                "model": the project's shipped skin model
    template: bool = True          # when the cap fit fails, follow the fingertip's patch (normalised cross-correlation)
    template_radii: float = 2.0    # half-side of that patch, in cap radii
    # weaker matches are misses (train video: 0.7 → PCK@30 0.88, 0.9 → 0.95, same time; 0.95 with the run
    # limit below, chosen on photos 1–600)
    min_ncc: float = 0.95
    max_template_run: int = 3      # patch-followed frames in a row before the learned model looks again
    # a patch match with less of the colour mask than this within half a radius of its cap centre is a
    # miss (None: no check; see the module notes, checks)
    template_min_skin: float | None = 0.5
    # a cap fit off the track in radius (ratio below this or above its inverse), position (farther than
    # disagree_jump_radii radii from the prediction) and direction (cos below disagree_cos) at once sends
    # the frame to the learned model (disagree_radius_ratio None: no check; see the module notes, checks)
    disagree_radius_ratio: float | None = 0.6
    disagree_jump_radii: float = 1.2
    disagree_cos: float = 0.8
    # a frame whose thumbnail correlates less than this with the last frame's is a scene cut: the learned
    # model looks at once (None: off). Photos 1–600 in file order, 599 consecutive pairs: 503 at ≥ 0.9,
    # 70 below 0.4 and two at 0.41 and 0.46 (jumps to an unrelated moment or clip), 24 at 0.55–0.9 (camera
    # swings, which the window follows); 20 fit photos moved ≤ 4 px per frame (1180 pairs): all ≥ 0.89
    cut_ncc: float | None = 0.5
    # a find whose landmark cap no cap fit confirms reads the landmarks again on the region they themselves
    # give, at most max_rereads times, until two readings' tips agree within reread_agree_radii cap radii
    # (settled); a find that never settles is not followed: the next frame goes to the learned model again
    # (recheck_unsettled). See the module notes, checks; max_rereads=0: the first reading, followed
    max_rereads: int = 2
    reread_agree_radii: float = 1.0
    recheck_unsettled: bool = True
    # ... except a find whose landmark cap agrees with the running track (module notes, item 5)
    reread_trusts_track: bool = True
    # a window cap fit farther than this many cap radii from the prediction sends the frame to the learned
    # model (None: off; see the module notes, checks)
    recheck_jump_radii: float | None = 1.6
    # where tip_end_uv lies, in cap radii out from the cap centre along the finger (1: the cap's end),
    # for a fitted cap and for the landmarks' cap (None: landmark 8); the annotations' medians on photos 1–600
    tip_end_frac: float = -0.17
    landmark_tip_end_frac: float | None = 0.53
    # a hand-held camera swings the whole image: more acceleration noise than a still rig's default
    tracker: TrackerConfig = TrackerConfig(q_px=2e5, r_px=1.0)

    def __post_init__(self) -> None:
        if self.skin not in ("local", "model"):
            raise ConfigError(f"skin must be 'local' or 'model', got {self.skin!r}", field="skin")
        if int(self.recheck_every) < 1 or int(self.max_misses) < 0:
            raise ConfigError("recheck_every must be ≥ 1 and max_misses ≥ 0", field="recheck_every")
        if self.template_min_skin is not None and not 0.0 <= float(self.template_min_skin) <= 1.0:
            raise ConfigError(f"template_min_skin must lie in [0, 1] or be None, got {self.template_min_skin}",
                              field="template_min_skin")
        if self.disagree_radius_ratio is not None and not 0.0 < float(self.disagree_radius_ratio) <= 1.0:
            raise ConfigError(f"disagree_radius_ratio must lie in (0, 1] or be None, got {self.disagree_radius_ratio}",
                              field="disagree_radius_ratio")
        if not float(self.disagree_jump_radii) > 0.0 or not math.isfinite(float(self.disagree_jump_radii)):
            raise ConfigError(f"disagree_jump_radii must be a finite number > 0, got {self.disagree_jump_radii}",
                              field="disagree_jump_radii")
        if not -1.0 <= float(self.disagree_cos) <= 1.0:
            raise ConfigError(f"disagree_cos must lie in [-1, 1], got {self.disagree_cos}", field="disagree_cos")
        if int(self.max_rereads) < 0 or not float(self.reread_agree_radii) > 0.0:
            raise ConfigError(f"max_rereads must be ≥ 0 and reread_agree_radii > 0, got {self.max_rereads} and "
                              f"{self.reread_agree_radii}", field="max_rereads")
        if self.recheck_jump_radii is not None and not (float(self.recheck_jump_radii) > 0.0
                                                        and math.isfinite(float(self.recheck_jump_radii))):
            raise ConfigError(f"recheck_jump_radii must be a finite number > 0 or None, got {self.recheck_jump_radii}",
                              field="recheck_jump_radii")
        if self.cut_ncc is not None and not -1.0 <= float(self.cut_ncc) <= 1.0:
            raise ConfigError(f"cut_ncc must lie in [-1, 1] or be None, got {self.cut_ncc}", field="cut_ncc")


class LocalSkin:
    """Two-class hue–saturation–value histogram model of one hand against its surroundings.

    Skin samples: a band of half the cap radius along the index finger's landmark chain (inside
    the finger, whose half-width is about one cap radius). Background samples: a window around the
    fingertip minus the hand (the landmarks' convex hull grown by two cap radii). A pixel is skin
    when its smoothed skin likelihood exceeds its background likelihood. The model is refit at each
    *find*, so it follows the light and the scene.
    """

    BINS = [18, 16, 8]             # hue, saturation, value
    _RANGES = [0, 180, 0, 256, 0, 256]
    # per-channel value → bin, applied with one cv2.LUT over the three channels
    _BIN_LUT = np.stack([np.minimum(np.arange(256) * BINS[0] // 180, BINS[0] - 1),
                         np.arange(256) * BINS[1] // 256, np.arange(256) * BINS[2] // 256], axis=-1
                        ).astype(np.uint8).reshape(256, 1, 3)

    def __init__(self):
        self.lut: np.ndarray | None = None

    def fit(self, image_bgr: np.ndarray, hand: HandLandmarks, radius_px: float) -> bool:
        h, w = image_bgr.shape[:2]
        r = max(2.0, float(radius_px))
        chain = hand.uv[[INDEX_MCP, INDEX_PIP, INDEX_DIP, INDEX_TIP]]
        half = 6.0 * r
        x0, y0 = (np.floor(chain.min(axis=0) - half)).astype(int).clip(0, (w, h))
        x1, y1 = (np.ceil(chain.max(axis=0) + half)).astype(int).clip(0, (w, h))
        if x1 - x0 < 4 or y1 - y0 < 4:
            return False
        hsv = cv2.cvtColor(image_bgr[y0:y1, x0:x1], cv2.COLOR_BGR2HSV)
        off = np.array([x0, y0], np.float64)
        skin = np.zeros(hsv.shape[:2], np.uint8)
        # the chain stops half a radius short of the tip's end, where the cap's edge starts
        end = chain[-1] + 0.5 * r * _unit(chain[-2] - chain[-1])
        pts = np.vstack([chain[:-1], end]) - off
        cv2.polylines(skin, [np.round(pts).astype(np.int32)], False, 255, thickness=max(1, int(round(r))))
        hand_region = np.zeros_like(skin)
        hull = cv2.convexHull(np.round(hand.uv - off).astype(np.int32))
        cv2.fillConvexPoly(hand_region, hull, 255)
        # grown by 2r: the hull's outline drawn 4r thick (round caps) is its dilation by a disk,
        # at a fraction of the cost of a morphological dilation with a large kernel
        cv2.polylines(hand_region, [hull], True, 255, thickness=max(1, int(round(4 * r))))
        background = cv2.bitwise_not(hand_region)
        if cv2.countNonZero(skin) < 20 or cv2.countNonZero(background) < 20:
            return False
        hs = cv2.calcHist([hsv], [0, 1, 2], skin, self.BINS, self._RANGES)
        hb = cv2.calcHist([hsv], [0, 1, 2], background, self.BINS, self._RANGES)
        # smooth over neighbouring bins so colours near the samples count too
        hs = _smooth_hist(hs / hs.sum())
        hb = _smooth_hist(hb / hb.sum())
        self.lut = np.where(hs > hb, 255, 0).astype(np.uint8).ravel()
        return True

    def mask(self, image_bgr: np.ndarray) -> np.ndarray:
        """Skin mask (uint8 0/255) of a BGR image (a 3-D look-up: OpenCV's back projection would
        read a 3-D NumPy histogram as a 2-D one with channels)."""
        hsv = cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV)
        idx = cv2.LUT(hsv, self._BIN_LUT).astype(np.intp)
        return self.lut[(idx[..., 0] * self.BINS[1] + idx[..., 1]) * self.BINS[2] + idx[..., 2]]


def _smooth_hist(h: np.ndarray) -> np.ndarray:
    """Separable [1 2 1]/4 smoothing of a 3-D histogram; the hue axis (0) wraps."""
    k = np.array([0.25, 0.5, 0.25], np.float32)
    h = k[0] * np.roll(h, 1, axis=0) + k[1] * h + k[2] * np.roll(h, -1, axis=0)
    for ax in (1, 2):
        p = np.concatenate([np.take(h, [0], axis=ax), h, np.take(h, [-1], axis=ax)], axis=ax)
        n = h.shape[ax]
        h = k[0] * np.take(p, range(0, n), axis=ax) + k[1] * np.take(p, range(1, n + 1), axis=ax) \
            + k[2] * np.take(p, range(2, n + 2), axis=ax)
    return h


def _parabola_vertex(a: float, b: float, c: float) -> float:
    den = a - 2.0 * b + c
    return float(np.clip(0.5 * (a - c) / den, -0.5, 0.5)) if den < 0 else 0.0


def _unit(v: np.ndarray) -> np.ndarray:
    n = float(np.hypot(*v))
    return v / n if n > 1e-9 else np.array([0.0, 1.0])


def _thumbnail(image: np.ndarray) -> np.ndarray:
    """Zero-mean, unit-norm 40×30 grey thumbnail: a bilinear 80×60 (which reads only the 2×2 pixels
    around each sample), then 2×2 area means, ~0.02 ms at 640×480 (a full area mean costs 0.2 ms, as
    much as a followed frame). Grey: the colours of one scene stay alike across its moments and would
    make a jump look like a continuation."""
    small = cv2.resize(image, (80, 60), interpolation=cv2.INTER_LINEAR)
    t = cv2.resize(cv2.cvtColor(small, cv2.COLOR_BGR2GRAY), (40, 30), interpolation=cv2.INTER_AREA).astype(np.float32)
    t -= t.mean()
    n = float(np.linalg.norm(t))
    return t / n if n > 1e-6 else t


@dataclass
class _Fit:
    cap_uv: np.ndarray
    radius: float
    direction: np.ndarray

    def tip_end_uv(self, frac: float) -> np.ndarray:
        return self.cap_uv - frac * self.radius * self.direction


class HybridDetector:
    """:class:`~vishap.vision.detector.MonoDetector`: learned find, geometric refine and follow."""

    name = "hybrid"

    def __init__(self, config: HybridConfig = HybridConfig(), *, learned: LearnedDetector | None = None,
                 skin_model: SkinModel | None = None):
        self.config = config
        self.learned = learned or LearnedDetector(LearnedConfig(mode="video"))
        self._skin_model = skin_model if skin_model is not None else (SkinModel.load() if config.skin == "model" else None)
        self._local = LocalSkin()
        self.tracker = TipTracker(config.tracker)
        self.reset()

    def reset(self) -> None:
        self.learned.reset()
        self.tracker = TipTracker(self.config.tracker)
        self._radius = 0.0
        self._direction = np.array([0.0, 1.0])
        self._since_find = 0
        self._misses = 0
        self._cap_at_find: np.ndarray | None = None
        self._have_colour = False
        self._template: np.ndarray | None = None
        self._template_run = 0
        self._tip_frac = self.config.tip_end_frac  # tip_end_frac of the cap the track follows
        self._thumb: np.ndarray | None = None

    def _scene_cut(self, image: np.ndarray) -> bool:
        """Is this frame unrelated to the last one (see ``HybridConfig.cut_ncc``)? Keeps its thumbnail."""
        if self.config.cut_ncc is None:
            return False
        thumb, last = _thumbnail(image), self._thumb
        self._thumb = thumb
        return last is not None and float(np.vdot(last, thumb)) < self.config.cut_ncc

    # ------------------------------------------------------------------ the two halves
    def _skin_mask(self, win: np.ndarray) -> np.ndarray:
        m = self._local.mask(win) if self._skin_model is None else self._skin_model.mask(win)
        return binary_median(m, 5)

    def _fit(self, image: np.ndarray, centre: np.ndarray, radius: float, direction: np.ndarray,
             extra_px: float = 0.0) -> _Fit | None:
        """Cap test + circle fit in a window around ``centre``; the candidate nearest ``centre``
        whose finger points the expected way, or None."""
        c = self.config
        h, w = image.shape[:2]
        half = c.window_radii * radius + extra_px
        x0, y0 = max(0, int(centre[0] - half)), max(0, int(centre[1] - half))
        x1, y1 = min(w, int(math.ceil(centre[0] + half)) + 1), min(h, int(math.ceil(centre[1] + half)) + 1)
        if x1 - x0 < 8 or y1 - y0 < 8:
            return None
        mask = self._skin_mask(image[y0:y1, x0:x1])
        origin = np.array([x0, y0], np.float64)
        tips = detect_fingertips(mask, max(1.5, c.fit_radius_frac * radius),
                                 prior_uv=centre - origin, max_tips=3)
        best = None
        for tip in tips:
            d = tip.direction
            if tip.cap_radius_px <= 0 or float(d @ direction) < c.min_direction_cos:
                continue
            uv = tip.uv + origin
            dist = float(np.hypot(*(uv - centre)))
            if dist > c.gate_radii * radius + extra_px:
                continue
            if best is None or dist < best[0]:
                best = (dist, _Fit(uv, float(tip.cap_radius_px), d))
        return None if best is None else best[1]

    def _disagrees(self, fit: _Fit, pred: np.ndarray) -> bool:
        """Is the window's cap fit off the track in radius, position and direction at once?"""
        c = self.config
        if c.disagree_radius_ratio is None:
            return False
        ratio = fit.radius / max(self._radius, 1e-6)
        return (not c.disagree_radius_ratio <= ratio <= 1.0 / c.disagree_radius_ratio
                and float(np.hypot(*(fit.cap_uv - pred))) > c.disagree_jump_radii * self._radius
                and float(fit.direction @ self._direction) < c.disagree_cos)

    def _track_sigma(self) -> float:
        """The track's position standard deviation (pixels, the larger axis)."""
        return float(np.sqrt(max(self.tracker.kf.P[0, 0], self.tracker.kf.P[1, 1])))

    def _agrees_with_track(self, cap: np.ndarray, radius: float, pred: np.ndarray, sig: float) -> bool:
        """Does a landmark cap agree with the track: within the window's gate of the prediction, with a
        radius within the disagreement ratio of the track's?"""
        c = self.config
        if float(np.hypot(*(cap - pred))) > c.gate_radii * self._radius + 2.0 * sig:
            return False
        q = c.disagree_radius_ratio
        return q is None or q <= radius / self._radius <= 1.0 / q

    def _jumped(self, fit: _Fit, pred: np.ndarray) -> bool:
        """Is the window's cap fit farther from the prediction than ``recheck_jump_radii`` radii?

        The window's gate already drops fits beyond ``gate_radii`` radii + 2σ of the track, so this acts
        only between the two: mostly in the first frames followed after a find, while σ is large (with
        the default tracker 2σ is 7.8 px on the first, 2.3 px from the fourth on; a cap of more than
        about 23 px radius is then never re-checked by it)."""
        j = self.config.recheck_jump_radii
        return j is not None and float(np.hypot(*(fit.cap_uv - pred))) > j * self._radius

    def _skin_share(self, image: np.ndarray, centre: np.ndarray, half: float) -> float:
        """Share of the colour mask in the square of half-side ``half`` around ``centre`` (segmented
        with a 3-pixel margin so the median filter sees the square's neighbourhood)."""
        h, w = image.shape[:2]
        k, m = max(1, int(round(half))), max(1, int(round(half))) + 3
        x, y = int(round(centre[0])), int(round(centre[1]))
        x0, y0, x1, y1 = max(0, x - m), max(0, y - m), min(w, x + m + 1), min(h, y + m + 1)
        if x1 - x0 < 3 or y1 - y0 < 3:
            return 0.0
        sq = self._skin_mask(image[y0:y1, x0:x1])[max(0, y - k) - y0: y + k + 1 - y0, max(0, x - k) - x0: x + k + 1 - x0]
        return float(np.count_nonzero(sq)) / max(1, sq.size)

    def _patch(self, image: np.ndarray, centre: np.ndarray, radius: float) -> np.ndarray | None:
        """Grey patch of half-side ``template_radii`` radii centred on the cap (None at the border)."""
        half = max(4, int(round(self.config.template_radii * radius)))
        x, y = int(round(centre[0])), int(round(centre[1]))
        h, w = image.shape[:2]
        if x - half < 0 or y - half < 0 or x + half + 1 > w or y + half + 1 > h:
            return None
        self._template_offset = np.array([x - centre[0], y - centre[1]])
        return cv2.cvtColor(image[y - half: y + half + 1, x - half: x + half + 1], cv2.COLOR_BGR2GRAY)

    def _match(self, image: np.ndarray, centre: np.ndarray, extra_px: float) -> np.ndarray | None:
        """Cap centre where the find frame's patch matches best around ``centre``, or None."""
        tmpl = self._template
        half = tmpl.shape[0] // 2
        reach = int(math.ceil(self.config.gate_radii * self._radius + extra_px))
        x, y = int(round(centre[0])), int(round(centre[1]))
        h, w = image.shape[:2]
        x0, y0 = max(0, x - half - reach), max(0, y - half - reach)
        x1, y1 = min(w, x + half + reach + 1), min(h, y + half + reach + 1)
        if x1 - x0 < tmpl.shape[1] + 2 or y1 - y0 < tmpl.shape[0] + 2:
            return None
        win = cv2.cvtColor(image[y0:y1, x0:x1], cv2.COLOR_BGR2GRAY)
        ncc = cv2.matchTemplate(win, tmpl, cv2.TM_CCOEFF_NORMED)
        _, best, _, (i, j) = cv2.minMaxLoc(ncc)
        if best < self.config.min_ncc:
            return None
        # sub-pixel: the vertex of a parabola through the peak and its two neighbours, per axis
        di = _parabola_vertex(ncc[j, i - 1], best, ncc[j, i + 1]) if 0 < i < ncc.shape[1] - 1 else 0.0
        dj = _parabola_vertex(ncc[j - 1, i], best, ncc[j + 1, i]) if 0 < j < ncc.shape[0] - 1 else 0.0
        uv = np.array([x0 + i + di + half, y0 + j + dj + half]) - self._template_offset
        min_skin = self.config.template_min_skin
        if min_skin is not None and (self._have_colour or self._skin_model is not None) \
                and self._skin_share(image, uv, 0.5 * self._radius) < min_skin:
            return None
        return uv

    def _find(self, image: np.ndarray, t: float, timings: dict, cut: bool = False) -> MonoDetection:
        if self._cap_at_find is not None and self.tracker.tracking:
            self.learned.shift_roi(self.tracker.kf.position - self._cap_at_find)
        # the track this find can be checked against (none after a scene cut: it belongs to another scene)
        track = None
        if not cut and self.tracker.tracking and self._radius > 0:
            pred = self.tracker.predict(t)
            track = (pred, self._track_sigma())
        hand, tm = self.learned.detect_hand(image)
        timings.update(tm)
        self._since_find = 0
        self._misses = 0
        self._template_run = 0
        if hand is None:
            self.tracker = TipTracker(self.config.tracker)
            self._cap_at_find = None
            return MonoDetection(t, False, mode="learned", reason="no hand found by the learned model")
        cap, r, d, fit = self._refine(image, hand, timings)
        settled = fit is not None or self.config.max_rereads == 0 or (
            self.config.reread_trusts_track and track is not None and self._agrees_with_track(cap, r, *track))
        for _ in range(0 if settled else self.config.max_rereads):
            again = self.learned.reread(image, hand, timings)
            if again is None:
                break
            step = float(np.hypot(*(again.uv[INDEX_TIP] - hand.uv[INDEX_TIP])))
            hand = again
            cap, r, d, fit = self._refine(image, hand, timings)
            if fit is not None or step <= self.config.reread_agree_radii * r:
                settled = True
                break
        if fit is not None:
            self._tip_frac, mode = self.config.tip_end_frac, "learned+refine"
            tip_end = fit.tip_end_uv(self._tip_frac)
        else:
            fit, mode, frac = _Fit(cap, r, d), "learned", self.config.landmark_tip_end_frac
            # None: landmark 8 itself (for a finger turned toward the camera not quite the cap's image end)
            self._tip_frac = 1.0 if frac is None else frac
            tip_end = hand.uvz[INDEX_TIP, :2].copy() if frac is None else fit.tip_end_uv(frac)
        meas, radius, direction = fit.cap_uv, fit.radius, fit.direction
        self.tracker.restart(t, meas)
        self._cap_at_find = meas.copy()
        self._template = self._patch(image, meas, radius) if self.config.template else None
        self._radius, self._direction = radius, direction
        if not settled and self.config.recheck_unsettled:
            self._since_find = self.config.recheck_every
        return MonoDetection(t, True, tip_end_uv=tip_end, cap_uv=meas.copy(), radius_px=radius, direction=direction,
                             confidence=float(hand.presence), mode=mode)

    def _refine(self, image: np.ndarray, hand: HandLandmarks, timings: dict):
        """The landmarks' cap (centre, radius, direction) and the window's cap fit around it (or None);
        learns the hand's colour from ``hand`` first."""
        cap, r, d = cap_from_landmarks(hand.uvz)
        t0 = time.perf_counter()
        if self._skin_model is None:
            self._have_colour = self._local.fit(image, hand, r)
        fit = self._fit(image, cap, r, d) if (self._have_colour or self._skin_model is not None) else None
        timings["refine_ms"] = timings.get("refine_ms", 0.0) + 1e3 * (time.perf_counter() - t0)
        return cap, r, d, fit

    def _follow(self, image: np.ndarray, t: float, timings: dict) -> MonoDetection | None:
        """One tracked frame; None when the window lost the tip (the caller finds it again)."""
        t0 = time.perf_counter()
        pred = self.tracker.predict(t)
        sig = self._track_sigma()
        fit = self._fit(image, pred, self._radius, self._direction, extra_px=2.0 * sig)
        if fit is not None and (self._disagrees(fit, pred) or self._jumped(fit, pred)):
            timings["window_ms"] = 1e3 * (time.perf_counter() - t0)
            return None  # not a miss the tracker can coast through: the learned model looks now
        mode, frac = "tracked", self.config.tip_end_frac
        if fit is None and self._template is not None and self._template_run < self.config.max_template_run:
            uv = self._match(image, pred, extra_px=2.0 * sig)
            if uv is not None:  # the patch is centred on the find's cap: that cap's tip_end_frac
                fit, mode, frac = _Fit(uv, self._radius, self._direction.copy()), "tracked_template", self._tip_frac
        timings["window_ms"] = 1e3 * (time.perf_counter() - t0)
        self._since_find += 1
        if fit is None:
            self.tracker.update(t, None)
            self._misses += 1
            if self._misses > self.config.max_misses:
                return None
            uv = self.tracker.kf.position.copy()
            return MonoDetection(t, True, tip_end_uv=uv - self._tip_frac * self._radius * self._direction, cap_uv=uv,
                                 radius_px=self._radius, direction=self._direction.copy(),
                                 confidence=self.tracker.confidence, mode="predicted")
        self._misses = 0
        self._template_run = self._template_run + 1 if mode == "tracked_template" else 0
        self._tip_frac = frac
        self.tracker.update(t, fit.cap_uv)
        # the radius and direction drift slowly: smooth them so one noisy fit cannot derail the next window
        self._radius = 0.7 * self._radius + 0.3 * fit.radius
        self._direction = _unit(0.7 * self._direction + 0.3 * fit.direction)
        return MonoDetection(t, True, tip_end_uv=fit.tip_end_uv(frac), cap_uv=fit.cap_uv.copy(), radius_px=fit.radius,
                             direction=fit.direction, confidence=1.0, mode=mode)

    # ------------------------------------------------------------------ MonoDetector
    def process(self, image: np.ndarray, t: float) -> MonoDetection:
        t0 = time.perf_counter()
        timings: dict = {}
        det = None
        cut = self._scene_cut(image)
        if not cut and self.tracker.tracking and self._radius > 0 and self._since_find < self.config.recheck_every:
            det = self._follow(image, t, timings)
        if det is None:
            det = self._find(image, t, timings, cut)
        timings["total_ms"] = 1e3 * (time.perf_counter() - t0)
        det.timings = timings
        return det


def _make(**options) -> HybridDetector:
    from vishap.vision import learned

    if not learned.runtime_available():
        raise ConfigError(INSTALL_HINT)
    return HybridDetector(HybridConfig(**options))


register_detector("hybrid", _make, "learned model finds the hand, the geometric cap fit and Kalman tracker follow "
                                   "it in a window (needs the [learned] extra)")
