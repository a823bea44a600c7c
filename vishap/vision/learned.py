"""A learned hand-landmark detector: MediaPipe's palm detector and hand-landmark model.

The two networks are MediaPipe Hands' (``palm_detection_full.tflite``, 192×192 input, and
``hand_landmark_full.tflite``, 224×224 input, 21 landmarks), the same pair that MediaPipe's
``HandLandmarker`` bundles in ``hand_landmarker.task``. They ship with this package
(``vishap/vision/data/hand/``, copied from the ``mediapipe`` 0.10.21 wheel on PyPI, Apache-2.0),
so nothing is fetched at run time. They run on the standalone LiteRT interpreter
(``ai-edge-litert``, the ``[learned]`` extra) rather than through the ``mediapipe`` package, whose
wheel requires the GUI ``opencv-contrib-python`` and would replace the headless OpenCV build the
project installs. The graph around the networks (letterbox, SSD anchors, box decoding, the rotated
hand rectangle, the crop, the landmark projection, the region of the next frame) follows
MediaPipe's hand-tracking graph and is written here with NumPy and OpenCV.

Two modes, as MediaPipe's:

``image``
    palm detection on the full frame, then landmarks, on every frame (independent photos);
``video``
    the hand's region in the next frame comes from this frame's landmarks; palm detection runs
    only when there is no hand being followed (the landmark model's presence score fell below
    its threshold).

Registered as ``learned`` (image mode) and ``learned_video`` (video mode). Without the extra the
factories raise a :class:`~vishap._core.errors.ConfigError` that says how to install it; nothing
else in the package needs it.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from vishap._core.errors import ConfigError, ShapeError
from vishap.vision.detector import MonoDetection, register_detector

__all__ = [
    "MODEL_DIR",
    "INSTALL_HINT",
    "runtime_available",
    "HandRect",
    "HandLandmarks",
    "HandLandmarkModel",
    "LearnedConfig",
    "MEDIAPIPE_PALM_RULE",
    "LearnedDetector",
    "cap_from_landmarks",
    "roi_from_landmarks",
]

MODEL_DIR = Path(__file__).with_name("data") / "hand"
PALM_MODEL = "palm_detection_full.tflite"
LANDMARK_MODEL = "hand_landmark_full.tflite"
INSTALL_HINT = ("the learned hand-landmark detectors need the optional LiteRT runtime: "
                "pip install -e '.[learned]' (ai-edge-litert); the classical detectors work without it")

# Landmark indices (MediaPipe Hands)
WRIST, INDEX_MCP, INDEX_PIP, INDEX_DIP, INDEX_TIP, MIDDLE_MCP, RING_MCP = 0, 5, 6, 7, 8, 9, 13

# Cap radius per length of the distal segment (DIP landmark 7 → tip end 8, in 3-D). The cap
# centre lies one cap radius behind the fingertip's end along the finger, and the cap radius is
# half the distal phalanx's width: an adult index finger is about 16 mm wide at the distal
# phalanx whose joint-to-tip length is about 21 mm, so r ≈ 8 / 21 ≈ 0.38 of the DIP→TIP length.
CAP_RADIUS_PER_DISTAL = 0.38


def runtime_available() -> bool:
    """Is the LiteRT interpreter (the ``[learned]`` extra) importable?"""
    try:
        import ai_edge_litert.interpreter  # noqa: F401
    except ImportError:
        return False
    return True


def _interpreter(path: Path, num_threads: int):
    try:
        from ai_edge_litert.interpreter import Interpreter
    except ImportError:
        raise ConfigError(INSTALL_HINT) from None
    if not path.is_file():
        raise ConfigError(f"hand model file missing: {path} (reinstall the package)", file=path)
    it = Interpreter(model_path=str(path), num_threads=int(num_threads))
    it.allocate_tensors()
    return it


@dataclass(frozen=True)
class HandRect:
    """A square, rotated region of the image (pixels; ``angle`` in radians, image y down: the
    region's "up" is the image direction ``(sin angle, -cos angle)``)."""

    cx: float
    cy: float
    size: float
    angle: float

    def rotation(self) -> np.ndarray:
        c, s = math.cos(self.angle), math.sin(self.angle)
        return np.array([[c, -s], [s, c]])

    def to_image(self, q: np.ndarray, n: int) -> np.ndarray:
        """Points ``q`` (N, 2) in the coordinates of an ``n``×``n`` crop of this rect → image pixels."""
        return (q / n - 0.5) * self.size @ self.rotation().T + (self.cx, self.cy)

    def crop(self, image: np.ndarray, n: int) -> np.ndarray:
        """The rect resampled to ``n``×``n`` pixels (outside the image: the nearest edge pixel)."""
        a = self.rotation() * (self.size / n)
        b = np.array([self.cx, self.cy]) + a @ np.array([0.5 - n / 2, 0.5 - n / 2]) - 0.5
        m = np.hstack([a, b[:, None]])
        return cv2.warpAffine(image, m, (n, n), flags=cv2.INTER_LINEAR | cv2.WARP_INVERSE_MAP,
                              borderMode=cv2.BORDER_REPLICATE)

    def moved(self, duv) -> "HandRect":
        return HandRect(self.cx + float(duv[0]), self.cy + float(duv[1]), self.size, self.angle)


@dataclass
class HandLandmarks:
    """The 21 landmarks of one hand: ``uvz`` (21, 3) in image pixels (z: relative depth, in the
    crop's pixel scale, wrist-relative, smaller = nearer), the presence score and the rect used."""

    uvz: np.ndarray
    presence: float
    rect: HandRect
    palm_score: float = 0.0
    candidate: int = -1     # which palm candidate (0: the best box) it came from; -1: the followed region

    @property
    def uv(self) -> np.ndarray:
        return self.uvz[:, :2]


def _normalize_angle(a: float) -> float:
    return a - 2 * math.pi * math.floor((a + math.pi) / (2 * math.pi))


def _transform_rect(cx, cy, w, h, angle, *, scale: float, shift_y: float) -> HandRect:
    """MediaPipe's RectTransformation: shift along the rect's own axes, square the long side, scale."""
    c, s = math.cos(angle), math.sin(angle)
    cx, cy = cx - h * shift_y * s, cy + h * shift_y * c
    return HandRect(float(cx), float(cy), float(max(w, h) * scale), float(angle))


def _ssd_anchors(size: int = 192, strides=(8, 16, 16, 16)) -> np.ndarray:
    """Anchor centres of the palm detector (MediaPipe's SsdAnchorsCalculator, fixed anchor size:
    two anchors per cell and layer; layers of the same stride share a grid)."""
    out = []
    i = 0
    while i < len(strides):
        n_same = 1
        while i + n_same < len(strides) and strides[i + n_same] == strides[i]:
            n_same += 1
        fm = int(math.ceil(size / strides[i]))
        yy, xx = np.mgrid[0:fm, 0:fm]
        c = np.stack([(xx + 0.5) / fm, (yy + 0.5) / fm], axis=-1).reshape(-1, 1, 2)
        out.append(np.repeat(c, 2 * n_same, axis=1).reshape(-1, 2))
        i += n_same
    return np.concatenate(out)


class HandLandmarkModel:
    """The palm detector and the landmark model on the LiteRT interpreter.

    ``num_threads`` threads per network (1 by default: the vision stage shares a core with the
    rest of the loop, and one thread gives repeatable timings).
    """

    PALM_SIZE = 192
    LANDMARK_SIZE = 224

    def __init__(self, *, num_threads: int = 1, min_palm_score: float = 0.5, model_dir: Path = MODEL_DIR):
        self._palm = _interpreter(Path(model_dir) / PALM_MODEL, num_threads)
        self._lm = _interpreter(Path(model_dir) / LANDMARK_MODEL, num_threads)
        self._palm_in = self._palm.get_input_details()[0]["index"]
        pout = {tuple(d["shape"]): d["index"] for d in self._palm.get_output_details()}
        self._palm_boxes, self._palm_scores = pout[(1, 2016, 18)], pout[(1, 2016, 1)]
        self._lm_in = self._lm.get_input_details()[0]["index"]
        lout = sorted(self._lm.get_output_details(), key=lambda d: d["name"])  # Identity, _1, _2, _3
        self._lm_xyz, self._lm_presence = lout[0]["index"], lout[1]["index"]
        self.min_palm_score = float(min_palm_score)
        self._anchors = _ssd_anchors(self.PALM_SIZE)

    # ------------------------------------------------------------------ palm detection
    def detect_palms(self, image_rgb: np.ndarray, max_palms: int = 2, min_score: float | None = None,
                     zoom: float = 1.0, *, bgr: bool = False) -> list[tuple[HandRect, float]]:
        """Palms of an RGB image as hand rects (best first) with their scores (at least ``min_score``,
        default the model's ``min_palm_score``). ``zoom`` > 1 shrinks the image to 1/zoom of the
        network's input (centred, zero border), for hands too large for it at full size.
        ``bgr``: the image is BGR, reordered after the resize (the same input, on 1/10 of the pixels)."""
        if not zoom >= 1.0:
            raise ConfigError(f"palm zoom must be ≥ 1, got {zoom}", field="zoom")
        h, w = image_rgb.shape[:2]
        n = self.PALM_SIZE
        s = n / (max(w, h) * zoom)
        nw, nh = int(round(w * s)), int(round(h * s))
        px, py = (n - nw) // 2, (n - nh) // 2
        small = cv2.resize(image_rgb, (nw, nh), interpolation=cv2.INTER_AREA)
        inp = np.zeros((n, n, 3), np.float32)
        inp[py:py + nh, px:px + nw] = _to_input(small, bgr)
        self._palm.set_tensor(self._palm_in, inp[None])
        self._palm.invoke()
        raw = self._palm.get_tensor(self._palm_boxes)[0]
        score = 1.0 / (1.0 + np.exp(-np.clip(self._palm.get_tensor(self._palm_scores)[0, :, 0], -100, 100)))
        keep = np.nonzero(score >= (self.min_palm_score if min_score is None else min_score))[0]
        if keep.size == 0:
            return []
        raw, score, anc = raw[keep].astype(np.float64), score[keep], self._anchors[keep]
        # boxes and the 7 palm keypoints, in letterbox pixels, then image pixels
        ctr = raw[:, 0:2] + anc * n
        kp = raw[:, 4:18].reshape(-1, 7, 2) + anc[:, None, :] * n
        to_img = lambda q: (q - (px, py)) / s  # noqa: E731
        ctr, kp, wh = to_img(ctr), to_img(kp), raw[:, 2:4] / s
        palms = []
        for group, weights in _weighted_nms(ctr, wh, score, iou_min=0.3)[:max_palms]:
            wgt = weights / weights.sum()
            c = wgt @ ctr[group]
            size = wgt @ wh[group]
            k = np.tensordot(wgt, kp[group], axes=1)
            angle = _normalize_angle(math.pi / 2 - math.atan2(-(k[2, 1] - k[0, 1]), k[2, 0] - k[0, 0]))
            rect = _transform_rect(c[0], c[1], size[0], size[1], angle, scale=2.6, shift_y=-0.5)
            palms.append((rect, float(score[group[0]])))
        return palms

    # ------------------------------------------------------------------ landmarks
    def landmarks(self, image_rgb: np.ndarray, rect: HandRect, *, bgr: bool = False) -> HandLandmarks:
        """The 21 landmarks in ``rect`` (image pixels) and the hand-presence score (``bgr``: as
        :meth:`detect_palms`)."""
        n = self.LANDMARK_SIZE
        crop = _to_input(rect.crop(image_rgb, n), bgr)
        self._lm.set_tensor(self._lm_in, crop[None])
        self._lm.invoke()
        xyz = self._lm.get_tensor(self._lm_xyz)[0].reshape(21, 3).astype(np.float64)
        presence = float(self._lm.get_tensor(self._lm_presence)[0, 0])  # already a probability
        uvz = np.empty((21, 3))
        uvz[:, :2] = rect.to_image(xyz[:, :2], n)
        uvz[:, 2] = xyz[:, 2] * (rect.size / n)
        return HandLandmarks(uvz, presence, rect)


def _to_input(small: np.ndarray, bgr: bool) -> np.ndarray:
    """A network's float input in [0, 1] from a uint8 RGB (or, ``bgr``, BGR) image. Resampling treats
    each channel alike, so reordering the small image gives the input that reordering the frame would."""
    if bgr:
        small = cv2.cvtColor(small, cv2.COLOR_BGR2RGB)
    return small.astype(np.float32) * np.float32(1.0 / 255.0)


def _weighted_nms(ctr: np.ndarray, wh: np.ndarray, score: np.ndarray, iou_min: float):
    """MediaPipe's weighted non-maximum suppression: groups of overlapping boxes (best first)."""
    lo, hi = ctr - wh / 2, ctr + wh / 2
    area = wh[:, 0] * wh[:, 1]
    # all pairwise overlaps at once: the low candidate threshold can leave a few hundred boxes
    inter = np.prod(np.clip(np.minimum(hi[:, None], hi[None]) - np.maximum(lo[:, None], lo[None]), 0, None), axis=2)
    iou = inter / np.maximum(area[:, None] + area[None] - inter, 1e-9)
    free = np.ones(len(score), bool)
    groups = []
    for i in np.argsort(-score, kind="stable"):
        if not free[i]:
            continue
        g = np.nonzero(free & (iou[i] > iou_min))[0]
        g = g[np.argsort(-score[g], kind="stable")]
        free[g] = False
        groups.append((g, score[g]))
    return groups


def roi_from_landmarks(uv: np.ndarray) -> HandRect:
    """The hand's region in the next frame from this frame's landmarks (MediaPipe's
    HandLandmarksToRect + RectTransformation: scale 2, shift −0.1 of the height toward the fingers)."""
    sel = uv[[0, 1, 2, 3, 5, 6, 9, 10, 13, 14, 17, 18]]
    p0 = uv[WRIST]
    p1 = ((uv[INDEX_MCP] + uv[RING_MCP]) / 2 + uv[MIDDLE_MCP]) / 2
    angle = _normalize_angle(math.pi / 2 - math.atan2(-(p1[1] - p0[1]), p1[0] - p0[0]))
    c, s = math.cos(angle), math.sin(angle)
    rot = np.array([[c, -s], [s, c]])
    box_c = (sel.min(axis=0) + sel.max(axis=0)) / 2
    q = (sel - box_c) @ rot  # into the hand's frame
    lo, hi = q.min(axis=0), q.max(axis=0)
    ctr = box_c + rot @ ((lo + hi) / 2)
    w, h = hi - lo
    return _transform_rect(ctr[0], ctr[1], w, h, angle, scale=2.0, shift_y=-0.1)


def cap_from_landmarks(uvz: np.ndarray, k: float = CAP_RADIUS_PER_DISTAL) -> tuple[np.ndarray, float, np.ndarray]:
    """Fingertip cap centre, cap radius (pixels) and the unit image direction from the tip into the
    finger, from the index finger's DIP (7) and tip (8) landmarks.

    The cap centre is the tip end moved one cap radius back along the finger's 3-D axis; its image
    offset is the radius times the image part of that unit axis (a finger pointing at the camera
    moves it little). The radius is ``k`` × the 3-D DIP→tip length (see ``CAP_RADIUS_PER_DISTAL``),
    not the 2-D one, so foreshortening does not shrink it.
    """
    d3 = uvz[INDEX_DIP] - uvz[INDEX_TIP]
    length = float(np.linalg.norm(d3))
    if not length > 1e-6:
        return uvz[INDEX_TIP, :2].copy(), 0.0, np.array([0.0, 1.0])
    r = k * length
    axis = d3 / length
    d2 = axis[:2]
    n2 = float(np.hypot(*d2))
    direction = d2 / n2 if n2 > 1e-6 else np.array([0.0, 1.0])
    return uvz[INDEX_TIP, :2] + r * d2, r, direction


@dataclass(frozen=True)
class LearnedConfig:
    """Settings of :class:`LearnedDetector`.

    MediaPipe keeps the palm detector's best box on the letterboxed frame only when it scores
    ≥ 0.5, and then trusts it. On the real train photos (fit split, photos 1–600) that loses 16 %
    of the hands, and looking at them says why: the hands are near the camera (hand boxes
    250–400 px of a 640×480 frame) with the palm cut by the image's edge. The palm network,
    trained on smaller hands, scores them 0.05–0.5, or fires on a part of the hand from which the
    landmark model reads a curled index finger (tip 140–250 px off). Two changes recover them:

    * the palm network also runs on the frame shrunk to 1/1.5 and 1/2 of its input
      (``palm_zooms``), where such a hand has the size it was trained on; the boxes of all zooms
      are ranked together by palm score, so a large hand's confident box at zoom 2 beats a
      fragment's box at zoom 1, and a small hand's box at zoom 1 beats its weaker ones at zoom 2;
    * boxes down to ``min_palm_score`` are kept as candidates, and each is verified by the
      landmark model's own hand-presence score (``min_presence``, MediaPipe's threshold): the
      first of the ``palm_candidates`` best that passes is the hand.

    Photos 1–600: detection 0.842 → 0.998, PCK@30 0.830 → 0.990, for 1.01 landmark runs per photo
    (three palm runs instead of one). Hand-free real images (291 background strips cut from
    beside the hand in the same photos): 1 false hand (0.3 %). Zooms, 0.1 and 2 were chosen there
    (zoom 1 alone with candidates: PCK@30 0.930; zooms 1 and 2: 0.982; threshold 0.05: the same
    PCK, 0.7 % false hands). ``LearnedConfig(min_palm_score=0.5, palm_candidates=1,
    palm_zooms=(1.0,))`` is MediaPipe's rule (:data:`MEDIAPIPE_PALM_RULE`).

    The zooms cost a palm run each, most of a search. A box that scores ≥ ``palm_sure_score`` (0.9)
    at zoom 1 and that the landmark model confirms is taken without running the other zooms (not
    provably the full search's pick: a later zoom could score higher). All 900 train photos, the
    hybrid with and without it: the same photos found, PCK@30 the same on both splits (fit 0.990,
    held out 0.963), PCK@10 0.842 → 0.848 and 0.870 → 0.883; 730 photos give the same output,
    170 another box's landmarks (tip moved 1.7 px median, 19.6 px at most); per photo 68.6 → 47.8
    ms median; the ``learned`` detector alone: PCK@30 the same (0.990, 0.960), 708 photos the same
    output, 89.5 → 63.8 ms median. The threshold was set once from the zoom-1 scores of 100 photos (median 0.89), not
    swept.
    """

    mode: str = "image"               # "image": full frame every frame; "video": follow the hand's region
    min_palm_score: float = 0.1       # palm boxes kept as candidates (MediaPipe: 0.5, the best box only)
    palm_candidates: int = 2          # candidates verified by the landmark model, best palm score first
    palm_zooms: tuple = (1.0, 1.5, 2.0)  # the frame at 1/zoom of the palm network's input
    min_presence: float = 0.5         # MediaPipe's min_hand_presence_confidence
    # a box scoring at least this at an earlier zoom is verified at once, and when the landmark model
    # confirms it the later zooms are not run (None: every zoom runs; see the class notes)
    palm_sure_score: float | None = 0.9
    num_threads: int = 1

    def __post_init__(self) -> None:
        if self.mode not in ("image", "video"):
            raise ConfigError(f"mode must be 'image' or 'video', got {self.mode!r}", field="mode")
        if not (0.0 <= self.min_palm_score <= 1.0 and 0.0 <= self.min_presence <= 1.0):
            raise ConfigError("min_palm_score and min_presence must lie in [0, 1]", field="min_presence")
        if not self.palm_zooms or any(not float(z) >= 1.0 for z in self.palm_zooms):
            raise ConfigError(f"palm_zooms must be a non-empty list of zooms ≥ 1, got {self.palm_zooms}",
                              field="palm_zooms")
        if int(self.palm_candidates) < 1:
            raise ConfigError(f"palm_candidates must be ≥ 1, got {self.palm_candidates}", field="palm_candidates")
        if int(self.num_threads) < 1:
            raise ConfigError(f"num_threads must be ≥ 1, got {self.num_threads}", field="num_threads")
        if self.palm_sure_score is not None and not 0.0 <= float(self.palm_sure_score) <= 1.0:
            raise ConfigError(f"palm_sure_score must lie in [0, 1] or be None, got {self.palm_sure_score}",
                              field="palm_sure_score")


# MediaPipe's own choice of the hand in a frame: the best palm box on the letterboxed frame, if ≥ 0.5
MEDIAPIPE_PALM_RULE = dict(min_palm_score=0.5, palm_candidates=1, palm_zooms=(1.0,))


class LearnedDetector:
    """:class:`~vishap.vision.detector.MonoDetector` over :class:`HandLandmarkModel`.

    ``tip_end_uv`` is the index-tip landmark (8); ``cap_uv`` and ``radius_px`` come from
    :func:`cap_from_landmarks`. :attr:`last_hand` keeps the last frame's landmarks for callers
    that want the whole hand (the hybrid detector).
    """

    def __init__(self, config: LearnedConfig = LearnedConfig(), *, model: HandLandmarkModel | None = None):
        self.config = config
        self.name = "learned" if config.mode == "image" else "learned_video"
        self.model = model or HandLandmarkModel(num_threads=config.num_threads)
        self._roi: HandRect | None = None
        self.last_hand: HandLandmarks | None = None

    def reset(self) -> None:
        self._roi = None
        self.last_hand = None

    def shift_roi(self, duv) -> None:
        """Move the followed hand region by ``duv`` pixels (a caller that tracked the hand meanwhile)."""
        if self._roi is not None:
            self._roi = self._roi.moved(duv)

    def detect_hand(self, image_bgr: np.ndarray, *, use_roi: bool | None = None) -> tuple[HandLandmarks | None, dict]:
        """Landmarks of the hand (or None) and the time each network took (ms).

        ``use_roi``: look only in the followed region when there is one (default: in video mode).
        """
        _check_image(image_bgr)
        timings: dict = {}
        use_roi = (self.config.mode == "video") if use_roi is None else use_roi
        hand = None
        if use_roi and self._roi is not None:
            t0 = time.perf_counter()
            hand = self.model.landmarks(image_bgr, self._roi, bgr=True)
            timings["landmarks_ms"] = 1e3 * (time.perf_counter() - t0)
            if hand.presence < self.config.min_presence:
                hand = None
        if hand is None:
            hand = self._find_hand(image_bgr, timings)
        self._roi = roi_from_landmarks(hand.uv) if hand is not None else None
        self.last_hand = hand
        return hand, timings

    def reread(self, image_bgr: np.ndarray, hand: HandLandmarks, timings: dict) -> HandLandmarks | None:
        """The landmark model once more, on the region ``hand``'s own landmarks give (what video mode
        looks at on the next frame), or None when it finds no hand there. A reading from a palm box or
        from a followed region sized for another moment can be off (a large hand read in a small region
        as a curled finger); the region drawn around its own landmarks frames the hand as the model
        was trained to see it. The followed region and :attr:`last_hand` become the new reading's."""
        t0 = time.perf_counter()
        again = self.model.landmarks(image_bgr, roi_from_landmarks(hand.uv), bgr=True)
        timings["landmarks_ms"] = timings.get("landmarks_ms", 0.0) + 1e3 * (time.perf_counter() - t0)
        if again.presence < self.config.min_presence:
            return None
        again.palm_score, again.candidate = hand.palm_score, hand.candidate
        self._roi = roi_from_landmarks(again.uv)
        self.last_hand = again
        return again

    def _find_hand(self, image_bgr: np.ndarray, timings: dict) -> HandLandmarks | None:
        """Palm candidates over the whole frame at each zoom, best palm score first, each verified by
        the landmark model's presence score (see :class:`LearnedConfig`). With ``palm_sure_score``
        the best box so far, when it scores that much, is verified after each zoom and a confirmed
        one ends the search."""
        c = self.config
        palms: list = []
        checked: dict = {}   # (zoom index, box index) → landmarks: each box goes through the network once

        def verify(score, k, i, rect):
            if (k, i) not in checked:
                t0 = time.perf_counter()
                checked[k, i] = self.model.landmarks(image_bgr, rect, bgr=True)
                timings["landmarks_ms"] = timings.get("landmarks_ms", 0.0) + 1e3 * (time.perf_counter() - t0)
            hand = checked[k, i]
            return hand if hand.presence >= c.min_presence else None

        for k, z in enumerate(c.palm_zooms):
            t0 = time.perf_counter()
            palms += [(score, k, i, rect) for i, (rect, score) in enumerate(
                self.model.detect_palms(image_bgr, max_palms=c.palm_candidates, min_score=c.min_palm_score,
                                        zoom=z, bgr=True))]
            palms.sort(key=lambda p: (-p[0], p[1]))  # ties: the smaller zoom first
            timings["palm_ms"] = timings.get("palm_ms", 0.0) + 1e3 * (time.perf_counter() - t0)
            last = k == len(c.palm_zooms) - 1
            if not last and c.palm_sure_score is not None and palms and palms[0][0] >= c.palm_sure_score:
                hand = verify(*palms[0])
                if hand is not None:
                    hand.palm_score, hand.candidate = palms[0][0], 0
                    return hand
        for j, p in enumerate(palms[:c.palm_candidates]):
            hand = verify(*p)
            if hand is not None:
                hand.palm_score, hand.candidate = p[0], j
                return hand
        return None

    def process(self, image: np.ndarray, t: float) -> MonoDetection:
        t0 = time.perf_counter()
        hand, timings = self.detect_hand(image)
        timings["total_ms"] = 1e3 * (time.perf_counter() - t0)
        if hand is None:
            return MonoDetection(t, False, mode="learned", reason="no hand found by the palm and landmark models",
                                 timings=timings)
        return detection_from_landmarks(hand, t, timings=timings)


def detection_from_landmarks(hand: HandLandmarks, t: float, *, mode: str = "learned",
                             timings: dict | None = None) -> MonoDetection:
    cap, r, direction = cap_from_landmarks(hand.uvz)
    return MonoDetection(t, True, tip_end_uv=hand.uvz[INDEX_TIP, :2].copy(), cap_uv=cap, radius_px=r,
                         direction=direction, confidence=float(hand.presence), mode=mode,
                         timings=dict(timings or {}))


def _check_image(image: np.ndarray) -> None:
    if not (isinstance(image, np.ndarray) and image.dtype == np.uint8 and image.ndim == 3 and image.shape[2] == 3):
        got = f"{image.dtype} {image.shape}" if isinstance(image, np.ndarray) else type(image).__name__
        raise ShapeError(f"image: expected a uint8 BGR array (H, W, 3), got {got}")


def _factory(mode: str):
    def make(**options) -> LearnedDetector:
        if not runtime_available():
            raise ConfigError(INSTALL_HINT)
        return LearnedDetector(LearnedConfig(mode=mode, **options))
    return make


register_detector("learned", _factory("image"),
                  "MediaPipe's palm + hand-landmark models on every full frame (needs the [learned] extra)")
register_detector("learned_video", _factory("video"),
                  "MediaPipe's hand models in video mode: the hand's region follows the landmarks (needs [learned])")
