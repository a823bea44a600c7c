"""The scene's virtual objects drawn into one camera image, lit and registered through the calibration.

What each object of a :class:`vishap.world.scene.Scene` looks like (VisHap §2.2; HAPTEX §II for the
fabric), with no more geometry than the scene needs:

* **wall** — a slab: its top face is the patch ``(centre, extent)`` on the plane ``(n, d)``, with a
  faint paint grain;
* **button** — a key cap ``w × h`` in a bezel whose top lies 2 mm under the cap's rest surface; the
  cap sinks by the current travel (``0 … travel_m``) into the bezel;
* **fabric** — a thin patch with a woven texture (the scene's ``texture_period_m``, filtered to the
  pixel footprint); under the finger it dents as a Gaussian height field whose depth is the
  contact depth: the dent shows through its shading (normals of the height field).

Static objects are ray-cast once (:func:`vishap.ar.faces.cast`); a button is cast again only when
its travel changes, and a dent re-lights only the fabric pixels near the contact.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import cv2
import numpy as np

from vishap.ar.camera import ViewCamera
from vishap.ar.faces import Face, Hits, Lighting, box_faces, cast, frame_faces, shade

__all__ = ["Material", "MATERIALS", "ObjectLayer", "object_corners_robot", "BEZEL_MARGIN_M", "BEZEL_DROP_M"]

BEZEL_MARGIN_M = 0.015   # bezel beyond the key on each side, m
BEZEL_DROP_M = 0.002     # bezel top below the key's rest surface, m
_KEY_GAP_M = 0.0008      # clearance between key and bezel, m
_BEZEL_HEIGHT_M = 0.008
_SLAB_MAX_M = 0.010      # thickest slab drawn for a patch, m


def _srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


def _linear_to_srgb8(c: np.ndarray) -> np.ndarray:
    c = np.clip(c, 0.0, 1.0)
    s = np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)
    return np.round(255.0 * s).astype(np.uint8)


@dataclass(frozen=True)
class Material:
    """sRGB base colour (0…1), highlight strength and sharpness."""

    rgb: tuple[float, float, float]
    specular: float = 0.1
    shininess: float = 30.0


MATERIALS = {
    "wall": Material((0.66, 0.72, 0.82), 0.12, 24.0),
    "wall_side": Material((0.50, 0.55, 0.63), 0.05, 12.0),
    "fabric": Material((0.20, 0.30, 0.62), 0.02, 6.0),
    "fabric_side": Material((0.14, 0.20, 0.42), 0.01, 6.0),
    "bezel": Material((0.24, 0.26, 0.31), 0.10, 20.0),
    "bezel_inner": Material((0.08, 0.08, 0.09), 0.02, 8.0),
    "key": Material((0.88, 0.87, 0.83), 0.25, 40.0),
    "key_side": Material((0.70, 0.69, 0.66), 0.10, 20.0),
}


def object_corners_robot(obj) -> np.ndarray:
    """(4, 3) outer corners of an object's top face as drawn (a button's: its bezel), robot frame."""
    R = obj.R
    half = np.asarray(obj.half, float)
    centre = np.asarray(obj.centre, float)
    if obj.kind == "button":
        half = half + BEZEL_MARGIN_M
        centre = centre - R[:, 2] * BEZEL_DROP_M
    return np.array([centre + sx * half[0] * R[:, 0] + sy * half[1] * R[:, 1] for sx, sy in ((-1, -1), (1, -1), (1, 1), (-1, 1))])


def _weave(period_m: float, extent_m, texel_m: float, footprint_m: float, seed: int) -> np.ndarray:
    """(H, W) float32 brightness of a plain weave, filtered to the pixel footprint."""
    rng = np.random.default_rng([seed, 0xFAB])
    nx, ny = (int(np.ceil(e / texel_m)) + 1 for e in extent_m)
    a = np.arange(nx) * texel_m
    b = np.arange(ny) * texel_m
    warp = 0.5 + 0.5 * np.cos(2 * np.pi * a / period_m)
    weft = 0.5 + 0.5 * np.cos(2 * np.pi * b / period_m)
    over = (np.floor(a / period_m)[None, :] + np.floor(b / period_m)[:, None]) % 2
    tex = np.where(over > 0, warp[None, :], weft[:, None])
    # yarn slubs: each thread a little lighter or darker
    thread_a = rng.normal(0.0, 0.06, int(nx * texel_m / period_m) + 2)[(a / period_m).astype(int)]
    thread_b = rng.normal(0.0, 0.06, int(ny * texel_m / period_m) + 2)[(b / period_m).astype(int)]
    tex = 0.78 + 0.22 * tex + thread_a[None, :] + thread_b[:, None]
    sigma = 0.5 * footprint_m / texel_m
    if sigma > 0.3:
        tex = cv2.GaussianBlur(tex.astype(np.float32), (0, 0), sigma)
    return tex.astype(np.float32)


def _grain(extent_m, texel_m: float, seed: int) -> np.ndarray:
    rng = np.random.default_rng([seed, 0x9A1])
    nx, ny = (int(np.ceil(e / texel_m)) + 1 for e in extent_m)
    g = cv2.GaussianBlur(rng.normal(0.0, 1.0, (ny, nx)).astype(np.float32), (0, 0), 2.0)
    return (1.0 + 0.05 * g / max(1e-6, float(g.std()))).astype(np.float32)


def _sample(tex: np.ndarray, a: np.ndarray, b: np.ndarray, half, texel_m: float) -> np.ndarray:
    """Bilinear look-up of a texture laid over a face (a, b in metres from the face centre)."""
    mx = ((a + half[0]) / texel_m).astype(np.float32).reshape(1, -1)
    my = ((b + half[1]) / texel_m).astype(np.float32).reshape(1, -1)
    return cv2.remap(tex, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE).ravel()


@dataclass
class _Raster:
    hits: Hits
    colour: np.ndarray                         # (N, 3) linear colour
    bgr: np.ndarray                            # (N, 3) uint8 BGR of ``colour``
    albedo: np.ndarray | None = None           # (N, 3), kept for re-lighting a dent
    top: np.ndarray | None = None              # (N,) bool: on the fabric's top face


@dataclass
class _Object:
    obj: object
    faces: list[Face]
    raster: _Raster | None = None
    travel: float | None = None
    textures: dict = field(default_factory=dict)


class ObjectLayer:
    """The virtual objects of ``scene`` as seen by ``camera``; :meth:`draw` gives a colour layer and
    its coverage for the current contact."""

    def __init__(self, scene, camera: ViewCamera, *, lighting: Lighting = Lighting(), dent_sigma_m: float = 0.008,
                 seed: int = 0):
        self.camera = camera
        self.lighting = lighting
        self.dent_sigma_m = float(dent_sigma_m)
        self.seed = int(seed)
        R = camera.T_cam_robot[:3, :3]
        key = np.asarray(lighting.key_dir_robot, float)
        self._key_cam = R @ (key / np.linalg.norm(key))
        self.objects = [self._build(o) for o in scene.objects]
        self._footprint = {}

    # ------------------------------------------------------------------ geometry
    def _build(self, obj) -> _Object:
        R = np.asarray(obj.R, float)
        z = R[:, 2]
        c = np.asarray(obj.centre, float)
        hx, hy = (float(v) for v in obj.half)
        if obj.kind == "button":
            bezel_c = c - z * BEZEL_DROP_M
            faces = frame_faces(bezel_c, R, (hx + BEZEL_MARGIN_M, hy + BEZEL_MARGIN_M),
                                (hx + _KEY_GAP_M, hy + _KEY_GAP_M), _BEZEL_HEIGHT_M, "bezel", "bezel_inner")
            return _Object(obj, faces)
        th = min(float(obj.depth_m), _SLAB_MAX_M)
        kind = "fabric" if obj.kind == "fabric" else "wall"
        faces = box_faces(c - z * th / 2, R, (hx, hy, th / 2), f"{kind}_side", top_material=kind)
        return _Object(obj, faces)

    def _key_faces(self, o: _Object, travel: float) -> list[Face]:
        obj = o.obj
        R = np.asarray(obj.R, float)
        z = R[:, 2]
        hx, hy = (float(v) for v in obj.half)
        top = np.asarray(obj.centre, float) - z * travel
        bottom = np.asarray(obj.centre, float) - z * (float(obj.spec.travel_m) + _BEZEL_HEIGHT_M)
        h = float(np.dot(top - bottom, z))
        return box_faces((top + bottom) / 2, R, (hx, hy, h / 2), "key_side", top_material="key")

    # ------------------------------------------------------------------ shading
    def _albedo(self, o: _Object, faces: list[Face], hits: Hits) -> np.ndarray:
        alb = np.empty((hits.index.size, 3))
        names = np.array([faces[k].material for k in hits.face])
        for name in np.unique(names):
            sel = names == name
            alb[sel] = _srgb_to_linear(MATERIALS[name].rgb)
            if name in ("wall", "fabric"):
                f = faces[int(hits.face[sel][0])]
                alb[sel] *= self._texture(o, name, f)(hits.a[sel], hits.b[sel])[:, None]
        return alb

    def _texture(self, o: _Object, name: str, f: Face):
        if name not in o.textures:
            texel = 0.0003
            extent = (2 * f.half[0], 2 * f.half[1])
            if name == "fabric":
                footprint = self._pixel_footprint_m(f.o)
                period = float(o.obj.spec.surface.texture_period_m)
                tex = _weave(period, extent, texel, footprint, self.seed)
            else:
                texel = 0.001
                tex = _grain(extent, texel, self.seed)
            o.textures[name] = (tex, texel)
        tex, texel = o.textures[name]
        return lambda a, b: _sample(tex, a, b, f.half, texel)

    def _pixel_footprint_m(self, p_robot) -> float:
        d = float(np.linalg.norm(self.camera.to_cam(p_robot)))
        return d / float(self.camera.rig.K_left[0, 0])

    def _light(self, faces, hits: Hits, albedo: np.ndarray, normals_cam: np.ndarray | None = None) -> np.ndarray:
        R = self.camera.T_cam_robot[:3, :3]
        n_cam = normals_cam if normals_cam is not None else np.array([R @ f.n for f in faces])[hits.face]
        out = np.empty_like(albedo)
        mats = np.array([faces[k].material for k in hits.face])
        for name in np.unique(mats):
            sel = mats == name
            m = MATERIALS[name]
            out[sel] = shade(albedo[sel], n_cam[sel], hits.ray[sel], self._key_cam, self.lighting,
                             specular=m.specular, shininess=m.shininess)
        return out

    def _raster(self, o: _Object, faces: list[Face]) -> _Raster:
        hits = cast(self.camera, faces)
        albedo = self._albedo(o, faces, hits)
        top = np.array([faces[k].material == "fabric" for k in hits.face], bool)
        colour = self._light(faces, hits, albedo)
        return _Raster(hits, colour, _linear_to_srgb8(colour)[:, ::-1], albedo, top)

    # ------------------------------------------------------------------ per frame
    def draw(self, *, travel: dict | None = None, dent: tuple | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(BGR ``uint8`` layer, coverage ``uint8`` 0/255) of every object.

        ``travel``: {button name: how far the key is pressed, m} (clipped to 0 … travel_m);
        ``dent``: (fabric name, contact point robot (3,), depth m) or None.
        """
        w, h = self.camera.size
        idx_all, dep_all, col_all = [], [], []
        for o in self.objects:
            faces = o.faces
            if o.obj.kind == "button":
                tr = float(np.clip((travel or {}).get(o.obj.name, 0.0), 0.0, float(o.obj.spec.travel_m)))
                if o.raster is None or o.travel is None or abs(tr - o.travel) > 1e-5:
                    faces = o.faces + self._key_faces(o, tr)
                    o.raster, o.travel = self._raster(o, faces), tr
            elif o.raster is None:
                o.raster = self._raster(o, faces)
            r = o.raster
            c = r.bgr
            if o.obj.kind == "fabric" and dent is not None and dent[0] == o.obj.name and dent[2] > 0:
                c = self._dented(o, r, np.asarray(dent[1], float), float(dent[2]))
            idx_all.append(r.hits.index)
            dep_all.append(r.hits.depth)
            col_all.append(c)
        layer = np.zeros((h * w, 3), np.uint8)
        cover = np.zeros(h * w, np.uint8)
        if idx_all:
            idx, dep, col = np.concatenate(idx_all), np.concatenate(dep_all), np.concatenate(col_all)
            if len(idx_all) > 1:  # an object in front of another wins the pixel
                order = np.lexsort((dep, idx))
                idx, col = idx[order], col[order]
                first = np.ones(idx.size, bool)
                first[1:] = idx[1:] != idx[:-1]
                idx, col = idx[first], col[first]
            layer[idx] = col
            cover[idx] = 255
        return layer.reshape(h, w, 3), cover.reshape(h, w)

    def _dented(self, o: _Object, r: _Raster, contact_robot: np.ndarray, depth_m: float) -> np.ndarray:
        """BGR colours with the fabric's top re-lit by the normals of a Gaussian dent at the contact."""
        obj = o.obj
        q = obj.local(contact_robot)
        s = self.dent_sigma_m
        near = r.top & ((r.hits.a - q[0]) ** 2 + (r.hits.b - q[1]) ** 2 < (3 * s) ** 2)
        if not near.any():
            return r.bgr
        da, db = r.hits.a[near] - q[0], r.hits.b[near] - q[1]
        g = depth_m * np.exp(-(da * da + db * db) / (2 * s * s)) / (s * s)
        # h = −depth·exp(−ρ²/2σ²): ∂h/∂a = a·g, normal ∝ (−∂h/∂a, −∂h/∂b, 1) in the object frame
        n_obj = np.stack([-da * g, -db * g, np.ones_like(g)], 1)
        n_obj /= np.linalg.norm(n_obj, axis=1, keepdims=True)
        n_cam = n_obj @ (self.camera.T_cam_robot[:3, :3] @ np.asarray(obj.R, float)).T
        faces = o.faces
        sub = Hits(r.hits.index[near], r.hits.depth[near], r.hits.face[near], r.hits.a[near], r.hits.b[near],
                   r.hits.p_cam[near], r.hits.ray[near])
        out = r.bgr.copy()
        out[near] = _linear_to_srgb8(self._light(faces, sub, r.albedo[near], n_cam))[:, ::-1]
        return out
