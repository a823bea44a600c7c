"""Kinematics of the PHANToM's three actuated joints (Cavusoglu et al. 2002; VisHap §2.3, Eq. 6).

Angles as in :mod:`vishap.robot.params`: θ1 yaw, θ2 upper-arm elevation, θ3 absolute forearm angle
from the downward vertical. With the horizontal reach ``r = l1·cos θ2 + l2·sin θ3`` and height
``h = l1·sin θ2 − l2·cos θ3``::

    p_robot = (r·cos θ1, r·sin θ1, h)

Eq. 6, ``τ = Jᵇᵀ Rᵀ F``: the body Jacobian rotated into the base frame is the positional Jacobian
``J = R Jᵇ`` used here, so ``τ = Jᵀ F`` and ``F = J⁻ᵀ τ`` (:func:`force_to_torque`,
:func:`torque_to_force`). The scalar versions (``*_scalar``) use only :mod:`math` and serve the
1 kHz servo loop.
"""
from __future__ import annotations

import math

import numpy as np

from vishap._core.errors import ShapeError
from vishap.robot.params import DEFAULT, PhantomParams

__all__ = [
    "fk",
    "jacobian",
    "ik",
    "link_points",
    "force_to_torque",
    "torque_to_force",
    "tip_state_scalar",
    "within_joint_limits",
    "clamp_to_workspace",
    "in_workspace",
]


def _q(q) -> np.ndarray:
    q = np.asarray(q, dtype=np.float64)
    if q.shape[-1:] != (3,):
        raise ShapeError(f"q: expected shape (3,) or (N, 3), got {q.shape}")
    return q


