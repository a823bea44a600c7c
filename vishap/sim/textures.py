"""Procedural, seeded background textures (sRGB ``uint8`` RGB images) for the table.

Ordinary backgrounds (``grey``, ``concrete``, ``checker``, ``blue_cloth``, ``cutting_mat``) and
skin-like hard negatives (``wood``, ``beige``), whose hue lies inside the skin hue range: VisHap
§3.1 segments skin by hue, so these test its background model, not its skin model. Hard negatives
are opt-in (see :data:`HARD_NEGATIVE`).
"""
from __future__ import annotations

import cv2
import numpy as np

from vishap._core.errors import ConfigError

__all__ = ["BACKGROUNDS", "HARD_NEGATIVE", "ORDINARY", "make_texture", "choose_background"]

ORDINARY = ("grey", "concrete", "checker", "blue_cloth", "cutting_mat")
HARD_NEGATIVE = ("wood", "beige")
BACKGROUNDS = ORDINARY + HARD_NEGATIVE


def _noise(rng: np.random.Generator, size: int, scale: int) -> np.ndarray:
    """Smooth value noise in 0…1 (bicubic upsampling of a coarse random grid)."""
    coarse = rng.random((max(2, size // scale), max(2, size // scale))).astype(np.float32)
    return cv2.resize(coarse, (size, size), interpolation=cv2.INTER_CUBIC).clip(0, 1)


def make_texture(name: str, rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """An RGB ``uint8`` (size, size, 3) texture; the same ``rng`` state gives the same image."""
    n1, n2, fine = _noise(rng, size, 32), _noise(rng, size, 8), rng.random((size, size)).astype(np.float32)
    yy, xx = np.mgrid[0:size, 0:size].astype(np.float32)
    if name == "grey":
        base = np.array([128, 130, 134]) * (0.85 + 0.2 * n1 + 0.05 * fine)[..., None]
    elif name == "concrete":
        v = 0.55 + 0.25 * n1 + 0.15 * n2 + 0.12 * fine
        base = np.array([150, 150, 146]) * v[..., None]
    elif name == "checker":
        c = ((xx // 64 + yy // 64) % 2).astype(np.float32)
        base = (np.array([70, 78, 92]) + np.array([90, 92, 96]) * c[..., None]) * (0.92 + 0.1 * n2)[..., None]
    elif name == "blue_cloth":
        weave = 0.5 + 0.25 * np.sin(xx * 0.9) * np.sin(yy * 0.9)
        base = np.array([40, 62, 120]) * (0.8 + 0.25 * weave + 0.1 * n1 + 0.08 * fine)[..., None]
    elif name == "cutting_mat":
        grid = ((xx % 40) < 2) | ((yy % 40) < 2)
        base = np.where(grid[..., None], np.array([170, 190, 170]), np.array([46, 92, 70])) * (0.95 + 0.08 * n1)[..., None]
    elif name == "wood":
        rings = 0.5 + 0.5 * np.sin((xx + 40 * n1) * 0.12 + 6 * n2)
        base = np.array([196, 140, 92]) * (0.7 + 0.25 * rings + 0.08 * fine)[..., None]
    elif name == "beige":
        base = np.array([214, 170, 138]) * (0.85 + 0.15 * n1 + 0.06 * n2 + 0.05 * fine)[..., None]
    else:
        raise ConfigError(f"unknown background {name!r}; expected one of {list(BACKGROUNDS)}", field="background")
    return np.clip(base, 0, 255).astype(np.uint8)


def choose_background(spec: str, seed: int) -> str:
    """Resolve a background spec: a name, ``auto`` (an ordinary one chosen by seed) or ``mixed``
    (chosen by seed, a skin-like hard negative for one seed in five)."""
    if spec in BACKGROUNDS:
        return spec
    rng = np.random.default_rng([seed, 0xBAC])
    if spec == "auto":
        return ORDINARY[int(rng.integers(len(ORDINARY)))]
    if spec == "mixed":
        if rng.random() < 0.2:
            return HARD_NEGATIVE[int(rng.integers(len(HARD_NEGATIVE)))]
        return ORDINARY[int(rng.integers(len(ORDINARY)))]
    raise ConfigError(f"unknown background {spec!r}; expected auto, mixed or one of {list(BACKGROUNDS)}", field="background")
