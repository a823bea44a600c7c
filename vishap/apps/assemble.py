"""Build the parts of a run from its :class:`DemoConfig`: the core (scene step, servo cycle) and the
simulated world around it (renderer, scripted finger) for a batch demo.

The rig, the true camera placement and the renderer are the simulated world's; vision,
registration (a calibration file, or the camera-robot calibration run in simulation on rendered
marker images), world, device and tactile layer are the system's own — the demo never hands the
system a ground-truth value. Live mode builds the same core (:func:`make_world`,
:func:`make_scene_step`, :func:`make_cycle`) around cameras or a recording and a device.
"""
from __future__ import annotations

import sys
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from vishap._core.pose import invert
from vishap.apps.config import DemoConfig
from vishap.world.finger import TIP_RADIUS_M

__all__ = ["build", "meta", "calibrate", "make_world", "make_scene_step", "make_servo_side", "make_cycle", "vision_result",
           "RIG_HFOV_DEG", "RIG_BASELINE_M", "TIP_RADIUS_M"]

RIG_HFOV_DEG = 60.0
RIG_BASELINE_M = 0.06


def make_rig(cfg: DemoConfig):
    from vishap.vision.rig import StereoRig

    return StereoRig.from_fov(cfg.width, cfg.height, RIG_HFOV_DEG, RIG_BASELINE_M)


def calibrate(cfg: DemoConfig, rig, out: Path, *, poses: int = 12) -> tuple[np.ndarray | None, dict]:
    """The system's camera → robot transform: from ``cfg.calib``, or calibrated in simulation.

    A calibration file that is missing or unreadable stops the run before it starts, naming the
    file: a run without it would only keep the device retreating (a lost calibration during a run
    is the ``calibration_missing`` fault). Without ``cfg.calib`` the camera-robot procedure runs on the simulated device
    (:func:`vishap.registration.sim.calibrate_sim`: the arm visits ``poses`` targets spanning the
    reachable box, its green marker is rendered, detected and triangulated, and the absolute
    orientation is solved, VisHap Eq. 3); the result is saved as ``OUT/camera_robot.yaml``.
    """
    from vishap.registration import camera_robot as cr

    if cfg.calib is not None:
        return cr.load(cfg.calib, rig=rig), {"source": str(cfg.calib)}
    from vishap.registration.sim import calibrate_sim

    rig_path = rig.save(out / "rig.yaml")
    rec = calibrate_sim(n_poses=poses, seed=cfg.seed, rig_path=rig_path, out=out / "camera_robot.yaml", scene=cfg.scene)
    keep = ("poses", "poses_used", "per_axis_error_mm", "rms_mm", "rotation_error_deg", "translation_error_mm",
            "workspace_per_axis_error_mm", "reprojection_rms_px")
    return cr.load(out / "camera_robot.yaml", rig=rig), {"source": "simulation", **{k: rec.get(k) for k in keep}}


def make_world(cfg: DemoConfig, scene, rig, T_est):
    """The world with a Kalman finger predictor whose measurement noise matches the stereo model
    (from the calibrated camera position; 5 mm without a calibration) and whose latency is the
    vision latency plus half a scene period (the mean wait for the scene tick)."""
    from vishap.world.predictor import KalmanPredictor
    from vishap.world.world import World

    noise = cfg.finger_noise_m or (0.005 if T_est is None else stereo_noise_m(rig, T_est, scene.objects[0].centre))
    return World(scene, predictor=KalmanPredictor(meas_std_m=noise),
                 latency_s=cfg.vision_latency_s + 0.5 / cfg.scene_hz, contact_model=cfg.contact_model)


def make_scene_step(world, T_est):
    from vishap.runtime.core import SceneStep

    return SceneStep(world, T_est, tip_radius_m=TIP_RADIUS_M, mount_offset=world.scene.passive_object.mount_offset_m)


