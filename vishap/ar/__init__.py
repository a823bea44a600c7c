"""The augmented view: the device deleted from the video, the scene's virtual objects drawn in place,
the hand in front (VisHap §2.2, world subsystem). See ``docs/ar.md``."""
from vishap.ar.background import INPAINT_METHODS, LearnedBackground, inpaint_region
from vishap.ar.camera import ViewCamera
from vishap.ar.compositor import ARCompositor, Contact, draw_note
from vishap.ar.device_geometry import DEVICE_GEOMETRIES, DeviceGeometry, device_geometry
from vishap.ar.faces import Lighting
from vishap.ar.live_view import LiveView, open_live_view
from vishap.ar.objects import ObjectLayer, object_corners_robot
from vishap.ar.silhouette import device_silhouette

__all__ = ["ARCompositor", "Contact", "draw_note", "LearnedBackground", "inpaint_region", "INPAINT_METHODS",
           "ViewCamera", "DeviceGeometry", "DEVICE_GEOMETRIES", "device_geometry", "device_silhouette", "Lighting",
           "ObjectLayer", "object_corners_robot", "LiveView", "open_live_view"]
