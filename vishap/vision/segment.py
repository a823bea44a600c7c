"""Appearance-based hand segmentation (VisHap §2.1, eq. 1).

The image is split into small tiles (5×5 pixels by default); each tile gets a hue histogram (8 bins
by default). The background model is the tile histograms of the average of the first frames. A
live tile whose histogram intersection with its background histogram,
``H(I, M) = sum_j min(I_j, M_j) / sum_j M_j``, falls below ``match_threshold`` is foreground. A
pixel of a foreground tile is kept when it passes the skin model's hue test; a median filter then
removes noise. The result is a binary skin mask (uint8, 0/255).

Vectorised: the histograms of all tiles of an image (or of a tile-aligned region of interest) come
from one ``np.bincount`` over ``tile_index * n_bins + bin``; no Python loop runs over tiles.

One addition to the paper, as in :mod:`vishap.vision.skin_model`: achromatic pixels (low
saturation or value), whose hue is undefined, fall into their own histogram bin, so a grey or
black object does not read as random hues. ``dilate_tiles`` optionally lets the skin test also
run in the tiles next to a foreground tile (a finger edge covering few pixels of a tile).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import cv2
import numpy as np

from vishap._core.errors import ShapeError, VisionError
from vishap.vision.skin_model import SkinModel

__all__ = [
    "SegmentConfig",
    "Segmenter",
    "hue_bin_image",
    "tile_histograms",
    "histogram_intersection",
    "snap_roi",
    "binary_median",
]


@dataclass(frozen=True)
class SegmentConfig:
    """Settings of the segmentation (defaults follow the paper where it gives a value)."""

    tile: int = 5                   # tile side, pixels (paper: small tiles; issue: 5×5)
    bins: int = 8                   # hue bins (issue: 8)
    sat_bins: int = 1               # saturation bins per hue bin (1 = the paper's hue-only histogram)
    match_threshold: float = 0.6    # intersection below this → foreground tile
    median: int = 5                 # median filter aperture (odd; 1 = off)
    dilate_tiles: int = 1           # also test skin in tiles this many tiles away from a foreground tile
    achromatic_bin: bool = True     # own bin for pixels whose hue is undefined
    min_saturation: int = 40        # achromatic gate (0…255)
    min_value: int = 30
    coarse: int = 1                 # > 1: a large region is first skin-tested on every coarse-th pixel of every
    #   coarse-th row, and segmented at full resolution only around the skin found (see Segmenter.segment)
    coarse_margin: int = 3          # … plus this many coarse pixels around it
    coarse_min_px: int = 160 * 160  # … for regions of at least this many pixels (a tracking window is smaller)

    def __post_init__(self) -> None:
        if self.bins * self.sat_bins > 254:
            raise VisionError(f"bins × sat_bins must be below 255, got {self.bins * self.sat_bins}")
        if self.tile < 1 or self.bins < 1 or self.sat_bins < 1:
            raise VisionError(f"tile and bins must be positive, got tile={self.tile} bins={self.bins}")
        if self.coarse < 1 or self.coarse_margin < 0:
            raise VisionError(f"coarse must be ≥ 1 and coarse_margin ≥ 0, got {self.coarse}, {self.coarse_margin}")
        if self.median < 1 or self.median % 2 == 0:
            raise VisionError(f"median aperture must be odd and positive, got {self.median}")
        if not (0.0 < self.match_threshold <= 1.0):
            raise VisionError(f"match_threshold must be in (0, 1], got {self.match_threshold}")


def _bin_lut(bins: int, sat_bins: int = 1) -> np.ndarray:
    """Hue (0…179) → hue bin × sat_bins."""
    return (np.minimum(np.arange(256) * bins // 180, bins - 1) * sat_bins).astype(np.uint8)


def _sat_lut(cfg: SegmentConfig) -> np.ndarray:
    """Saturation (0…255) → saturation bin (0 below the achromatic gate, which is handled apart)."""
    s = np.clip(np.arange(256) - cfg.min_saturation, 0, None)
    return np.minimum(s * cfg.sat_bins // max(1, 256 - cfg.min_saturation), cfg.sat_bins - 1).astype(np.uint8)


def hue_bin_image(hsv: np.ndarray, cfg: SegmentConfig, lut: np.ndarray | None = None, *,
                  hue: np.ndarray | None = None, chroma: np.ndarray | None = None) -> np.ndarray:
    """Per-pixel histogram bin (uint8): chromatic bins ``0…bins·sat_bins−1``, then one bin for
    achromatic pixels (when ``achromatic_bin``). ``hue``, ``chroma``: the image's hue channel and
    its achromatic gate (``inRange`` of ``min_saturation``/``min_value``), if the caller has them."""
    lut = _bin_lut(cfg.bins, cfg.sat_bins) if lut is None else lut
    b = cv2.LUT(np.ascontiguousarray(hsv[..., 0]) if hue is None else hue, lut)
    if cfg.sat_bins > 1:
        b = cv2.add(b, cv2.LUT(np.ascontiguousarray(hsv[..., 1]), _sat_lut(cfg)))
    if cfg.achromatic_bin:
        if chroma is None:
            chroma = cv2.inRange(hsv, (0, cfg.min_saturation, cfg.min_value), (255, 255, 255))
        b = cv2.min(cv2.max(b, cv2.bitwise_not(chroma)), cfg.bins * cfg.sat_bins)
    return b


_DENSE_MAX_TILES = 400  # regions of at most this many tiles get every tile's histogram (the same mask as
#   the sparse choice of tiles, in fewer, cheaper calls: the tile gather pays off on large regions only)


def _n_bins(cfg: SegmentConfig) -> int:
    return cfg.bins * cfg.sat_bins + (1 if cfg.achromatic_bin else 0)


class _TileIndex:
    """``tile_index * n_bins`` of a region's pixels as a row and a column term (cached per size;
    their sum is the index image), and that sum itself for regions up to ``_BASE_MAX_PX`` (a
    tracking window: one addition of the bins per window instead of two)."""

    def __init__(self, tile: int, nb: int):
        self.tile, self.nb = tile, nb
        self._rows: dict = {}
        self._cols: dict = {}
        self._base: dict = {}

    def base(self, h: int, w: int) -> np.ndarray | None:
        """``rows + cols`` of an h×w region, or None for a large one."""
        if h * w > _BASE_MAX_PX:
            return None
        b = self._base.get((h, w))
        if b is None:
            if len(self._base) >= 256:  # (window sizes vary; keep the cache bounded)
                self._base.clear()
            rows, cols, _, _ = self.get(h, w)
            b = self._base[(h, w)] = rows + cols
        return b

    def get(self, h: int, w: int) -> tuple[np.ndarray, np.ndarray, int, int]:
        t = self.tile
        ty, tx = -(-h // t), -(-w // t)
        rows = self._rows.get((h, tx))
        if rows is None:
            rows = self._rows[(h, tx)] = ((np.arange(h) // t) * (tx * self.nb)).astype(np.intp)[:, None]
        cols = self._cols.get(w)
        if cols is None:
            cols = self._cols[w] = ((np.arange(w) // t) * self.nb).astype(np.intp)
        return rows, cols, ty, tx


_BASE_MAX_PX = 160 * 160


def tile_histograms(bin_image: np.ndarray, tile: int, n_bins: int, _index: _TileIndex | None = None) -> np.ndarray:
    """All tile histograms of a bin image: (tiles_y, tiles_x, n_bins) int64, from one bincount."""
    h, w = bin_image.shape
    index = _index or _TileIndex(tile, n_bins)
    rows, cols, ty, tx = index.get(h, w)
    base = index.base(h, w)
    if base is not None:
        idx = base + bin_image
    else:
        idx = cols + bin_image
        idx += rows
    return np.bincount(idx.ravel(), minlength=ty * tx * n_bins).reshape(ty, tx, n_bins)


def histogram_intersection(I: np.ndarray, M: np.ndarray) -> np.ndarray:
    """VisHap eq. (1) over the last axis: ``sum min(I, M) / sum M`` (1 where M is empty)."""
    num = np.minimum(I, M).sum(axis=-1)
    den = M.sum(axis=-1)
    return np.where(den > 0, num / np.maximum(den, 1), 1.0)


def _foreground_counts(background: np.ndarray, threshold: float) -> np.ndarray:
    """Per model tile, the intersection count ``Σ min(I, M)`` below which a live tile is foreground:
    eq. (1) ``count / Σ M < threshold`` turned into an integer bound, evaluated with the same float
    division for every possible ``Σ M``, so the decision is exactly the one of
    :func:`histogram_intersection` (an empty model tile, intersection 1, is never foreground)."""
    den = background.sum(axis=-1)
    top = int(den.max()) if den.size else 0
    d = np.arange(top + 1)
    below = (d[None, :] / np.maximum(d[:, None], 1) < threshold) & (d[None, :] <= d[:, None])
    count = below.sum(axis=1)
    count[0] = 0
    return count[den]


def snap_roi(roi, tile: int, size: tuple[int, int]) -> tuple[int, int, int, int]:
    """Clip ``(x0, y0, x1, y1)`` to the image and widen it to whole tiles."""
    w, h = size
    x0, y0, x1, y1 = roi
    x0 = max(0, (math.floor(x0) // tile) * tile)
    y0 = max(0, (math.floor(y0) // tile) * tile)
    x1 = min(w, -(-math.floor(x1) // tile) * tile)
    y1 = min(h, -(-math.floor(y1) // tile) * tile)
    return x0, y0, max(x0, x1), max(y0, y1)


@dataclass
class Segmenter:
    """Tile hue-histogram background model + skin model + median filter (one camera).

    ``learn(frames)`` builds the background; ``segment(image, roi=None)`` returns the skin mask of the
    image or of the tile-aligned region ``roi = (x0, y0, x1, y1)`` (the mask then has the ROI's size).
    """

    skin: SkinModel
    config: SegmentConfig = field(default_factory=SegmentConfig)
    background: np.ndarray | None = None    # (tiles_y, tiles_x, n_bins)
    image_size: tuple[int, int] | None = None

    def __post_init__(self) -> None:
        c = self.config
        # one achromatic gate for histograms and skin test
        if (self.skin.min_saturation, self.skin.min_value) != (c.min_saturation, c.min_value):
            self.config = c = replace(c, min_saturation=self.skin.min_saturation, min_value=self.skin.min_value)
        self._lut = _bin_lut(c.bins, c.sat_bins)
        self._slut = _sat_lut(c)
        self._index = _TileIndex(c.tile, _n_bins(c))
        k = 2 * c.dilate_tiles + 1
        self._dilate_kernel = np.ones((k, k), np.uint8) if c.dilate_tiles > 0 else None
        self._coarse_kernel = np.ones((2 * c.coarse_margin + 1,) * 2, np.uint8)
        self._tile_offsets: dict = {}
        self._model_of = None  # the background array the derived model below was made from
        self._hue_lut = getattr(self.skin, "hue_lut", None)  # a hue-interval skin test: one look-up
        #   table, sharing the saturation/value gate with the tile histograms' achromatic bin
        self._skin_v = self._bin_v = None
        if self._hue_lut is not None and c.sat_bins == 1 and c.achromatic_bin:
            # the same tables read at "hue | not chromatic": an achromatic pixel reads entry 255
            # (8-bit hue stops at 179), which is no skin and the achromatic bin
            self._skin_v, self._bin_v = self._hue_lut.copy(), self._lut.copy()
            self._skin_v[255], self._bin_v[255] = 0, c.bins

    def _model(self) -> tuple[np.ndarray, np.ndarray]:
        """The background as float32 histograms and its per-tile foreground counts
        (:func:`_foreground_counts`), remade whenever ``background`` is replaced."""
        if self._model_of is not self.background:
            self._bg_f32 = self.background.astype(np.float32)
            self._bg_count = _foreground_counts(self.background, self.config.match_threshold)
            self._ones = np.ones(self.background.shape[-1], np.float32)
            self._model_of = self.background
        return self._bg_f32, self._bg_count

    def _foreground(self, hist: np.ndarray, tiles) -> np.ndarray:
        """Eq. (1) against the model tiles ``tiles`` (an index into the (tiles_y, tiles_x) grid):
        True where a live histogram ``hist`` differs from the background (counts below 2**24 add up
        exactly in float32)."""
        M, count = self._model()
        num = np.minimum(hist.astype(np.float32), M[tiles]) @ self._ones
        return num < count[tiles]

    @property
    def learned(self) -> bool:
        return self.background is not None

    def learn(self, frames) -> None:
        """Background model from the average of ``frames`` (BGR images of one camera)."""
        acc = None
        n = 0
        for f in frames:
            f = _check_image(f, self.image_size if acc is not None else None)
            if acc is None:
                acc = np.zeros(f.shape, np.float32)
            cv2.accumulate(f, acc)
            n += 1
        if n == 0:
            raise VisionError("learning the background needs at least one frame")
        mean = cv2.convertScaleAbs(acc, alpha=1.0 / n)
        self.image_size = (mean.shape[1], mean.shape[0])
        self.mean_image = mean                  # the averaged background (used for colour refinement)
        self.background = self.histograms(mean)

    def histograms(self, image: np.ndarray) -> np.ndarray:
        hsv = cv2.cvtColor(image, cv2.COLOR_BGR2HSV)
        return tile_histograms(hue_bin_image(hsv, self.config, self._lut), self.config.tile, _n_bins(self.config), self._index)

    def foreground_tiles(self, hsv: np.ndarray, roi: tuple[int, int, int, int], *, bins: np.ndarray | None = None
                         ) -> np.ndarray:
        """Boolean (tiles_y, tiles_x) of the ROI: True where the tile differs from the background
        (``bins``: the region's :func:`hue_bin_image`, if the caller has it)."""
        c = self.config
        x0, y0, x1, y1 = roi
        if bins is None:
            bins = hue_bin_image(hsv, c, self._lut)
        hist = tile_histograms(bins, c.tile, _n_bins(c), self._index)
        return self._foreground(hist, (slice(y0 // c.tile, -(-y1 // c.tile)), slice(x0 // c.tile, -(-x1 // c.tile))))

    def segment(self, image: np.ndarray, roi=None, *, method: str = "sparse") -> np.ndarray:
        """Skin mask (uint8 0/255) of ``image`` or of the region ``roi`` (snapped to tiles)."""
        if self.background is None:
            raise VisionError("segment() before learn(): no background model")
        image = _check_image(image, self.image_size)
        c = self.config
        if roi is None:
            roi = (0, 0, self.image_size[0], self.image_size[1])
        else:
            roi = snap_roi(roi, c.tile, self.image_size)
        return self._segment_snapped(image, roi, method)

    def _segment_snapped(self, image: np.ndarray, roi, method: str = "sparse") -> np.ndarray:
        """:meth:`segment` of a checked image and a tile-aligned region within it."""
        c = self.config
        x0, y0, x1, y1 = roi
        if x1 <= x0 or y1 <= y0:
            return np.zeros((max(0, y1 - y0), max(0, x1 - x0)), np.uint8)
        if c.coarse > 1 and method == "sparse" and (x1 - x0) * (y1 - y0) >= c.coarse_min_px:
            return self._segment_coarse(image, roi)
        return self.segment_hsv(_region_hsv(image, x0, y0, x1, y1), roi, method=method)

    def segment_region(self, image: np.ndarray, roi=None, *, pad: int = 0) -> tuple[np.ndarray, tuple[int, int]]:
        """:meth:`segment`, cut to where it can hold skin: ``(mask, (x, y))``, the mask over the
        boxes the coarse pass segments (their bounding box) widened by ``pad`` pixels within the
        region, and that mask's top-left corner in the image. :meth:`segment`'s mask is zero
        outside it (a 1×1 zero mask when there is no skin); a region without the coarse pass comes
        whole. A detector that looks ``pad`` pixels around skin finds the same there, without
        allocating and scanning the whole frame."""
        if self.background is None:
            raise VisionError("segment_region() before learn(): no background model")
        image = _check_image(image, self.image_size)
        c = self.config
        roi = (0, 0, *self.image_size) if roi is None else snap_roi(roi, c.tile, self.image_size)
        x0, y0, x1, y1 = roi
        if c.coarse > 1 and (x1 - x0) * (y1 - y0) >= c.coarse_min_px:
            return self._segment_coarse(image, roi, pad=pad)
        return self._segment_snapped(image, roi), (x0, y0)

    def _segment_coarse(self, image: np.ndarray, roi, *, pad: int | None = None):
        """:meth:`segment` of a large region through a coarse pass: the skin test on a subsampled
        image (every ``coarse``-th pixel), its skin regions widened by ``coarse_margin`` coarse
        pixels, and the full-resolution segmentation run only in the tile-aligned boxes of those
        regions (a lone sample is skipped). A skin region over ``2·coarse`` pixels wide always has
        neighbouring samples, and the margin covers the tile neighbourhood and the median filter, so
        the mask equals the one of the whole region except for skin specks a few pixels wide, which
        the median filter mostly removes and which cannot hold a fingertip, and slivers that the
        region's own edge cuts off the hand (measured: the same masks over the full frames of the
        standard sequences, docs/vision.md)."""
        c = self.config
        x0, y0, x1, y1 = roi
        k = c.coarse
        if (x1 - x0) % k or (y1 - y0) % k:
            small = image[y0:y1:k, x0:x1:k]
        else:  # the same samples as the slice (nearest neighbour at an integer step), without a strided copy
            small = cv2.resize(image[y0:y1, x0:x1], ((x1 - x0) // k, (y1 - y0) // k), interpolation=cv2.INTER_NEAREST)
        sk = self.skin.mask(small)
        # a lone skin sample (sensor noise on a skin-like background) starts no box: a region that
        # can hold a fingertip (a disk over 2·coarse pixels wide) has neighbouring samples
        near = cv2.boxFilter(cv2.threshold(sk, 0, 1, cv2.THRESH_BINARY)[1], -1, (3, 3), normalize=False,
                             borderType=cv2.BORDER_CONSTANT)
        sk = cv2.bitwise_and(sk, sk, mask=(near >= 2).view(np.uint8))
        boxes = []
        if sk.any():
            if c.coarse_margin:
                sk = cv2.dilate(sk, self._coarse_kernel)
            # 16-bit labels where they fit (several times faster here than 32-bit ones)
            ltype = cv2.CV_16U if sk.size < 2 ** 16 else cv2.CV_32S
            n, _, stats, _ = cv2.connectedComponentsWithStats(sk, connectivity=8, ltype=ltype)
            for bx, by, bw, bh, _area in stats[1:].tolist():
                bx0, by0, bx1, by1 = snap_roi((x0 + bx * k, y0 + by * k, x0 + (bx + bw) * k, y0 + (by + bh) * k),
                                              c.tile, self.image_size)
                # within the region (tile-aligned, so the box stays tile-aligned)
                bx0, by0, bx1, by1 = max(bx0, x0), max(by0, y0), min(bx1, x1), min(by1, y1)
                if bx1 > bx0 and by1 > by0:
                    boxes.append((bx0, by0, bx1, by1))
        if pad is None:
            ox, oy, out = x0, y0, np.zeros((y1 - y0, x1 - x0), np.uint8)
        elif not boxes:
            return np.zeros((1, 1), np.uint8), (x0, y0)
        else:  # the boxes' bounding box, widened by pad within the region
            ox, oy = max(x0, min(b[0] for b in boxes) - pad), max(y0, min(b[1] for b in boxes) - pad)
            ex, ey = min(x1, max(b[2] for b in boxes) + pad), min(y1, max(b[3] for b in boxes) + pad)
            out = np.zeros((ey - oy, ex - ox), np.uint8)
        for box in boxes:
            bx0, by0, bx1, by1 = box
            m = self.segment_hsv(_region_hsv(image, bx0, by0, bx1, by1), box)
            dst = out[by0 - oy: by1 - oy, bx0 - ox: bx1 - ox]
            cv2.bitwise_or(dst, m, dst=dst)
        return out if pad is None else (out, (ox, oy))

    def segment_hsv(self, hsv: np.ndarray, roi: tuple[int, int, int, int], *, method: str = "sparse") -> np.ndarray:
        """Skin mask of an HSV region. ``method="sparse"`` (default) builds histograms only for the
        tiles whose foreground state can matter — tiles holding a skin pixel and their neighbours —
        and gives exactly the mask of ``method="dense"`` (every tile of the region)."""
        c = self.config
        hv = hue = chroma = None
        if self._skin_v is not None:  # the hue test, its gate and the histogram bins from two look-ups
            chroma = cv2.inRange(hsv, (0, c.min_saturation, c.min_value), (255, 255, 255))
            hv = cv2.bitwise_or(cv2.extractChannel(hsv, 0), cv2.bitwise_not(chroma))
            skin = cv2.LUT(hv, self._skin_v)
        elif self._hue_lut is not None:
            hue = cv2.extractChannel(hsv, 0)
            chroma = cv2.inRange(hsv, (0, c.min_saturation, c.min_value), (255, 255, 255))
            skin = cv2.bitwise_and(cv2.LUT(hue, self._hue_lut), chroma)
        else:
            skin = self.skin.mask_hsv(hsv)
        h, w = skin.shape
        t = c.tile
        ty, tx = -(-h // t), -(-w // t)
        dense = method == "dense" or h % t or w % t
        if not dense and ty * tx <= _DENSE_MAX_TILES:  # a small region (a tracking window): every tile costs fewer calls
            if not cv2.countNonZero(skin):
                return skin
            dense = True
        if not dense:
            skin_tiles = cv2.resize(skin, (tx, ty), interpolation=cv2.INTER_AREA)
            need = skin_tiles if self._dilate_kernel is None else cv2.dilate(skin_tiles, self._dilate_kernel)
            sel = np.flatnonzero(need)
            if sel.size == 0:
                return np.zeros((h, w), np.uint8)
            dense = sel.size > 0.4 * ty * tx
        if dense:
            bins = cv2.LUT(hv, self._bin_v) if hv is not None else hue_bin_image(hsv, c, self._lut, hue=hue, chroma=chroma)
            fg = self.foreground_tiles(hsv, roi, bins=bins).view(np.uint8)
        else:
            fg = self._foreground_sparse(hsv, roi, sel, (ty, tx), hue, chroma, hv)
        if self._dilate_kernel is not None:
            fg = cv2.dilate(fg, self._dilate_kernel)
        fg_px = cv2.resize(fg, (tx * t, ty * t), interpolation=cv2.INTER_NEAREST)[:h, :w]
        mask = cv2.bitwise_and(skin, skin, mask=fg_px)
        if c.median > 1:
            bx, by, bw, bh = cv2.boundingRect(mask)
            if bw:  # outside the mask's box (plus half the aperture) the median is 0: filter the box only
                k = c.median // 2 + 1
                x0, y0, x1, y1 = max(0, bx - k), max(0, by - k), min(w, bx + bw + k), min(h, by + bh + k)
                _median_in_place(mask[y0:y1, x0:x1], c.median)
        return mask

    def _foreground_sparse(self, hsv, roi, sel, shape, hue=None, chroma=None, hv=None) -> np.ndarray:
        """Foreground tiles ``sel`` (flat indices) of the region, the others 0; ``hue``/``chroma``: the
        region's hue channel and achromatic gate, ``hv``: the two as one image (``_bin_v``'s index),
        if the caller has them (hue-only bins)."""
        c = self.config
        t = c.tile
        ty, tx = shape
        h, w = hsv.shape[:2]
        iy, ix = np.divmod(sel, tx)
        key = (w, t)
        off = self._tile_offsets.get(key)
        if off is None:
            dy, dx = np.mgrid[0:t, 0:t]
            off = self._tile_offsets[key] = (dy * w + dx).ravel()
        idx = ((iy * t) * w + ix * t)[:, None] + off[None, :]          # (T, t²) pixel indices
        if hv is not None:
            b = self._bin_v[hv.ravel()[idx]]
        elif hue is not None and c.sat_bins == 1 and c.achromatic_bin:
            b = np.where(chroma.ravel()[idx], self._lut[hue.ravel()[idx]], c.bins)
        else:
            px = hsv.reshape(-1, 3)[idx]                                # (T, t², 3)
            b = self._lut[px[..., 0]]
            if c.sat_bins > 1:
                b = b + self._slut[px[..., 1]]
            if c.achromatic_bin:
                b = np.where((px[..., 1] >= c.min_saturation) & (px[..., 2] >= c.min_value), b, c.bins * c.sat_bins)
        nb = _n_bins(c)
        hist = np.bincount((np.arange(sel.size)[:, None] * nb + b).ravel(), minlength=sel.size * nb)
        x0, y0 = roi[0] // t, roi[1] // t
        fg = np.zeros(ty * tx, np.uint8)
        fg[sel] = self._foreground(hist.reshape(-1, nb), (y0 + iy, x0 + ix))
        return fg.reshape(ty, tx)


def _region_hsv(image: np.ndarray, x0: int, y0: int, x1: int, y1: int) -> np.ndarray:
    """HSV of the region ``[x0, x1) × [y0, y1)`` of a BGR image. The region is copied out first:
    cvtColor reads a strided view of a frame that is not in the cache yet 2–3× slower than the
    copy and the conversion of the copy together (70×70 tracking windows of 640×480 frames)."""
    return cv2.cvtColor(np.ascontiguousarray(image[y0:y1, x0:x1]), cv2.COLOR_BGR2HSV)


def binary_median(mask: np.ndarray, k: int) -> np.ndarray:
    """``cv2.medianBlur(mask, k)`` of a 0/255 mask, as a majority count: a pixel is skin when at
    least ``(k² + 1) / 2`` of its k×k neighbours are (replicated border, as medianBlur). The same
    mask, about 4× faster (one box sum instead of a sorting network)."""
    if k * k > 255:
        return cv2.medianBlur(mask, k)
    ones = cv2.threshold(mask, 0, 1, cv2.THRESH_BINARY)[1]
    count = cv2.boxFilter(ones, -1, (k, k), normalize=False, borderType=cv2.BORDER_REPLICATE)
    return cv2.threshold(count, (k * k) // 2, 255, cv2.THRESH_BINARY)[1]


def _median_in_place(mask: np.ndarray, k: int) -> None:
    """:func:`binary_median` of a mask holding only 0 and 255 (a view is fine), written into it.
    For k ≤ 7 the box mean of the 0/255 values is thresholded half-way between the means of
    ``(k² − 1)/2`` and ``(k² + 1)/2`` skin neighbours (at least 5 grey levels apart, so the mean's
    rounding cannot cross it): one call fewer than the count, and no copy."""
    if k > 7:
        mask[...] = binary_median(np.ascontiguousarray(mask), k)
        return
    level = int(255 * (k * k // 2 + 0.5) / (k * k))
    cv2.threshold(cv2.boxFilter(mask, -1, (k, k), borderType=cv2.BORDER_REPLICATE), level, 255, cv2.THRESH_BINARY,
                  dst=mask)


def _check_image(img, size) -> np.ndarray:
    if not isinstance(img, np.ndarray) or img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        desc = f"{getattr(img, 'dtype', type(img).__name__)} {getattr(img, 'shape', '')}"
        raise ShapeError(f"image: expected uint8 BGR of shape (H, W, 3), got {desc}")
    if size is not None and (img.shape[1], img.shape[0]) != tuple(size):
        raise ShapeError(f"image: expected size {size[0]}×{size[1]}, got {img.shape[1]}×{img.shape[0]}")
    return img