def fk(q, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Tip position ``p_robot`` (m) for joint angles ``q`` (rad); (3,) → (3,), (N, 3) → (N, 3)."""
    q = _q(q)
    t1, t2, t3 = q[..., 0], q[..., 1], q[..., 2]
    r = params.l1 * np.cos(t2) + params.l2 * np.sin(t3)
    h = params.l1 * np.sin(t2) - params.l2 * np.cos(t3)
    return np.stack([r * np.cos(t1), r * np.sin(t1), h], axis=-1)


def jacobian(q, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Positional Jacobian ``∂p_robot/∂q`` (3, 3), in metres per radian."""
    q = _q(q)
    if q.ndim != 1:
        raise ShapeError(f"q: expected shape (3,), got {q.shape}")
    l1, l2 = params.l1, params.l2
    s1, c1 = math.sin(q[0]), math.cos(q[0])
    s2, c2 = math.sin(q[1]), math.cos(q[1])
    s3, c3 = math.sin(q[2]), math.cos(q[2])
    r = l1 * c2 + l2 * s3
    return np.array(
        [
            [-r * s1, -l1 * s2 * c1, l2 * c3 * c1],
            [r * c1, -l1 * s2 * s1, l2 * c3 * s1],
            [0.0, l1 * c2, l2 * s3],
        ]
    )


def ik(p_robot, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Joint angles (rad) that put the tip at ``p_robot`` (elbow-up branch, the PHANToM's).

    Raises :class:`ShapeError` if the point is out of the arm's reach (farther than ``l1 + l2``,
    closer than ``|l1 − l2|`` or on the yaw axis); joint limits are not applied here
    (see :func:`within_joint_limits`).
    """
    p = np.asarray(p_robot, dtype=np.float64)
    if p.shape != (3,) or not np.all(np.isfinite(p)):
        raise ShapeError(f"p_robot: expected a finite (3,) point, got {p!r}")
    l1, l2 = params.l1, params.l2
    r = math.hypot(p[0], p[1])
    h = p[2]
    d2 = r * r + h * h
    cos_g = (d2 - l1 * l1 - l2 * l2) / (2.0 * l1 * l2)
    if r < 1e-9 or not -1.0 <= cos_g <= 1.0:
        raise ShapeError(f"p_robot {p.tolist()} is out of the arm's reach (l1={l1}, l2={l2})")
    # planar two-link with absolute angles φ1 = θ2, φ2 = θ3 − π/2; elbow angle γ = φ2 − φ1 < 0
    gamma = -math.acos(cos_g)
    phi1 = math.atan2(h, r) - math.atan2(l2 * math.sin(gamma), l1 + l2 * math.cos(gamma))
    theta3 = phi1 + gamma + 0.5 * math.pi
    theta1 = math.atan2(p[1], p[0])
    return np.array([theta1, phi1, theta3])


def link_points(q, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Polyline for drawing the arm, (4, 3) in metres: base (below the shoulder), shoulder, elbow, tip."""
    q = _q(q)
    if q.ndim != 1:
        raise ShapeError(f"q: expected shape (3,), got {q.shape}")
    t1, t2 = q[0], q[1]
    c1, s1 = math.cos(t1), math.sin(t1)
    elbow_r, elbow_h = params.l1 * math.cos(t2), params.l1 * math.sin(t2)
    base = np.array([0.0, 0.0, -0.5 * params.l2])
    shoulder = np.zeros(3)
    elbow = np.array([elbow_r * c1, elbow_r * s1, elbow_h])
    return np.stack([base, shoulder, elbow, fk(q, params)])


def force_to_torque(q, F_robot, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Eq. 6: joint torques (N·m) that exert the tip force ``F_robot`` (N): ``τ = Jᵀ F``."""
    return jacobian(q, params).T @ np.asarray(F_robot, dtype=np.float64).reshape(3)


def torque_to_force(q, tau, params: PhantomParams = DEFAULT) -> np.ndarray:
    """Eq. 6 inverted: the tip force (N) that joint torques ``tau`` (N·m) exert, ``F = J⁻ᵀ τ``.

    Raises :class:`ShapeError` at a kinematic singularity (arm stretched/folded, tip on the yaw axis).
    """
    q = _q(q)
    tau = np.asarray(tau, dtype=np.float64).reshape(3)
    F = torque_to_force_scalar(q[0], q[1], q[2], tau[0], tau[1], tau[2], params.l1, params.l2)
    if F is None:
        raise ShapeError(f"q {q.tolist()}: Jacobian is singular, Eq. 6 cannot be inverted")
    return np.array(F)


def torque_to_force_scalar(t1, t2, t3, tau1, tau2, tau3, l1, l2, eps=1e-9):
    """``F = J⁻ᵀ τ`` on floats (closed form); None at a singularity (|det J| below ``eps``)."""
    s1, c1 = math.sin(t1), math.cos(t1)
    s2, c2 = math.sin(t2), math.cos(t2)
    s3, c3 = math.sin(t3), math.cos(t3)
    r = l1 * c2 + l2 * s3
    # J = Rz(θ1) · [[0, a, b], [r, 0, 0], [0, c, d]] with the planar block below
    a, b, c, d = -l1 * s2, l2 * c3, l1 * c2, l2 * s3
    det2 = a * d - b * c  # = −l1·l2·cos(θ2 − θ3)
    if abs(r) < eps or abs(det2) < eps:
        return None
    f_t = tau1 / r
    f_r = (d * tau2 - c * tau3) / det2
    f_h = (a * tau3 - b * tau2) / det2
    return (f_r * c1 - f_t * s1, f_r * s1 + f_t * c1, f_h)


def tip_state_scalar(t1, t2, t3, w1, w2, w3, l1, l2):
    """(px, py, pz, vx, vy, vz): tip position (m) and velocity (m/s) from joint state, on floats."""
    s1, c1 = math.sin(t1), math.cos(t1)
    s2, c2 = math.sin(t2), math.cos(t2)
    s3, c3 = math.sin(t3), math.cos(t3)
    r = l1 * c2 + l2 * s3
    vr = -l1 * s2 * w2 + l2 * c3 * w3
    vt = r * w1
    return (r * c1, r * s1, l1 * s2 - l2 * c3, vr * c1 - vt * s1, vr * s1 + vt * c1, l1 * c2 * w2 + l2 * s3 * w3)


def within_joint_limits(q, params: PhantomParams = DEFAULT, *, margin: float = 0.0) -> bool:
    """True when ``q`` respects the joint limits and the parallelogram (elbow) limits."""
    q = _q(q)
    lo = params.q_min_array + margin
    hi = params.q_max_array - margin
    elbow = q[2] - q[1]
    return bool(
        np.all(q >= lo) and np.all(q <= hi) and params.elbow_min + margin <= elbow <= params.elbow_max - margin
    )


def in_workspace(p_robot, params: PhantomParams = DEFAULT) -> bool:
    """True when ``p_robot`` lies inside the reachable box (inclusive)."""
    p = np.asarray(p_robot, dtype=np.float64).reshape(3)
    return bool(np.all(p >= params.workspace_min) and np.all(p <= params.workspace_max))


def clamp_to_workspace(p_robot, params: PhantomParams = DEFAULT) -> tuple[np.ndarray, bool]:
    """Nearest point of the reachable box to ``p_robot`` and whether it moved.

    Non-finite coordinates are replaced by the box centre on that axis (and count as clamped).
    """
    p = np.asarray(p_robot, dtype=np.float64).reshape(3).copy()
    lo = np.asarray(params.workspace_min)
    hi = np.asarray(params.workspace_max)
    bad = ~np.isfinite(p)
    p[bad] = 0.5 * (lo + hi)[bad]
    out = np.minimum(np.maximum(p, lo), hi)
    return out, bool(bad.any() or np.any(out != p))
