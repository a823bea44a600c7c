"""A right hand for synthetic sequences: palm, articulated index finger with a rounded tip, thumb,
curled middle/ring/little fingers and a wrist stub.

The index fingertip is the hemispherical cap of the distal phalanx; its centre is the fingertip
point of VisHap §3.2 (the detector fits a circle of radius r = K/z to the finger's end). The hand is
built backwards from the cap centre along the finger direction, so a trajectory only states where
the tip is, where the finger points, how much it is bent, and how the hand is rolled.

Geometry (metres) follows adult hand anthropometry; each part is a capsule or a rounded box whose
mesh is built once, and only its pose changes per frame.
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import trimesh

from vishap.sim.state import TIP_RADIUS_M

__all__ = ["HAND_PARTS", "hand_part_meshes", "hand_part_poses", "hand_frame", "skin_tone_rgb", "SKIN_TONES"]

# index finger: lengths between joint centres (distal: DIP → cap centre) and radii, m
_INDEX = [("index_proximal", 0.044, 0.0095), ("index_middle", 0.026, 0.0088), ("index_distal", 0.016, TIP_RADIUS_M)]
_PALM = (0.090, 0.082, 0.028)   # length (along the fingers), width, thickness, m
_OTHER = [0.042, 0.025, 0.018]  # segment lengths of the curled fingers, m
_OTHER_R = 0.0088
_THUMB = [("thumb_meta", 0.040, 0.0115), ("thumb_proximal", 0.032, 0.0100), ("thumb_distal", 0.024, 0.0092)]

SKIN_TONES = {  # sRGB, from light to dark
    "light": (232, 190, 172),
    "medium": (210, 160, 122),
    "tan": (176, 122, 88),
    "dark": (112, 74, 56),
}


@dataclass(frozen=True)
class _Part:
    name: str
    kind: str      # "capsule" (along local +x, from 0 to length) or "box" (centred) or "nail"
    dims: tuple


def _parts() -> list[_Part]:
    parts = [_Part(n, "capsule", (L, r)) for n, L, r in _INDEX]
    parts.append(_Part("nail", "nail", (0.011, 0.010, 0.0016)))
    parts.append(_Part("palm", "box", _PALM))
    for k in ("middle", "ring", "little"):
        for j, L in enumerate(_OTHER):
            parts.append(_Part(f"{k}_{j}", "capsule", (L, _OTHER_R * (1.0 - 0.06 * j) * (0.9 if k == "little" else 1.0))))
    parts += [_Part(n, "capsule", (L, r)) for n, L, r in _THUMB]
    parts.append(_Part("wrist", "capsule", (0.090, 0.024)))
    return parts


HAND_PARTS = _parts()


def hand_part_meshes() -> dict[str, trimesh.Trimesh]:
    """One mesh per part in its local frame (capsules along +x starting at the origin)."""
    out = {}
    for p in HAND_PARTS:
        if p.kind == "capsule":
            L, r = p.dims
            m = trimesh.creation.capsule(height=L, radius=r, count=[20, 20])
            m.apply_transform(_rot_y(math.pi / 2))  # trimesh's capsule runs along z, centred: z → x
            m.apply_translation([L / 2.0, 0.0, 0.0])  # first cap centre at the origin, second at L
        elif p.kind == "box":
            L, W, H = p.dims
            m = trimesh.creation.icosphere(subdivisions=3, radius=1.0)
            m.apply_scale([L / 2.0, W / 2.0, H / 2.0])
        else:  # nail: a thin ellipsoid lying on the back of the distal phalanx
            L, W, H = p.dims
            m = trimesh.creation.icosphere(subdivisions=2, radius=1.0)
            m.apply_scale([L / 2.0, W / 2.0, H / 2.0])
        out[p.name] = m
    return out


def _rot_y(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    T = np.eye(4)
    T[:3, :3] = [[c, 0, s], [0, 1, 0], [-s, 0, c]]
    return T


def _ry(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, 0, s], [0, 1, 0], [-s, 0, c]])


def _rz(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s, 0], [s, c, 0], [0, 0, 1]])


def _rx(a: float) -> np.ndarray:
    c, s = math.cos(a), math.sin(a)
    return np.array([[1, 0, 0], [0, c, -s], [0, s, c]])


def hand_frame(finger_dir_robot, roll: float = 0.0) -> np.ndarray:
    """Rotation of the distal phalanx: columns (x along the finger, y towards the thumb, z dorsal)."""
    d = np.asarray(finger_dir_robot, dtype=np.float64)
    d = d / np.linalg.norm(d)
    up = np.array([0.0, 0.0, 1.0])
    y = np.cross(up, d)
    if np.linalg.norm(y) < 1e-6:  # pointing straight up/down: pick any lateral axis
        y = np.array([0.0, 1.0, 0.0])
    y /= np.linalg.norm(y)
    z = np.cross(d, y)
    R = np.column_stack([d, y, z])
    return R @ _rx(roll)


def _pose(R: np.ndarray, p: np.ndarray) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p
    return T


def hand_part_poses(tip_robot, finger_dir_robot, flexion: float = 0.2, roll: float = 0.0) -> dict[str, np.ndarray]:
    """4×4 robot-frame pose of every hand part for a fingertip cap centre, direction, bend and roll.

    Bending (``flexion`` 0…1) rotates each index joint about the lateral axis (MCP 5–30°, PIP
    8–60°, DIP 4–35°): positive bends the finger palm-wards (local −z).
    """
    f = float(np.clip(flexion, 0.0, 1.0))
    th_mcp, th_pip, th_dip = (math.radians(a + (b - a) * f) for a, b in ((5, 30), (8, 60), (4, 35)))
    tip = np.asarray(tip_robot, dtype=np.float64)
    R_d = hand_frame(finger_dir_robot, roll)
    # walk back from the tip: each more proximal segment is bent less (rotate back about local y)
    R_m = R_d @ _ry(-th_dip)
    R_p = R_m @ _ry(-th_pip)
    R_palm = R_p @ _ry(-th_mcp)
    L_p, L_m, L_d = (L for _, L, _ in _INDEX)
    dip = tip - L_d * R_d[:, 0]
    pip = dip - L_m * R_m[:, 0]
    mcp = pip - L_p * R_p[:, 0]
    poses = {
        "index_distal": _pose(R_d, dip),
        "index_middle": _pose(R_m, pip),
        "index_proximal": _pose(R_p, mcp),
        "nail": _pose(R_d, tip - 0.006 * R_d[:, 0] + (TIP_RADIUS_M - 0.0006) * R_d[:, 2]),
    }
    ex, ey, ez = R_palm[:, 0], R_palm[:, 1], R_palm[:, 2]
    L, W, H = _PALM
    # the index knuckle sits at the thumb-side front corner of the palm
    palm_c = mcp - 0.46 * L * ex - (0.5 * W - 0.012) * ey - 0.2 * H * ez
    poses["palm"] = _pose(R_palm, palm_c)
    poses["wrist"] = _pose(R_palm @ _rz(math.pi), palm_c - 0.40 * L * ex - 0.05 * H * ez)
    # curled fingers: knuckles spaced towards the little-finger side, each joint strongly flexed
    for k, name in enumerate(("middle", "ring", "little")):
        base = mcp - (0.020 * (k + 1)) * ey - (0.004 + 0.006 * k) * ex - 0.002 * ez
        R = R_palm @ _ry(math.radians(65))
        p = base
        for j, Lj in enumerate(_OTHER):
            poses[f"{name}_{j}"] = _pose(R, p)
            p = p + Lj * R[:, 0]
            R = R @ _ry(math.radians(80 if j == 0 else 60))
    # thumb: from the base of the palm on the thumb side, forward and palm-wards
    R = R_palm @ _rz(math.radians(38)) @ _ry(math.radians(35)) @ _rx(math.radians(-40))
    p = palm_c - 0.28 * L * ex + 0.36 * W * ey - 0.2 * H * ez
    for (name, Lj, _), bend in zip(_THUMB, (12, 18, 0)):
        poses[name] = _pose(R, p)
        p = p + Lj * R[:, 0]
        R = R @ _ry(math.radians(bend))
    return poses


def skin_tone_rgb(tone: str | float, rng: np.random.Generator | None = None) -> tuple[float, float, float]:
    """sRGB skin colour in 0…1 for a named tone or a position 0 (light) … 1 (dark) between them
    (``real:TONE`` gives TONE's colour; how the real look draws and lights it is
    :mod:`vishap.sim.skin_look`).

    With ``rng``, a small per-sequence variation (±4 % per channel) is added.
    """
    from vishap.sim.skin_look import parse_skin_tone

    names = list(SKIN_TONES)
    _, tone = parse_skin_tone(tone)  # ``real[:TONE]``: the tone (the middle one when drawn by seed)
    if tone is None:
        tone = 0.5
    if isinstance(tone, str):
        rgb = np.array(SKIN_TONES[tone], dtype=np.float64)
    else:
        x = float(np.clip(tone, 0.0, 1.0)) * (len(names) - 1)
        i = min(int(x), len(names) - 2)
        a = x - i
        rgb = (1 - a) * np.array(SKIN_TONES[names[i]], float) + a * np.array(SKIN_TONES[names[i + 1]], float)
    if rng is not None:
        rgb = rgb * (1.0 + rng.uniform(-0.04, 0.04, size=3))
    return tuple(float(c) for c in np.clip(rgb / 255.0, 0.0, 1.0))
