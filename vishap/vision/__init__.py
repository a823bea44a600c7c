"""Vision (VisHap §2.1): stereo pairs to the fingertip's 3-D position ``p_cam`` in the left-camera frame."""
from vishap.vision.rig import StereoRig

__all__ = ["StereoRig"]
