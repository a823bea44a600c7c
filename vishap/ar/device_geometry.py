"""What the haptic device occupies in space, from its joint state: the parts the augmented view deletes.

The arm's kinematics are the MuJoCo model's own (:mod:`vishap.robot.kinematics` with the
:class:`~vishap.robot.params.PhantomParams` that :mod:`vishap.robot.mjcf` is built from): base,
shoulder, elbow and end-effector follow from the joint angles ``q``. Around that skeleton the device
has a visible *envelope*: round links and joint housings, a base block, the passive object on its
bracket (VisHap §2.1). The envelope's sizes are those of the device as the synthetic renderer draws
it (:mod:`vishap.sim.renderer`: 7 mm links, 11 mm joints, a 16 × 14 × 2 cm base); the MJCF capsules
are thinner because they only carry the dynamics, not the look.

Every part is convex (a cylinder, a sphere, a box), so its image is the convex hull of a few
projected points: :func:`part_hull_points_cam` gives those points for a part in the camera frame,
circumscribed (the polygon contains the exact outline).

Known devices are listed by name in :data:`DEVICE_GEOMETRIES` (the name of the MuJoCo model,
``phantom_premium_1_0``); :func:`device_geometry` looks one up and fails with a
:class:`~vishap._core.errors.ConfigError` naming the known ones.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace
from functools import lru_cache

import numpy as np

from vishap._core.errors import ConfigError
from vishap.robot import kinematics
from vishap.robot.params import DEFAULT, PhantomParams
from vishap.sim.device import TABLE_Z_M

__all__ = ["Part", "DeviceGeometry", "DEVICE_GEOMETRIES", "device_geometry", "part_hull_points_cam"]


@dataclass(frozen=True)
class Part:
    """One convex part in the robot frame: ``cylinder`` (a, b, radius), ``sphere`` (a = centre,
    radius) or ``box`` (a = centre, ``extent`` along the robot axes)."""

    kind: str
    a: np.ndarray
    b: np.ndarray | None = None
    radius: float = 0.0
    extent: tuple[float, float, float] | None = None


@dataclass(frozen=True)
class DeviceGeometry:
    """The device's envelope as a function of its joint angles (robot frame, metres).

    ``stand_z_m``: height of the surface the base stands on (a column rises from there to the
    kinematic base point, and the base block rests on it); None puts the base block directly under
    the kinematic base point. ``passive_size_m`` (x, y, thickness) and ``mount_offset_robot`` place
    the passive object's top face at ``ee + mount_offset_robot`` on a bracket from the end-effector
    (as :class:`vishap.sim.state.PassiveObject`); ``passive_size_m=None``: no passive object.
    """

    name: str
    params: PhantomParams = DEFAULT
    link_radius_m: float = 0.007
    joint_radius_m: float = 0.011
    base_extent_m: tuple[float, float, float] = (0.16, 0.14, 0.02)
    base_lift_m: float = 0.010            # the base block's centre above its foot point
    stand_z_m: float | None = TABLE_Z_M
    passive_size_m: tuple[float, float, float] | None = None
    mount_offset_robot: tuple[float, float, float] = (0.0, 0.0, 0.0)  # the passive object's, from the scene file
    bracket_section_m: tuple[float, float] = (0.010, 0.004)   # width × thickness of the bracket bar

    def with_passive(self, size_m, mount_offset_robot=None) -> DeviceGeometry:
        """The same device carrying a passive object of ``size_m`` (x, y, thickness)."""
        size = tuple(float(v) for v in size_m)
        if len(size) != 3 or not all(v > 0 and math.isfinite(v) for v in size):
            raise ConfigError(f"expected 3 positive sizes (x, y, thickness) in metres, got {size_m!r}",
                              field="passive_size_m")
        if mount_offset_robot is None:  # the scene file holds it (world.scene.PassiveObject.mount_offset_m)
            raise ConfigError("a passive object needs its mount offset (the scene file's passive_object.mount_offset_m)",
                              field="mount_offset_robot")
        return replace(self, passive_size_m=size, mount_offset_robot=tuple(float(v) for v in mount_offset_robot))

    def link_points(self, q) -> np.ndarray:
        """(K, 3) skeleton base → end-effector: the stand's foot (if any), then
        :func:`vishap.robot.kinematics.link_points` of ``q``."""
        pts = kinematics.link_points(np.asarray(q, dtype=np.float64), self.params)
        if self.stand_z_m is None:
            return pts
        return np.vstack([[pts[0, 0], pts[0, 1], self.stand_z_m], pts])

    def parts(self, q) -> list[Part]:
        """The convex parts at joint angles ``q`` (rad): links, joint housings, base block, bracket
        and passive object."""
        pts = self.link_points(q)
        out = [Part("cylinder", pts[i], pts[i + 1], self.link_radius_m) for i in range(len(pts) - 1)]
        out += [Part("sphere", p, radius=self.joint_radius_m) for p in pts[1:]]
        out.append(Part("box", pts[0] + np.array([0.0, 0.0, self.base_lift_m]), extent=tuple(self.base_extent_m)))
        if self.passive_size_m is not None:
            ee = pts[-1]
            sx, sy, sz = self.passive_size_m
            top = ee + np.asarray(self.mount_offset_robot, dtype=np.float64)
            out.append(Part("box", top - np.array([0.0, 0.0, sz / 2.0]), extent=(sx, sy, sz)))
            if np.linalg.norm(self.mount_offset_robot) > 0:
                w, t = self.bracket_section_m
                end = top - np.array([0.0, 0.0, sz + 0.002])
                out.append(Part("cylinder", ee, end, 0.5 * math.hypot(w, t)))
        return out


#: Devices whose envelope is known, by the name of their MuJoCo model.
DEVICE_GEOMETRIES: dict[str, DeviceGeometry] = {
    "phantom_premium_1_0": DeviceGeometry("phantom_premium_1_0"),
}


def device_geometry(name: str, *, passive_size_m=None, mount_offset_robot=None, stand_z_m="default") -> DeviceGeometry:
    """The envelope of the device called ``name`` (see :data:`DEVICE_GEOMETRIES`), optionally with its
    passive object and stand height; an unknown name raises :class:`ConfigError`."""
    if name not in DEVICE_GEOMETRIES:
        raise ConfigError(f"unknown device geometry {name!r}; known: {sorted(DEVICE_GEOMETRIES)}", field="device")
    g = DEVICE_GEOMETRIES[name]
    if stand_z_m != "default":
        g = replace(g, stand_z_m=None if stand_z_m is None else float(stand_z_m))
    if passive_size_m is not None:
        g = g.with_passive(passive_size_m, mount_offset_robot)
    return g


@lru_cache(maxsize=8)
def _unit_polygon(n: int) -> tuple[np.ndarray, np.ndarray]:
    a = np.arange(n) * (2.0 * math.pi / n)
    r = 1.0 / math.cos(math.pi / n)  # circumscribed: the polygon contains the circle
    return (r * np.cos(a))[:, None], (r * np.sin(a))[:, None]


def _circle(centre, u, v, radius, n):
    """``n`` points of the polygon circumscribed about a circle (centre, in-plane unit axes u, v)."""
    c, s = _unit_polygon(n)
    return centre + radius * (c * u + s * v)


def _perp(d):
    d = d / np.linalg.norm(d)
    h = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(d, h)
    u /= np.linalg.norm(u)
    return u, np.cross(d, u)


def part_hull_points_cam(part: Part, T_cam_robot: np.ndarray, *, n: int = 16) -> list[np.ndarray]:
    """Points (camera frame) whose projections' convex hull contains the part's image.

    A cylinder gives its two end discs; a sphere the circle where the cone of sight touches it;
    a box its eight corners. A long cylinder is cut into pieces (one hull each) so that lens
    distortion, which bends straight edges, is followed.
    """
    R, t = T_cam_robot[:3, :3], T_cam_robot[:3, 3]
    if part.kind == "box":
        e = 0.5 * np.asarray(part.extent, dtype=np.float64)
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * e + part.a
        return [corners @ R.T + t]
    if part.kind == "sphere":
        c = R @ part.a + t
        d = float(np.linalg.norm(c))
        r = part.radius
        if d <= r * 1.001:
            return []
        u, v = _perp(c)
        return [_circle(c * (1.0 - r * r / (d * d)), u, v, r * math.sqrt(d * d - r * r) / d, n)]
    a, b = R @ part.a + t, R @ part.b + t
    axis = b - a
    length = float(np.linalg.norm(axis))
    if length < 1e-9:
        u, v = np.eye(3)[0], np.eye(3)[1]
        return [np.vstack([_circle(a, u, v, part.radius, n), a + np.array([0, 0, part.radius])])]
    u, v = _perp(axis)
    pieces = max(1, int(math.ceil(length / 0.05)))
    ends = [a + axis * (k / pieces) for k in range(pieces + 1)]
    rings = [_circle(p, u, v, part.radius, n) for p in ends]
    return [np.vstack([rings[k], rings[k + 1]]) for k in range(pieces)]
