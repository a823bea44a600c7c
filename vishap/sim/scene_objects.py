"""Static scene geometry: the table with its textured surface and the scene's objects.

The objects of ``datasets/synthetic/scenes/NAME.yaml`` (VisHap §2.2: wall plane P = (n, d), key
B = (p, n, w, h); HAPTEX §II: a fabric patch) are *virtual* in an encountered-type system: what
the finger really touches is the device's passive object, brought to the contact point. They are
drawn as what a user would see on the bench: the wall's patch as a thin frame, the key as its
bezel, the fabric as a frame of cloth, each with an open middle in which the device's passive
object meets the finger. Their top faces lie on the object's surface (z = −0.150 m).
"""
from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import trimesh

from vishap._core.errors import ConfigError
from vishap.sim.device import TABLE_Z_M
from vishap.world.scene import SCENES_DIR

__all__ = ["SCENES_DIR", "SCENE_NAMES", "SceneSpec", "load_scene_spec", "object_meshes", "opening_half_extent"]

SCENE_NAMES = ("wall", "button", "fabric")


@dataclass(frozen=True)
class SceneSpec:
    """What the renderer draws of a scene (derived from the validated :class:`vishap.world.scene.Scene`)."""

    name: str
    path: Path
    surface_z_m: float                         # height of the touched surface, robot frame
    centre_robot: tuple[float, float, float]
    extent_m: tuple[float, float]              # size of the object's patch along robot x, y
    passive_shape: str
    passive_size_m: tuple[float, float, float]
    kind: str
    passive_mount_offset_m: tuple[float, float, float]  # top face centre = end-effector + this
    travel_m: float = 0.0                      # key travel (button), 0 otherwise


def load_scene_spec(name_or_path: str | Path) -> SceneSpec:
    """Read a scene file (a name in ``datasets/synthetic/scenes`` or a path) for drawing.

    The file goes through the one scene schema (:func:`vishap.world.scene.load_scene`), so the
    renderer draws exactly the scene the world, the device and the servo use.
    """
    from vishap.world.scene import load_scene

    scene = load_scene(name_or_path)
    obj = scene.objects[0]
    path = Path(scene.file) if scene.file else Path(str(name_or_path))
    if not np.allclose(obj.normal, [0, 0, 1], atol=1e-6):
        raise ConfigError("the renderer draws horizontal objects only (normal [0, 0, 1])", file=path, field="objects.0.normal")
    po = scene.passive_object
    return SceneSpec(
        name=scene.name, path=path, surface_z_m=float(obj.centre[2]), centre_robot=tuple(float(v) for v in obj.centre),
        extent_m=tuple(float(2.0 * h) for h in obj.half), passive_shape=po.shape,
        passive_size_m=tuple(float(v) for v in po.size_m), kind=obj.kind,
        travel_m=float(getattr(obj.spec, "travel_m", 0.0)), passive_mount_offset_m=tuple(po.mount_offset_m),
    )


def _box(size, centre) -> trimesh.Trimesh:
    m = trimesh.creation.box(extents=size)
    m.apply_translation(centre)
    return m


def _frame(cx, cy, z_top, outer_x, outer_y, band, thick) -> trimesh.Trimesh:
    """A rectangular ring lying on the plane z = z_top (top face), open in the middle."""
    zc = z_top - thick / 2.0
    parts = [
        _box((outer_x, band, thick), (cx, cy - (outer_y - band) / 2.0, zc)),
        _box((outer_x, band, thick), (cx, cy + (outer_y - band) / 2.0, zc)),
        _box((band, outer_y - 2 * band, thick), (cx - (outer_x - band) / 2.0, cy, zc)),
        _box((band, outer_y - 2 * band, thick), (cx + (outer_x - band) / 2.0, cy, zc)),
    ]
    return trimesh.util.concatenate(parts)


# width of the drawn frame around each object's open middle, and the button bezel's margin, m
_BAND_M = {"wall": 0.008, "fabric": 0.016, "button": 0.013}
_BEZEL_MARGIN_M = 0.030
_CAP_CLEARANCE_M = 0.002  # gap between the passive keycap and the bezel's opening on each side


def _bezel_size(spec: SceneSpec) -> tuple[float, float]:
    """Outer size (x, y) of a key's bezel: the key plus the margin, and wide enough that the passive
    keycap (the scene file's ``passive_object``, wider than the virtual key) moves freely in its opening."""
    cap = [s + 2.0 * (_BAND_M["button"] + _CAP_CLEARANCE_M) for s in spec.passive_size_m[:2]]
    return tuple(max(e + _BEZEL_MARGIN_M, c) for e, c in zip(spec.extent_m, cap))


def opening_half_extent(spec: SceneSpec) -> tuple[float, float]:
    """Half size (x, y) of the open middle of the drawn object, in which the passive object meets the finger."""
    ex, ey = _bezel_size(spec) if spec.kind == "button" else spec.extent_m
    band = _BAND_M.get(spec.kind, _BAND_M["wall"])
    return ex / 2.0 - band, ey / 2.0 - band


def object_meshes(spec: SceneSpec) -> list[tuple[str, trimesh.Trimesh, tuple[float, float, float]]]:
    """(name, mesh, sRGB colour 0…1) of the scene's drawn objects, robot frame."""
    cx, cy, _ = spec.centre_robot
    z = spec.surface_z_m
    ex, ey = spec.extent_m
    out = []
    if spec.kind == "button":
        out.append(("bezel", _frame(cx, cy, z - 0.002, *_bezel_size(spec), _BAND_M["button"], 0.006), (0.30, 0.34, 0.42)))
    elif spec.kind == "fabric":
        out.append(("fabric", _frame(cx, cy, z, ex, ey, _BAND_M["fabric"], 0.002), (0.18, 0.26, 0.52)))
    else:
        out.append(("wall", _frame(cx, cy, z, ex, ey, _BAND_M["wall"], 0.003), (0.55, 0.62, 0.74)))
    # posts holding the patch above the table at its corners
    for sx in (-1, 1):
        for sy in (-1, 1):
            h = z - 0.006 - TABLE_Z_M
            px = cx + sx * (ex / 2.0 + (0.010 if spec.kind == "button" else -0.006))
            py = cy + sy * (ey / 2.0 + (0.010 if spec.kind == "button" else -0.006))
            out.append((f"post{sx}{sy}", _box((0.008, 0.008, h), (px, py, TABLE_Z_M + h / 2.0)), (0.35, 0.37, 0.40)))
    return out
