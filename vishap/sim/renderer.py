"""Offscreen stereo rendering of a hand, the haptic device and a scene (pyrender, EGL on the CPU).

``StereoRenderer(rig, T_robot_cam, scene).render(state)`` draws both cameras of a
:class:`~vishap.vision.rig.StereoRig` and returns, from the same scene and the same pass, colour
(BGR ``uint8``), per-pixel labels (0 background, 1 skin, 2 device and its passive object, 3 scene
object) and depth (``float32`` metres along the optical axis, 0 where nothing was hit).

Labels cost no second colour pass: every material carries its label in its alpha
(``label × 64 / 255``) and the colour pass is read back as RGBA. That is exact without multisample
anti-aliasing (the default; the camera's defocus softens edges instead). With ``msaa > 0`` the
alpha of edge pixels would mix labels, so a flat segmentation pass without MSAA is made instead.

Cameras with distortion or skew are rendered as ideal pinhole cameras on a larger canvas and
warped into the real camera with ``cv2.remap`` (nearest neighbour for labels and depth), so that
the ground truth ``rig.project(p_cam)`` and the pixels agree for any calibrated rig.
"""
from __future__ import annotations

import math
from dataclasses import replace

import cv2
import numpy as np
import trimesh

from vishap._core.check import as_transform
from vishap._core.errors import ConfigError
from vishap.sim import hand as _hand
from vishap.sim._pyrender import import_pyrender, set_msaa
from vishap.sim.camera_placement import look_at
from vishap.sim.camera_effects import CameraEffects, EffectsState, apply_effects
from vishap.sim.scene_objects import SceneSpec, load_scene_spec, object_meshes
from vishap.sim.state import FrameState, PassiveObject, RenderedPair
from vishap.sim.skin_look import mottling_colours, skin_look
from vishap.sim.textures import choose_background, is_photo, make_texture, texture_tile_m
from vishap.vision.rig import StereoRig

__all__ = ["StereoRenderer", "FrameState", "RenderedPair", "PassiveObject"]

_GL_FROM_CV = np.diag([1.0, -1.0, -1.0, 1.0])  # OpenCV camera axes → OpenGL camera axes
_MAX_LINKS = 8
_ALPHA_STEP = 64


def _srgb_to_linear(c):
    c = np.asarray(c, dtype=np.float64)
    return np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)


