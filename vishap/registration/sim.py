"""Camera-to-robot calibration run end to end in simulation (VisHap §2.2, Eq. 3).

The simulated PHANToM (:mod:`vishap.robot.kinematics`: inverse kinematics to reach a target,
forward kinematics of the joints for ``p_robot``) carries the green calibration marker; the
synthetic stereo renderer (:class:`vishap.sim.renderer.StereoRenderer`, camera effects on:
gain, defocus, sensor noise) draws it from the true rig pose
:func:`vishap.sim.camera_placement.default_T_robot_cam`; :mod:`vishap.registration.robot_calib`
detects, triangulates, solves and reports against that truth.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np

from vishap._core.errors import CalibrationError
from vishap.registration import camera_robot
from vishap.registration.robot_calib import measure, report, select_poses, solve
from vishap.vision.rig import StereoRig

__all__ = ["SimCalibration", "calibrate_sim", "default_rig", "scaled_rig"]

_POSE_DWELL_S = 2.0  # time between poses: the arm is still when the pair is taken


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


class SimCalibration:
    """The simulated set-up: arm, marker, renderer and the true ``T_robot_cam``.

    ``rig`` (default :func:`default_rig`) at ``size`` (default: the rig's); ``scene``: the scene
    drawn around the arm (its objects may hide some poses, which are then dropped and reported).
    ``stand_off_m``: the renderer draws the arm's last joint as an 11 mm ball at the end-effector
    and its forearm 7 mm thick, both around the 5 mm marker, which would hide it; the marker is
    therefore mounted on a stylus: the drawn arm ends ``stand_off_m`` before the end-effector,
    the marker stays centred exactly at the end-effector (``ee_robot`` = forward kinematics).
    ``encoder_resolution_rad``: the joint angles paired with the images are quantised like the
    simulated plant's encoders (:class:`vishap.robot.plant.MujocoPlant`, 1.5e-4 rad); 0 = exact.
    """

    def __init__(self, *, rig: StereoRig | None = None, size=None, scene: str = "wall", seed: int = 0,
                 msaa: int = 4, stand_off_m: float = 0.022, encoder_resolution_rad: float = 1.5e-4):
        from vishap.robot import kinematics
        from vishap.robot.params import DEFAULT
        from vishap.sim.camera_placement import default_T_robot_cam
        from vishap.sim.renderer import StereoRenderer

        rig = rig if rig is not None else default_rig()
        if size is not None and tuple(size) != tuple(rig.image_size):
            rig = scaled_rig(rig, size)
        self.rig = rig
        self.size = tuple(rig.image_size)
        self.T_true = np.asarray(default_T_robot_cam(baseline_m=rig.baseline_m), dtype=np.float64)
        self.kin = kinematics
        self.box = np.column_stack([DEFAULT.workspace_min, DEFAULT.workspace_max])
        self.renderer = StereoRenderer(rig, self.T_true, scene, seed=seed, msaa=msaa)
        self.stand_off_m = float(stand_off_m)
        self.encoder_resolution_rad = float(encoder_resolution_rad)

    # the arm ------------------------------------------------------------------------------
    def reachable(self, p_robot) -> bool:
        from vishap._core.errors import ShapeError

        try:
            q = self.kin.ik(np.asarray(p_robot, dtype=np.float64))
        except ShapeError:
            return False
        return self.kin.within_joint_limits(q)

    def _move_to(self, target):
        if not self.reachable(target):
            return None
        self._q = self.kin.ik(target)  # where the arm is
        q_read = self._q
        if self.encoder_resolution_rad > 0:  # what its encoders report
            q_read = np.round(self._q / self.encoder_resolution_rad) * self.encoder_resolution_rad
        return self.kin.fk(q_read)

    def _grab(self, p_robot, target):
        from vishap.sim.state import FrameState

        p_robot = self.kin.fk(self._q)  # the marker is where the arm really is
        self._t += _POSE_DWELL_S
        pts = self.kin.link_points(self._q)
        if self.stand_off_m > 0:  # the marker on a short stylus beyond the drawn end joint
            d = pts[-1] - pts[-2]
            pts[-1] = pts[-1] - d / np.linalg.norm(d) * self.stand_off_m
        state = FrameState(t=self._t, tip_robot=np.asarray(p_robot, dtype=np.float64), hand_visible=False,
                           device_points_robot=pts, ee_robot=np.asarray(p_robot),
                           passive_object=None, marker=True)
        pair = self.renderer.render(state)
        return pair.left, pair.right

    # the procedure ------------------------------------------------------------------------
    def run(self, n_poses: int, seed: int = 0, *, robust: bool = False, keep_observations: bool = False,
            design: str = "maximin") -> dict:
        """Measure ``n_poses`` usable poses, solve two ways; reports for both.

        Poses follow the maximin sequence of :func:`select_poses` (``design="random"``: uniform
        in the box; ``"cluster"``: uniform in a 4 cm cube at the box centre — the comparisons of
        ``vishap bench registration``); when the marker is hidden at one, the arm moves on to the
        next in the sequence (``poses_visited`` counts them).

        ``closed_form``: absolute orientation of the triangulated points (VisHap's method);
        ``reprojection_refined``: then refined on the marker's image positions (the default
        result: it weighs the triangulation's poor depth resolution correctly).
        """
        self._t = 0.0
        self.renderer.reset_effects()
        # the maximin sequence beyond n: where to go instead when the marker is hidden at a pose
        m = max(3 * n_poses, n_poses + 12)
        if design == "maximin":
            targets = select_poses(m, seed, box=self.box, reachable=self.reachable)
        elif design in ("random", "cluster"):
            rng = np.random.default_rng([seed, 0xD5])
            lo, hi = self.box[:, 0] + 0.01, self.box[:, 1] - 0.01
            if design == "cluster":
                c = (lo + hi) / 2
                lo, hi = c - 0.02, c + 0.02
            cand = lo + rng.random((4 * m, 3)) * (hi - lo)
            targets = cand[[self.reachable(p) for p in cand]][:m]
        else:
            raise CalibrationError(f"pose design must be maximin, random or cluster, got {design!r}", field="design")
        obs = measure(targets, self.rig, move_to=self._move_to, grab=self._grab, needed=n_poses)
        out = {"poses": int(n_poses), "poses_visited": len(obs.targets_robot), "seed": int(seed), "design": design,
               "render_size": list(self.size)}
        fits = {}
        for name, refine in (("closed_form", False), ("reprojection_refined", True)):
            fit = solve(obs, self.rig, robust=robust, refine=refine)
            if not fit:
                raise CalibrationError(f"camera-to-robot calibration failed: {fit.reason}; "
                                       f"dropped poses: {[r for r in obs.reasons if r]}")
            fits[name] = fit
            out[name] = report(fit, obs, self.T_true, rig=self.rig, box=self.box)
        out["fit"] = fits["reprojection_refined"]
        if keep_observations:
            out["observations"] = {k: v.tolist() for k, v in obs.as_arrays().items()}
            out["observations"]["reasons"] = list(obs.reasons)
            # marker detection error against the true projection of the end-effector
            ok = obs.ok
            p_true = np.array([self.kin.fk(self.kin.ik(t)) for t in obs.targets_robot[ok]]).reshape(-1, 3)
            p_cam = (p_true - self.T_true[:3, 3]) @ self.T_true[:3, :3]
            uv_l, uv_r = self.rig.project(p_cam)
            err = np.concatenate([np.linalg.norm(uv_l - obs.uv_left[ok], axis=1),
                                  np.linalg.norm(uv_r - obs.uv_right[ok], axis=1)])
            out["marker_error_px"] = {"median": float(np.median(err)), "max": float(np.max(err))}
            out["triangulation_error_mm"] = {
                "median": float(np.median(np.linalg.norm(obs.p_cam[ok] - p_cam, axis=1)) * 1e3),
                "max": float(np.max(np.linalg.norm(obs.p_cam[ok] - p_cam, axis=1)) * 1e3)}
        return out

    def close(self) -> None:
        self.renderer.close()


def calibrate_sim(*, n_poses: int, seed: int = 0, rig_path=None, size=None, robust: bool = False,
                  out=None, poses_out=None, scene: str = "wall") -> dict:
    """``vishap calibrate robot --sim``: run, save ``out`` (tied to the rig) and return the JSON record."""
    rig = StereoRig.load(rig_path) if rig_path else None
    sim = SimCalibration(rig=rig, size=size, seed=seed, scene=scene)
    try:
        res = sim.run(n_poses, seed, robust=robust, keep_observations=True)
    finally:
        sim.close()
    fit = res.pop("fit")
    main = res["reprojection_refined"]
    record = {
        "poses": n_poses,
        "poses_visited": res["poses_visited"],
        "poses_used": main["poses_used"],
        "per_axis_error_mm": main["per_axis_error_mm"],
        "rms_mm": main["rms_mm"],
        "rotation_error_deg": main["rotation_error_deg"],
        "translation_error_mm": main["translation_error_mm"],
        "workspace_per_axis_error_mm": main["workspace_per_axis_error_mm"],
        "reprojection_rms_px": main.get("reprojection_rms_px"),
        "method": "closed-form absolute orientation refined on reprojection error" + (" (robust)" if robust else ""),
        "closed_form": res["closed_form"],
        "poses_dropped": main["poses_dropped"],
        "marker_error_px": res["marker_error_px"],
        "triangulation_error_mm": res["triangulation_error_mm"],
        "pose_set_robot": [[round(v, 5) for v in p] for p in res["observations"]["targets_robot"]],
        "render_size": res["render_size"],
    }
    if out is not None:
        camera_robot.save(out, fit.T, {k: v for k, v in record.items() if k != "pose_set_robot"}, rig=sim.rig)
        record["out"] = str(out)
    if poses_out is not None:
        Path(poses_out).parent.mkdir(parents=True, exist_ok=True)
        np.savez(poses_out, **{k: np.asarray(v) for k, v in res["observations"].items()}, T_true=sim.T_true,
                 T_robot_cam=fit.T)
        record["poses_out"] = str(poses_out)
    return record
