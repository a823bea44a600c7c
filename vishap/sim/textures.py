"""Procedural, seeded background textures (sRGB ``uint8`` RGB images) for the table.

Ordinary backgrounds (``grey``, ``concrete``, ``checker``, ``blue_cloth``, ``cutting_mat``) and
skin-like hard negatives (``wood``, ``beige``), whose hue lies inside the skin hue range: VisHap
§3.1 segments skin by hue, so these test its background model, not its skin model. Hard negatives
are opt-in (see :data:`HARD_NEGATIVE`).

Real photographs (``photo``, ``photo:NAME``, ``photo:FILE``): on real images the backgrounds that
pass the skin test are real surfaces (brick, soil, wood, faces, hair), not procedural noise, so a
photograph can be laid on the table instead. :data:`PHOTOS` are the photographs that installed
packages ship (nothing is downloaded); ``photo:FILE`` takes any image file. Each seed takes its
own crop (at least half the photo's shorter side), quarter-turn and mirror of it.
"""
from __future__ import annotations

import cv2
import numpy as np

from vishap._core.errors import ConfigError

__all__ = ["BACKGROUNDS", "HARD_NEGATIVE", "ORDINARY", "PHOTOS", "make_texture", "choose_background", "photo_path",
           "is_photo", "texture_tile_m"]

ORDINARY = ("grey", "concrete", "checker", "blue_cloth", "cutting_mat")
HARD_NEGATIVE = ("wood", "beige")
BACKGROUNDS = ORDINARY + HARD_NEGATIVE

#: photographs shipped by installed packages: name → (package, file as the package's own API finds
#: it, licence). Matplotlib's sample photograph is a U.S. Navy portrait (public domain); it holds a
#: face and a flag, skin-hued surfaces of a real photograph (26 % of its pixels pass a skin hue
#: test with saturation ≥ 40).
PHOTOS = {"hopper": ("matplotlib", "grace_hopper.jpg", "public domain (U.S. Navy photograph)")}
_PHOTO = "photo"
_TILE_M = 0.40        # table repeat of a procedural texture, m
_PHOTO_TILE_M = 0.90  # a photograph spans more of the table (mirrored at its edges, no seams)


def _noise(rng: np.random.Generator, size: int, scale: int) -> np.ndarray:
    """Smooth value noise in 0…1 (bicubic upsampling of a coarse random grid)."""
    coarse = rng.random((max(2, size // scale), max(2, size // scale))).astype(np.float32)
    return cv2.resize(coarse, (size, size), interpolation=cv2.INTER_CUBIC).clip(0, 1)


def is_photo(name: str) -> bool:
    return name == _PHOTO or name.startswith(_PHOTO + ":")


def texture_tile_m(name: str) -> float:
    """Size on the table of one repeat of the background ``name`` (m)."""
    return _PHOTO_TILE_M if is_photo(name) else _TILE_M


def photo_path(name: str):
    """The image file of ``photo:NAME`` (a :data:`PHOTOS` name) or ``photo:FILE``; a clear error if
    there is none."""
    from pathlib import Path

    key = name.split(":", 1)[1] if ":" in name else ""
    if key in PHOTOS:
        package, file, _ = PHOTOS[key]
        if package == "matplotlib":
            from matplotlib import cbook

            return Path(cbook.get_sample_data(file, asfileobj=False))
    path = Path(key)
    if not key or not path.is_file():
        raise ConfigError(f"unknown photograph {key!r}: expected one of {list(PHOTOS)} or an image file", field="background")
    return path


def _photo_texture(name: str, rng: np.random.Generator, size: int) -> np.ndarray:
    path = photo_path(name)
    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise ConfigError(f"cannot read the photograph {str(path)!r}", field="background")
    h, w = img.shape[:2]
    side = int(min(h, w) * rng.uniform(0.5, 1.0))
    y0, x0 = int(rng.integers(0, h - side + 1)), int(rng.integers(0, w - side + 1))
    crop = np.rot90(img[y0:y0 + side, x0:x0 + side], int(rng.integers(4)))
    if rng.random() < 0.5:
        crop = crop[:, ::-1]
    crop = cv2.resize(np.ascontiguousarray(crop), (size, size), interpolation=cv2.INTER_AREA)
    return cv2.cvtColor(crop, cv2.COLOR_BGR2RGB)


def make_texture(name: str, rng: np.random.Generator, size: int = 512) -> np.ndarray:
    """An RGB ``uint8`` (size, size, 3) texture; the same ``rng`` state gives the same image."""
    if is_photo(name):
        return _photo_texture(name, rng, size)
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
    """Resolve a background spec: a name, ``auto`` (an ordinary one chosen by seed), ``mixed``
    (chosen by seed, a skin-like hard negative for one seed in five), ``photo`` (a shipped
    photograph chosen by seed), ``photo:NAME`` or ``photo:FILE``."""
    if spec in BACKGROUNDS:
        return spec
    if isinstance(spec, str) and is_photo(spec):
        if spec == _PHOTO:
            names = sorted(PHOTOS)
            return f"{_PHOTO}:{names[int(np.random.default_rng([seed, 0xF070]).integers(len(names)))]}"
        photo_path(spec)
        return spec
    rng = np.random.default_rng([seed, 0xBAC])
    if spec == "auto":
        return ORDINARY[int(rng.integers(len(ORDINARY)))]
    if spec == "mixed":
        if rng.random() < 0.2:
            return HARD_NEGATIVE[int(rng.integers(len(HARD_NEGATIVE)))]
        return ORDINARY[int(rng.integers(len(ORDINARY)))]
    raise ConfigError(f"unknown background {spec!r}; expected auto, mixed, photo, photo:NAME|FILE or one of "
                      f"{list(BACKGROUNDS)}", field="background")
