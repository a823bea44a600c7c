"""Closed-loop meeting of a simulated finger and the MuJoCo device (VisHap §2.2–2.3, Fig. 6).

A finger, driven by a trajectory (:mod:`vishap.world.trajectories`), approaches an object, meets
the device's passive object, presses, slides and leaves. Its pad is compliant (normal and
tangential spring-dampers with Coulomb slip, :class:`FingerPad`) and pushes on the device's tip
through :meth:`MujocoPlant.apply_tip_force`. A simulated camera (:class:`VisionModel`) samples the
fingertip at the vision rate with latency, noise and drop-outs; the :class:`~vishap.world.World`
turns each sample into ``X_d``; the servo (:class:`vishap.robot.servo.ServoLoop`) runs at 1 kHz.

Contact rendering follows Eq. 8–9: while the device is under the subject's surface (and the world
announces an imminent or current interaction) the object gain ``ᴼΛ`` sets λ_z = 0 and the force
law enters as the servo's extra force; once pushed in deeper than ``engage_m`` the lateral gains
take the mode's ``contact_gain`` (0 for a wall: the finger drags the device, sliding is free) —
all decided by :meth:`World.contact_render`.

Per approach we measure (:class:`ApproachResult`): the contact time (the pad first touches the
passive object, or the finger crosses the surface if it misses), whether the device was in place
(within ``in_place_m`` of the ideal contact point) and for how long before (lead time), the
contact-position error, and during the press the fingertip depth against the device's normal
force (``Λ f`` + law, without gravity compensation — VisHap Fig. 6's quantity).
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from time import perf_counter

import numpy as np

from vishap.world.scene import Scene
from vishap.world.trajectories import FingerTrajectory
from vishap.world.world import World

__all__ = ["FingerPad", "VisionModel", "ApproachResult", "run_approach", "make_device"]


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
    through_object: bool = False  # the device's path cut through a non-subject object
    slide_friction_ratio: float | None = None  # median |F_t| / F_n while sliding (fabric: ≈ μ_k)
    log: dict | None = None


#: servo gains (Kp N/m, Kv N·s/m) while the device travels to X_d, and while the subject's law renders
#: contact. Both lie in the robot's measured stable region (``vishap/robot/gains.yaml``); the travel
#: gains were also checked with ``vishap.robot.stability`` under a 1 ms transport delay, both sensors,
#: in free space and against 800/1000 N/m walls (stable; Kp 2400+ or Kv ≥ 45 at Kp 1600 oscillate).
TRAVEL_GAINS = (1600.0, 32.0)
CONTACT_GAINS = (800.0, 32.0)


def make_device(scene: Scene, *, substeps: int = 1, ramp_s: float = 0.05, gains: tuple[float, float] = TRAVEL_GAINS):
    """A MuJoCo PHANToM carrying the scene's passive object, with its servo loop: the robot's
    :func:`~vishap.robot.build.build_servo` (gains checked against the stable region, the device's
    wall-stiffness limit) at ``gains`` = (Kp, Kv)."""
    from vishap.robot.build import build_servo
    from vishap.robot.controller import Gains
    from vishap.robot.mjcf import PassiveObject

    po = scene.passive_object
    shape = "sphere" if po.shape == "sphere" else "plate"
    size = (po.size_m[0] / 2,) if shape == "sphere" else tuple(po.size_m)
    servo = build_servo(PassiveObject(shape, size, po.mass_kg), substeps=substeps,
                        gains=Gains(kp=gains[0], kv=gains[1], ramp_s=ramp_s))
    return servo.device, servo.controller, servo


def run_approach(
    scene: Scene,
    traj: FingerTrajectory,
    world: World,
    *,
    vision: VisionModel = VisionModel(),
    pad: FingerPad | None = None,
    seed: int = 0,
    in_place_m: float = 0.001,
    substeps: int = 1,
    stop_after_contact_s: float | None = None,
    record: bool = False,
    device=None,
    gains: tuple[tuple[float, float], tuple[float, float]] = (TRAVEL_GAINS, CONTACT_GAINS),
) -> ApproachResult:
    """Simulate one approach–press–slide–leave; ``stop_after_contact_s`` ends it early.

    ``gains`` = ((Kp, Kv) while travelling, (Kp, Kv) while the law renders contact).
    """
    from vishap.robot import kinematics
    from vishap.robot.controller import Gains

    rng = np.random.default_rng(seed)
    pad = pad or FingerPad()
    plant, ctrl, servo = device or make_device(scene, substeps=substeps)
    world.reset()
    obj = scene.object(traj.object_name)
    dt = plant.dt
    l1, l2 = plant.params.l1, plant.params.l2
    half = 0.5 * min(scene.passive_object.size_m[:2])
    p_start = traj.position(0.0)
    it = world.update(-1.0 / vision.rate_hz, p_start)
    X_d = it.X_d
    plant.reset(kinematics.ik(X_d + obj.normal * 0.002, plant.params))
    ramp = ctrl.gains.ramp_s
    g_travel, g_contact = (Gains(kp=g[0], kv=g[1], ramp_s=ramp) for g in gains)
    ctrl.set_gains(g_travel)
    ctrl.reset()
    ctrl.set_lambda(None)
    servo.shaper.reset()

    n_ticks = int(math.ceil(traj.duration / dt))
    if stop_after_contact_s is not None:
        n_ticks = min(n_ticks, int(math.ceil((traj.t_surface + stop_after_contact_s + 0.3) / dt)))
    P_f = np.array([traj.position(k * dt) for k in range(n_ticks + 1)])  # the finger, sampled once
    V_f = np.gradient(P_f, dt, axis=0)
    t_next_cam = 0.0
    pending: list[tuple[float, float, np.ndarray | None]] = []  # (arrival, capture time, measurement)
    pressed_state = False  # contact gains in use
    lam_state = None  # the object gain in use: None (identity, free motion) or a diagonal
    dev = np.empty((n_ticks, 3))
    subj = np.empty(n_ticks, dtype=object)
    f_n = np.zeros(n_ticks)
    f_t = np.zeros(n_ticks)
    d_f = np.zeros(n_ticks)
    touching = np.zeros(n_ticks, dtype=bool)
    xd_log = np.empty((n_ticks, 3))
    t_contact, k_contact = None, 0
    touched = False
    cost = 0.0
    for k in range(n_ticks):
        t = k * dt
        # camera: capture now, deliver after the latency
        if t >= t_next_cam - 1e-12:
            p_true = P_f[k]
            meas = None if rng.random() < vision.dropout else p_true + rng.normal(0.0, vision.noise_m, 3)
            pending.append((t + vision.latency_s, t, meas))
            t_next_cam += 1.0 / vision.rate_hz
        q1, q2, q3, w1, w2, w3 = plant.read_scalar()
        px, py, pz, vx, vy, vz = kinematics.tip_state_scalar(q1, q2, q3, w1, w2, w3, l1, l2)
        p_dev = np.array([px, py, pz])
        v_dev = np.array([vx, vy, vz])
        while pending and pending[0][0] <= t + 1e-12:
            _, t_cap, meas = pending.pop(0)
            it = world.update(t_cap, meas, p_dev)
            X_d = it.X_d
        # the finger pushes on the passive object
        p_f, v_f = P_f[k], V_f[k]
        s = world.subject or obj
        F_pad = pad.force_on_device(p_f, v_f, p_dev, v_dev, s.normal, half)
        plant.apply_tip_force(F_pad)
        c0 = perf_counter()
        # the subject's law renders contact while the device is under its surface (Eq. 8-9)
        F_law, lam, R = world.contact_render(p_dev, v_dev, it)
        pressed = lam is not None and world.law.depth(p_dev) > world.engage_m
        if pressed != pressed_state:  # travel gains until the finger pushes the device in
            ctrl.set_gains(g_contact if pressed else g_travel)
            ctrl.set_lambda(lam, None if lam is None else R)
            pressed_state = pressed
        if lam != lam_state:
            ctrl.set_lambda(lam, None if lam is None else R)
            if lam is None and world.law is not None:
                world.law.reset()
            lam_state = lam
        servo.tick(t, X_d, F_law)
        cost += perf_counter() - c0
        F = ctrl.F_pd
        nrm = s.normal
        f_n[k] = F[0] * nrm[0] + F[1] * nrm[1] + F[2] * nrm[2]
        f_t[k] = math.sqrt(max(F[0] * F[0] + F[1] * F[1] + F[2] * F[2] - f_n[k] * f_n[k], 0.0))
        d_f[k] = -obj.height(p_f)
        dev[k] = p_dev
        xd_log[k] = X_d
        subj[k] = world.subject.name if world.subject is not None else ""
        touching[k] = bool(F_pad.any())
        if t_contact is None and (touching[k] or d_f[k] >= 0.0):
            t_contact, touched = t, bool(touching[k])
            k_contact = k
        if stop_after_contact_s is not None and t_contact is not None and t > t_contact + stop_after_contact_s:
            n_ticks = k + 1
            break
    plant.check_state()
    dev, f_n, d_f, touching, subj, xd_log = dev[:n_ticks], f_n[:n_ticks], d_f[:n_ticks], touching[:n_ticks], subj[:n_ticks], xd_log[:n_ticks]

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
    order = [x for i, x in enumerate(subj) if x and (i == 0 or x != subj[i - 1])]
    log = None
    if record:
        log = {"t": np.arange(n_ticks) * dt, "device": dev, "X_d": xd_log, "depth_finger": d_f, "force_n": f_n,
               "touching": touching, "finger": P_f[:n_ticks]}
    return ApproachResult(
        traj.object_name, obj.kind, traj.speed_m_s, t_contact, touched, in_place, lead, err,
        cost / max(n_ticks, 1) * 1e6, order, None if t_contact is None else subj[k_contact],
        d_f[sel], f_n[sel], through, ratio, log,
    )


def _cuts_through(scene: Scene, dev: np.ndarray, subj: np.ndarray) -> bool:
    """True if the device path ever entered a solid object other than the one it was rendering."""
    step = max(1, len(dev) // 400)
    for o in scene.objects:
        q = (dev[::step] - o.centre) @ o.R
        inside = (np.abs(q[:, 0]) < o.half[0]) & (np.abs(q[:, 1]) < o.half[1]) & (q[:, 2] < -0.001) & (q[:, 2] > -o.depth_m)
        if np.any(inside & (subj[::step] != o.name)):
            return True
    return False
