"""Contact data exchanged with the world/servo loop (DESIGN.md, tactile interface).

The world's force law produces one :class:`ContactSample` per 1 ms servo tick. Positions are in
the object frame (z along the surface normal, so ``position[2]`` is the height of the finger above
the surface before contact). The optional fields carry what a richer contact model knows about the
pad (HAPTEX §III-B: "a contact area instead of a single contact point"); when absent, the tactile
layer derives them from the force (Hertz patch) and the surface velocity.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from vishap._core.check import as_array

__all__ = ["ContactSample"]


@dataclass(frozen=True)
class ContactSample:
    """One contact observation.

    Attributes
    ----------
    t: time, s.
    position: (3,) finger contact point in the object frame, m (z = height above the surface).
    normal_force_n: normal force between finger and surface, N (≥ 0).
    velocity: (3,) finger velocity in the object frame, m/s.
    in_contact: whether the world reports contact.
    pad_position: optional (2,) contact centre on the sleeve (x along the finger, y across), m.
    contact_radius_m: optional (2,) semi-axes of the pad contact patch, m.
    finger_dir: optional (3,) finger pointing direction in the object frame; its pitch tells a
        fingertip press from a flat pad stroke when the patch itself is not given.
    """

    t: float
    position: np.ndarray
    normal_force_n: float
    velocity: np.ndarray
    in_contact: bool
    pad_position: np.ndarray | None = None
    contact_radius_m: np.ndarray | None = field(default=None)
    finger_dir: np.ndarray | None = None

    def __post_init__(self):
        # shapes are checked here; non-finite values are allowed and rendered as "no contact"
        for name in ("position", "velocity"):
            object.__setattr__(self, name, as_array(getattr(self, name), (3,), name, finite=False))
        for name, n in (("pad_position", 2), ("contact_radius_m", 2), ("finger_dir", 3)):
            v = getattr(self, name)
            if v is not None:
                object.__setattr__(self, name, as_array(v, (n,), name, finite=False))

    @property
    def tangential_speed(self) -> float:
        """Speed of the finger along the surface (object x–y plane), m/s."""
        return math.hypot(self.velocity[0], self.velocity[1])
