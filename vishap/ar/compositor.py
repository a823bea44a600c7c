"""The augmented view (VisHap §2.2, world subsystem): the camera's video "with the haptic device
deleted and a virtual object overlaid", the hand in front.

:meth:`ARCompositor.compose` is the one call a loop makes per camera frame::

    ar = ARCompositor(rig, T_robot_cam_est, scene, device_geometry("phantom_premium_1_0", ...))
    view = ar.compose(image_left, skin_mask, q_device, t, contact=Contact(p_robot, depth_m))

1. **Delete the device.** Its silhouette (:func:`~vishap.ar.silhouette.device_silhouette`) comes from
   the joint state ``q_device``, the calibration and the device geometry; the region it covers,
   less the hand in front of it, is filled from the background learned from the frames' hand- and
   device-free pixels (:class:`~vishap.ar.background.LearnedBackground`), inpainted where the
   background was never seen.
2. **Overlay the objects** of the scene, lit and registered through the same calibration
   (:class:`~vishap.ar.objects.ObjectLayer`); a pressed key sinks by its travel, the fabric dents
   under the contact.
3. **Keep the hand in front**: skin pixels (the vision's mask) are never painted over.

Bad input never gives a wrong overlay: without a calibration, with an unusable one or with an
unknown device geometry the compositor is *off* and returns the plain frame with a note saying why;
a frame without a finite joint state is passed through with a note.

``skin_mask=None`` segments the frame with ``segmenter`` (a :class:`vishap.vision.segment.Segmenter`,
e.g. the vision pipeline's left one: frames are passed through with a note until it has learned),
or with the compositor's own one, which learns its background from the first ``learn_frames``
frames (the hand must be out of view then, as for the vision).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import cv2
import numpy as np

from vishap._core.errors import VishapError
from vishap.ar.background import LearnedBackground
from vishap.ar.camera import ViewCamera
from vishap.ar.device_geometry import DEVICE_GEOMETRIES, DeviceGeometry, device_geometry
from vishap.ar.faces import Lighting
from vishap.ar.objects import ObjectLayer
from vishap.ar.silhouette import device_silhouette, dilate

__all__ = ["Contact", "ARCompositor", "draw_note"]


@dataclass(frozen=True)
class Contact:
    """Where the finger presses an object: the contact point (robot frame, m) and how deep under the
    surface (m, ≥ 0); ``object_name`` None: the object whose patch holds the point."""

    point_robot: tuple[float, float, float]
    depth_m: float
    object_name: str | None = None


def draw_note(image: np.ndarray, lines) -> np.ndarray:
    """A copy of ``image`` with ``lines`` of text on a dark band at its top."""
    out = image.copy()
    lines = [lines] if isinstance(lines, str) else list(lines)
    scale = max(0.3, out.shape[1] / 1100.0)
    th = max(1, int(round(scale * 1.6)))
    y = 4
    for text in lines:
        (w, h), base = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, th)
        cv2.rectangle(out, (0, y), (min(out.shape[1] - 1, w + 8), y + h + base + 6), (0, 0, 0), -1)
        cv2.putText(out, text, (4, y + h + 3), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 215, 255), th, cv2.LINE_AA)
        y += h + base + 8
    return out


class ARCompositor:
    """The augmented view of one camera of ``rig`` (``side``).

    ``T_robot_cam``: the calibrated left camera → robot transform (None: no calibration).
    ``device``: a :class:`DeviceGeometry`, or a name of :data:`DEVICE_GEOMETRIES` (None or an
    unknown name: no device geometry). ``margin_px``: growth of the device silhouette (default
    2 px per 640 px of width); ``skin_margin_px``: the hand's pixels kept out of the background
    update. ``background_tau_s``: time constant of the background's exponential average once its
    first ``learn_frames`` observations of a pixel are averaged; ``inpaint``: ``telea`` or ``ns``
    (or pass a configured ``background``). ``last`` holds the latest frame's intermediate images
    (``skin``, ``region`` deleted, ``deleted``, ``cover`` of the objects) for inspection.
    """

    def __init__(self, rig, T_robot_cam, scene, device, *, side: str = "left", segmenter=None,
                 learn_frames: int = 10, margin_px: int | None = None, skin_margin_px: int | None = None,
                 background_tau_s: float = 1.0, inpaint: str = "telea", background: LearnedBackground | None = None,
                 lighting: Lighting = Lighting(), seed: int = 0):
        self.rig = rig
        self.scene = scene
        self.reason = None
        self.segmenter = segmenter
        self._own_segmenter = False
        self.learn_frames = int(learn_frames)
        self._learn_buf: list = []
        self.timings: dict[str, float] = {}
        self.last: dict[str, np.ndarray] = {}
        w = int(rig.image_size[0])
        self.margin_px = int(margin_px if margin_px is not None else max(1, round(2 * w / 640)))
        self.skin_margin_px = int(skin_margin_px if skin_margin_px is not None else max(2, round(6 * w / 640)))
        self.background_tau_s = float(background_tau_s)
        self._last_t: float | None = None
        self.geometry: DeviceGeometry | None = None
        if isinstance(device, DeviceGeometry):
            self.geometry = device
        elif isinstance(device, str) and device in DEVICE_GEOMETRIES:
            self.geometry = device_geometry(device)
        else:
            self.reason = f"AR off: unknown device geometry {device!r} (known: {', '.join(sorted(DEVICE_GEOMETRIES))})"
        if T_robot_cam is None:
            self.reason = "AR off: no camera-robot calibration"
        self.camera = None
        if self.reason is None:
            try:
                self.camera = ViewCamera(rig, T_robot_cam, side)
            except VishapError as exc:
                self.reason = f"AR off: calibration unusable ({exc})"
        if self.reason is None:
            self.background = background or LearnedBackground(rig.image_size, average_frames=learn_frames,
                                                              inpaint=inpaint)
            self.objects = ObjectLayer(scene, self.camera, lighting=lighting, seed=seed)

    @property
    def enabled(self) -> bool:
        return self.reason is None

    # ------------------------------------------------------------------ stages
    def skin(self, image: np.ndarray) -> np.ndarray | None:
        """The skin mask of ``image`` from the segmenter (None while its background is learned)."""
        if self.segmenter is None:
            from vishap.vision.segment import Segmenter
            from vishap.vision.skin_model import SkinModel

            self.segmenter = Segmenter(SkinModel.load())
            self._own_segmenter = True
        if not self.segmenter.learned:
            if not self._own_segmenter:  # another stage (the vision) learns it: wait for it
                return None
            self._learn_buf.append(image)
            if len(self._learn_buf) < self.learn_frames:
                return None
            self.segmenter.learn(self._learn_buf)
            self._learn_buf = []
        return self.segmenter.segment(image)

    def delete(self, image: np.ndarray, skin_mask: np.ndarray, q_device, t: float) -> tuple[np.ndarray, np.ndarray]:
        """(image with the device deleted, the deleted region 0/255); the background learns from
        this frame's pixels that show neither hand nor device."""
        c0 = time.perf_counter()
        dev = device_silhouette(self.geometry, q_device, self.camera, margin_px=self.margin_px)
        c1 = time.perf_counter()
        skin = skin_mask if skin_mask is not None else np.zeros(dev.shape, np.uint8)
        busy = cv2.bitwise_or(dilate(dev, self.margin_px + 1), dilate(skin, self.skin_margin_px))
        dt = None if self._last_t is None else float(t) - self._last_t
        rate = None if dt is None or dt <= 0 else 1.0 - math.exp(-dt / self.background_tau_s)
        self.background.update(image, busy == 0, rate=rate)
        self._last_t = float(t)
        region = cv2.bitwise_and(dev, cv2.bitwise_not(skin))
        out = self.background.fill(image, region)
        c2 = time.perf_counter()
        self.timings.update(silhouette_ms=1e3 * (c1 - c0), fill_ms=1e3 * (c2 - c1))
        self.last.update(region=region, deleted=out)
        return out, region

    def overlay(self, image: np.ndarray, skin_mask: np.ndarray | None, contact: Contact | None = None) -> np.ndarray:
        """``image`` with the scene's objects drawn where no skin is."""
        c0 = time.perf_counter()
        travel, dent = self._contact_inputs(contact)
        layer, cover = self.objects.draw(travel=travel, dent=dent)
        self.last["cover"] = cover
        if skin_mask is not None:
            cover = cv2.bitwise_and(cover, cv2.bitwise_not(skin_mask))
        out = image.copy()
        x, y, w, h = cv2.boundingRect(cover)
        if w:
            x0, y0, x1, y1 = max(0, x - 1), max(0, y - 1), min(out.shape[1], x + w + 1), min(out.shape[0], y + h + 1)
            # a 3×3 box on the coverage softens the stair-stepped edges by half a pixel
            a = cv2.blur(cover[y0:y1, x0:x1], (3, 3)).astype(np.float32)[..., None] * (1.0 / 255.0)
            a = np.where(cover[y0:y1, x0:x1, None] > 0, np.maximum(a, 0.5), a)
            if skin_mask is not None:  # never soften into the hand
                a[skin_mask[y0:y1, x0:x1] > 0] = 0.0
            roi = out[y0:y1, x0:x1].astype(np.float32)
            out[y0:y1, x0:x1] = np.round(roi + a * (layer[y0:y1, x0:x1].astype(np.float32) - roi)).astype(np.uint8)
        self.timings["overlay_ms"] = 1e3 * (time.perf_counter() - c0)
        return out

    def _contact_inputs(self, contact: Contact | None):
        if contact is None or not np.all(np.isfinite(contact.point_robot)) or not math.isfinite(contact.depth_m):
            return None, None
        p = np.asarray(contact.point_robot, float)
        for obj in self.scene.objects:
            if contact.object_name is not None and obj.name != contact.object_name:
                continue
            if contact.object_name is None and not obj.inside_extent(p):
                continue
            depth = max(0.0, float(contact.depth_m))
            if obj.kind == "button":
                return {obj.name: depth}, None
            if obj.kind == "fabric":
                return None, (obj.name, p, depth)
            return None, None
        return None, None

    # ------------------------------------------------------------------ the one call per frame
    def compose(self, image: np.ndarray, skin_mask: np.ndarray | None, q_device, t: float, *,
                contact: Contact | None = None) -> np.ndarray:
        """The augmented view of one camera frame (BGR ``uint8``) at time ``t`` (s)."""
        c0 = time.perf_counter()
        if not self.enabled:
            return draw_note(image, [self.reason, "plain video"])
        if skin_mask is None:
            c1 = time.perf_counter()
            skin_mask = self.skin(image)
            self.timings["skin_ms"] = 1e3 * (time.perf_counter() - c1)
            if skin_mask is None:
                n = len(self._learn_buf)
                what = f" ({n}/{self.learn_frames})" if self._own_segmenter else ""
                return draw_note(image, f"AR: learning the background{what}")
        q = np.asarray(q_device, dtype=np.float64).reshape(-1) if q_device is not None else np.full(3, np.nan)
        if q.shape != (3,) or not np.all(np.isfinite(q)):
            return draw_note(image, "AR paused: no device joint state (plain video)")
        self.last["skin"] = skin_mask
        deleted, _ = self.delete(image, skin_mask, q, t)
        out = self.overlay(deleted, skin_mask, contact)
        self.timings["total_ms"] = 1e3 * (time.perf_counter() - c0)
        return out
