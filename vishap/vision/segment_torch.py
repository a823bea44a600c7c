"""Batch backend of the tile hue-histogram segmentation (VisHap §2.1) in torch/kornia.

Same algorithm and same masks as :class:`vishap.vision.segment.Segmenter` (a test checks equality
pixel for pixel): tile histograms from one ``bincount`` over the whole batch, histogram
intersection (eq. 1) against the background model, tile dilation (``max_pool2d``), the skin
model's hue interval and achromatic gate, and the median filter as a majority vote of the
``k×k`` window (exactly a median for a binary image), computed with kornia's box filter on
replicated borders as OpenCV's ``medianBlur`` does.

Input is the OpenCV HSV of the frames (``cv2.cvtColor(..., COLOR_BGR2HSV)``): kornia's float HSV
differs from OpenCV's 8-bit rounding, and equal masks need equal hues.
"""
from __future__ import annotations

import numpy as np

from vishap.vision.segment import SegmentConfig, _bin_lut, _n_bins, _sat_lut
from vishap.vision.skin_model import SkinModel

__all__ = ["TorchSegmenter"]


class TorchSegmenter:
    """Segment a batch ``(B, H, W, 3)`` of OpenCV-HSV frames against a learned background model."""

    def __init__(self, skin: SkinModel, config: SegmentConfig, background: np.ndarray, *, device: str = "cpu"):
        import torch

        self.torch = torch
        self.skin, self.config, self.device = skin, config, device
        self.background = torch.as_tensor(np.asarray(background), dtype=torch.int64, device=device)
        self.lut_h = torch.as_tensor(_bin_lut(config.bins, config.sat_bins).astype(np.int64), device=device)
        self.lut_s = torch.as_tensor(_sat_lut(config).astype(np.int64), device=device)
        self._tile_cache: dict = {}

    def _tile_ids(self, h: int, w: int):
        key = (h, w)
        if key not in self._tile_cache:
            t = self.config.tile
            tx = -(-w // t)
            ys = self.torch.arange(h, device=self.device) // t
            xs = self.torch.arange(w, device=self.device) // t
            self._tile_cache[key] = ys[:, None] * tx + xs[None, :]
        return self._tile_cache[key]

    def segment(self, hsv_batch) -> np.ndarray:
        """Masks (B, H, W) uint8 0/255 of a batch of full frames (HSV, uint8)."""
        import kornia
        import torch.nn.functional as F

        torch = self.torch
        c = self.config
        hsv = torch.as_tensor(np.asarray(hsv_batch), device=self.device)
        if hsv.ndim == 3:
            hsv = hsv[None]
        B, H, W, _ = hsv.shape
        hue, sat, val = (hsv[..., i].long() for i in range(3))
        chroma = (sat >= c.min_saturation) & (val >= c.min_value)
        b = self.lut_h[hue]
        if c.sat_bins > 1:
            b = b + self.lut_s[sat]
        nb = _n_bins(c)
        if c.achromatic_bin:
            b = torch.where(chroma, b, torch.full_like(b, c.bins * c.sat_bins))
        t = c.tile
        ty, tx = -(-H // t), -(-W // t)
        nt = ty * tx
        idx = (torch.arange(B, device=self.device)[:, None, None] * nt + self._tile_ids(H, W)[None]) * nb + b
        hist = torch.bincount(idx.reshape(-1), minlength=B * nt * nb).reshape(B, ty, tx, nb)
        M = self.background[None]
        den = M.sum(-1)
        inter = torch.minimum(hist, M).sum(-1).double() / den.clamp(min=1).double()
        inter = torch.where(den > 0, inter, torch.ones_like(inter))
        fg = (inter < c.match_threshold).float()[:, None]                     # (B, 1, ty, tx)
        if c.dilate_tiles > 0:
            k = 2 * c.dilate_tiles + 1
            fg = F.max_pool2d(fg, k, stride=1, padding=c.dilate_tiles)
        fg_px = fg.repeat_interleave(t, dim=2).repeat_interleave(t, dim=3)[:, 0, :H, :W] > 0
        skin = torch.zeros_like(chroma)
        for lo, hi in self.skin._ranges:
            skin |= (hue >= lo) & (hue <= hi)
        skin &= (sat >= self.skin.min_saturation) & (val >= self.skin.min_value)
        mask = (skin & fg_px).float()[:, None]
        if c.median > 1:
            k = c.median
            mean = kornia.filters.box_blur(mask, (k, k), border_type="replicate", separable=False)
            mask = (mean * (k * k) > (k * k // 2) + 0.5).float()
        return (mask[:, 0] * 255).to(torch.uint8).cpu().numpy()
