"""Finger trajectories for the closed-loop meeting (VisHap §3 experiments: approach, press, slide, leave).

A :class:`FingerTrajectory` is a fingertip path in the robot frame, piecewise in time:

1. rest at the start ``S`` (``settle_s``) while the device settles;
2. approach: minimum-jerk from ``S`` to ``press_start_m`` under the contact point (the finger meets
   the surface still moving), optionally bowed sideways, with the given peak speed;
3. press: the depth grows slowly to ``press_max_m`` and returns (the Fig. 6 force–depth sweep);
4. slide (objects that allow it): a minimum-jerk stroke along the surface;
5. leave: minimum-jerk lift-off.

:func:`make_approaches` draws seeded approaches over a scene's objects and a list of peak speeds.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap._core.motion import min_jerk
from vishap.robot.params import WORKSPACE_MAX, WORKSPACE_MIN
from vishap.world.scene import Scene, SceneObject

__all__ = ["FingerTrajectory", "make_approaches", "min_jerk"]

REACH_MIN = np.array(WORKSPACE_MIN)  # the device's workspace box (robot params)
REACH_MAX = np.array(WORKSPACE_MAX)


@dataclass
class FingerTrajectory:
    object_name: str
    normal: np.ndarray  # (3,) the object's outward normal
    start: np.ndarray  # (3,) S
    contact: np.ndarray  # (3,) the intended contact point on the surface
    speed_m_s: float  # peak approach speed
    bow_m: float = 0.0  # sideways bow of the approach (m)
    settle_s: float = 0.15
    press_start_m: float = 0.0015
    press_max_m: float = 0.007
    press_s: float = 1.0
    slide: np.ndarray | None = None  # (3,) tangential stroke, None for no slide
    slide_s: float = 0.6
    leave_m: float = 0.05
    leave_s: float = 0.35

    def __post_init__(self):
        self.normal = np.asarray(self.normal, dtype=float)
        self.start = np.asarray(self.start, dtype=float)
        self.contact = np.asarray(self.contact, dtype=float)
        self.A = self.contact - self.normal * self.press_start_m
        L = float(np.linalg.norm(self.A - self.start))
        self.approach_s = max(1.875 * L / self.speed_m_s, 0.05)
        d = self.A - self.start
        side = np.cross(self.normal, d)
        ns = float(np.linalg.norm(side))
        self.side = side / ns if ns > 1e-9 else np.zeros(3)
        self.t_approach_end = self.settle_s + self.approach_s
        self.t_press_end = self.t_approach_end + self.press_s
        self.t_slide_end = self.t_press_end + (self.slide_s if self.slide is not None else 0.0)
        self.duration = self.t_slide_end + self.leave_s
        ts = np.linspace(self.settle_s, self.t_approach_end, 2000)
        h = np.array([self.normal @ (self.position(t) - self.contact) for t in ts])
        self.t_surface = float(ts[np.argmax(h <= 0.0)])

    def position(self, t: float) -> np.ndarray:
        n = self.normal
        if t <= self.settle_s:
            return self.start.copy()
        if t <= self.t_approach_end:
            s = (t - self.settle_s) / self.approach_s
            m = min_jerk(s)
            return self.start + (self.A - self.start) * m + self.side * (self.bow_m * np.sin(np.pi * m))
        if t <= self.t_press_end:
            u = (t - self.t_approach_end) / self.press_s
            tri = 1.0 - abs(2.0 * u - 1.0)  # 0 → 1 → 0
            depth = self.press_start_m + (self.press_max_m - self.press_start_m) * tri
            return self.contact - n * depth
        base = self.A.copy()
        if self.slide is not None:
            base = base + self.slide * min_jerk((min(t, self.t_slide_end) - self.t_press_end) / self.slide_s)
        if t <= self.t_slide_end:
            return base
        return base + n * (self.leave_m + self.press_start_m) * min_jerk((t - self.t_slide_end) / self.leave_s)

    def velocity(self, t: float, h: float = 1e-4) -> np.ndarray:
        return (self.position(t + h) - self.position(t - h)) / (2.0 * h)

    def press_mask(self, t, *, before_s: float = 0.05) -> np.ndarray:
        """Times of the Fig. 6 sweep: from ``before_s`` before the finger reaches the surface to the
        end of the press."""
        t = np.asarray(t)
        return (t > self.t_surface - before_s) & (t <= self.t_press_end)


def _contact_point(obj: SceneObject, rng: np.random.Generator) -> np.ndarray:
    if obj.kind == "button":
        xy = rng.uniform(-0.3, 0.3, 2) * obj.half
    else:
        room = np.maximum(obj.half - 0.015, 0.0)
        xy = rng.uniform(-1.0, 1.0, 2) * room
    p = obj.centre + obj.R[:, 0] * xy[0] + obj.R[:, 1] * xy[1]
    lo, hi = REACH_MIN + [0.03, 0.015, 0.0], REACH_MAX - [0.03, 0.015, 0.0]
    return obj.project(np.clip(p, lo, hi))


def make_approaches(
    scene: Scene,
    n: int,
    *,
    speeds=(0.1, 0.2, 0.3, 0.4, 0.5),
    seed: int = 0,
    objects: list[str] | None = None,
    bow_fraction: float = 0.15,
    slide: bool = True,
) -> list[FingerTrajectory]:
    """``n`` seeded approaches cycling over ``objects`` (default all) and ``speeds`` (peak, m/s).

    The start is 40–80 mm above the surface and up to 40 mm to the side; in a scene with several
    objects it is above a different object than the target, so the subject switches on the way.
    """
    rng = np.random.default_rng(seed)
    names = objects or [o.name for o in scene.objects]
    out = []
    for i in range(n):
        obj = scene.object(names[i % len(names)])
        c = _contact_point(obj, rng)
        others = [o for o in scene.objects if o.name != obj.name]
        for _ in range(50):  # a finger path that passes clear of every other object
            if others:
                o2 = others[rng.integers(len(others))]
                start = _contact_point(o2, rng) + o2.normal * rng.uniform(0.03, 0.06)
            else:
                ang = rng.uniform(0, 2 * np.pi)
                lateral = (obj.R[:, 0] * np.cos(ang) + obj.R[:, 1] * np.sin(ang)) * rng.uniform(0.0, 0.04)
                start = c + obj.normal * rng.uniform(0.04, 0.08) + lateral
            start = np.clip(start, REACH_MIN + 0.005, REACH_MAX - 0.005)
            if not any(o.segment_hits(start, c, margin=0.008, top_clearance=0.008) for o in others):
                break
        L = float(np.linalg.norm(c - start))
        stroke = None
        if slide and "slide" in obj.mode.allows:
            ang = rng.uniform(0, 2 * np.pi)
            stroke = (obj.R[:, 0] * np.cos(ang) + obj.R[:, 1] * np.sin(ang)) * 0.02
            end = c + stroke
            if not (obj.inside_extent(end, -0.005) and np.all(end > REACH_MIN) and np.all(end < REACH_MAX)):
                stroke = -stroke
        press_max = {"button": 0.0065, "fabric": 0.005}.get(obj.kind, 0.007)
        out.append(
            FingerTrajectory(
                obj.name, obj.normal, start, c, float(speeds[i % len(speeds)]),
                bow_m=float(rng.uniform(-bow_fraction, bow_fraction) * L), slide=stroke, press_max_m=press_max,
            )
        )
    return out
