"""A synthetic sequence in memory: scripted finger, encountered-type device, rendered stereo pair and
exact ground truth per frame (issue 3, items 3, 4 and 6).

:func:`generate` yields ``(FrameState, RenderedPair, gt_row)`` for a :class:`SequenceSpec`, so a user
that works in memory (vision evaluation, calibration, closed-loop demos) never touches the disk;
:mod:`vishap.sim.writer` stores the same stream in the folder layout of the issue.

Ground truth per frame (``gt_row``; the arrays of ``gt.npz`` stack them, see
``datasets/synthetic/README.md``): the fingertip cap centre in the robot and left-camera frames, its
projections (``StereoRig.project``: exact for any calibrated rig), whether it is visible in each
view, the finger's velocity, the phase of the script, contact, the device state and the light.

The tip is *visible* in a view when its projection falls inside the image and the rendered depth at
that pixel lies on the fingertip's cap (between the cap centre's depth minus its radius (−1 mm) and
the centre's depth): nothing is in front of it, and it is not pointing away. The label image is not
used for this, so tests can check that the label there is skin.
"""
from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from vishap._core.errors import ConfigError
from vishap._core.pose import invert, transform_points, transform_vectors
from vishap.sim.camera_effects import CameraEffects
from vishap.sim.device import device_links, encounter_ee, touch_region
from vishap.sim.scene_objects import load_scene_spec
from vishap.sim.state import TIP_RADIUS_M, FrameState, Occluder, PassiveObject, RenderedPair
from vishap.sim.trajectory import PHASES, Trajectory, load_trajectory, occluder_segment
from vishap.vision.rig import StereoRig

__all__ = ["LIGHTING", "SequenceSpec", "Prepared", "generate", "prepare", "make_renderer", "render_frames", "frame_state",
           "constants", "default_rig", "light_function", "tip_visible"]

LIGHTING = ("constant", "step", "ramp", "flicker")
_VIS_FRONT_M = 0.001  # depth tolerance in front of the cap surface


def default_rig(width: int = 640, height: int = 480) -> StereoRig:
    """The synthetic rig: 60° horizontal field of view, 60 mm baseline, no distortion."""
    return StereoRig.from_fov(int(width), int(height), 60.0, 0.06)


@dataclass
class SequenceSpec:
    """What to generate. ``trajectory`` defaults to the scene's name; ``rig`` to :func:`default_rig`
    at ``width`` × ``height``; ``T_robot_cam`` to :func:`~vishap.sim.camera_placement.default_T_robot_cam`.
    ``start_s``: time of the first frame (frames are ``start_s + i / fps``; 0 starts with the
    hand-free frames)."""

    scene: str = "wall"
    frames: int = 60
    seed: int = 0
    trajectory: str | None = None
    width: int = 640
    height: int = 480
    rig: StereoRig | None = None
    T_robot_cam: np.ndarray | None = None
    lighting: str = "constant"
    skin_tone: str | float | None = None
    background: str = "auto"
    occlusion: bool = True
    effects: bool = True
    msaa: int = 0
    #: the cameras' exposure time (s; None: the camera model's, 12 ms): the motion blur's length, and the
    #: sensor noise of a shorter exposure under the same light (:class:`~vishap.sim.camera_effects.CameraEffects`)
    exposure_s: float | None = None
    fps: float | None = None
    hand_free_frames: int | None = None
    start_s: float = 0.0
    #: how :mod:`vishap.sim.writer` stores the frames: ``png`` (one file per image) or ``video``
    #: (lossless FFV1, :mod:`vishap.scale.store`); the rendered frames are the same
    store: str = "png"

    def validate(self) -> None:
        """Check everything a user can get wrong before anything is rendered or written."""
        if not isinstance(self.frames, (int, np.integer)) or self.frames < 1:
            raise ConfigError(f"frames must be a positive integer, got {self.frames!r}", field="frames")
        if self.rig is None and (int(self.width) < 16 or int(self.height) < 16):
            raise ConfigError(f"resolution must be at least 16×16, got {self.width}×{self.height}", field="resolution")
        if self.lighting not in LIGHTING:
            raise ConfigError(f"unknown lighting {self.lighting!r}; expected one of {list(LIGHTING)}", field="lighting")
        if self.fps is not None and not 0 < float(self.fps) <= 1000:
            raise ConfigError(f"fps must be in (0, 1000], got {self.fps}", field="fps")
        if self.hand_free_frames is not None and int(self.hand_free_frames) < 0:
            raise ConfigError(f"hand-free frames must be >= 0, got {self.hand_free_frames}", field="hand_free_frames")
        if not 0.0 <= float(self.start_s) < 1e5:
            raise ConfigError(f"start time must be >= 0 s, got {self.start_s}", field="start_s")
        if self.exposure_s is not None:
            if not self.effects:
                raise ConfigError("an exposure needs the camera effects (exact pixels have no motion blur or noise)",
                                  field="exposure_s")
            camera_effects(self)  # the camera model checks its exposure (a positive time)
        if int(self.msaa) not in (0, 2, 4, 8):
            raise ConfigError(f"msaa must be 0, 2, 4 or 8, got {self.msaa}", field="msaa")
        from vishap.scale.store import STORES

        if self.store not in STORES:
            raise ConfigError(f"unknown store {self.store!r}; expected one of {list(STORES)}", field="store")


