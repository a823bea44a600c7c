"""Closed-loop stability runs of the servo in MuJoCo and their classification (VisHap §2.3).

Two scenarios, each a short simulated run of :class:`~vishap.robot.servo.ServoLoop` on a
:class:`~vishap.robot.plant.MujocoPlant`:

* :func:`run_free_space` — the target (sampled at ``rate_hz`` and bridged by the gap ``policy``)
  moves 3 cm along a smooth path, then holds; the tip must follow and settle.
* :func:`run_wall` — a unilateral virtual wall ``F = K·d + B·ḋ`` (depth ``d`` along the normal,
  the rendering the Colgate–Schenkel passivity bound ``b > K·T/2 + |B|`` is about) with a finger
  pushing the tip into it with a constant force. With ``RunSpec.mode`` set it runs that interaction
  mode's own contact set-up instead, through the system's servo step
  (:class:`~vishap.runtime.core.ServoStep`, the one place force laws and Λ are applied): the mode's
  force law (``modes.yaml``) with its stiffest part set to ``wall_k`` and its damping to ``wall_b``,
  the object gain's hand-over to the mode's contact gain Λ (λ_z = 0: the law gives the normal
  force), the guard, and — with ``jitter`` — each command delayed by a servo tick duration drawn
  from the demos' measured ones (:data:`SERVO_TICK_MS`).

:func:`classify` labels the settled part of a run ``stable``, ``oscillating`` (bounded but not
settling: limit cycles, ringing, chatter) or ``diverged`` (non-finite state, the tip thrown out of
the workspace, or a device error).
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from vishap._core.errors import DeviceError
from vishap.robot.controller import Controller, Gains
from vishap.robot.params import DEFAULT
from vishap.robot.plant import MujocoPlant
from vishap.robot.servo import ServoLoop
from vishap.world.scene import demo_passive_object

__all__ = ["RunSpec", "run_free_space", "run_wall", "classify", "passivity_margin", "tip_damping",
           "measured_jitter_s", "jitter_from_log", "contact_law", "SERVO_TICK_PERCENTILES", "SERVO_TICK_MS"]

START = np.array([0.215, 0.0, -0.170])  # home
STEP = np.array([-0.02, 0.015, 0.015])  # 3 cm move of the free-space run
WALL_POINT = np.array([0.200, 0.0, -0.150])  # on the scenes' table plane, normal +z

#: Servo tick durations (compute time of one tick, ms) at these percentiles, measured in the wall and
#: button demos (seeds 0–4, encoder, 10 substeps: 49 165 ticks, the project's shared 2-core machine;
#: `servo/tick_us` of their logs). A command reaches the motors that long after its tick began.
SERVO_TICK_PERCENTILES = (0.0, 10.0, 25.0, 50.0, 75.0, 90.0, 95.0, 99.0, 99.5, 99.9, 99.95)
SERVO_TICK_MS = (0.059, 0.091, 0.099, 0.111, 0.127, 0.167, 0.231, 0.352, 0.485, 8.16, 12.6)


def measured_jitter_s(n: int = 2000) -> np.ndarray:
    """``n`` tick durations (s) spread evenly over the measured distribution (its inverse CDF)."""
    u = (np.arange(n) + 0.5) / n * SERVO_TICK_PERCENTILES[-1]
    return np.interp(u, SERVO_TICK_PERCENTILES, SERVO_TICK_MS) * 1e-3


def jitter_from_log(path) -> np.ndarray:
    """The servo tick durations (s) of a demo's ``log.npz`` (``servo/tick_us``)."""
    with np.load(path) as log:
        return np.asarray(log["servo/tick_us"], dtype=np.float64) * 1e-6


@dataclass
class RunSpec:
    """Parameters of one run (SI units; ``delay_ticks`` in servo periods)."""

    kp: float = Gains.kp
    kv: float = Gains.kv
    a: float = Gains.a
    rate_hz: float = 1000.0
    policy: str = "hold"
    delay_ticks: int = 0
    substeps: int = 10
    sensor: str = "exact"
    wall_k: float = 0.0
    wall_b: float = 0.0
    push_n: float = 1.0
    duration_s: float = 1.2
    #: interaction mode (``modes.yaml`` name) whose contact set-up :func:`run_wall` uses; None: a bare
    #: spring–damper wall with Λ = I (the servo's PD also holds the tip along the normal)
    mode: str | None = None
    #: delay each command by a measured servo tick duration (:func:`measured_jitter_s`)
    jitter: bool = False

    def as_dict(self) -> dict:
        return asdict(self)


