"""Scripted, seeded finger motions defined as data (issue 3, item 3; VisHap §4 tested approach,
press, slide, fast motion, pauses, illumination change and occlusion on live sequences).

A trajectory file (``datasets/synthetic/trajectories/NAME.yaml``) lists timed segments. Each
segment moves the index fingertip from where the previous one ended to a target, with a
minimum-jerk profile ``s(τ) = 10τ³ − 15τ⁴ + 6τ⁵`` (Flash & Hogan 1985: the shape of unconstrained
human point-to-point reaches). A target is one of

* ``contact: [x, y]`` — the fingertip touches the scene's surface at (x, y): the cap's lowest
  point lies on z = surface − ``depth_m`` (``depth_m`` > 0 only where the surface gives: a key's
  travel, cloth), i.e. the cap centre is ``TIP_RADIUS_M`` above it;
* ``hover: [x, y, h]`` — the cap's lowest point ``h`` above the surface at (x, y);
* ``tip: [x, y, z]`` — the cap centre itself (robot frame), e.g. outside the view;
* nothing — stay (a pause).

Segments may also set ``dir`` (finger direction), ``flexion``, ``roll``, ``light`` (intensity
scale, interpolated), ``occluder: true`` (a rod crosses the line of sight) and ``hand_visible``.
The script repeats for as many frames as asked; every repetition draws its own jitter (positions
±``jitter.position_m``, durations ±``jitter.duration``, the hand's pose: finger direction
±``jitter.dir_deg``, roll ±``jitter.roll_deg``, bend ±``jitter.flexion``) from the sequence's seed, and a small
physiological tremor (8–12 Hz, ``tremor_m``) is added while the finger is not in contact.
The first ``hand_free_frames`` frames show no hand (VisHap learns its background from them).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, model_validator

from vishap._core.config import Schema, load_config
from vishap._core.errors import ConfigError
from vishap._core.motion import min_jerk
from vishap.sim.state import TIP_RADIUS_M

__all__ = ["TRAJECTORIES_DIR", "PHASES", "HIDDEN_PHASES", "TrajectorySpec", "FingerSample", "Trajectory",
           "load_trajectory", "min_jerk", "occluder_segment"]

TRAJECTORIES_DIR = Path(__file__).resolve().parents[2] / "datasets" / "synthetic" / "trajectories"

#: phase names, in the order of their integer codes in ``gt.npz`` (``phase``)
PHASES = ("hand_free", "enter", "approach", "press", "hold", "release", "slide", "lift", "hover", "fast_sweep",
          "pause", "occlusion", "leave", "away", "return")
#: phases in which the fingertip is meant to be hidden or outside the view (at least partly)
HIDDEN_PHASES = ("hand_free", "enter", "occlusion", "leave", "away", "return")

_CONTACT_TOL_M = 1e-6  # a cap this close to the surface at the end of an approach touches it

Vec2 = tuple[float, float]
Vec3 = tuple[float, float, float]


class SegmentSpec(Schema):
    phase: Literal[PHASES[1:]]  # type: ignore[valid-type]
    duration_s: float = Field(gt=0.0, le=30.0)
    contact: Vec2 | None = None
    depth_m: float = Field(default=0.0, ge=0.0, le=0.01)
    hover: Vec3 | None = None
    tip: Vec3 | None = None
    dir: Vec3 | None = None
    flexion: float | None = Field(default=None, ge=0.0, le=1.0)
    roll: float | None = None
    light: float | None = Field(default=None, gt=0.0, le=3.0)
    occluder: bool = False
    hand_visible: bool = True

    @model_validator(mode="after")
    def _one_target(self):
        if sum(x is not None for x in (self.contact, self.hover, self.tip)) > 1:
            raise ValueError("give at most one of contact, hover, tip")
        if self.dir is not None and np.linalg.norm(self.dir) < 1e-6:
            raise ValueError("dir must be a non-zero vector")
        return self


class JitterSpec(Schema):
    position_m: float = Field(default=0.003, ge=0.0, le=0.02)   # targets, ± m per axis
    duration: float = Field(default=0.15, ge=0.0, lt=0.9)       # durations, ± fraction
    dir_deg: float = Field(default=6.0, ge=0.0, le=20.0)       # finger direction: yaw ±, pitch ± half of it
    roll_deg: float = Field(default=10.0, ge=0.0, le=45.0)     # hand roll about the finger, ±
    flexion: float = Field(default=0.05, ge=0.0, le=0.3)       # bend, ±


class TrajectorySpec(Schema):
    name: str
    scenes: list[str] = Field(min_length=1)
    fps: float = Field(default=30.0, gt=0.0, le=1000.0)
    hand_free_frames: int = Field(default=10, ge=0)
    start_tip: Vec3
    finger_dir: Vec3 = (-0.766, 0.0, -0.643)
    flexion: float = Field(default=0.2, ge=0.0, le=1.0)
    roll: float = 0.0
    tremor_m: float = Field(default=0.0003, ge=0.0, le=0.005)
    jitter: JitterSpec = JitterSpec()
    segments: list[SegmentSpec] = Field(min_length=1)


def load_trajectory(name_or_path: str | Path) -> tuple[TrajectorySpec, Path]:
    """A trajectory by name (``datasets/synthetic/trajectories/NAME.yaml``) or path, validated."""
    p = Path(name_or_path)
    if not p.suffix:
        p = TRAJECTORIES_DIR / f"{name_or_path}.yaml"
        if not p.is_file():
            known = sorted(q.stem for q in TRAJECTORIES_DIR.glob("*.yaml"))
            raise ConfigError(f"unknown trajectory {str(name_or_path)!r}; expected one of {known} or a .yaml file",
                              field="trajectory")
    return load_config(p, TrajectorySpec), p


@dataclass
class FingerSample:
    """The scripted finger at one instant (robot frame, metres)."""

    t: float
    phase: str
    tip_robot: np.ndarray
    finger_dir_robot: np.ndarray
    flexion: float
    roll: float
    hand_visible: bool
    in_contact: bool
    depth_m: float            # how far the touched surface is pushed in (0 for a rigid one)
    light: float
    occluder_progress: float | None  # 0…1 across an occlusion segment, None without occluder


@dataclass
class _Key:
    t0: float
    t1: float
    seg: SegmentSpec
    p0: np.ndarray
    p1: np.ndarray
    d0: np.ndarray
    d1: np.ndarray
    f0: float
    f1: float
    r0: float
    r1: float
    l0: float
    l1: float
    contact: bool


class Trajectory:
    """A trajectory file bound to a scene surface and a seed; :meth:`sample` gives the finger at ``t``.

    ``touch_region``: ((x_min, y_min), (x_max, y_max)) where the scene's passive object can meet the
    finger; a ``contact`` target outside it (after jitter, which is clipped into it) is an error.
    """

    def __init__(self, spec: TrajectorySpec, *, surface_z_m: float, touch_region, seed: int = 0,
                 file: str | Path | None = None, light_fn=None):
        self.spec = spec
        self.file = file
        self.surface_z = float(surface_z_m)
        self.region = np.asarray(touch_region, dtype=np.float64).reshape(2, 2)
        self.seed = int(seed)
        self.fps = float(spec.fps)
        self.t_hand = spec.hand_free_frames / self.fps  # time at which the hand appears
        self.light_fn = light_fn
        for i, s in enumerate(spec.segments):
            if s.contact is not None and not self._in_region(s.contact, tol=1e-9):
                raise ConfigError(f"contact {list(s.contact)} lies outside the region where the device's passive "
                                  f"object can meet the finger ({self.region.tolist()})",
                                  file=file, field=f"segments.{i}.contact")
        self._keys: list[_Key] = []
        self._cycle_rngs = []
        phases = np.random.default_rng([self.seed, 0x7AE]).uniform(0, 2 * np.pi, size=(3, 2))
        freqs = np.random.default_rng([self.seed, 0x7AF]).uniform(8.0, 12.0, size=(3, 2))
        self._tremor = (phases, freqs)

    def _in_region(self, xy, tol=0.0) -> bool:
        xy = np.asarray(xy, dtype=np.float64)
        return bool(np.all(xy >= self.region[0] - tol) and np.all(xy <= self.region[1] + tol))

    # ------------------------------------------------------------------ building keys lazily
    def _extend(self, t: float) -> None:
        sp = self.spec
        while not self._keys or self._keys[-1].t1 < t:
            cycle = len(self._cycle_rngs)
            rng = np.random.default_rng([self.seed, 0xC7C, cycle])
            self._cycle_rngs.append(rng)
            if self._keys:
                k = self._keys[-1]
                p, d, f, r, lt = k.p1, k.d1, k.f1, k.r1, k.l1
                t_now = k.t1
            else:
                p = np.asarray(sp.start_tip, dtype=np.float64)
                d = _unit(sp.finger_dir)
                f, r, lt, t_now = sp.flexion, sp.roll, 1.0, self.t_hand
            # this repetition's hand pose: finger direction turned by a small yaw and pitch, roll
            # and bend offset; segments without their own dir/flexion/roll keep the cycle's
            J = sp.jitter
            yaw, pitch = np.radians(rng.uniform(-J.dir_deg, J.dir_deg)), np.radians(rng.uniform(-J.dir_deg, J.dir_deg) / 2)
            d_roll, d_flex = np.radians(rng.uniform(-J.roll_deg, J.roll_deg)), rng.uniform(-J.flexion, J.flexion)
            turn = lambda v: _turn(v, yaw, pitch)  # noqa: E731
            dc, fc, rc = turn(sp.finger_dir), float(np.clip(sp.flexion + d_flex, 0, 1)), sp.roll + d_roll
            if not self._keys:
                d, f, r = dc, fc, rc
            for seg in sp.segments:
                dur = seg.duration_s * (1.0 + rng.uniform(-J.duration, J.duration))
                jit = rng.uniform(-J.position_m, J.position_m, size=3)
                p1 = self._target(seg, p, jit)
                dc = turn(seg.dir) if seg.dir is not None else dc
                fc = float(np.clip(seg.flexion + d_flex, 0, 1)) if seg.flexion is not None else fc
                rc = seg.roll + d_roll if seg.roll is not None else rc
                d1, f1, r1 = dc, fc, rc
                l1 = seg.light if seg.light is not None else lt
                stays = seg.tip is None and seg.hover is None and seg.contact is None
                contact = seg.contact is not None or (stays and bool(self._keys) and self._keys[-1].contact)
                self._keys.append(_Key(t_now, t_now + dur, seg, p, p1, d, d1, f, f1, r, r1, lt, l1, contact))
                p, d, f, r, lt, t_now = p1, d1, f1, r1, l1, t_now + dur

    def _target(self, seg: SegmentSpec, p_prev: np.ndarray, jit: np.ndarray) -> np.ndarray:
        r = TIP_RADIUS_M
        if seg.contact is not None:
            xy = np.clip(np.asarray(seg.contact) + jit[:2], self.region[0], self.region[1])
            return np.array([xy[0], xy[1], self.surface_z - seg.depth_m + r])
        if seg.hover is not None:
            x, y, h = seg.hover
            return np.array([x + jit[0], y + jit[1], self.surface_z + r + max(0.0, h + jit[2])])
        if seg.tip is not None:
            return np.asarray(seg.tip, dtype=np.float64) + jit
        return p_prev.copy()

    # ------------------------------------------------------------------ sampling
    def _position(self, t: float, key: _Key) -> np.ndarray:
        s = float(min_jerk((t - key.t0) / (key.t1 - key.t0)))
        p = key.p0 + s * (key.p1 - key.p0)
        if self.spec.tremor_m > 0:
            ph, fr = self._tremor
            w = np.sum(np.sin(2 * np.pi * fr * t + ph), axis=1) / 2.0 * self.spec.tremor_m
            if key.contact:
                w[2] = 0.0  # a touching finger stays on the surface
            p = p + w
        return p

    def _key_at(self, t: float) -> _Key:
        self._extend(t)
        lo, hi = 0, len(self._keys) - 1
        while lo < hi:  # first key with t1 >= t
            mid = (lo + hi) // 2
            if self._keys[mid].t1 < t:
                lo = mid + 1
            else:
                hi = mid
        return self._keys[lo]

    def sample(self, t: float) -> FingerSample:
        """The finger at time ``t`` (s); before the hand appears it is not visible."""
        t = float(t)
        light = float(self.light_fn(t)) if self.light_fn is not None else 1.0
        if t < self.t_hand - 1e-9:
            p = np.asarray(self.spec.start_tip, dtype=np.float64)
            return FingerSample(t, "hand_free", p, _unit(self.spec.finger_dir), self.spec.flexion, self.spec.roll,
                                False, False, 0.0, light, None)
        k = self._key_at(t)
        s = float(min_jerk((t - k.t0) / (k.t1 - k.t0)))
        tau = float(np.clip((t - k.t0) / (k.t1 - k.t0), 0.0, 1.0))
        p = self._position(t, k)
        d = _unit(k.d0 + s * (k.d1 - k.d0))
        bottom = p[2] - TIP_RADIUS_M
        in_contact = bool(k.contact and bottom <= self.surface_z + _CONTACT_TOL_M)
        if in_contact and abs(bottom - self.surface_z) <= _CONTACT_TOL_M:  # touching the resting surface
            p[2] = self.surface_z + TIP_RADIUS_M
            bottom = self.surface_z
        depth = max(0.0, self.surface_z - bottom) if in_contact else 0.0
        light *= k.l0 + s * (k.l1 - k.l0)
        return FingerSample(t, k.seg.phase, p, d, k.f0 + s * (k.f1 - k.f0), k.r0 + s * (k.r1 - k.r0),
                            bool(k.seg.hand_visible), in_contact, depth, light, tau if k.seg.occluder else None)

    def velocity(self, t: float, h: float = 1e-4) -> np.ndarray:
        """Fingertip velocity (m/s, robot frame) by a central difference of the continuous motion."""
        t = float(t)
        if t < self.t_hand:
            return np.zeros(3)
        a, b = max(t - h, self.t_hand), t + h
        return (self.sample(b).tip_robot - self.sample(a).tip_robot) / (b - a)

    def first_cycle_end_s(self) -> float:
        """Time at which the first pass through the script ends (hand-free frames included)."""
        self._extend(self.t_hand)
        return self._keys[len(self.spec.segments) - 1].t1

    def frame_times(self, n: int) -> np.ndarray:
        return np.arange(int(n), dtype=np.float64) / self.fps


def _turn(v, yaw: float, pitch: float) -> np.ndarray:
    """Unit vector ``v`` turned by ``yaw`` about the robot z axis and tilted by ``pitch`` (rad) towards/away from z."""
    v = _unit(v)
    c, s_ = np.cos(yaw), np.sin(yaw)
    v = np.array([c * v[0] - s_ * v[1], s_ * v[0] + c * v[1], v[2]])
    h = np.hypot(v[0], v[1])
    if h < 1e-9:
        return v
    el = np.arctan2(v[2], h) + pitch
    return np.array([v[0] / h * np.cos(el), v[1] / h * np.cos(el), np.sin(el)])


def _unit(v) -> np.ndarray:
    v = np.asarray(v, dtype=np.float64)
    return v / np.linalg.norm(v)


def occluder_segment(progress: float, tip_robot, T_robot_cam, *, stand_off_m: float = 0.08,
                     sweep_m: float = 0.06, half_length_m: float = 0.06):
    """A rod between the cameras and the fingertip, sweeping across the line of sight.

    The rod stands ``stand_off_m`` in front of the tip (towards the rig's centre), along the
    camera's image-vertical axis, and moves sideways (image-horizontal) from ``−sweep_m/2`` to
    ``+sweep_m/2`` as ``progress`` goes 0 → 1, so it passes over the tip in each view in turn.
    Returns the two end points (robot frame).
    """
    T = np.asarray(T_robot_cam, dtype=np.float64)
    cam = T[:3, 3]
    tip = np.asarray(tip_robot, dtype=np.float64)
    to_cam = _unit(cam - tip)
    x_img, y_img = T[:3, 0], T[:3, 1]
    c = tip + stand_off_m * to_cam + (float(progress) - 0.5) * sweep_m * x_img
    return c - half_length_m * y_img, c + half_length_m * y_img