def light_function(mode: str, duration_s: float, seed: int):
    """Light intensity scale over time: ``constant``; ``step`` (dims to 55 % from 40 % to 60 % of the
    sequence: a lamp switched off, as in VisHap §4's illumination test); ``ramp`` (slow ±30 %
    drift, period 6 s); ``flicker`` (random steps of ±15 % every 0.5 s)."""
    if mode == "constant":
        return lambda t: 1.0
    if mode == "step":
        a, b = 0.4 * duration_s, 0.6 * duration_s
        return lambda t: 0.55 if a <= t < b else 1.0
    if mode == "ramp":
        ph = float(np.random.default_rng([seed, 0x1A]).uniform(0, 2 * np.pi))
        return lambda t: 1.0 + 0.3 * np.sin(2 * np.pi * t / 6.0 + ph)
    if mode == "flicker":
        levels = 1.0 + np.random.default_rng([seed, 0x1B]).uniform(-0.15, 0.15, size=int(duration_s / 0.5) + 2)
        return lambda t: float(levels[min(int(t / 0.5), len(levels) - 1)])
    raise ConfigError(f"unknown lighting {mode!r}; expected one of {list(LIGHTING)}", field="lighting")


def tip_visible(uv, tip_depth_m: float, depth: np.ndarray) -> bool:
    """Whether the pixel at ``uv`` shows the fingertip's cap (see the module docstring)."""
    h, w = depth.shape
    u, v = int(np.floor(uv[0] + 0.5)), int(np.floor(uv[1] + 0.5))
    if not (0 <= u < w and 0 <= v < h):
        return False
    d = float(depth[v, u])
    return d > 0 and tip_depth_m - TIP_RADIUS_M - _VIS_FRONT_M <= d <= tip_depth_m


@dataclass
class Prepared:
    spec: SequenceSpec
    scene_spec: object
    passive: PassiveObject
    trajectory: Trajectory
    rig: StereoRig
    T_robot_cam: np.ndarray
    times: np.ndarray
    trajectory_file: Path


def prepare(spec: SequenceSpec) -> Prepared:
    """Validate the spec and resolve scene, trajectory, rig and camera pose (no rendering)."""
    from vishap.sim.camera_placement import default_T_robot_cam

    spec.validate()
    scene = load_scene_spec(spec.scene)
    passive = PassiveObject(shape=scene.passive_shape, size_m=scene.passive_size_m,
                            mount_offset_robot=scene.passive_mount_offset_m)
    tspec, tfile = load_trajectory(spec.trajectory or scene.name)
    if scene.name not in tspec.scenes:
        raise ConfigError(f"trajectory {tspec.name!r} is written for scenes {tspec.scenes}, not {scene.name!r}",
                          file=tfile, field="scenes")
    if spec.fps is not None:
        tspec = tspec.model_copy(update={"fps": float(spec.fps)})
    if spec.hand_free_frames is not None:
        tspec = tspec.model_copy(update={"hand_free_frames": int(spec.hand_free_frames)})
    if spec.exposure_s is not None and spec.exposure_s > 1.0 / tspec.fps + 1e-12:
        raise ConfigError(f"exposure {spec.exposure_s * 1e3:g} ms is longer than a frame at {tspec.fps:g} fps "
                          f"({1e3 / tspec.fps:.1f} ms)", field="exposure_s")
    duration = spec.start_s + spec.frames / tspec.fps
    traj = Trajectory(tspec, surface_z_m=scene.surface_z_m, touch_region=touch_region(scene, passive),
                      seed=spec.seed, file=tfile, light_fn=light_function(spec.lighting, duration, spec.seed))
    rig = spec.rig if spec.rig is not None else default_rig(spec.width, spec.height)
    T = np.asarray(spec.T_robot_cam if spec.T_robot_cam is not None else default_T_robot_cam(baseline_m=rig.baseline_m),
                   dtype=np.float64)
    times = spec.start_s + traj.frame_times(spec.frames)
    return Prepared(spec, scene, passive, traj, rig, T, times, tfile)


