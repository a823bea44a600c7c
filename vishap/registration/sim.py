"""Camera-to-robot calibration in simulation: the ``sim`` device watched by rendered cameras (VisHap §2.2, Eq. 3).

``vishap calibrate robot --sim`` is ``vishap calibrate robot --device sim --cameras render``: the
shared procedure (:mod:`vishap.registration.procedure`) drives the MuJoCo PHANToM
(:class:`vishap.robot.plant.MujocoPlant`, joints read through its encoder model) to each pose with
the servo loop, and :class:`RenderedCameras` — the synthetic stereo renderer
(:class:`vishap.sim.renderer.StereoRenderer`, camera effects on: gain, defocus, sensor noise) at the
true rig pose :func:`vishap.sim.camera_placement.default_T_robot_cam` — draws the arm and its green
marker where the plant's own tip site is. The truth is used only to report against.
"""
from __future__ import annotations

import numpy as np

from vishap._core.errors import ConfigError
from vishap.registration.procedure import Truth, calibrate, run_calibration
from vishap.vision.capture import StereoSource
from vishap.vision.rig import StereoRig

__all__ = ["RenderedCameras", "SimCalibration", "calibrate_sim", "default_rig", "scaled_rig"]


def default_rig(size=(640, 480)) -> StereoRig:
    """The synthetic data's rig: 60° horizontal field of view, 60 mm baseline, no distortion."""
    return StereoRig.from_fov(int(size[0]), int(size[1]), 60.0, 0.06)


def scaled_rig(rig: StereoRig, size) -> StereoRig:
    """The same cameras at another image size (intrinsics scaled; rectification recomputed)."""
    sx, sy = size[0] / rig.image_size[0], size[1] / rig.image_size[1]
    S = np.diag([sx, sy, 1.0])

    def k(K):
        K2 = S @ K
        K2[0, 2] = (K[0, 2] + 0.5) * sx - 0.5  # pixel centres stay pixel centres
        K2[1, 2] = (K[1, 2] + 0.5) * sy - 0.5
        return K2

    return StereoRig(image_size=(int(size[0]), int(size[1])), K_left=k(rig.K_left), dist_left=rig.dist_left,
                     K_right=k(rig.K_right), dist_right=rig.dist_right, R=rig.R, T=rig.T)


class RenderedCameras(StereoSource):
    """A stereo source that renders the simulated device where it truly is, one pair per frame pulled.

    ``device`` must be the MuJoCo plant: the end-effector is its tip site (MuJoCo's own kinematics,
    not the encoder readings), the arm is drawn through it. ``stand_off_m``: the renderer draws the
    arm's last joint as an 11 mm ball and its forearm 7 mm thick around the 5 mm marker, which would
    hide it; the marker is therefore mounted on a stylus: the drawn arm ends ``stand_off_m`` before
    the end-effector, the marker stays centred exactly on it. ``ee_by_frame`` keeps the true
    end-effector of every frame (for the report against the truth only).
    """

    name = "render"

    def __init__(self, renderer, device, *, stand_off_m: float = 0.022):
        super().__init__()
        if not callable(getattr(device, "tip_position", None)):
            raise ConfigError(f"rendered cameras need the simulated device ('sim'), got {type(device).__name__}",
                              field="cameras")
        self.renderer = renderer
        self.device = device
        self.stand_off_m = float(stand_off_m)
        self.ee_by_frame: dict[int, np.ndarray] = {}

    def _raw(self):
        from vishap.robot import kinematics
        from vishap.sim.state import FrameState

        i = 0
        while True:
            ee = self.device.tip_position()
            pts = kinematics.link_points(kinematics.ik(ee, self.device.params), self.device.params)
            if self.stand_off_m > 0:  # the marker on a short stylus beyond the drawn end joint
                d = pts[-1] - pts[-2]
                pts[-1] = pts[-1] - d / np.linalg.norm(d) * self.stand_off_m
            state = FrameState(t=self.device.time, tip_robot=ee, hand_visible=False, device_points_robot=pts,
                               ee_robot=ee, passive_object=None, marker=True)
            pair = self.renderer.render(state)
            self.ee_by_frame[i] = ee
            yield i, state.t, pair.left, pair.right
            i += 1