def _make(spec: RunSpec, q0=None):
    plant = MujocoPlant(
        passive_object=demo_passive_object(), substeps=spec.substeps, delay_ticks=spec.delay_ticks, sensor=spec.sensor, q0=q0,
        jitter_s=measured_jitter_s() if spec.jitter else None,
    )
    ctrl = Controller(plant.params, Gains(kp=spec.kp, kv=spec.kv, a=spec.a, ramp_s=0.0), limits=plant.limits)
    return plant, ctrl


def _smooth(s: float) -> float:
    s = min(max(s, 0.0), 1.0)
    return 0.5 - 0.5 * math.cos(math.pi * s)


def run_free_space(spec: RunSpec) -> dict:
    """Move 3 cm in 0.4 s (raised cosine) starting at 0.05 s, then hold; X_d sampled at ``rate_hz``."""
    plant, ctrl = _make(spec)
    servo = ServoLoop(plant, ctrl, policy=spec.policy)
    n = int(round(spec.duration_s * plant.params.servo_rate_hz))
    period = 1.0 / spec.rate_hz
    p = np.empty((n, 3))
    # the whole reference up front: a run that leaves the workspace stops early, and its error is
    # taken over every tick (an unfilled tail read uninitialised memory: errors changed run to run)
    ref = np.array([START + STEP * _smooth((i * plant.dt - 0.05) / 0.4) for i in range(n)])
    X = START.copy()
    t_sample = -1.0
    status = "ok"
    for i in range(n):
        t = i * plant.dt
        ts = math.floor(t / period + 1e-9) * period
        if ts != t_sample:  # a new vision sample
            t_sample = ts
            X = START + STEP * _smooth((ts - 0.05) / 0.4)
        try:
            servo.tick(t, X, t_sample=t_sample)
        except DeviceError as exc:  # pragma: no cover - the controller never commands beyond limits
            status = f"device error: {exc}"
            p[i:] = np.nan
            break
        p[i] = ctrl.p
        if not np.all(np.isfinite(p[i])) or np.linalg.norm(p[i] - START) > 0.2:
            p[i:] = p[i]
            status = "left workspace"
            break
    return _summarise(spec, p, ref, plant.dt, ctrl, status, settle_from=0.45 + 0.2)


def run_wall(spec: RunSpec) -> dict:
    """Hold at the wall point; a finger pushes ``push_n`` into the wall (−z) from 0.1 s on.

    With ``spec.mode`` the run goes through the system's own servo step
    (:class:`~vishap.runtime.core.ServoStep`: guard → the renderer's force law and object gain →
    controller), fed each tick the record a scene step makes for a finger resting on the face from
    the start and in contact from 0.1 s. Without one, a bare spring–damper wall ``K·d − B·ż`` is added
    to the servo's PD (Λ = I), the textbook sampled wall of the Colgate–Schenkel bound."""
    from vishap.robot.kinematics import ik, tip_state_scalar

    plant, ctrl = _make(spec, q0=ik(WALL_POINT))
    servo = ServoLoop(plant, ctrl, policy="hold")
    n = int(round(spec.duration_s * plant.params.servo_rate_hz))
    step = None if spec.mode is None else _servo_step(spec, servo)
    z_wall, K, B = float(WALL_POINT[2]), float(spec.wall_k), float(spec.wall_b)
    l1, l2 = plant.params.l1, plant.params.l2
    p = np.empty((n, 3))
    ref = np.tile(WALL_POINT, (n, 1))
    status = "ok"
    push = np.array([0.0, 0.0, -abs(spec.push_n)])
    for i in range(n):
        t = i * plant.dt
        plant.apply_tip_force(push if t >= 0.1 else np.zeros(3))
        try:
            if step is not None:
                step.tick(t, _resting_finger(i, t))
            else:
                joints = plant.read_scalar()
                _, _, pz, _, _, vz = tip_state_scalar(*joints, l1, l2)
                d = z_wall - pz  # penetration depth (m)
                F = np.array([0.0, 0.0, K * d - B * vz]) if d > 0.0 else None
                servo.tick(t, WALL_POINT, F, joints=joints)
        except DeviceError as exc:  # pragma: no cover
            status = f"device error: {exc}"
            p[i:] = np.nan
            break
        p[i] = ctrl.p
        if not np.all(np.isfinite(p[i])) or np.linalg.norm(p[i] - WALL_POINT) > 0.2:
            p[i:] = p[i]
            status = "left workspace"
            break
    rec = _summarise(spec, p, ref, plant.dt, ctrl, status, settle_from=0.6)
    if step is not None:  # the object gain's state at the end (2: engaged, the mode's own contact gain)
        rec["lambda_state"] = step.contact.state_code
    return rec