def frame_state(p: Prepared, t: float) -> tuple[FrameState, dict]:
    """The scene at time ``t`` and the geometric part of its ground truth."""
    f = p.trajectory.sample(t)
    ee = encounter_ee(p.scene_spec, p.passive, f.tip_robot, f.depth_m)
    occ = None
    if f.occluder_progress is not None and p.spec.occlusion and f.hand_visible:
        a, b = occluder_segment(f.occluder_progress, f.tip_robot, p.T_robot_cam)
        occ = Occluder(tuple(a), tuple(b))
    state = FrameState(t=t, tip_robot=f.tip_robot, finger_dir_robot=f.finger_dir_robot, flexion=f.flexion,
                       hand_visible=f.hand_visible, hand_roll=f.roll, device_points_robot=device_links(ee),
                       ee_robot=ee, passive_object=p.passive, marker=False, light=f.light, occluder=occ)
    contact = f.tip_robot - np.array([0.0, 0.0, TIP_RADIUS_M]) if f.in_contact else np.full(3, np.nan)
    geo = {"phase": PHASES.index(f.phase), "in_contact": f.in_contact, "press_depth": f.depth_m,
           "contact_robot": contact, "hand_visible": f.hand_visible, "light": f.light,
           "occluder_present": occ is not None, "finger_dir_robot": f.finger_dir_robot, "flexion": f.flexion}
    return state, geo


def make_renderer(p: Prepared):
    """The :class:`~vishap.sim.renderer.StereoRenderer` a prepared sequence is drawn with."""
    from vishap.sim.renderer import StereoRenderer

    s = p.spec
    return StereoRenderer(p.rig, p.T_robot_cam, p.scene_spec, background=s.background, seed=s.seed,
                          skin_tone=s.skin_tone, effects=camera_effects(s), msaa=s.msaa)


def camera_effects(spec: SequenceSpec) -> CameraEffects | None:
    """The camera model a sequence is drawn with (None: exact pixels)."""
    if not spec.effects:
        return None
    return CameraEffects() if spec.exposure_s is None else CameraEffects(exposure_s=float(spec.exposure_s))


def generate(spec: SequenceSpec, *, renderer=None) -> Iterator[tuple[FrameState, RenderedPair, dict]]:
    """Yield ``(FrameState, RenderedPair, gt_row)`` for every frame of the sequence.

    ``renderer``: an existing :class:`~vishap.sim.renderer.StereoRenderer` for the same rig, pose and
    scene; by default one is made and closed at the end.
    """
    p = prepare(spec)
    own = renderer is None
    renderer = make_renderer(p) if own else renderer
    try:
        yield from render_frames(p, renderer)
    finally:
        if own:
            renderer.close()


def render_frames(p: Prepared, renderer) -> Iterator[tuple[FrameState, RenderedPair, dict]]:
    """Render every frame of a prepared sequence (the camera effects' memory is reset first)."""
    renderer.reset_effects()
    T_cam_robot = invert(p.T_robot_cam)
    for i, t in enumerate(p.times):
        state, geo = frame_state(p, float(t))
        pair = renderer.render(state)
        tip_cam = transform_points(T_cam_robot, state.tip_robot)
        uvl, uvr = p.rig.project(tip_cam)
        tip_cam_r = p.rig.R @ tip_cam + p.rig.T
        vel = p.trajectory.velocity(float(t))
        vis_l = bool(state.hand_visible and tip_visible(uvl[0], tip_cam[2], pair.depth_left))
        vis_r = bool(state.hand_visible and tip_visible(uvr[0], tip_cam_r[2], pair.depth_right))
        row = {"index": i, "t": float(t), "tip_robot": state.tip_robot.copy(), "tip_cam": tip_cam,
               "tip_uv_left": uvl[0], "tip_uv_right": uvr[0], "tip_visible_left": vis_l,
               "tip_visible_right": vis_r, "finger_velocity_robot": vel,
               "finger_velocity_cam": transform_vectors(T_cam_robot, vel), "ee_robot": state.ee_robot.copy(),
               "device_points_robot": state.device_points_robot.copy(), **geo}
        yield state, pair, row


def constants(p: Prepared, renderer=None) -> dict:
    """The per-sequence entries of ``gt.npz``."""
    out = {"tip_radius": np.float64(TIP_RADIUS_M), "T_robot_cam": p.T_robot_cam, "scene": np.str_(p.scene_spec.name),
           "seed": np.int64(p.spec.seed), "fps": np.float64(p.trajectory.fps),
           "hand_free_frames": np.int64(p.trajectory.spec.hand_free_frames),
           "trajectory": np.str_(p.trajectory.spec.name), "phase_names": np.array(PHASES),
           "lighting": np.str_(p.spec.lighting), "occlusion": np.bool_(p.spec.occlusion),
           "effects": np.bool_(p.spec.effects),  # exact pixels model no exposure: exposure_s 0
           "exposure_s": np.float64(camera_effects(p.spec).exposure_s if p.spec.effects else 0.0),
           "passive_shape": np.str_(p.passive.shape),
           "passive_size_m": np.array(p.passive.size_m), "passive_mount_offset_robot": np.array(p.passive.mount_offset_robot),
           "surface_z": np.float64(p.scene_spec.surface_z_m)}
    if renderer is not None:
        out["background"] = np.str_(renderer.background)
        out["skin_rgb"] = np.array(renderer.skin_rgb)
    return out