def make_servo_side(cfg: DemoConfig, scene, *, device: str = "sim"):
    """The device (:func:`vishap.runtime.assembly.open_device`; ``sim``: the MuJoCo PHANToM with the
    scene's passive object, ``cfg``'s substeps and joint sensor) behind its guarded servo step with
    ``cfg``'s target policy, travel limiter (:meth:`TravelLimiter.for_approach`) and guard timings:
    what the demos, live mode and the world benchmark's closed loop run."""
    from vishap.robot.travel import TravelLimiter
    from vishap.runtime.assembly import make_servo_step, open_device

    dev = (open_device("sim", passive_object=scene.passive_object.for_mujoco(), substeps=cfg.substeps, sensor=cfg.encoder)
           if device == "sim" else open_device(device))
    travel = None if cfg.travel_speed_m_s is None else TravelLimiter.for_approach(cfg.travel_speed_m_s, cfg.travel_accel_m_s2)
    return make_servo_step(dev, scene, policy=cfg.servo_policy, travel=travel, retreat_m=cfg.retreat_m,
                           stale_after_s=cfg.stale_after_s, retreat_after_s=cfg.retreat_after_s)


def make_cycle(cfg: DemoConfig, scene, log, *, device: str = "sim", finger=None, tactile: bool = True):
    """The 1 kHz side of a run: the device and its guarded servo step (:func:`make_servo_side`) and the
    tactile sleeve, as a :class:`~vishap.apps.cycle.ServoCycle` writing into ``log``."""
    from vishap.apps.cycle import ServoCycle

    step = make_servo_side(cfg, scene, device=device)
    return ServoCycle(step, scene_object=scene.objects[0], log=log, finger=finger,
                      half_size_m=scene.passive_object.half_size_m, tactile=make_tactile(cfg, scene) if tactile else None)


def make_tactile(cfg: DemoConfig, scene):
    """The tactile sleeve renderer for the scene's surface (attributes from the demo module)."""
    from vishap.apps.demos import demo_module
    from vishap.tactile.config import SurfaceAttributes
    from vishap.tactile.renderer import TactileRenderer

    return TactileRenderer(surface=SurfaceAttributes(**demo_module(cfg.scene).surface(scene)), seed=cfg.seed)


def build(cfg: DemoConfig, out: Path, log) -> SimpleNamespace:
    """Every part of a batch demo (renderer and scripted finger around the system's core)."""
    from vishap.apps.cycle import ScriptedFinger
    from vishap.apps.script import script_for
    from vishap.robot import kinematics as kin
    from vishap.sim.camera_placement import default_T_robot_cam
    from vishap.sim.renderer import StereoRenderer
    from vishap.sim.state import FrameState
    from vishap.vision.capture import StereoFrame
    from vishap.vision.pipeline import VisionPipeline
    from vishap.world.scene import load_scene

    rig = make_rig(cfg)
    T_true = default_T_robot_cam(baseline_m=RIG_BASELINE_M)
    scene = load_scene(cfg.scene)
    po_render = scene.passive_object.for_renderer()
    renderer = StereoRenderer(rig, T_true, cfg.scene, seed=cfg.seed)
    script = script_for(cfg.scene, hidden_s=cfg.background_frames / cfg.camera_hz)
    cycle = make_cycle(cfg, scene, log, finger=ScriptedFinger(script))
    T_est, calib_report = calibrate(cfg, rig, out)
    world = make_world(cfg, scene, rig, T_est)
    st = SimpleNamespace(
        cfg=cfg, rig=rig, T_true=T_true, T_cam_robot_true=invert(T_true), T_est=T_est, calib_report=calib_report,
        renderer=renderer, vision=VisionPipeline(rig), StereoFrame=StereoFrame, scene=scene,
        scene_object=scene.objects[0], world=world, scene_step=make_scene_step(world, T_est), cycle=cycle,
        plant=cycle.step.device, guard=cycle.step.guard, script=script, kin=kin, po_render=po_render,
        mount_offset=np.asarray(scene.passive_object.mount_offset_m, float), tip_radius_m=TIP_RADIUS_M,
        force_limit_n=float(cycle.step.device.limits.peak_force_n))
    st.render = lambda t, *, tip_robot, finger_dir, flexion, hand_visible, q, ee: renderer.render(
        FrameState(t=t, tip_robot=tip_robot, finger_dir_robot=np.asarray(finger_dir, float), flexion=flexion,
                   hand_visible=hand_visible, device_points_robot=kin.link_points(q), ee_robot=np.asarray(ee, float),
                   passive_object=po_render))
    st.overlay = lambda pair, row, dev, target, t, extra=(): _overlay(st, pair, row, dev, target, t, extra)
    return st