def _servo_step(spec: RunSpec, servo):
    """The core's servo step over ``servo`` for one object: the plane z = WALL_POINT_z in mode
    ``spec.mode``, its law from :func:`contact_law` (the plane is the device's contact point: no mount)."""
    from vishap.runtime.core import ServoStep
    from vishap.runtime.safety import TargetGuard
    from vishap.world.modes import default_modes
    from vishap.world.scene import SceneObject

    mode = default_modes().get(spec.mode)
    plane = SceneObject(name="wall", kind=mode.kinds[0], mode_name=spec.mode, mode=mode, spec=None,
                        centre=WALL_POINT.copy(), R=np.eye(3), half=np.array([0.05, 0.05]), depth_m=0.05)
    lim = servo.device.limits
    guard = TargetGuard(np.asarray(lim.workspace_min, float), np.asarray(lim.workspace_max, float),
                        WALL_POINT - np.array([0.0, 0.0, 0.02]))
    law = contact_law(spec.mode, float(spec.wall_k), float(spec.wall_b), max_force_n=lim.peak_force_n)
    return ServoStep(servo, guard, [plane], mount_offset=np.zeros(3), laws=[law])


def _resting_finger(i: int, t: float):
    """The record of tick ``i``: target the wall point, a finger's pad resting on it (the touch is now:
    the object gain hands the normal over to the law), pushing (in contact) from 0.1 s."""
    from vishap.runtime.core import TargetRecord

    w = tuple(float(v) for v in WALL_POINT)
    return TargetRecord(i + 1, w, t, 1.0, True, True, 0, True, t >= 0.1, w, (0.0, 0.0, 0.0), t)


def contact_law(mode: str, stiffness_n_m: float, damping_n_s_m: float, *, max_force_n: float = DEFAULT.peak_force_n):
    """Mode ``mode``'s force law on the plane z = WALL_POINT_z (normal +z), its stiffest part set to
    ``stiffness_n_m`` (a wall's spring, a key's bottom board, a fabric's penalty) and its normal
    damping to ``damping_n_s_m``; ``lambda_contact`` is the mode's contact gain. The key travels
    4 mm and clicks at 1.8 mm (the scenes' key)."""
    from vishap.world import force_laws as fl
    from vishap.world.modes import default_modes

    m = default_modes().get(mode)
    law = m.law
    n, off = (0.0, 0.0, 1.0), float(WALL_POINT[2])
    if law.kind == "wall_spring":
        built = fl.WallSpring(n, off, stiffness_n_m=stiffness_n_m, damping_n_s_m=damping_n_s_m, max_force_n=max_force_n)
    elif law.kind == "button_click":
        built = fl.ButtonClick(n, off, trigger_depth_m=0.0018, travel_m=0.004, k_resist_n_m=law.k_resist_n_m,
                               k_click_n_m=law.k_click_n_m, k_bottom_n_m=stiffness_n_m, transition_m=law.transition_m,
                               damping_n_s_m=damping_n_s_m, max_force_n=max_force_n)
    else:
        R = np.eye(3)
        built = fl.FabricFriction(R, WALL_POINT, mu_static=0.6, mu_kinetic=0.4, k_penalty_n_m=stiffness_n_m,
                                  k_tangential_n_m=law.k_tangential_n_m, damping_n_s_m=damping_n_s_m,
                                  damping_tangential_n_s_m=law.damping_tangential_n_s_m, max_force_n=max_force_n)
    built.lambda_contact = tuple(float(v) for v in m.contact_gain)
    return built


