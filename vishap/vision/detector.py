"""One camera, one fingertip: the interface every 2-D fingertip detector implements.

A *mono detector* takes one BGR image at a time (``t`` on the caller's clock) and reports the
index fingertip of the hand it sees, or that it saw none. The paper's geometric detector (skin
segmentation → r = K/z cap test → Kalman tracker), a learned hand-landmark model and hybrids of
the two implement it; ``vishap eval fingertip`` scores any of them by name on real photos and
video, and the stereo pipeline pairs two of them for 3-D.

Two points are reported because they answer different questions:

``tip_end_uv``
    the outermost point of the fingertip along the finger (what annotators click and what
    MediaPipe's landmark 8 marks): the point 2-D scores are computed on;
``cap_uv``
    the centre of the fingertip's hemispherical cap: the same 3-D point seen from both cameras,
    hence what stereo triangulates. ``None`` for a detector that cannot tell it.

Detectors are found by name in a registry; a module registers its factories at import with
:func:`register_detector`, and :func:`make_detector` imports the modules listed in
``_BUILTIN_MODULES`` on first use so a name resolves without the caller importing anything.
"""
from __future__ import annotations

import importlib
from dataclasses import dataclass, field
from typing import Callable, Protocol, runtime_checkable

import numpy as np

from vishap._core.errors import ConfigError

__all__ = ["MonoDetection", "MonoDetector", "register_detector", "make_detector", "detector_names",
           "DEFAULT_DETECTORS", "make_default_detector"]


@dataclass
class MonoDetection:
    """One view's answer for one frame (pixels are float ``(u, v)`` in the full image)."""

    t: float
    found: bool
    tip_end_uv: np.ndarray | None = None   # outermost point of the index fingertip
    cap_uv: np.ndarray | None = None       # centre of the fingertip's cap (what stereo uses)
    radius_px: float = 0.0                 # cap radius in pixels (0 when unknown)
    direction: np.ndarray | None = None    # unit image vector from the tip into the finger
    confidence: float = 0.0                # 0..1
    mode: str = "full"                     # how this frame was searched ("full", "tracked", "learned", ...)
    reason: str = ""                       # why nothing was found, when found is False
    timings: dict = field(default_factory=dict)


@runtime_checkable
class MonoDetector(Protocol):
    """What ``vishap eval fingertip`` and the mono path need of a detector."""

    name: str

    def process(self, image: np.ndarray, t: float) -> MonoDetection:
        """Detect (and, for a tracking detector, track) the fingertip in one uint8 BGR image."""

    def reset(self) -> None:
        """Forget all state (tracks, learned backgrounds): the next frame starts a new sequence."""


_REGISTRY: dict[str, tuple[Callable[..., MonoDetector], str]] = {}
# modules whose import registers the project's own detectors (optional ones register only when
# their extra is installed; their factories raise a ConfigError that says how to install it)
_BUILTIN_MODULES: tuple[str, ...] = (
    "vishap.vision.mono",
    "vishap.vision.learned",
    "vishap.vision.hybrid",
)


def register_detector(name: str, factory: Callable[..., MonoDetector], help: str = "") -> None:
    """Make ``factory(**options)`` available as ``name`` (a later registration of a name replaces it)."""
    _REGISTRY[name] = (factory, help)


def _load_builtins() -> None:
    for mod in _BUILTIN_MODULES:
        importlib.import_module(mod)


def detector_names() -> dict[str, str]:
    """Registered detector names and their one-line descriptions."""
    _load_builtins()
    return {k: v[1] for k, v in sorted(_REGISTRY.items())}


def make_detector(name: str, **options) -> MonoDetector:
    """A new detector by name; unknown names give a :class:`ConfigError` listing the known ones."""
    _load_builtins()
    if name not in _REGISTRY:
        raise ConfigError(f"detector {name!r}: unknown (known: {', '.join(sorted(_REGISTRY)) or 'none'})")
    return _REGISTRY[name][0](**options)


#: The default detector, best first: the hybrid (learned hand finder + the paper's cap fit and
#: Kalman tracker) when the ``learned`` extra is installed, else the classical geometric detector.
DEFAULT_DETECTORS: tuple[str, ...] = ("hybrid", "geometric")


def make_default_detector(**options) -> tuple[MonoDetector, str]:
    """The first of :data:`DEFAULT_DETECTORS` that can be built, and a note ("" when it is the first)
    saying why an earlier one was passed over."""
    notes = []
    for name in DEFAULT_DETECTORS:
        try:
            return make_detector(name, **options), "; ".join(notes)
        except ConfigError as exc:
            notes.append(f"detector {name!r} unavailable ({exc.reason}): using the next one")
    raise ConfigError("no default detector can be built: " + "; ".join(notes))