class SimCalibration:
    """The simulated set-up: rig, renderer and the true ``T_robot_cam``; each :meth:`run` opens a fresh
    ``sim`` device and runs the shared procedure on it.

    ``rig`` (default :func:`default_rig`) at ``size`` (default: the rig's); ``scene``: the scene
    drawn around the arm (its objects may hide some poses, which are then dropped and reported).
    ``sensor``: the plant's joint sensing (``"encoder"``: 1.5e-4 rad counts, backward-difference rates).
    """

    def __init__(self, *, rig: StereoRig | None = None, size=None, scene: str = "wall", seed: int = 0,
                 msaa: int = 4, stand_off_m: float = 0.022, sensor: str = "encoder"):
        from vishap.sim.camera_placement import default_T_robot_cam
        from vishap.sim.renderer import StereoRenderer

        rig = rig if rig is not None else default_rig()
        if size is not None and tuple(size) != tuple(rig.image_size):
            rig = scaled_rig(rig, size)
        self.rig = rig
        self.size = tuple(rig.image_size)
        self.T_true = np.asarray(default_T_robot_cam(baseline_m=rig.baseline_m), dtype=np.float64)
        self.renderer = StereoRenderer(rig, self.T_true, scene, seed=seed, msaa=msaa)
        self.stand_off_m = float(stand_off_m)
        self.sensor = sensor

    def open(self):
        """A fresh ``sim`` device at home and the rendered cameras watching it."""
        from vishap.robot.drivers import open_device

        self.renderer.reset_effects()
        device = open_device("sim", sensor=self.sensor)
        return device, RenderedCameras(self.renderer, device, stand_off_m=self.stand_off_m)

    def run(self, n_poses: int, seed: int = 0, *, robust: bool = False, keep_observations: bool = False,
            design: str = "maximin") -> dict:
        """Measure ``n_poses`` usable poses and solve two ways (see :func:`procedure.calibrate`).

        ``closed_form``: absolute orientation of the triangulated points (VisHap's method);
        ``reprojection_refined``: then refined on the marker's image positions (the default
        result: it weighs the triangulation's poor depth resolution correctly).
        """
        device, cameras = self.open()
        try:
            out = calibrate(device, cameras, self.rig, n_poses=n_poses, seed=seed, robust=robust, design=design,
                            truth=Truth(self.T_true, cameras.ee_by_frame))
        finally:
            device.close()
        out["render_size"] = list(self.size)
        if not keep_observations:
            out.pop("observations")
        return out

    def close(self) -> None:
        self.renderer.close()


def calibrate_sim(*, n_poses: int, seed: int = 0, rig_path=None, size=None, robust: bool = False,
                  out=None, poses_out=None, scene: str = "wall", progress: bool = False) -> dict:
    """``vishap calibrate robot --sim``: the shared procedure on the ``sim`` device and rendered cameras;
    saves ``out`` (tied to the rig) and returns the JSON record."""
    rig = StereoRig.load(rig_path) if rig_path else None
    sim = SimCalibration(rig=rig, size=size, seed=seed, scene=scene)
    try:
        device, cameras = sim.open()
        try:
            record = run_calibration(device, cameras, sim.rig, n_poses=n_poses, seed=seed, robust=robust,
                                     truth=Truth(sim.T_true, cameras.ee_by_frame), out=out, poses_out=poses_out,
                                     describe={"device": "sim", "cameras": "render"}, progress=progress)
        finally:
            device.close()
    finally:
        sim.close()
    record["render_size"] = list(sim.size)
    return record
