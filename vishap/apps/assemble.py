"""Build every stage of a batch demo from its :class:`DemoConfig` (see :mod:`vishap.apps.stages`).

The rig, the true camera placement and the renderer are the simulated world's; vision,
registration (a calibration file, or the camera-robot calibration run in simulation on rendered
marker images), world, device and tactile layer are the system's own stages — the demo never
hands the system a ground-truth value.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from vishap._core.errors import CalibrationError
from vishap._core.pose import invert
from vishap.apps.config import DemoConfig
from vishap.apps.stages import Stages, need

__all__ = ["build", "meta", "calibrate", "RIG_HFOV_DEG", "RIG_BASELINE_M"]

RIG_HFOV_DEG = 60.0
RIG_BASELINE_M = 0.06
STATE_CODES = {"none": 0, "concentrated": 1, "distributed": 2, "slip": 3}


def make_rig(cfg: DemoConfig):
    from vishap.vision.rig import StereoRig

    return StereoRig.from_fov(cfg.width, cfg.height, RIG_HFOV_DEG, RIG_BASELINE_M)


def calibrate(cfg: DemoConfig, rig, out: Path, *, poses: int = 12) -> tuple[np.ndarray | None, dict]:
    """The system's camera → robot transform: from ``cfg.calib``, or calibrated in simulation.

    A missing or unreadable calibration file is not fatal in a batch run: the run goes on without a
    calibration (the guard retreats the device and the summary counts it) and a warning names the
    file. Without ``cfg.calib`` the camera-robot procedure runs on the simulated device
    (:func:`vishap.registration.sim.calibrate_sim`: the arm visits ``poses`` targets spanning the
    reachable box, its green marker is rendered, detected and triangulated, and the absolute
    orientation is solved, VisHap Eq. 3); the result is saved as ``OUT/camera_robot.yaml``.
    """
    cr = need("vishap.registration.camera_robot", "registration (camera-robot file)")
    if cfg.calib is not None:
        try:
            return cr.load(cfg.calib, rig=rig), {"source": str(cfg.calib)}
        except CalibrationError as exc:
            print(f"vishap demo: warning: calibration unavailable, the device will retreat: {exc}", file=sys.stderr)
            return None, {"source": str(cfg.calib), "error": str(exc)}
    sim = need("vishap.registration.sim", "registration (simulated camera-robot calibration)")
    rig_path = rig.save(out / "rig.yaml")
    rec = sim.calibrate_sim(n_poses=poses, seed=cfg.seed, rig_path=rig_path, out=out / "camera_robot.yaml",
                            scene=cfg.scene)
    keep = ("poses", "poses_used", "per_axis_error_mm", "rms_mm", "rotation_error_deg", "translation_error_mm",
            "workspace_per_axis_error_mm", "reprojection_rms_px")
    return cr.load(out / "camera_robot.yaml", rig=rig), {"source": "simulation", **{k: rec.get(k) for k in keep}}


def build(cfg: DemoConfig, out: Path) -> Stages:
    sim_place = need("vishap.sim.camera_placement", "synthetic camera placement")
    sim_state = need("vishap.sim.state", "synthetic frame state")
    sim_render = need("vishap.sim.renderer", "synthetic renderer")
    vision = need("vishap.vision.pipeline", "vision")
    capture = need("vishap.vision.capture", "vision capture")
    world_scene = need("vishap.world.scene", "world (scenes)")
    kin = need("vishap.robot.kinematics", "robot kinematics")
    mjcf = need("vishap.robot.mjcf", "robot (model)")
    runtime = need("vishap.runtime", "runtime")

    rig = make_rig(cfg)
    T_true = sim_place.default_T_robot_cam(baseline_m=RIG_BASELINE_M)
    scene = world_scene.load_scene(cfg.scene)
    obj = scene.objects[0]
    po_spec = scene.passive_object
    po_render = sim_state.PassiveObject(shape=po_spec.shape, size_m=tuple(po_spec.size_m))
    mount = np.asarray(po_render.mount_offset_robot, float)
    renderer = sim_render.StereoRenderer(rig, T_true, cfg.scene, seed=cfg.seed)
    build_mod = need("vishap.robot.build", "robot (servo builder)")
    shape = "sphere" if po_spec.shape == "sphere" else "plate"
    size = (po_spec.size_m[0] / 2,) if shape == "sphere" else tuple(po_spec.size_m)
    travel = None
    if cfg.travel_speed_m_s is not None:
        from vishap.robot.travel import TravelLimiter

        travel = TravelLimiter(cfg.travel_speed_m_s, cfg.travel_accel_m_s2)
    servo = build_mod.build_servo(mjcf.PassiveObject(shape, size, po_spec.mass_kg), substeps=cfg.substeps,
                                  sensor=cfg.encoder, policy=cfg.servo_policy, travel=travel)
    plant, controller = servo.device, servo.controller
    T_est, calib_report = calibrate(cfg, rig, out)
    world = make_world(cfg, scene, rig, T_est)
    lim = plant.limits
    lo = np.asarray(lim.workspace_min, float)
    hi = np.asarray(lim.workspace_max, float)
    centre = np.asarray(obj.centre, float)
    n = np.asarray(obj.normal, float)
    retreat = centre - cfg.retreat_m * n - mount
    guard = runtime.TargetGuard(lo, hi, retreat, stale_after_s=cfg.stale_after_s, retreat_after_s=cfg.retreat_after_s)
    tactile, tactile_step_state = _build_tactile(cfg, scene)

    st = Stages(
        cfg=cfg, rig=rig, T_true=T_true, T_cam_robot_true=invert(T_true), T_est=T_est, calib_report=calib_report,
        renderer=renderer, vision=vision.VisionPipeline(rig), StereoFrame=capture.StereoFrame, controller=controller,
        scene=scene, scene_object=obj, world=world, plant=plant, servo=servo, guard=guard,
        mount_offset=mount, tip_radius_m=float(sim_state.TIP_RADIUS_M),
        face_half_extent=(0.5 * float(po_spec.size_m[0]), 0.5 * float(po_spec.size_m[1])),
        force_limit_n=float(lim.peak_force_n), tactile=tactile, kin=kin, po_render=po_render,
    )
    names = [o.name for o in scene.objects]
    st.object_index = names.index
    st.render = lambda t, *, tip_robot, finger_dir, flexion, hand_visible, q, ee: renderer.render(
        sim_state.FrameState(t=t, tip_robot=tip_robot, finger_dir_robot=np.asarray(finger_dir, float),
                             flexion=flexion, hand_visible=hand_visible, device_points_robot=kin.link_points(q),
                             ee_robot=np.asarray(ee, float), passive_object=po_render))
    st.vision_result = _vision_result
    st.contact_sample = lambda t, pad, v_pad, F_on_finger, finger_dir=None: _contact_sample(
        obj, t, pad, v_pad, F_on_finger, finger_dir)
    st.pad_force = _pad_force(obj, st.face_half_extent)
    st.tactile_state = tactile_step_state
    st.overlay = lambda pair, row, dev, target, t, extra=(): _overlay(st, pair, row, dev, target, t, extra)
    return st


def make_world(cfg: DemoConfig, scene, rig, T_est):
    """The world with a Kalman finger predictor whose measurement noise matches the stereo model
    (from the calibrated camera position; 5 mm without a calibration) and whose latency is the
    vision latency plus half a scene period (the mean wait for the scene tick)."""
    world_mod = need("vishap.world.world", "world")
    pred = need("vishap.world.predictor", "world (predictor)")
    noise = cfg.finger_noise_m or (0.005 if T_est is None else stereo_noise_m(rig, T_est, scene.objects[0].centre))
    return world_mod.World(scene, predictor=pred.KalmanPredictor(meas_std_m=noise),
                           latency_s=cfg.vision_latency_s + 0.5 / cfg.scene_hz, contact_model=cfg.contact_model)


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


def _vision_result(est) -> dict:
    found = bool(est.found and est.p_cam is not None)
    return {
        "found": found,
        "p_cam": np.asarray(est.p_cam, float).reshape(3) if found else np.full(3, np.nan),
        "uv_left": np.full(2, np.nan) if est.uv_left is None else np.asarray(est.uv_left, float).reshape(2),
        "uv_right": np.full(2, np.nan) if est.uv_right is None else np.asarray(est.uv_right, float).reshape(2),
        "confidence": float(est.confidence),
        "vision_ms": float(est.timings.get("total_ms", np.nan)),
    }


def _contact_sample(obj, t, pad, v_pad, F_on_finger, finger_dir_robot=None):
    """The tactile layer's contact sample in the object frame; with the finger's pointing direction
    (robot frame) the sleeve's patch follows the finger's pitch (fingertip press or flat pad)."""
    from vishap.tactile.contact import ContactSample

    p_obj = obj.local(pad)
    v_obj = obj.R.T @ np.asarray(v_pad, float)
    fn = float(np.asarray(F_on_finger, float) @ np.asarray(obj.normal, float))
    d_obj = None if finger_dir_robot is None else obj.R.T @ np.asarray(finger_dir_robot, float)
    return ContactSample(t=t, position=p_obj, normal_force_n=max(0.0, fn), velocity=v_obj, in_contact=fn > 0.0,
                         finger_dir=d_obj)


def _pad_force(obj, half_extent):
    """The finger pad's force on the passive object: the world's compliant pad (normal and tangential
    spring-dampers with slip) when available."""
    try:
        from vishap.world.closed_loop import FingerPad
    except ImportError:
        from vishap.apps.contact import FingerPad as _Frictionless

        pad = _Frictionless()
        n = np.asarray(obj.normal, float)
        return lambda p_f, v_f, p_dev, v_dev: -pad.evaluate(p_f, v_f, p_dev, v_dev, n, half_extent).force_on_finger
    pad = FingerPad()
    n = np.asarray(obj.normal, float)
    half = min(half_extent)
    return lambda p_f, v_f, p_dev, v_dev: pad.force_on_device(p_f, v_f, p_dev, v_dev, n, half)


def _build_tactile(cfg: DemoConfig, scene):
    """The tactile sleeve renderer for the scene's surface (attributes from the demo module)."""
    from vishap.apps.demos import demo_module

    tr = need("vishap.tactile.renderer", "tactile")
    tcfg = need("vishap.tactile.config", "tactile (config)")
    surface = tcfg.SurfaceAttributes(**demo_module(cfg.scene).surface(scene))
    renderer = tr.TactileRenderer(surface=surface, seed=cfg.seed)

    def state(out) -> int:
        s = getattr(out, "state", None)
        s = getattr(s, "value", s)
        return STATE_CODES.get(str(s), 0) if s is not None else 0

    return renderer, state


