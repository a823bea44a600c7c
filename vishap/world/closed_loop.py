"""Closed-loop meeting of a simulated finger and the MuJoCo device (VisHap §2.2–2.3, Fig. 6).

A finger, driven by a trajectory (:mod:`vishap.world.trajectories`), approaches an object, meets
the device's passive object, presses, slides and leaves. Its pad is compliant (normal and
tangential spring-dampers with Coulomb slip, :class:`FingerPad`) and pushes on the device's tip
through :meth:`MujocoPlant.apply_tip_force`. A simulated camera (:class:`VisionModel`) samples the
fingertip at the vision rate with latency, noise and drop-outs; the :class:`~vishap.world.World`
turns each sample into ``X_d``; the servo (:class:`vishap.robot.servo.ServoLoop`) runs at 1 kHz.

The system runs as it does in the demo and live mode: the camera model's samples go through the
core's scene step and servo step (:mod:`vishap.runtime.core`: guard, force law and object gain
``ᴼΛ`` per Eq. 8–9, controller with the gains file's gains, travel limiter), the servo side built by
the demos' own assembly code (:func:`vishap.apps.assemble.make_servo_side`: the approach travel
limiter, encoder readings, the demos' physics substeps). The servo reads its encoders; the finger pad
and every figure below read the plant's true tip state.

Per approach we measure (:class:`ApproachResult`): the contact time (the pad first touches the
passive object, or the finger crosses the surface if it misses), whether the device was in place
(within ``in_place_m`` of the ideal contact point) and for how long before (lead time), the
contact-position error, and during the press the fingertip depth against the device's normal
force (``Λ f`` + law, without gravity compensation — VisHap Fig. 6's quantity).

Whether the device was *ready* at the touch (issue 16; :func:`device_ready`) says more than "in
place within 1 mm" about what the finger feels on a 40 mm plate: still along the normal, moving with
the finger sideways, its face on the virtual surface, the finger landing well inside the face.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from time import perf_counter

import numpy as np

from vishap.vision.track import TrackerConfig
from vishap.world.scene import Scene
from vishap.world.trajectories import FingerTrajectory
from vishap.world.world import BASE_CONTACT_M, World

__all__ = ["FingerPad", "VisionModel", "ApproachResult", "run_approach", "make_device", "device_ready", "ready_checks"]


@dataclass
class FingerPad:
    """Compliant fingertip pad (N/m, N·s/m); ``mu`` is the skin–plate friction coefficient."""

    k_normal_n_m: float = 1000.0
    c_normal_n_s_m: float = 1.5
    k_tangential_n_m: float = 800.0
    c_tangential_n_s_m: float = 1.0
    mu: float = 1.0

    def __post_init__(self):
        self.reset()

    def reset(self) -> None:
        self.anchor: np.ndarray | None = None  # finger − device offset (tangential) at touch-down

    def force_on_device(self, p_f, v_f, p_dev, v_dev, n, half_size: float) -> np.ndarray:
        """Force (N, robot frame) the finger applies to the passive object's top face at ``p_dev``.

        ``p_f`` is the pad's lowest point; the face is the square of ``half_size`` around ``p_dev``
        in the plane of normal ``n``. Zero when apart.
        """
        r = p_f - p_dev
        overlap = -float(n @ r)
        rt = r + n * overlap  # tangential offset finger − device
        if overlap <= 0.0 or abs(rt[0]) > half_size or abs(rt[1]) > half_size:
            self.anchor = None
            return np.zeros(3)
        vr = v_f - v_dev
        fn = self.k_normal_n_m * overlap - self.c_normal_n_s_m * float(n @ vr)
        if fn <= 0.0:
            return np.zeros(3)
        if self.anchor is None:
            self.anchor = rt.copy()
        vt = vr - n * float(n @ vr)
        ft = self.k_tangential_n_m * (rt - self.anchor) + self.c_tangential_n_s_m * vt
        lim = self.mu * fn
        nt = float(np.linalg.norm(ft))
        if nt > lim:  # the skin slips on the plate: drag the anchor
            ft *= lim / nt
            self.anchor = rt - ft / self.k_tangential_n_m
        return ft - n * fn


@dataclass
class VisionModel:
    """Fingertip measurements: rate (Hz), latency (s), noise σ per axis (m), drop-out probability."""

    rate_hz: float = 30.0
    latency_s: float = 0.033
    noise_m: float = 0.0003
    dropout: float = 0.05


@dataclass
class ApproachResult:
    object_name: str
    kind: str
    speed_m_s: float
    t_contact: float | None
    touched: bool  # the pad met the passive object (not the bare virtual surface)
    in_place: bool
    lead_time_s: float | None
    contact_error_m: float | None
    servo_tick_us: float
    subjects: list[str] = field(default_factory=list)  # the subjects in the order they were chosen
    subject_at_contact: str | None = None
    press_depth_m: np.ndarray | None = None  # fingertip depth under the surface (m) in the press
    press_force_n: np.ndarray | None = None  # device normal force (N) in the press
    through_object: bool = False  # the device's path (its contact point) cut through a non-subject object
    face_through_object: bool = False  # the passive face, at its real size, entered a non-subject object
    slide_friction_ratio: float | None = None  # median |F_t| / F_n while sliding (fabric: ≈ μ_k)
    log: dict | None = None
    ready: bool = False  # the device was ready at the first touch (:func:`device_ready`)
    ready_checks: dict = field(default_factory=dict)  # each of its conditions (:func:`ready_checks`)
    press_law_n: np.ndarray | None = None  # the force law's share of ``press_force_n`` (N)


def make_device(scene: Scene, cfg=None, *, travel: bool = True):
    """The device and its guarded servo step exactly as the demos and live mode build them
    (:func:`vishap.apps.assemble.make_servo_side` from ``cfg``, a :class:`~vishap.apps.config.DemoConfig`;
    None: the demos' defaults — the MuJoCo PHANToM with the scene's passive object, its substeps and
    encoders, gains from the gains file, limits from the device, the approach travel limiter).
    ``travel`` False runs the same servo step without a travel limiter (unlimited travel)."""
    from vishap.apps.assemble import make_servo_side
    from vishap.apps.config import DemoConfig

    cfg = cfg or DemoConfig()
    if not travel:
        cfg = cfg.model_copy(update={"travel_speed_m_s": None})
    return make_servo_side(cfg, scene)


def run_approach(
    scene: Scene,
    traj: FingerTrajectory,
    world: World,
    *,
    vision: VisionModel = VisionModel(),
    pad: FingerPad | None = None,
    seed: int = 0,
    in_place_m: float = 0.001,
    stop_after_contact_s: float | None = None,
    record: bool = False,
    step=None,
) -> ApproachResult:
    """Simulate one approach–press–slide–leave; ``stop_after_contact_s`` ends it early.

    The camera model is the core's source: its samples (robot frame, the pad point) go through the
    system's scene step (:class:`~vishap.runtime.core.SceneStep`) and servo step (guard, force law
    and Λ, controller, travel limiter); ``step`` is a servo step from :func:`make_device` to reuse.
    """
    from vishap.robot import kinematics
    from vishap.runtime.core import SceneStep

    rng = np.random.default_rng(seed)
    pad = pad or FingerPad()
    step = step or make_device(scene)
    plant, ctrl, servo = step.device, step.controller, step.servo
    world.reset()
    scene_step = SceneStep(world, np.eye(4), tip_radius_m=0.0, mount_offset=scene.passive_object.mount_offset_m)
    obj = scene.object(traj.object_name)
    dt = plant.dt
    half = scene.passive_object.half_size_m
    p_start = traj.position(0.0)
    rec, _, _ = scene_step.step(-1.0 / vision.rate_hz, True, p_start, 1.0, None)
    plant.reset(kinematics.ik(np.asarray(rec.X_ee) + obj.normal * 0.002, plant.params))
    ctrl.reset()
    ctrl.set_lambda(None)
    servo.shaper.reset()
    if servo.travel is not None:
        servo.travel.ready = False
    step.reset()

    n_ticks = int(math.ceil(traj.duration / dt))
    if stop_after_contact_s is not None:
        n_ticks = min(n_ticks, int(math.ceil((traj.t_surface + stop_after_contact_s + 0.3) / dt)))
    P_f = np.array([traj.position(k * dt) for k in range(n_ticks + 1)])  # the finger, sampled once
    V_f = np.gradient(P_f, dt, axis=0)
    t_next_cam = 0.0
    misses = 0  # missed detections in a row
    pending: list[tuple[float, float, np.ndarray | None]] = []  # (arrival, capture time, measurement)
    dev = np.empty((n_ticks, 3))
    subj = np.empty(n_ticks, dtype=object)
    v_dev = np.empty((n_ticks, 3))
    f_n = np.zeros(n_ticks)
    f_law = np.zeros(n_ticks)
    f_t = np.zeros(n_ticks)
    d_f = np.zeros(n_ticks)
    touching = np.zeros(n_ticks, dtype=bool)
    xd_log = np.empty((n_ticks, 3))
    v_cmd = np.full((n_ticks, 3), np.nan)  # the travel limiter's output velocity
    t_contact, k_contact = None, 0
    touched = False
    cost = 0.0
    names = [o.name for o in scene.objects]
    nan3 = np.full(3, np.nan)
    for k in range(n_ticks):
        t = k * dt
        # camera: capture now, deliver after the latency
        if t >= t_next_cam - 1e-12:
            p_true = P_f[k]
            meas = None if rng.random() < vision.dropout else p_true + rng.normal(0.0, vision.noise_m, 3)
            pending.append((t + vision.latency_s, t, meas))
            t_next_cam += 1.0 / vision.rate_hz
        state, p_dev = step.read()
        while pending and pending[0][0] <= t + 1e-12:
            _, t_cap, meas = pending.pop(0)
            # a drop-out is a missed detection of a finger still in view, not the hand leaving it: vision's
            # tracker coasts and reports its confidence decaying with the misses in a row (lost only once
            # that falls under the guard's floor), not 0 at the first miss (the guard would hold at once)
            misses = 0 if meas is not None else misses + 1
            rec, _, _ = scene_step.step(t_cap, meas is not None, nan3 if meas is None else meas,
                                        _DECAY ** misses, p_dev, lost=False)
        # the finger pushes on the passive object where it truly is (the servo reads its encoders)
        p_f, v_f = P_f[k], V_f[k]
        s = scene.objects[rec.subject] if rec.subject >= 0 else obj
        p_tip, v_tip = plant.true_tip_state()
        p_true = p_tip + step.mount
        F_pad = pad.force_on_device(p_f, v_f, p_true, v_tip, s.normal, half)
        plant.apply_tip_force(F_pad)
        c0 = perf_counter()
        tick = step.tick(t, rec, state)
        cost += perf_counter() - c0
        F = ctrl.F_pd
        nrm = s.normal
        if tick.F_law is not None:
            f_law[k] = float(np.dot(tick.F_law, nrm))
        f_n[k] = F[0] * nrm[0] + F[1] * nrm[1] + F[2] * nrm[2]
        f_t[k] = math.sqrt(max(F[0] * F[0] + F[1] * F[1] + F[2] * F[2] - f_n[k] * f_n[k], 0.0))
        d_f[k] = -obj.height(p_f)
        dev[k] = p_true
        v_dev[k] = v_tip
        xd_log[k] = np.asarray(rec.X_ee) + step.mount
        if servo.travel is not None:
            v_cmd[k] = servo.travel._v
        subj[k] = names[rec.subject] if rec.subject >= 0 else ""
        touching[k] = bool(F_pad.any())
        if t_contact is None and (touching[k] or d_f[k] >= 0.0):
            t_contact, touched = t, bool(touching[k])
            k_contact = k
        if stop_after_contact_s is not None and t_contact is not None and t > t_contact + stop_after_contact_s:
            n_ticks = k + 1
            break
    plant.check_state()
    dev, f_n, d_f, touching, subj, xd_log = dev[:n_ticks], f_n[:n_ticks], d_f[:n_ticks], touching[:n_ticks], subj[:n_ticks], xd_log[:n_ticks]
    checks = {} if t_contact is None else ready_checks(obj, dev[: k_contact + 1], v_dev[: k_contact + 1], P_f[k_contact],
                                                         V_f[: k_contact + 1], half, dt)
    ready = bool(checks) and all(checks.values())

    in_place, lead, err = False, None, None
    if t_contact is not None:
        p_c = P_f[k_contact]
        ideal = obj.centre if obj.mode.target == "centre" else obj.project(p_c)
        dist = np.linalg.norm(dev[: k_contact + 1] - ideal, axis=1)
        err = float(dist[-1])
        in_place = err <= in_place_m
        if in_place:
            out = np.nonzero(dist > in_place_m)[0]
            first_in = 0 if out.size == 0 else int(out[-1]) + 1
            lead = t_contact - first_in * dt
    ts = np.arange(n_ticks) * dt
    sel = traj.press_mask(ts)
    ratio = None
    if traj.slide is not None:
        mid = (ts > traj.t_press_end + 0.2 * traj.slide_s) & (ts < traj.t_slide_end - 0.2 * traj.slide_s)
        mid &= f_n[:n_ticks] > 0.1
        if mid.sum() > 10:
            ratio = float(np.median(f_t[:n_ticks][mid] / f_n[:n_ticks][mid]))
    through = _cuts_through(scene, dev, subj)
    face_through = _cuts_through(scene, dev, subj, half)
    order = [x for i, x in enumerate(subj) if x and (i == 0 or x != subj[i - 1])]
    log = None
    if record:
        log = {"t": np.arange(n_ticks) * dt, "device": dev, "X_d": xd_log, "depth_finger": d_f, "force_n": f_n,
               "touching": touching, "finger": P_f[:n_ticks],
               "v_device": v_dev[:n_ticks], "v_command": v_cmd[:n_ticks], "v_finger": V_f[:n_ticks], "k_contact": k_contact}
    return ApproachResult(
        traj.object_name, obj.kind, traj.speed_m_s, t_contact, touched, in_place, lead, err,
        cost / max(n_ticks, 1) * 1e6, order, None if t_contact is None else subj[k_contact],
        d_f[sel], f_n[sel], through, face_through, ratio, log, ready, checks, f_law[:n_ticks][sel],
    )


#: the vision tracker's confidence after each missed detection in a row (its own setting)
_DECAY = TrackerConfig().confidence_decay

#: issue 16's "ready at the touch": still for this long before it, …
READY_WINDOW_S = 0.020
READY_NORMAL_SPEED_M_S = 0.010      # … along the normal at most this fast,
READY_TANGENTIAL_SPEED_M_S = 0.020  # … sideways relative to the finger at most this fast,
READY_FACE_M = 0.0005               # the face this close to the virtual surface,
READY_INSIDE_M = 0.010              # the finger landing this far inside the face's edge


def ready_checks(obj, p_device, v_device, p_touch, v_finger, half_size_m: float, dt: float) -> dict[str, bool]:
    """Each condition of "ready" when the finger first touched (the last row of each array).

    ``p_device``/``v_device``: the device's contact point (centre of the passive object's face) and
    velocity per tick up to the touch; ``v_finger`` the finger's velocity per tick; ``p_touch`` the
    finger's pad at the touch; ``half_size_m`` the face's half width. ``still_normal``: over the last
    ``READY_WINDOW_S`` the device's normal speed ≤ 10 mm/s; ``still_tangential``: its tangential speed
    relative to the finger ≤ 20 mm/s; ``face``: its face within 0.5 mm of the virtual surface along
    the normal; ``inside``: the touch point at least 10 mm inside the face's edges (never on a face
    narrower than 20 mm)."""
    n_win = int(round(READY_WINDOW_S / dt))
    if len(p_device) < n_win + 1:
        return {"still_normal": False, "still_tangential": False, "face": False, "inside": False}
    n = np.asarray(obj.normal, float)
    v = np.asarray(v_device[-n_win - 1:], float)
    rel = v - np.asarray(v_finger[-n_win - 1:], float)
    v_n = np.abs(v @ n)
    rel_t = np.linalg.norm(rel - np.outer(rel @ n, n), axis=1)
    p = np.asarray(p_device[-1], float)
    q = obj.R.T @ (np.asarray(p_touch, float) - p)  # the touch point in the face's frame, from its centre
    return {"still_normal": bool(np.all(v_n <= READY_NORMAL_SPEED_M_S)),
            "still_tangential": bool(np.all(rel_t <= READY_TANGENTIAL_SPEED_M_S)),
            "face": bool(abs(obj.height(p)) <= READY_FACE_M),
            "inside": bool(max(abs(q[0]), abs(q[1])) <= half_size_m - READY_INSIDE_M)}


def device_ready(obj, p_device, v_device, p_touch, v_finger, half_size_m: float, dt: float) -> bool:
    """Whether the device was ready when the finger first touched: every one of :func:`ready_checks`."""
    return all(ready_checks(obj, p_device, v_device, p_touch, v_finger, half_size_m, dt).values())


def _cuts_through(scene: Scene, dev: np.ndarray, subj: np.ndarray, r: float = 0.0) -> bool:
    """True if the device's contact point ``dev`` (with ``r``: the square of half width ``r`` around it in
    the object's plane, the passive face) ever entered a solid object other than the one it was
    rendering: more than 1 mm under its top and more than ``BASE_CONTACT_M`` above its base."""
    step = max(1, len(dev) // 400)
    for o in scene.objects:
        q = (dev[::step] - o.centre) @ o.R
        inside = (np.abs(q[:, 0]) < o.half[0] + r) & (np.abs(q[:, 1]) < o.half[1] + r) & (q[:, 2] < -0.001) \
            & (q[:, 2] > -o.depth_m + BASE_CONTACT_M)
        if np.any(inside & (subj[::step] != o.name)):
            return True
    return False