class StereoRenderer:
    """Render :class:`FrameState` s of one scene through both cameras of a rig.

    Parameters
    ----------
    rig: the stereo rig (image size, intrinsics, distortion, right camera pose).
    T_robot_cam: (4, 4) left camera → robot frame.
    scene: a scene name (``wall``, ``button``, ``fabric``) or a scene file.
    background: a texture name, ``auto`` (an ordinary texture chosen by seed), ``mixed``, or a real
        photograph (``photo``, ``photo:NAME``, ``photo:FILE``; :mod:`vishap.sim.textures`).
    seed: per-sequence randomness (skin-tone variation, texture, sensor noise).
    skin_tone: a name of :data:`vishap.sim.hand.SKIN_TONES` or 0 (light) … 1 (dark); None picks by seed;
        ``real`` or ``real:TONE`` draws the skin and its light as measured on real photographs
        (:mod:`vishap.sim.skin_look`).
    effects: camera effects (on by default); ``CameraEffects.off()`` or None for exact pixels.
    msaa: multisample count of the colour pass (0 = off, labels from the same pass).
    threads: llvmpipe rasteriser threads (``LP_NUM_THREADS``), only before the first renderer.
    """

    def __init__(self, rig: StereoRig, T_robot_cam, scene: str | SceneSpec = "wall", *, background: str = "auto",
                 seed: int = 0, skin_tone=None, effects: CameraEffects | None = CameraEffects(), msaa: int = 0,
                 threads: int | None = None):
        if not isinstance(rig, StereoRig):
            raise ConfigError(f"rig must be a StereoRig, got {type(rig).__name__}", field="rig")
        self.pyrender = pr = import_pyrender(threads)
        self.rig = rig
        self.T_robot_cam = as_transform(T_robot_cam, "T_robot_cam")
        self.spec = scene if isinstance(scene, SceneSpec) else load_scene_spec(scene)
        self.seed = int(seed)
        self.msaa = int(msaa)
        self.effects = effects if effects is not None else CameraEffects.off()
        self._fx_state = EffectsState()
        rng = np.random.default_rng([self.seed, 0x5EED])
        self.background = choose_background(background, self.seed)
        self.look = skin_look(skin_tone, self.seed, rng)
        self.skin_rgb = self.look.rgb
        # the exposure of the real look: auto-exposure aims at a brighter (or darker) mean; without
        # auto-exposure the lights carry it
        self._light_gain = 1.0
        if self.look.exposure != 1.0:
            if self.effects.gain:
                self.effects = replace(self.effects, target_mean=self.effects.target_mean * self.look.exposure)
            else:
                self._light_gain = self.look.exposure
        self._light_base: dict = {}
        self._ambient = np.full(3, 0.22 * self.look.ambient_scale * self._light_gain) * np.asarray(self.look.light_rgb)
        self.scene = pr.Scene(bg_color=[0.0, 0.0, 0.0, 0.0], ambient_light=self._ambient)
        self._build_static(rng)
        self._build_hand()
        self._build_device()
        self._build_cameras()
        self._offscreen = None

    # ------------------------------------------------------------------ building
    def _material(self, rgb, label: int, *, roughness=0.6, metallic=0.0, texture=None):
        pr = self.pyrender
        lin = list(_srgb_to_linear(rgb)) if rgb is not None else [1.0, 1.0, 1.0]
        return pr.MetallicRoughnessMaterial(
            baseColorFactor=lin + [label * _ALPHA_STEP / 255.0], metallicFactor=metallic, roughnessFactor=roughness,
            baseColorTexture=texture, alphaMode="OPAQUE",
        )

    def _add(self, mesh: trimesh.Trimesh, material, label: int, pose=None, name=None):
        m = self.pyrender.Mesh.from_trimesh(mesh, material=material, smooth=False)
        node = self.scene.add(m, pose=np.eye(4) if pose is None else pose, name=name)
        self._labels[node] = label
        return node

    def _build_static(self, rng) -> None:
        pr = self.pyrender
        self._labels: dict = {}
        tex = make_texture(self.background, np.random.default_rng([self.seed, 0x7E7]))
        wrap = 33648 if is_photo(self.background) else 10497  # GL_MIRRORED_REPEAT: a photograph has no seamless edge
        texture = pr.Texture(source=tex, source_channels="RGB",
                             sampler=pr.Sampler(magFilter=9729, minFilter=9987, wrapS=wrap, wrapT=wrap))
        size, tile = 2.4, texture_tile_m(self.background)  # table size and texture repeat, m
        half = size / 2.0
        cx = 0.3
        pos = np.array([[cx - half, -half, 0], [cx + half, -half, 0], [cx + half, half, 0], [cx - half, half, 0]], np.float32)
        pos[:, 2] = _TABLE_Z
        uv = (pos[:, :2] - pos[0, :2]) / tile
        prim = pr.Primitive(positions=pos, normals=np.tile([0, 0, 1], (4, 1)).astype(np.float32),
                            texcoord_0=uv.astype(np.float32), indices=np.array([[0, 1, 2], [0, 2, 3]], np.uint32),
                            material=self._material(None, 0, roughness=0.85, texture=texture))
        node = self.scene.add(pr.Mesh([prim]), name="table")
        self._labels[node] = 0
        for name, mesh, rgb in object_meshes(self.spec):
            self._add(mesh, self._material(rgb, 3, roughness=0.5), 3, name=name)
        # lights: a key light from above the user's side, a fill near the cameras
        look, gain = self.look, self._light_gain
        key = pr.DirectionalLight(color=np.asarray(look.light_rgb), intensity=2.6)
        fill = pr.PointLight(color=np.asarray(look.light_rgb), intensity=0.9)
        target = np.array([0.2, 0.0, -0.15])
        eye = [0.6, 0.2, 0.6] if look.key_direction is None else target + 0.8 * np.asarray(look.key_direction)
        self._key_node = self.scene.add(key, pose=_light_pose(eye, target))
        cam_pos = self.T_robot_cam[:3, 3]
        self._fill_node = self.scene.add(fill, pose=_translation(cam_pos + np.array([0.0, 0.0, 0.15])))
        self._light_base = {self._key_node: 2.6 * look.key_scale * gain, self._fill_node: 0.9 * look.ambient_scale * gain}

    def _build_hand(self) -> None:
        look = self.look
        skin = self._material(look.rgb, 1, roughness=look.roughness)
        nail = self._material(look.nail_rgb, 1, roughness=look.nail_roughness)
        self._hand_nodes = {}
        for i, (name, mesh) in enumerate(_hand.hand_part_meshes().items()):
            mat = nail if name == "nail" else skin
            if not (look.smooth or look.mottling):
                self._hand_nodes[name] = self._add(mesh, mat, 1, name=name)
                continue
            # smooth shading and a mottled albedo (vertex colours multiply the lit colour)
            colours = mottling_colours(mesh.vertices, look.mottling if name != "nail" else 0.0, look.seed, i)
            prim = self.pyrender.Primitive(positions=mesh.vertices.astype(np.float32),
                                           normals=mesh.vertex_normals.astype(np.float32), color_0=colours,
                                           indices=mesh.faces.astype(np.uint32), material=mat)
            node = self.scene.add(self.pyrender.Mesh([prim]), name=name)
            self._labels[node] = 1
            self._hand_nodes[name] = node

    def _build_device(self) -> None:
        link_mat = self._material((0.16, 0.16, 0.17), 2, roughness=0.45, metallic=0.2)
        joint_mat = self._material((0.05, 0.05, 0.05), 2, roughness=0.4)
        cyl = trimesh.creation.cylinder(radius=0.007, height=1.0, sections=16)  # unit length along z
        ball = trimesh.creation.icosphere(subdivisions=2, radius=0.011)
        self._link_nodes = [self._add(cyl, link_mat, 2) for _ in range(_MAX_LINKS)]
        self._joint_nodes = [self._add(ball, joint_mat, 2) for _ in range(_MAX_LINKS + 1)]
        base = trimesh.creation.box(extents=(0.16, 0.14, 0.02))
        self._base_node = self._add(base, joint_mat, 2)
        bracket = trimesh.creation.box(extents=(1.0, 0.010, 0.004))  # scaled along x per frame
        self._bracket_node = self._add(bracket, joint_mat, 2)
        plate_mat = self._material((0.62, 0.64, 0.67), 2, roughness=0.35, metallic=0.4)
        key_mat = self._material((0.22, 0.22, 0.24), 2, roughness=0.5)
        self._passive_nodes = {
            "plate": self._add(trimesh.creation.box(extents=(1.0, 1.0, 1.0)), plate_mat, 2),
            "key": self._add(trimesh.creation.box(extents=(1.0, 1.0, 1.0)), key_mat, 2),
        }
        marker = trimesh.creation.icosphere(subdivisions=3, radius=0.005)
        self._marker_node = self._add(marker, self._material((0.0, 1.0, 0.0), 2, roughness=0.5), 2)
        occ = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=16)  # scaled per frame
        self._occluder_node = self._add(occ, self._material((0.10, 0.10, 0.11), 0, roughness=0.5), 0)

    def _build_cameras(self) -> None:
        pr = self.pyrender
        w, h = self.rig.image_size
        self._cams = {}
        self._remap = {}
        T_left_right = np.eye(4)
        T_left_right[:3, :3] = self.rig.R.T
        T_left_right[:3, 3] = -self.rig.R.T @ self.rig.T
        poses = {"left": self.T_robot_cam, "right": self.T_robot_cam @ T_left_right}
        self._canvas = (w, h)
        margins = {}
        for side, K, d in (("left", self.rig.K_left, self.rig.dist_left), ("right", self.rig.K_right, self.rig.dist_right)):
            if np.any(d) or K[0, 1] != 0.0:
                margins[side] = _pinhole_margin(K, d, w, h)
        m = max(margins.values(), default=0)
        self._margin = m
        self._canvas = (w + 2 * m, h + 2 * m)
        for side, K, d in (("left", self.rig.K_left, self.rig.dist_left), ("right", self.rig.K_right, self.rig.dist_right)):
            cam = pr.IntrinsicsCamera(fx=K[0, 0], fy=K[1, 1], cx=K[0, 2] + 0.5 + m, cy=K[1, 2] + 0.5 + m, znear=0.03, zfar=6.0)
            self._cams[side] = self.scene.add(cam, pose=poses[side] @ _GL_FROM_CV, name=f"camera_{side}")
            if m:
                self._remap[side] = _distortion_maps(K, d, w, h, m)

    # ------------------------------------------------------------------ per frame
    def _set_visible(self, node, visible: bool) -> None:
        node.mesh.is_visible = bool(visible)

    def _update(self, s: FrameState) -> None:
        # hand
        if s.hand_visible:
            poses = _hand.hand_part_poses(s.tip_robot, s.finger_dir_robot, s.flexion, s.hand_roll)
            for name, node in self._hand_nodes.items():
                self._set_visible(node, True)
                self.scene.set_pose(node, poses[name])
        else:
            for node in self._hand_nodes.values():
                self._set_visible(node, False)
        # device
        pts = None if s.device_points_robot is None else np.asarray(s.device_points_robot, dtype=np.float64)
        n_links = 0 if pts is None else min(len(pts) - 1, _MAX_LINKS)
        for i, node in enumerate(self._link_nodes):
            if i < n_links:
                self._set_visible(node, True)
                self.scene.set_pose(node, _segment_pose(pts[i], pts[i + 1]))
            else:
                self._set_visible(node, False)
        for i, node in enumerate(self._joint_nodes):
            if pts is not None and 0 < i <= n_links:
                self._set_visible(node, True)
                self.scene.set_pose(node, _translation(pts[i]))
            else:
                self._set_visible(node, False)
        self._set_visible(self._base_node, pts is not None)
        if pts is not None:
            self.scene.set_pose(self._base_node, _translation(pts[0] + np.array([0.0, 0.0, 0.010])))
        ee = None if s.ee_robot is None else np.asarray(s.ee_robot, dtype=np.float64)
        po = s.passive_object
        for shape, node in self._passive_nodes.items():
            show = po is not None and ee is not None and po.shape == shape
            self._set_visible(node, show)
            if show:
                top = po.top_centre_robot(ee)
                sx, sy, sz = po.size_m
                T = np.diag([sx, sy, sz, 1.0])
                T[:3, 3] = top - np.array([0.0, 0.0, sz / 2.0])
                self.scene.set_pose(node, T)
        show_bracket = po is not None and ee is not None and np.linalg.norm(po.mount_offset_robot) > 0
        self._set_visible(self._bracket_node, show_bracket)
        if show_bracket:
            a = ee
            b = po.top_centre_robot(ee) - np.array([0.0, 0.0, po.size_m[2] + 0.002])
            self.scene.set_pose(self._bracket_node, _segment_pose(a, b, along="x"))
        self._set_visible(self._marker_node, bool(s.marker) and ee is not None)
        if s.marker and ee is not None:
            self.scene.set_pose(self._marker_node, _translation(ee))
        # occluder
        occ = s.occluder
        self._set_visible(self._occluder_node, occ is not None)
        if occ is not None:
            T = _segment_pose(np.asarray(occ.a_robot), np.asarray(occ.b_robot))
            T[:3, :3] = T[:3, :3] @ np.diag([occ.radius_m, occ.radius_m, 1.0])
            self.scene.set_pose(self._occluder_node, T)
        # lights
        for node, base in self._light_base.items():
            node.light.intensity = base * float(s.light)
        self.scene.ambient_light = self._ambient * float(s.light)

    def _renderer(self):
        if self._offscreen is None:
            w, h = self._canvas
            self._offscreen = self.pyrender.OffscreenRenderer(w, h)
        return self._offscreen

    def render(self, state: FrameState, *, labels: str | None = None) -> RenderedPair:
        """Render one frame through both cameras.

        ``labels``: how the label images are made — ``alpha`` (from the colour pass's alpha; exact
        without MSAA), ``seg`` (a flat pass without MSAA), ``none`` (all zero; for timing the colour
        alone); None picks ``alpha`` without MSAA and ``seg`` with it.
        """
        pr = self.pyrender
        mode = labels or ("seg" if self.msaa else "alpha")
        if mode not in ("alpha", "seg", "none"):
            raise ConfigError(f"labels must be alpha, seg or none, got {labels!r}", field="labels")
        self._update(state)
        r = self._renderer()
        out = {}
        set_msaa(r, self.msaa)
        for side in ("left", "right"):
            self.scene.main_camera_node = self._cams[side]
            rgba, depth = r.render(self.scene, flags=pr.RenderFlags.RGBA)
            if mode == "alpha":
                lab = ((rgba[..., 3].astype(np.uint16) + _ALPHA_STEP // 2) // _ALPHA_STEP).astype(np.uint8)
            else:
                lab = np.zeros(depth.shape, np.uint8)
            out[side] = [np.ascontiguousarray(rgba[..., 2::-1]), lab, depth]
        if mode == "seg":
            set_msaa(r, 0)
            # every node, label 0 included: pyrender leaves nodes out of the map undrawn, and the
            # occluding rod (label 0) must still hide what is behind it
            seg_map = {n: np.full(3, v * _ALPHA_STEP, np.uint8) for n, v in self._labels.items()}
            for side in ("left", "right"):
                self.scene.main_camera_node = self._cams[side]
                seg, _ = r.render(self.scene, flags=pr.RenderFlags.SEG, seg_node_map=seg_map)
                out[side][1] = ((seg[..., 0].astype(np.uint16) + _ALPHA_STEP // 2) // _ALPHA_STEP).astype(np.uint8)
            set_msaa(r, self.msaa)
        for side, maps in self._remap.items():
            c, lab, dep = out[side]
            out[side] = [cv2.remap(c, *maps, cv2.INTER_LINEAR), cv2.remap(lab, *maps, cv2.INTER_NEAREST),
                         cv2.remap(dep, *maps, cv2.INTER_NEAREST)]
        images = {k: v[0] for k, v in out.items()}
        if self.effects.any:
            tip_uv = {"left": None, "right": None}
            if state.hand_visible:
                p_cam = (np.linalg.inv(self.T_robot_cam) @ np.append(state.tip_robot, 1.0))[:3]
                uvl, uvr = self.rig.project(p_cam)
                tip_uv = {"left": uvl[0], "right": uvr[0]}
            masks = {k: v[1] == 1 for k, v in out.items()}
            images = apply_effects(self.effects, self._fx_state, images, masks, tip_uv, float(state.t), self.seed)
        return RenderedPair(left=images["left"], right=images["right"], labels_left=out["left"][1],
                            labels_right=out["right"][1], depth_left=out["left"][2], depth_right=out["right"][2])

    def reset_effects(self) -> None:
        """Forget the auto-exposure gain and motion history (start of a new sequence)."""
        self._fx_state = EffectsState()

    def close(self) -> None:
        if self._offscreen is not None:
            self._offscreen.delete()
            self._offscreen = None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


from vishap.sim.device import TABLE_Z_M as _TABLE_Z  # noqa: E402


def _translation(p) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = p
    return T


def _light_pose(eye, target) -> np.ndarray:
    """A light's pose: pyrender lights shine along their local −z (OpenGL axes: the OpenCV
    camera's look-at frame with y and z turned round)."""
    return look_at(eye, target) @ np.diag([1.0, -1.0, -1.0, 1.0])


def _segment_pose(a, b, along: str = "z") -> np.ndarray:
    """Pose that maps a unit-length, origin-centred primitive along ``along`` onto segment a→b."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    v = b - a
    L = float(np.linalg.norm(v))
    u = v / L if L > 1e-12 else np.array([0.0, 0.0, 1.0])
    helper = np.array([1.0, 0.0, 0.0]) if abs(u[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    p = np.cross(u, helper)
    p /= np.linalg.norm(p)
    q = np.cross(u, p)
    R = np.column_stack([p, q, u]) if along == "z" else np.column_stack([u, p, q])
    S = np.diag([1.0, 1.0, max(L, 1e-6)]) if along == "z" else np.diag([max(L, 1e-6), 1.0, 1.0])
    T = np.eye(4)
    T[:3, :3] = R @ S
    T[:3, 3] = (a + b) / 2.0
    return T


def _pinhole_margin(K, d, w, h) -> int:
    """Extra pixels around the pinhole canvas needed to cover a distorted camera's view."""
    border = np.concatenate([
        np.stack([np.arange(w), np.zeros(w)], 1), np.stack([np.arange(w), np.full(w, h - 1)], 1),
        np.stack([np.zeros(h), np.arange(h)], 1), np.stack([np.full(h, w - 1), np.arange(h)], 1),
    ]).astype(np.float64)
    x = cv2.undistortPoints(border.reshape(-1, 1, 2), K, d).reshape(-1, 2)
    u = K[0, 0] * x[:, 0] + K[0, 2]
    v = K[1, 1] * x[:, 1] + K[1, 2]
    over = max(-u.min(), -v.min(), u.max() - (w - 1), v.max() - (h - 1), 0.0)
    return int(math.ceil(over)) + 2


def _distortion_maps(K, d, w, h, m):
    """``cv2.remap`` maps from the real (distorted, skewed) camera to the pinhole canvas."""
    uu, vv = np.meshgrid(np.arange(w, dtype=np.float64), np.arange(h, dtype=np.float64))
    pts = np.stack([uu.ravel(), vv.ravel()], 1).reshape(-1, 1, 2)
    crit = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 40, 1e-12)
    undistort = getattr(cv2, "undistortPointsIter", None)  # OpenCV 4.x name; 5.x takes criteria in undistortPoints
    if undistort is None:
        x = cv2.undistortPoints(pts, K, d, None, None, None, crit)
    else:
        x = undistort(pts, K, d, None, None, crit)
    x = x.reshape(-1, 2)
    mx = (K[0, 0] * x[:, 0] + K[0, 2] + m).reshape(h, w).astype(np.float32)
    my = (K[1, 1] * x[:, 1] + K[1, 2] + m).reshape(h, w).astype(np.float32)
    return mx, my
