"""Scene files (VisHap §2.2 "Scene Configuration"; HAPTEX §II-B surface parameters for fabric).

A scene is data: a YAML/TOML file validated on load. Geometry is in the robot frame (metres, z up).

* wall   ``P = (n, d)``: the plane ``n·p = d``; a finite patch (``centre``, ``extent_m``) is modelled.
* button ``B = (p, n, w, h)``: top-surface centre ``position``, ``normal``, ``width_m`` × ``height_m``,
  with ``travel_m`` to the bottom board, ``trigger_depth_m`` and optional stiffness overrides.
* fabric: a patch like a wall plus ``surface`` (μ_s, μ_k and a roughness description for the
  tactile layer).
* ``passive_object``: the shape fixed to the device's end-effector that the finger touches.

Every object names an interaction mode (:mod:`vishap.world.modes`). Each object has its own frame
with z along the surface normal (VisHap §2.3); :class:`SceneObject` offers the distance, projection
and "solid" tests that :mod:`vishap.world.world` needs.
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Annotated, Literal, Union

import numpy as np
from pydantic import Field, field_validator, model_validator

from vishap._core.config import Schema, load_config
from vishap._core.errors import ConfigError
from vishap.world.modes import Mode, ModeDatabase, default_modes

__all__ = [
    "demo_passive_object",
    "SCENES_DIR",
    "PassiveObject",
    "WallSpec",
    "ButtonSpec",
    "FabricSpec",
    "FabricSurface",
    "SceneSpec",
    "SceneObject",
    "Scene",
    "load_scene",
    "surface_frame",
    "available_scenes",
]

SCENES_DIR = Path(__file__).resolve().parents[2] / "datasets" / "synthetic" / "scenes"

Positive = Annotated[float, Field(gt=0)]
Vec3 = tuple[float, float, float]


def _unit(v: Vec3) -> Vec3:
    a = np.asarray(v, dtype=float)
    n = float(np.linalg.norm(a))
    if not np.isfinite(n) or n < 1e-9:
        raise ValueError("must be a non-zero vector")
    return tuple(float(x) for x in a / n)


class PassiveObject(Schema):
    """The real object on the end-effector (VisHap §2.2: a flat metal piece, a keyboard key)."""

    shape: Literal["plate", "key", "sphere"]
    size_m: tuple[Positive, Positive, Positive]
    mass_kg: Positive
    #: the object's top face is centred at ``ee + mount_offset_m`` (robot frame): a short bracket holds
    #: it off the end-effector, whose forearm would otherwise stand where the finger touches
    mount_offset_m: Vec3

    def for_mujoco(self):
        """The :class:`vishap.robot.mjcf.PassiveObject` the plant carries (a sphere by its radius)."""
        from vishap.robot.mjcf import PassiveObject as Mj

        if self.shape == "sphere":
            return Mj("sphere", (self.size_m[0] / 2,), self.mass_kg)
        return Mj("plate", tuple(self.size_m), self.mass_kg)

    def for_renderer(self):
        """The :class:`vishap.sim.state.PassiveObject` the synthetic renderer draws."""
        from vishap.sim.state import PassiveObject as Drawn

        return Drawn(shape=self.shape, size_m=tuple(self.size_m), mount_offset_robot=tuple(self.mount_offset_m))

    @property
    def half_size_m(self) -> float:
        """Half the smaller side of the top face (where a finger pad can press)."""
        return 0.5 * min(self.size_m[:2])


class _Object(Schema):
    name: str = Field(min_length=1)
    mode: str = Field(min_length=1)
    normal: Vec3

    _unit_normal = field_validator("normal")(classmethod(lambda cls, v: _unit(v)))


class _Patch(_Object):
    offset_m: float
    centre: Vec3
    extent_m: tuple[Positive, Positive]
    thickness_m: Positive = 0.02  # how far below the surface the object is solid (for path checks)

    @model_validator(mode="after")
    def _centre_on_plane(self):
        off = float(np.dot(self.normal, self.centre)) - self.offset_m
        if abs(off) > 1e-4:
            raise ValueError(f"centre is {off * 1e3:.2f} mm off the plane n·p = offset_m; expected a point on it")
        return self


class WallSpec(_Patch):
    kind: Literal["wall"]


class FabricSurface(Schema):
    """Surface parameters: friction for the force law, texture for the tactile layer."""

    mu_static: Positive
    mu_kinetic: Positive
    texture_period_m: Positive
    roughness_rms_m: Annotated[float, Field(ge=0)]
    texture: str = "woven"  # a word for the tactile layer (woven, knit, felt, ...)

    @model_validator(mode="after")
    def _kinetic_below_static(self):
        if self.mu_kinetic > self.mu_static:
            raise ValueError(f"mu_kinetic ({self.mu_kinetic}) must not exceed mu_static ({self.mu_static})")
        return self


class FabricSpec(_Patch):
    kind: Literal["fabric"]
    surface: FabricSurface


class ButtonStiffness(Schema):
    """Optional per-button overrides of the mode's stiffnesses (N/m)."""

    k_resist_n_m: Positive | None = None
    k_click_n_m: Positive | None = None
    k_bottom_n_m: Positive | None = None