def _overlay(st, pair, row, dev, target, t, extra=()):
    from vishap.apps.overlay import draw_overlay, object_outline_robot

    T_cam_robot = invert(st.T_est) if st.T_est is not None else st.T_cam_robot_true
    outlines = [object_outline_robot(o.centre, o.normal, 2.0 * np.asarray(o.half[:2], float)) for o in st.scene.objects]
    X = target["X_d"]
    lines = [f"{st.cfg.scene}  t={t:6.3f}s  frame {row['index']}",
             "tip: " + ("found" if row["found"] else ("frame DROPPED" if row["dropped"] else "not found")), *extra]
    return draw_overlay(pair.left, pair.right, rig=st.rig, T_cam_robot=T_cam_robot,
                        tip_uv=(row["uv_left"] if row["found"] else None, row["uv_right"] if row["found"] else None),
                        device_points_robot=np.vstack([st.kin.link_points(dev.q), dev.p_robot + st.mount_offset]),
                        object_outlines_robot=outlines,
                        target_robot=None if not np.all(np.isfinite(X)) else X + st.mount_offset, lines=lines)


def meta(cfg: DemoConfig, st: Stages) -> dict:
    import vishap

    from vishap.apps.log import code_version

    return {
        "format": "vishap.demo_log/1",
        "version": vishap.__version__,
        "config": cfg.model_dump(),
        "rig": st.rig.to_filestorage_string(),
        "T_robot_cam_true": st.T_true,
        "T_robot_cam_est": st.T_est,
        "calibration": st.calib_report,
        "mount_offset": st.mount_offset,
        "tip_radius_m": st.tip_radius_m,
        "force_limit_n": st.force_limit_n,
        "continuous_force_n": float(st.plant.limits.continuous_force_n),
        "object": {"name": st.scene_object.name, "normal": np.asarray(st.scene_object.normal, float),
                   "centre": np.asarray(st.scene_object.centre, float),
                   "target": getattr(st.scene_object.mode, "target", "projection")},
        "python": sys.version.split()[0],
        "code": code_version(),
    }