def stereo_noise_m(rig, T_robot_cam, p_robot) -> float:
    """Isotropic-equivalent σ (m) of a triangulated point at ``p_robot``: the vision's pixel σ
    propagated through the rig (lateral z·σ/f, depth z²·√2·σ/(f·B)); what the world's Kalman
    predictor should assume. Uses the rig's geometry (the camera distance is a property of the set-up)."""
    from vishap.vision.stereo import StereoConfig

    sigma_px = StereoConfig().sigma_px
    z = float(np.linalg.norm(np.asarray(p_robot, float) - np.asarray(T_robot_cam, float)[:3, 3]))
    f = rig.rectified_fx_px
    lateral = z * sigma_px / f
    depth = z * z * np.sqrt(2.0) * sigma_px / (f * rig.rectified_baseline_m)
    return float(np.sqrt((2 * lateral ** 2 + depth ** 2) / 3.0))


def vision_result(est) -> dict:
    found = bool(est.found and est.p_cam is not None)
    return {
        "found": found,
        "p_cam": np.asarray(est.p_cam, float).reshape(3) if found else np.full(3, np.nan),
        "uv_left": np.full(2, np.nan) if est.uv_left is None else np.asarray(est.uv_left, float).reshape(2),
        "uv_right": np.full(2, np.nan) if est.uv_right is None else np.asarray(est.uv_right, float).reshape(2),
        "confidence": float(est.confidence),
        "lost": bool(not found and est.lost),
        "vision_ms": float(est.timings.get("total_ms", np.nan)),
    }


def _overlay(st, pair, row, dev, target, t, extra=()):
    from vishap.apps.overlay import draw_overlay, object_outline_robot

    T_cam_robot = invert(st.T_est) if st.T_est is not None else st.T_cam_robot_true
    outlines = [object_outline_robot(o.centre, o.normal, 2.0 * np.asarray(o.half[:2], float)) for o in st.scene.objects]
    X = np.asarray(target.X_ee, float)
    lines = [f"{st.cfg.scene}  t={t:6.3f}s  frame {row['index']}",
             "tip: " + ("found" if row["found"] else ("frame DROPPED" if row["dropped"] else "not found")), *extra]
    return draw_overlay(pair.left, pair.right, rig=st.rig, T_cam_robot=T_cam_robot,
                        tip_uv=(row["uv_left"] if row["found"] else None, row["uv_right"] if row["found"] else None),
                        device_points_robot=np.vstack([st.kin.link_points(dev.q), dev.p_robot + st.mount_offset]),
                        object_outlines_robot=outlines,
                        target_robot=None if not np.all(np.isfinite(X)) else X + st.mount_offset, lines=lines)


def meta(cfg: DemoConfig, *, rig, T_true, T_est, calib_report, scene, force_limit_n: float, continuous_force_n: float,
         hold_friction_n: float = float("nan"), hold_ramp_m: float = float("nan"), mode: str = "batch",
         source: str | None = None,
         device: str = "sim") -> dict:
    """The log's metadata: one schema for batch and live runs (``mode``). ``hold_friction_n``,
    ``hold_ramp_m``: the device friction the servo's surface hold cancels and the height over which
    its share grows (:class:`~vishap.runtime.core.ContactRenderer`; replay renders the hold with them)."""
    import vishap

    from vishap.apps.log import code_version

    obj = scene.objects[0]
    return {
        "format": "vishap.demo_log/1",
        "mode": mode,
        "source": source,
        "device": device,
        "version": vishap.__version__,
        "config": cfg.model_dump(),
        "rig": rig.to_filestorage_string(),
        "T_robot_cam_true": T_true,
        "T_robot_cam_est": T_est,
        "calibration": calib_report,
        "mount_offset": np.asarray(scene.passive_object.mount_offset_m, float),
        "tip_radius_m": TIP_RADIUS_M,
        "force_limit_n": force_limit_n,
        "continuous_force_n": continuous_force_n,
        "hold_friction_n": hold_friction_n,
        "hold_ramp_m": hold_ramp_m,
        "object": {"name": obj.name, "normal": np.asarray(obj.normal, float), "centre": np.asarray(obj.centre, float),
                   "target": getattr(obj.mode, "target", "projection")},
        "python": sys.version.split()[0],
        "code": code_version(),
    }
