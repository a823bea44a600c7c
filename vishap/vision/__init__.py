"""Vision (VisHap §2.1): stereo pairs to the fingertip's 3-D position ``p_cam`` in the left-camera frame.

capture (sources, StereoFrame) → segment (tile hue histograms + skin model + median) → fingertip
(r = K/z circle, square ring, diagonal test) → track (constant-velocity Kalman, search window) →
stereo (rectified sparse triangulation) — put together by :class:`~vishap.vision.pipeline.VisionPipeline`.
"""
from vishap.vision.capture import StereoFrame, open_source
from vishap.vision.pipeline import PipelineConfig, TipEstimate, VisionPipeline
from vishap.vision.rig import StereoRig
from vishap.vision.skin_model import SkinModel

__all__ = ["StereoRig", "StereoFrame", "open_source", "SkinModel", "VisionPipeline", "PipelineConfig", "TipEstimate"]
