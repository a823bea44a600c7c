"""Which module defines each demo (:mod:`vishap.apps.wall`, ``button``, ``fabric``).

A demo module offers ``DEFAULT_FRAMES`` (camera frames covering its script at 30 Hz), ``script(hidden_s)``
(its :class:`~vishap.apps.script.FingerScript`) and ``extra_summary(meta, channels) -> dict`` (the
figures particular to it, merged into ``summary.json``).
"""
from __future__ import annotations

import importlib

__all__ = ["demo_module"]


def demo_module(scene: str):
    from vishap.apps.config import SCENES

    if scene not in SCENES:
        from vishap._core.errors import ConfigError

        raise ConfigError(f"unknown demo {scene!r}; expected one of {', '.join(SCENES)}", field="scene")
    return importlib.import_module(f"vishap.apps.{scene}")