def _summarise(spec, p, ref, dt, ctrl, status, *, settle_from: float) -> dict:
    n = len(p)
    i0 = min(int(settle_from / dt), n - 1)
    tail = p[i0:]
    finite = bool(np.all(np.isfinite(p)))
    ptp_mm = float(np.max(np.ptp(tail, axis=0)) * 1e3) if finite else math.inf
    # late half vs early half of the settling window: growth means not settling
    h = len(tail) // 2
    dev = np.linalg.norm(tail - tail[-1], axis=1) if finite else None
    err = np.linalg.norm(p - ref, axis=1) if finite else None
    rec = {
        **spec.as_dict(),
        "status": status,
        "ptp_settled_mm": ptp_mm,
        "ptp_last_half_mm": float(np.max(np.ptp(tail[h:], axis=0)) * 1e3) if finite else math.inf,
        # what is left after a quadratic trend is removed: a slow creep leaves ~0, ringing does not
        "ripple_last_half_mm": _ripple(tail[h:]) * 1e3 if finite else math.inf,
        "max_dev_settled_mm": float(dev.max() * 1e3) if finite else math.inf,
        "final_error_mm": float(err[-1] * 1e3) if finite else math.inf,
        "rms_error_mm": float(np.sqrt(np.mean(err**2)) * 1e3) if finite else math.inf,
        "max_error_mm": float(err.max() * 1e3) if finite else math.inf,
        "saturated_fraction": ctrl.n_saturated / max(n, 1),
        "faults": ctrl.n_faults,
    }
    rec["outcome"] = classify(rec)
    return rec


def _ripple(x: np.ndarray) -> float:
    """Largest peak-to-peak (m) over axes of ``x`` minus its least-squares quadratic trend."""
    tt = np.linspace(-1.0, 1.0, len(x))
    V = np.stack([np.ones_like(tt), tt, tt * tt], -1)
    coef, *_ = np.linalg.lstsq(V, x, rcond=None)
    return float(np.max(np.ptp(x - V @ coef, axis=0)))


def classify(rec: dict, *, ripple_mm: float = 0.1, diverge_mm: float = 30.0) -> str:
    """``diverged`` / ``oscillating`` / ``stable`` from a run summary.

    Diverged: a device error, non-finite state, or an error beyond ``diverge_mm``. Oscillating: in
    the last half of the settling window the tip's motion, less a quadratic trend, still spans more
    than ``ripple_mm`` (limit cycles, ringing, chatter). A slow monotonic approach (heavy damping,
    low stiffness) is a trend, so it counts as stable; its sluggishness shows in the errors.
    """
    if rec["status"] != "ok" or not math.isfinite(rec["ptp_settled_mm"]) or rec["faults"]:
        return "diverged"
    if rec["max_error_mm"] > diverge_mm:
        return "diverged"
    if rec["ripple_last_half_mm"] > ripple_mm:
        return "oscillating"
    return "stable"


def tip_damping(params=None, p_robot=WALL_POINT) -> float:
    """Physical viscous damping of the arm at the tip along z (N·s/m): ``J⁻ᵀ E⁻ᵀ D E⁻¹ J⁻¹``."""
    from vishap.robot.kinematics import ik, jacobian
    from vishap.robot.params import DEFAULT

    params = params or DEFAULT
    q = ik(p_robot, params)
    E_inv = np.array([[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, -1.0, 1.0]])
    D_theta = E_inv.T @ (params.joint_damping * np.eye(3)) @ E_inv
    Jinv = np.linalg.inv(jacobian(q, params))
    return float((Jinv.T @ D_theta @ Jinv)[2, 2])


def passivity_margin(K: float, B: float, b: float, T: float) -> float:
    """Colgate–Schenkel: ``b − (K·T/2 + |B|)``; positive means the sampled wall is passive."""
    return b - (K * T / 2.0 + abs(B))
