"""The stages a demo assembles, built in one place from the other subpackages.

Each builder imports its subpackage when called, so the demo names precisely the stage that is
missing when a subpackage is not installed. Small adapters bridge conventions between stages:

- the device target: the world gives ``X_d`` as the contact point on the object's surface; the
  device controls its end-effector, which carries the passive object's top face at
  ``ee + mount_offset`` (:class:`vishap.sim.state.PassiveObject`), so the end-effector target is
  ``X_d - mount_offset``;
- the finger: vision locates the centre of the fingertip's cap; the world is given the *pad* point
  (cap centre minus the cap radius along the surface normal), the point that touches.
"""
from __future__ import annotations

import importlib

import numpy as np

from vishap._core.errors import VishapError

__all__ = ["StageMissing", "need", "Stages", "tactile_row"]


class StageMissing(VishapError, RuntimeError):
    """A stage of the pipeline is not installed (its subpackage module is missing)."""


def need(module: str, stage: str):
    try:
        return importlib.import_module(module)
    except ModuleNotFoundError as exc:
        if exc.name and exc.name.startswith("vishap"):
            raise StageMissing(f"the {stage} stage is not available: module {exc.name} is missing") from None
        raise


def tactile_row(out) -> dict[str, np.ndarray]:
    """Flatten the tactile renderer's per-tick output into named numeric arrays for the log."""
    if out is None:
        return {}
    if isinstance(out, dict):
        items = out.items()
    elif hasattr(out, "__dataclass_fields__"):
        items = ((k, getattr(out, k)) for k in out.__dataclass_fields__)
    elif isinstance(out, np.ndarray):
        items = (("drive", out),)
    else:
        items = ((k, v) for k, v in vars(out).items() if not k.startswith("_"))
    row = {}
    for k, v in items:
        if isinstance(v, str):
            continue
        if hasattr(v, "value") and isinstance(getattr(v, "value"), str):  # an Enum state
            continue
        try:
            a = np.asarray(v, dtype=np.float64)
        except (TypeError, ValueError):
            continue
        row[k] = a.astype(np.float32) if a.size > 1 else a
    return row


class Stages:
    """Holds the built stages of one run (filled by :func:`vishap.apps.loop.build_stages`)."""

    def __init__(self, **kw):
        self.__dict__.update(kw)