class ButtonSpec(_Object):
    kind: Literal["button"]
    position: Vec3
    width_m: Positive
    height_m: Positive
    travel_m: Positive
    trigger_depth_m: Positive
    stiffness: ButtonStiffness = Field(default_factory=ButtonStiffness)

    @model_validator(mode="after")
    def _trigger_within_travel(self):
        if self.trigger_depth_m >= self.travel_m:
            raise ValueError(
                f"trigger_depth_m ({self.trigger_depth_m}) must be smaller than travel_m ({self.travel_m})"
            )
        return self


ObjectSpec = Annotated[Union[WallSpec, ButtonSpec, FabricSpec], Field(discriminator="kind")]


class SceneSpec(Schema):
    name: str = Field(min_length=1)
    passive_object: PassiveObject
    objects: list[ObjectSpec] = Field(min_length=1)


def surface_frame(normal) -> np.ndarray:
    """Rotation ``R_robot_obj`` (columns x, y, z) with z along ``normal`` and x as close to robot x as
    possible (robot y when the normal is along x)."""
    n = np.asarray(normal, dtype=float)
    n = n / np.linalg.norm(n)
    ref = np.array([1.0, 0.0, 0.0]) if abs(n[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = ref - n * np.dot(ref, n)
    x /= np.linalg.norm(x)
    return np.column_stack([x, np.cross(n, x), n])


@dataclass
class SceneObject:
    """One object, ready for geometry: a rectangle in its surface plane and a solid slab below it."""

    name: str
    kind: str
    mode_name: str
    mode: Mode
    spec: WallSpec | ButtonSpec | FabricSpec
    centre: np.ndarray  # (3,) robot frame, on the surface
    R: np.ndarray  # (3, 3) R_robot_obj, z = outward normal
    half: np.ndarray  # (2,) half extents along the object's x, y (m)
    depth_m: float  # how deep the solid reaches below the surface (m)
    normal: np.ndarray = field(init=False)
    offset: float = field(init=False)

    def __post_init__(self):
        self.normal = self.R[:, 2].copy()
        self.offset = float(self.normal @ self.centre)

    def local(self, p_robot) -> np.ndarray:
        """Point(s) in the object frame: (x, y) along the surface, z = height above it."""
        return (np.asarray(p_robot, dtype=float) - self.centre) @ self.R

    def height(self, p_robot) -> float:
        """Signed height of ``p_robot`` above the surface plane (negative: under the surface)."""
        return float(self.normal @ np.asarray(p_robot, dtype=float) - self.offset)

    def inside_extent(self, p_robot, margin: float = 0.0) -> bool:
        q = self.local(p_robot)
        return bool(abs(q[0]) <= self.half[0] + margin and abs(q[1]) <= self.half[1] + margin)

    def project(self, p_robot) -> np.ndarray:
        """The point of the surface patch nearest to the normal projection of ``p_robot`` (clamped)."""
        q = self.local(p_robot)
        xy = np.clip(q[:2], -self.half, self.half)
        return self.centre + self.R[:, 0] * xy[0] + self.R[:, 1] * xy[1]

    def signed_distance(self, p_robot) -> float:
        """Distance to the surface patch; inside the solid slab, minus the depth under the surface."""
        q = self.local(p_robot)
        dxy = np.maximum(np.abs(q[:2]) - self.half, 0.0)
        if not dxy.any() and -self.depth_m < q[2] < 0.0:
            return float(q[2])
        return float(np.sqrt(dxy @ dxy + q[2] * q[2]))

    def segment_hits(self, a, b, *, margin: float = 0.0, top_clearance: float = 0.0,
                     bottom_clearance: float = 0.0) -> bool:
        """True when the segment a→b enters the solid slab (grown by ``margin`` sideways, reaching
        ``top_clearance`` above the surface and starting ``bottom_clearance`` above its base): the slab
        method on the box in the object frame."""
        qa, qb = self.local(a), self.local(b)
        lo = np.array([-self.half[0] - margin, -self.half[1] - margin, -self.depth_m + bottom_clearance])
        hi = np.array([self.half[0] + margin, self.half[1] + margin, top_clearance])
        d = qb - qa
        t0, t1 = 0.0, 1.0
        for k in range(3):
            if abs(d[k]) < 1e-12:
                if qa[k] <= lo[k] or qa[k] >= hi[k]:
                    return False
                continue
            ta, tb = (lo[k] - qa[k]) / d[k], (hi[k] - qa[k]) / d[k]
            if ta > tb:
                ta, tb = tb, ta
            t0, t1 = max(t0, ta), min(t1, tb)
            if t0 >= t1:
                return False
        return True


@dataclass
class Scene:
    """A validated scene: its objects (in file order), the passive object and where it came from."""

    name: str
    passive_object: PassiveObject
    objects: list[SceneObject]
    spec: SceneSpec
    file: str | None = None

    def object(self, name: str) -> SceneObject:
        for o in self.objects:
            if o.name == name:
                return o
        raise KeyError(f"scene {self.name!r} has no object {name!r}; it has {[o.name for o in self.objects]}")

    @property
    def kinds(self) -> set[str]:
        return {o.kind for o in self.objects}

    @classmethod
    def from_spec(cls, spec: SceneSpec, *, modes: ModeDatabase | None = None, file=None) -> "Scene":
        modes = modes or default_modes()
        seen: set[str] = set()
        objs = []
        for i, s in enumerate(spec.objects):
            if s.name in seen:
                raise ConfigError(f"duplicate object name {s.name!r}", file=file, field=f"objects.{i}.name")
            seen.add(s.name)
            mode = modes.get(s.mode, kind=s.kind, file=file, field=f"objects.{i}.mode")
            R = surface_frame(s.normal)
            if isinstance(s, ButtonSpec):
                centre, half = np.array(s.position), np.array([s.width_m, s.height_m]) / 2
                depth = s.travel_m
            else:
                centre, half, depth = np.array(s.centre), np.array(s.extent_m) / 2, s.thickness_m
            objs.append(SceneObject(s.name, s.kind, s.mode, mode, s, centre, R, half, float(depth)))
        return cls(spec.name, spec.passive_object, objs, spec, None if file is None else str(file))


def available_scenes() -> list[str]:
    return sorted(p.stem for p in SCENES_DIR.glob("*.yaml"))


def load_scene(name_or_path: str | os.PathLike, *, modes: ModeDatabase | None = None) -> Scene:
    """Load a scene by name (``datasets/synthetic/scenes/NAME.yaml``) or by path, validated."""
    p = Path(name_or_path)
    if not p.suffix and not p.is_file():  # a folder named like a scene (a run's --out) is not a scene file
        p = SCENES_DIR / f"{name_or_path}.yaml"
        if not p.is_file():
            raise ConfigError(f"unknown scene {str(name_or_path)!r}; expected a file or one of {available_scenes()}",
                              field="scene")
    try:
        spec = load_config(p, SceneSpec)
    except ConfigError as exc:
        raise _without_tags(exc, ("wall", "button", "fabric")) from None
    return Scene.from_spec(spec, modes=modes, file=p)


def demo_passive_object():
    """The plant's passive object (:class:`vishap.robot.mjcf.PassiveObject`) as the demos' scene files
    give it — the wall scene's plate — for the device-only benches and tests that have no scene."""
    return load_scene("wall").passive_object.for_mujoco()


def _without_tags(exc: ConfigError, tags) -> ConfigError:
    """Drop pydantic's union tags from a field path (``objects.0.wall.normal`` -> ``objects.0.normal``)."""
    if exc.field is None:
        return exc
    parts = exc.field.split(".")
    kept = [x for i, x in enumerate(parts) if not (x in tags and i > 0 and (parts[i - 1].isdigit() or parts[i - 1] == "law"))]
    return type(exc)(exc.reason, file=exc.file, field=".".join(kept))
