"""Ray-casting flat rectangles through a calibrated camera: the drawing primitive of the virtual objects.

Every virtual object of a scene (VisHap §2.2: a wall patch, a key in its bezel, a fabric patch) is a
few flat rectangles (a box's faces, a frame's top with its hole). For each pixel in a face's image
box, the pixel's undistorted viewing ray (:meth:`ViewCamera.rays`) is intersected with the face's
plane: this is exact under lens distortion, gives the depth for hiding one face behind another,
and gives the face coordinates (a, b) where the material is looked up. Back faces are skipped.

:func:`shade` is Blinn–Phong with a directional key light, a fill light at the camera and ambient
light; normals may be perturbed per pixel (the fabric's dent).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from vishap.ar.camera import ViewCamera

__all__ = ["Face", "Hits", "box_faces", "frame_faces", "cast", "Lighting", "shade"]


@dataclass(frozen=True)
class Face:
    """A rectangle: centre ``o``, in-plane unit axes ``u``, ``v``, half sizes ``half``, outward
    normal ``n`` (robot frame, metres); ``hole`` cuts a centred rectangle of those half sizes out."""

    o: np.ndarray
    u: np.ndarray
    v: np.ndarray
    half: tuple[float, float]
    n: np.ndarray
    material: str
    hole: tuple[float, float] | None = None

    def corners(self) -> np.ndarray:
        hu, hv = self.half
        return np.array([self.o + su * hu * self.u + sv * hv * self.v for su, sv in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def box_faces(centre, R, half_xyz, material: str, *, top_material: str | None = None, skip_bottom: bool = True) -> list[Face]:
    """The faces of a box: centre and axes ``R`` (columns x, y, z; z up the object's normal), half sizes."""
    c = np.asarray(centre, float)
    x, y, z = R[:, 0], R[:, 1], R[:, 2]
    hx, hy, hz = half_xyz
    faces = [Face(c + z * hz, x, y, (hx, hy), z, top_material or material)]
    if not skip_bottom:
        faces.append(Face(c - z * hz, x, -y, (hx, hy), -z, material))
    for s in (-1.0, 1.0):
        faces.append(Face(c + s * x * hx, y, z, (hy, hz), s * x, material))
        faces.append(Face(c + s * y * hy, x, z, (hx, hz), s * y, material))
    return faces


def frame_faces(centre, R, outer_half, inner_half, height: float, material: str, inner_material: str) -> list[Face]:
    """A rectangular frame whose top face (centred at ``centre``) has a hole, with outer sides and the
    hole's inner walls ``height`` deep."""
    c = np.asarray(centre, float)
    x, y, z = R[:, 0], R[:, 1], R[:, 2]
    (ox, oy), (ix, iy) = outer_half, inner_half
    h2 = 0.5 * height
    faces = [Face(c, x, y, (ox, oy), z, material, hole=(ix, iy))]
    for s in (-1.0, 1.0):
        faces.append(Face(c + s * x * ox - z * h2, y, z, (oy, h2), s * x, material))
        faces.append(Face(c + s * y * oy - z * h2, x, z, (ox, h2), s * y, material))
        faces.append(Face(c + s * x * ix - z * h2, y, z, (iy, h2), -s * x, inner_material))
        faces.append(Face(c + s * y * iy - z * h2, x, z, (ix, h2), -s * y, inner_material))
    return faces


@dataclass
class Hits:
    """Pixels (flat indices into the image) where faces were hit, nearest face first."""

    index: np.ndarray        # (N,) flat pixel index
    depth: np.ndarray        # (N,) z in the camera frame, m
    face: np.ndarray         # (N,) index into the face list
    a: np.ndarray            # (N,) face coordinates along u, v, m
    b: np.ndarray
    p_cam: np.ndarray        # (N, 3) hit points, camera frame
    ray: np.ndarray          # (N, 3) viewing rays


def _bbox(camera: ViewCamera, pts_robot) -> tuple[int, int, int, int] | None:
    uv = camera.project_robot(pts_robot)
    if not np.all(np.isfinite(uv)):
        return None
    x0, y0 = np.floor(uv.min(0)).astype(int) - 2
    x1, y1 = np.ceil(uv.max(0)).astype(int) + 3
    x0, y0 = max(0, x0), max(0, y0)
    x1, y1 = min(camera.width, x1), min(camera.height, y1)
    if x1 <= x0 or y1 <= y0:
        return None
    return x0, y0, x1, y1


def cast(camera: ViewCamera, faces: list[Face]) -> Hits:
    """Ray-cast ``faces``; each pixel keeps its nearest front-facing hit."""
    rays = camera.rays()
    R, t = camera.T_cam_robot[:3, :3], camera.T_cam_robot[:3, 3]
    W = camera.width
    idx_all, dep_all, face_all, a_all, b_all = [], [], [], [], []
    for k, f in enumerate(faces):
        box = _bbox(camera, f.corners())
        if box is None:
            continue
        x0, y0, x1, y1 = box
        r = rays[y0:y1, x0:x1].reshape(-1, 3).astype(np.float64)
        o, u, v, n = R @ f.o + t, R @ f.u, R @ f.v, R @ f.n
        denom = r @ n
        front = denom < -1e-9
        tt = np.where(front, (n @ o) / np.where(front, denom, -1.0), -1.0)
        p = r * tt[:, None]
        a = (p - o) @ u
        b = (p - o) @ v
        inside = front & (tt > 0) & (np.abs(a) <= f.half[0]) & (np.abs(b) <= f.half[1])
        if f.hole is not None:
            inside &= ~((np.abs(a) < f.hole[0]) & (np.abs(b) < f.hole[1]))
        sel = np.flatnonzero(inside)
        if sel.size == 0:
            continue
        yy, xx = np.divmod(sel, x1 - x0)
        idx_all.append((yy + y0) * W + xx + x0)
        dep_all.append(tt[sel])
        face_all.append(np.full(sel.size, k))
        a_all.append(a[sel])
        b_all.append(b[sel])
    if not idx_all:
        e = np.zeros(0)
        return Hits(e.astype(np.int64), e, e.astype(np.int64), e, e, np.zeros((0, 3)), np.zeros((0, 3)))
    idx, dep, fid = np.concatenate(idx_all), np.concatenate(dep_all), np.concatenate(face_all)
    a, b = np.concatenate(a_all), np.concatenate(b_all)
    order = np.lexsort((dep, idx))                         # per pixel, nearest first
    idx, dep, fid, a, b = idx[order], dep[order], fid[order], a[order], b[order]
    first = np.ones(idx.size, bool)
    first[1:] = idx[1:] != idx[:-1]
    idx, dep, fid, a, b = idx[first], dep[first], fid[first], a[first], b[first]
    ray = rays.reshape(-1, 3)[idx].astype(np.float64)
    return Hits(idx, dep, fid, a, b, ray * dep[:, None], ray)


@dataclass(frozen=True)
class Lighting:
    """Light of the virtual objects: a directional key light (unit direction *towards* the light,
    robot frame), a fill light at the camera, ambient light; Blinn–Phong highlights."""

    key_dir_robot: tuple[float, float, float] = (0.45, 0.25, 0.86)
    key: float = 0.70
    fill: float = 0.30
    ambient: float = 0.25


def shade(albedo: np.ndarray, normal_cam: np.ndarray, ray: np.ndarray, key_dir_cam: np.ndarray, lighting: Lighting,
          *, specular: float = 0.1, shininess: float = 30.0) -> np.ndarray:
    """(N, 3) linear colour of points with ``albedo`` (N, 3) and unit normals (N, 3), camera frame."""
    view = -ray / np.linalg.norm(ray, axis=1, keepdims=True)
    ndl = np.clip(normal_cam @ key_dir_cam, 0.0, None)
    ndv = np.clip(np.sum(normal_cam * view, axis=1), 0.0, None)
    h = view + key_dir_cam
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    ndh = np.clip(np.sum(normal_cam * h, axis=1), 0.0, None)
    diffuse = lighting.ambient + lighting.key * ndl + lighting.fill * ndv
    spec = specular * lighting.key * ndh ** shininess * (ndl > 0)
    return albedo * diffuse[:, None] + spec[:, None]
