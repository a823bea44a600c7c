"""How the rendered hand's skin looks: the plain look, and the look measured on real photographs.

The plain look (the default, unchanged since the first renders) is one evenly coloured, faceted,
matte skin colour under the scene's white key light: at the fingertip its HSV saturation stays
within 55–124 (5th–95th percentile), while on real photos of hands (TI1K train photos 1–600) it
spans 4–165, with 29 % of the pixels under the paper's saturation gate of 40 against 1.6 % on the
render (``vishap bench synth_appearance``). What the real photos show and the plain look lacks,
and what the *real* look adds (``skin_tone: real`` or ``real:TONE``):

* pale, brightly lit skin: pale albedos (the skin's distance from grey drawn from 0.05 to 1.5 of
  the tone's) and exposures that clip the brightest skin (a phone exposes for the whole scene;
  sunlit skin saturates), which is where the saturation falls under the paper's gate of 40; a
  sheen (roughness 0.3–0.5 for 0.55; its white highlights are a few pixels at these sizes, so
  they moved the statistics little);
* the real saturation range: the same chroma draw, per-sequence white balance (light colour from
  cool to warm) and tones from light to between tan and dark;
* shading: smooth normals, a harder key light from a per-sequence direction and less ambient light
  (shadowed sides of the finger are dark on real photos);
* mottling: slow albedo variation over the hand (vertex colours), and a paler, glossier nail.

Every draw comes from ``numpy.random.default_rng([seed, 0x5C1`` …``])``, a stream of its own, so a
plain-look render stays byte-identical. The ranges below were fitted to the fingertip pixels of
the TI1K train photos 1–600 only (see docs/synth.md, "Real appearance").
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap._core.errors import ConfigError

__all__ = ["SkinLook", "RealLookRanges", "REAL", "REAL_LOOK", "skin_look", "parse_skin_tone", "mottling_colours"]

REAL = "real"


@dataclass(frozen=True)
class RealLookRanges:
    """Per-sequence ranges of the real look (uniform unless said otherwise)."""

    tone: tuple[float, float] = (0.0, 0.75)          # position on the light … dark scale of SKIN_TONES
    chroma: tuple[float, float] = (0.05, 1.5)         # albedo's distance from grey × this (pale … vivid)
    roughness: tuple[float, float] = (0.30, 0.50)
    mottling: float = 0.10                            # relative albedo variation over the hand
    log_exposure: tuple[float, float] = (0.30, 0.35)  # ln of the exposure factor: normal (mean, sd)
    warmth: tuple[float, float] = (-0.10, 0.25)       # light colour: blue −, red + (white balance)
    key_scale: tuple[float, float] = (1.2, 2.4)       # key light × this
    ambient_scale: tuple[float, float] = (0.10, 0.7)  # ambient and fill × this
    key_azimuth_deg: tuple[float, float] = (-60.0, 60.0)
    key_elevation_deg: tuple[float, float] = (35.0, 75.0)


REAL_LOOK = RealLookRanges()


@dataclass(frozen=True)
class SkinLook:
    """What the renderer needs to draw the skin and light it."""

    rgb: tuple[float, float, float]          # albedo, sRGB 0…1
    real: bool = False
    roughness: float = 0.55
    smooth: bool = False                     # smooth normals (the plain look is faceted)
    mottling: float = 0.0
    nail_mix: float = 0.45                   # nail = (1 − mix)·skin + mix·pale pink
    nail_roughness: float = 0.3
    light_rgb: tuple[float, float, float] = (1.0, 1.0, 1.0)
    key_scale: float = 1.0
    ambient_scale: float = 1.0
    key_direction: tuple[float, float, float] | None = None  # towards the light, robot frame; None: the scene's
    exposure: float = 1.0                    # auto-exposure target (or, without it, the lights) × this
    seed: int = 0

    @property
    def nail_rgb(self) -> tuple[float, float, float]:
        return tuple(min(1.0, (1 - self.nail_mix) * c + self.nail_mix * d) for c, d in zip(self.rgb, (0.96, 0.80, 0.80)))


def parse_skin_tone(tone) -> tuple[bool, str | float | None]:
    """``(real, tone)`` of a skin-tone spec: None, a name of SKIN_TONES, a number 0…1, ``real``
    (the real look, tone drawn by seed) or ``real:NAME|NUMBER``. A bad spec is a ConfigError."""
    from vishap.sim.hand import SKIN_TONES

    real = isinstance(tone, str) and (tone == REAL or tone.startswith(REAL + ":"))
    if real:
        rest = tone[len(REAL) + 1:].strip()
        if not rest:
            return True, None
        try:
            tone = float(rest)
        except ValueError:
            tone = rest
    if tone is None:
        return real, None
    if isinstance(tone, str):
        if tone not in SKIN_TONES:
            raise ConfigError(f"unknown skin tone {tone!r}; expected one of {list(SKIN_TONES)}, a number 0…1, "
                              f"{REAL!r} or {REAL}:TONE", field="skin_tone")
        return real, tone
    if isinstance(tone, bool) or not isinstance(tone, (int, float, np.integer, np.floating)) or not np.isfinite(tone):
        raise ConfigError(f"skin tone must be a name or a number 0…1, got {tone!r}", field="skin_tone")
    return real, float(tone)


def skin_look(tone, seed: int, rng: np.random.Generator) -> SkinLook:
    """The look of a sequence. ``rng`` is the renderer's plain-look generator (its draws, as before
    this look existed, give the plain tone and its variation); the real look draws from its own."""
    from vishap.sim.hand import skin_tone_rgb

    real, tone = parse_skin_tone(tone)
    if not real:
        if tone is None:
            tone = float(rng.uniform(0.0, 1.0))
        return SkinLook(rgb=skin_tone_rgb(tone, rng), seed=int(seed))
    r = REAL_LOOK
    g = np.random.default_rng([int(seed), 0x5C1])
    tone_v = float(g.uniform(*r.tone)) if tone is None else tone
    rgb = np.asarray(skin_tone_rgb(tone_v, g))
    grey = float(rgb @ [0.2126, 0.7152, 0.0722])
    rgb = tuple(float(c) for c in np.clip(grey + g.uniform(*r.chroma) * (rgb - grey), 0.0, 1.0))
    warmth = float(g.uniform(*r.warmth))
    light = np.array([1.0 + 0.5 * warmth, 1.0, 1.0 - warmth])
    light = light / (0.2126 * light[0] + 0.7152 * light[1] + 0.0722 * light[2])  # same luminance
    az, el = np.radians(g.uniform(*r.key_azimuth_deg)), np.radians(g.uniform(*r.key_elevation_deg))
    # azimuth 0: the light stands beyond the scene, opposite the user (as the plain key light)
    key_dir = (float(np.cos(el) * np.cos(az)), float(np.cos(el) * np.sin(az)), float(np.sin(el)))
    return SkinLook(rgb=rgb, real=True, roughness=float(g.uniform(*r.roughness)), smooth=True, mottling=r.mottling,
                    nail_mix=0.6, nail_roughness=0.2, light_rgb=tuple(float(c) for c in light),
                    key_scale=float(g.uniform(*r.key_scale)), ambient_scale=float(g.uniform(*r.ambient_scale)),
                    key_direction=key_dir, exposure=float(np.exp(g.normal(*r.log_exposure))), seed=int(seed))


def mottling_colours(vertices: np.ndarray, amount: float, seed: int, part: int) -> np.ndarray:
    """(n, 4) float vertex colours around 1: slow albedo variation over a part (a few random plane
    waves of ≈ 2–6 cm wavelength in the part's own frame, so the pattern moves with the part);
    alpha 1 (the colour pass's alpha carries the label)."""
    g = np.random.default_rng([int(seed), 0x5C2, int(part)])
    v = np.asarray(vertices, dtype=np.float64)
    f = np.zeros(len(v))
    for _ in range(4):
        k = g.normal(size=3)
        k *= 2 * np.pi / (np.linalg.norm(k) * g.uniform(0.02, 0.06))
        f += np.sin(v @ k + g.uniform(0, 2 * np.pi))
    f /= 2.0  # ≈ unit spread
    redness = g.uniform(0.3, 0.7)
    out = np.ones((len(v), 4))
    out[:, 0] += amount * f * (1 + redness) / 2
    out[:, 1] += amount * f
    out[:, 2] += amount * f
    out[:, :3] = np.clip(out[:, :3], 0.0, 1.5)
    return out.astype(np.float32)
