"""Synthetic stereo sequences with exact ground truth: a hand, the haptic device and a scene rendered
with pyrender through a calibrated stereo rig (issue 3; VisHap §3 is what they are made to test).

Modules: ``camera_placement`` (the true ``T_robot_cam``), ``renderer`` (``StereoRenderer``,
``FrameState``, ``RenderedPair``), ``hand``, ``device``, ``scene_objects``, ``textures``,
``camera_effects``, ``trajectory`` (scripted finger motion from data), ``device`` (also the
encountered-type device path), ``sequence`` (frames + ground truth in memory), ``writer`` and
``reader`` (the on-disk sequence format). Importing this package does not import pyrender.
"""
