"""Histogram Bayes skin classifier fitted on real skin (Jones & Rehg style, in OpenCV HSV).

The paper's single Gaussian on hue with a hard saturation gate (:mod:`vishap.vision.skin_model`)
loses pale, brightly lit skin: on real photos a fifth of the pixels just inside the fingertip
(half in sunlight) fall under the gate of 40, and lowering the gate admits a third of the
background. Here the decision is made on hue, saturation and value together: two 3-D
histograms (skin and non-skin pixels), ``P(skin | h, s, v)`` by Bayes' rule with the skin prior
``prior``, and a pixel is skin when that probability exceeds ``threshold``. The gate thus depends
on brightness and hue (pale bright skin keeps low saturation; a dim, grey pixel does not), as
learned from the data.

The evaluation is one ``cv2.calcBackProject`` of the probability table (uint8, 0…255) and one
threshold: a few ms per 640×480 image.

The shipped table (``data/skin_hist_real.npz``) was fitted on pixels weakly labelled from the
fingertip, thumb and hand-box annotations of real photos (:func:`weak_skin_labels`); see
``docs/vision.md`` for the split it was fitted on and the figures on the rest.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np

from vishap._core.config import write_atomic
from vishap._core.errors import ConfigError, ShapeError

__all__ = ["HistogramSkinModel", "weak_skin_labels", "default_hist_path", "read_annotations", "annotated_pixels",
           "fit_skin_from_annotations", "skin_pixel_scores"]

_RANGES = [0, 180, 0, 256, 0, 256]


def default_hist_path() -> Path:
    return Path(__file__).with_name("data") / "skin_hist_real.npz"


@dataclass
class HistogramSkinModel:
    """``P(skin | h, s, v)`` on an (H, S, V) grid, thresholded. Same interface as
    :class:`~vishap.vision.skin_model.SkinModel` where the segmentation uses it (``mask_hsv``,
    ``mask``, and the achromatic gate ``min_saturation``/``min_value`` of the tile histograms)."""

    prob: np.ndarray                 # float32 (bins_h, bins_s, bins_v), 0…255
    threshold: float = 0.5           # P(skin | colour) above this → skin
    min_saturation: int = 15         # achromatic bin of the background's tile histograms (not a skin gate)
    min_value: int = 30
    source: str = ""

    def __post_init__(self) -> None:
        self.prob = np.ascontiguousarray(self.prob, dtype=np.float32)
        if self.prob.ndim != 3:
            raise ShapeError(f"prob: expected a 3-D (H, S, V) table, got shape {self.prob.shape}")
        if not (0.0 < self.threshold < 1.0):
            raise ConfigError(f"threshold must be in (0, 1), got {self.threshold}", field="threshold")
        self._level = int(np.floor(self.threshold * 255.0))
        bh, bs, bv = self.prob.shape
        # the bins of cv2.calcHist with uniform ranges: floor(x · bins / range)
        self._lut_h = (np.minimum(np.arange(256) * bh // 180, bh - 1) * bs * bv).astype(np.int32)
        self._lut_s = (np.arange(256) * bs // 256 * bv).astype(np.int32)
        self._lut_v = (np.arange(256) * bv // 256).astype(np.int32)
        self._flat = np.clip(np.rint(self.prob), 0, 255).astype(np.uint8).ravel()

    @property
    def bins(self) -> tuple[int, int, int]:
        return tuple(self.prob.shape)

    # ------------------------------------------------------------------ evaluation
    def probability_hsv(self, hsv: np.ndarray) -> np.ndarray:
        """``P(skin)`` per pixel as uint8 0…255 (a table look-up; ``cv2.calcBackProject`` would read a
        3-D NumPy table as a 2-D many-channel image)."""
        idx = self._lut_h[hsv[..., 0]] + self._lut_s[hsv[..., 1]] + self._lut_v[hsv[..., 2]]
        return self._flat[idx]

    def mask_hsv(self, hsv: np.ndarray) -> np.ndarray:
        """Skin mask (uint8 0/255) of an HSV image (OpenCV 8-bit)."""
        return cv2.threshold(self.probability_hsv(hsv), self._level, 255, cv2.THRESH_BINARY)[1]

    def mask(self, image_bgr: np.ndarray) -> np.ndarray:
        return self.mask_hsv(cv2.cvtColor(image_bgr, cv2.COLOR_BGR2HSV))

    # ------------------------------------------------------------------ fitting
    @classmethod
    def fit(cls, images, skin_masks, other_masks, *, bins=(30, 32, 16), prior: float = 0.3,
            threshold: float = 0.5, smooth: float = 1.0, source: str = "") -> "HistogramSkinModel":
        """Fit from BGR ``images`` with boolean masks of skin pixels and of non-skin pixels (pixels in
        neither are not used). ``prior`` is the skin share assumed in a scene; ``smooth`` the
        standard deviation (in bins) of a Gaussian blur of both histograms (generalises between
        neighbouring colours)."""
        hs = np.zeros(bins, np.float64)
        hb = np.zeros(bins, np.float64)
        for img, ms, mb in zip(images, skin_masks, other_masks):
            if img.shape[:2] != ms.shape or img.shape[:2] != mb.shape:
                raise ShapeError(f"image {img.shape[:2]} and masks {ms.shape}/{mb.shape} differ in size")
            hsv = cv2.cvtColor(img, cv2.COLOR_BGR2HSV)
            hs += cv2.calcHist([hsv], [0, 1, 2], ms.astype(np.uint8), list(bins), _RANGES)
            hb += cv2.calcHist([hsv], [0, 1, 2], mb.astype(np.uint8), list(bins), _RANGES)
        if hs.sum() < 100 or hb.sum() < 100:
            raise ConfigError(f"too few labelled pixels to fit ({int(hs.sum())} skin, {int(hb.sum())} other)")
        n_s, n_b = hs.sum(), hb.sum()
        if smooth > 0:
            hs, hb = _blur3(hs, smooth), _blur3(hb, smooth)
        ps = hs / hs.sum()
        pb = hb / hb.sum()
        post = prior * ps / np.maximum(prior * ps + (1 - prior) * pb, 1e-12)
        return cls(prob=(post * 255.0).astype(np.float32), threshold=threshold,
                   source=source or f"{int(n_s)} skin and {int(n_b)} other pixels")

    # ------------------------------------------------------------------ files
    def save(self, path: str | os.PathLike) -> Path:
        import io

        buf = io.BytesIO()
        np.savez_compressed(buf, prob=self.prob.astype(np.float16), threshold=self.threshold,
                            min_saturation=self.min_saturation, min_value=self.min_value, source=self.source)
        return write_atomic(path, buf.getvalue())

    @classmethod
    def load(cls, path: str | os.PathLike | None = None) -> "HistogramSkinModel":
        path = default_hist_path() if path is None else Path(path)
        try:
            with np.load(path, allow_pickle=False) as d:
                return cls(prob=d["prob"].astype(np.float32), threshold=float(d["threshold"]),
                           min_saturation=int(d["min_saturation"]), min_value=int(d["min_value"]),
                           source=str(d["source"]))
        except (OSError, KeyError, ValueError) as exc:
            raise ConfigError(f"not a histogram skin model ({exc})", file=path) from None


def _blur3(h: np.ndarray, sigma: float) -> np.ndarray:
    from scipy.ndimage import gaussian_filter

    # hue is circular: wrap along the first axis, clamp the others
    return gaussian_filter(h, sigma, mode=("wrap", "nearest", "nearest"))


def weak_skin_labels(shape, tip_uv, thumb_uv=None, box=None, *, margin_px: float = 12.0, stroke_frac: float = 0.15):
    """Skin and non-skin pixel masks of one photo from its fingertip annotations alone.

    Skin: a thin stroke from the index tip end toward the hand box's centre over ``stroke_frac`` of
    the box's diagonal, started a few pixels inside the tip (annotators click the finger's edge) —
    the index finger's own pixels in most photos (``thumb_uv`` is not used: a stroke from the thumb
    toward the centre crosses the gap between thumb and index). Non-skin: outside the hand box
    grown by ``margin_px``, above the box's bottom edge only (the box ends at the wrist; the
    forearm below it is skin). Without a box both masks are empty."""
    h, w = shape[:2]
    skin = np.zeros((h, w), np.uint8)
    other = np.zeros((h, w), np.uint8)
    if box is None or tip_uv is None:
        return skin.astype(bool), other.astype(bool)
    x0, y0, x1, y1 = box
    centre = np.array([(x0 + x1) / 2, (y0 + y1) / 2])
    diag = float(np.hypot(x1 - x0, y1 - y0))
    other[: max(0, int(y1 - margin_px))] = 1
    cv2.rectangle(other, (int(x0 - margin_px), int(y0 - margin_px)), (int(x1 + margin_px), int(y1 + margin_px)), 0, -1)
    width = max(2, int(round(0.012 * diag)))
    p = np.asarray(tip_uv, dtype=np.float64)
    d = centre - p
    n = np.hypot(*d)
    if n >= 1:
        d /= n
        a = p + d * (width + 4)
        b = p + d * min(stroke_frac * diag, n)
        cv2.line(skin, tuple(int(round(x)) for x in a), tuple(int(round(x)) for x in b), 1, 2 * width + 1)
    return skin.astype(bool), other.astype(bool)


def read_annotations(labels) -> list[dict]:
    """Rows of an annotation CSV with ``frame,u,v`` and optionally ``thumb_u,thumb_v`` and
    ``box_x0,box_y0,box_x1,box_y1`` (values None where empty)."""
    import csv

    from vishap.vision.fingertip_eval import read_fingertip_labels

    base = {x.frame: x for x in read_fingertip_labels(labels)}  # checks the required columns
    out = []
    with open(labels, newline="") as f:
        for rec in csv.DictReader(f):
            rec = {k.strip(): (v or "").strip() for k, v in rec.items() if k}
            lab = base[rec["frame"]]

            def num(*keys):
                try:
                    vals = [float(rec[k]) for k in keys]
                except (KeyError, ValueError):
                    return None
                return np.array(vals)

            out.append({"frame": lab.frame, "tip": lab.uv, "thumb": num("thumb_u", "thumb_v"),
                        "box": num("box_x0", "box_y0", "box_x1", "box_y1")})
    return out


def annotated_pixels(folder, labels, frames=None):
    """``(image, skin_mask, other_mask, row)`` of each annotated photo of ``folder`` (only ``frames``
    when given), weakly labelled by :func:`weak_skin_labels`."""
    folder = Path(folder)
    for row in read_annotations(labels):
        if frames is not None and row["frame"] not in frames:
            continue
        if row["tip"] is None:
            continue
        img = cv2.imread(str(folder / row["frame"]), cv2.IMREAD_COLOR)
        if img is None:
            raise ConfigError(f"frame {row['frame']!r}: cannot read {folder / row['frame']}", file=labels)
        s, o = weak_skin_labels(img.shape, row["tip"], row["thumb"], row["box"])
        yield img, s, o, row


def fit_skin_from_annotations(folder, labels, frames=None, **kw) -> HistogramSkinModel:
    """Fit :class:`HistogramSkinModel` on the weakly labelled pixels of annotated photos."""
    imgs, ss, os_ = [], [], []
    names = []
    for img, s, o, row in annotated_pixels(folder, labels, frames):
        imgs.append(img)
        ss.append(s)
        os_.append(o)
        names.append(row["frame"])
    if not imgs:
        raise ConfigError("no annotated photos to fit on", file=labels)
    src = kw.pop("source", f"weak labels (strokes from the index tip, outside the hand box) of {len(imgs)} photos "
                           f"({names[0]} … {names[-1]}) of {Path(folder).name}")
    return HistogramSkinModel.fit(imgs, ss, os_, source=src, **kw)


def skin_pixel_scores(model, folder, labels, frames=None) -> dict:
    """Share of weakly labelled skin pixels kept (``skin_kept``) and of non-skin pixels (outside the
    hand box) passed as skin (``other_passed``) by ``model`` (any object with ``mask_hsv``)."""
    ks = ns = ko = no = 0
    n = 0
    for img, s, o, _ in annotated_pixels(folder, labels, frames):
        m = model.mask_hsv(cv2.cvtColor(img, cv2.COLOR_BGR2HSV)) > 0
        ks += int((m & s).sum())
        ns += int(s.sum())
        ko += int((m & o).sum())
        no += int(o.sum())
        n += 1
    return {"photos": n, "skin_kept": ks / max(ns, 1), "other_passed": ko / max(no, 1)}
