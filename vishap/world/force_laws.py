"""Force laws evaluated by the 1 kHz servo tick (VisHap §2.3 Fig. 5; HAPTEX §II-B for fabric).

Each law turns the device's contact point ``p_robot`` and velocity ``v_robot`` into the force
(robot frame, N) that the device presents to the finger, saturated at the device's limit:

* :class:`WallSpring`  — Fig. 5 left: zero above the plane, a linear spring ``k·d`` in the depth ``d``
  below it (VisHap's large λ_z), plus damping on the normal velocity; tangential motion is free
  (a hard wall only allows sliding).
* :class:`ButtonClick` — Fig. 5 right: resistance spring ``k_resist·d`` up to the trigger depth, then a
  gradual drop to the low stiffness ``k_click·d`` (the click), then the hard bottom board
  ``k_bottom`` beyond the travel.
* :class:`FabricFriction` — penalty force ``k·d`` on penetration and stick/slip friction: the
  tangential force is a spring to a stick point while ``|f_t| < μ_s·|f_n|``; beyond that the contact
  slides with kinetic friction ``μ_k·|f_n|`` (the stick point is dragged along) until the relative
  velocity falls below a re-stick threshold.

The laws are built per object by :func:`make_law`, so a wall scene runs only a dot product, a
comparison and a multiply per tick — never the button or fabric machinery.
"""
from __future__ import annotations

import math

import numpy as np

__all__ = ["WallSpring", "ButtonClick", "FabricFriction", "make_law", "saturate", "DEFAULT_MAX_FORCE_N"]

DEFAULT_MAX_FORCE_N = 8.5  # PHANToM Premium 1.0 peak force (DESIGN.md); the device's limits override it


def saturate(F: np.ndarray, max_force_n: float) -> np.ndarray:
    """Scale ``F`` (in place) so that its norm does not exceed ``max_force_n``; NaN/inf become zero."""
    n2 = F[0] * F[0] + F[1] * F[1] + F[2] * F[2]
    if not math.isfinite(n2):
        F[:] = 0.0
    elif n2 > max_force_n * max_force_n:
        F *= max_force_n / math.sqrt(n2)
    return F


class _PlaneLaw:
    """Shared set-up: the surface plane ``n·p = d`` and the force limit.

    ``lambda_contact`` is VisHap's object gain ``ᴼΛ = diag(λx, λy, λz)`` (Eq. 8–9) to use while the
    law renders contact: the law supplies the normal force itself, so the position servo's λ_z is
    0; λx, λy come from the interaction mode (:func:`make_law`).
    """

    lambda_contact = (0.0, 0.0, 0.0)

    def __init__(self, normal, offset_m: float, max_force_n: float):
        n = np.asarray(normal, dtype=float)
        self.normal = n / np.linalg.norm(n)
        self.nx, self.ny, self.nz = (float(c) for c in self.normal)
        self.offset = float(offset_m)
        self.max_force_n = float(max_force_n)

    def depth(self, p_robot) -> float:
        """Depth of ``p_robot`` under the surface (m); negative above it."""
        return self.offset - (self.nx * p_robot[0] + self.ny * p_robot[1] + self.nz * p_robot[2])

    def reset(self) -> None:
        """Forget contact state (nothing to forget for a stateless law)."""

    def normal_force_curve(self, depths) -> np.ndarray:
        """Static normal force (N, no damping, before saturation) at each depth — Fig. 5 as force."""
        return np.array([self.normal_force(float(d)) for d in np.asarray(depths, dtype=float)])


class WallSpring(_PlaneLaw):
    """A hard wall: a linear spring in depth below the plane, with normal damping."""

    def __init__(self, normal, offset_m, *, stiffness_n_m, damping_n_s_m=0.0, max_force_n=DEFAULT_MAX_FORCE_N):
        super().__init__(normal, offset_m, max_force_n)
        self.k = float(stiffness_n_m)
        self.c = float(damping_n_s_m)

    def normal_force(self, depth: float) -> float:
        return self.k * depth if depth > 0.0 else 0.0

    def force_robot(self, p_robot, v_robot) -> np.ndarray:
        nx, ny, nz = self.nx, self.ny, self.nz
        d = self.offset - (nx * p_robot[0] + ny * p_robot[1] + nz * p_robot[2])
        if d <= 0.0:
            return np.zeros(3)
        f = self.k * d - self.c * (nx * v_robot[0] + ny * v_robot[1] + nz * v_robot[2])
        f = min(max(f, 0.0), self.max_force_n)
        return np.array([nx * f, ny * f, nz * f])


class ButtonClick(_PlaneLaw):
    """A key with a click: resistance, trigger, low stiffness, hard bottom (Fig. 5 right)."""

    def __init__(
        self,
        normal,
        offset_m,
        *,
        trigger_depth_m,
        travel_m,
        k_resist_n_m,
        k_click_n_m,
        k_bottom_n_m,
        transition_m=0.0002,
        damping_n_s_m=0.0,
        max_force_n=DEFAULT_MAX_FORCE_N,
    ):
        super().__init__(normal, offset_m, max_force_n)
        self.d_trig = float(trigger_depth_m)
        self.travel = float(travel_m)
        self.k1, self.k2, self.k3 = float(k_resist_n_m), float(k_click_n_m), float(k_bottom_n_m)
        self.w = min(float(transition_m), 0.5 * (self.travel - self.d_trig))
        self.c = float(damping_n_s_m)

    def normal_force(self, d: float) -> float:
        if d <= 0.0:
            return 0.0
        if d < self.d_trig:
            return self.k1 * d
        if d < self.d_trig + self.w:  # the gradual drop at the trigger (VisHap §3: for stability)
            s = (d - self.d_trig) / self.w
            return (1.0 - s) * self.k1 * self.d_trig + s * self.k2 * (self.d_trig + self.w)
        if d < self.travel:
            return self.k2 * d
        return self.k2 * self.travel + self.k3 * (d - self.travel)

    def force_robot(self, p_robot, v_robot) -> np.ndarray:
        nx, ny, nz = self.nx, self.ny, self.nz
        d = self.offset - (nx * p_robot[0] + ny * p_robot[1] + nz * p_robot[2])
        if d <= 0.0:
            return np.zeros(3)
        f = self.normal_force(d) - self.c * (nx * v_robot[0] + ny * v_robot[1] + nz * v_robot[2])
        f = min(max(f, 0.0), self.max_force_n)
        return np.array([nx * f, ny * f, nz * f])


class FabricFriction(_PlaneLaw):
    """Penalty contact with static/kinetic friction on a fabric patch (HAPTEX §II-B).

    State (public, inspectable): ``anchor`` (stick point in the surface, object frame, or None when
    out of contact), ``sliding``, and the last ``normal_force_n`` / ``tangential_force_n``.
    """

    def __init__(
        self,
        R_robot_obj,
        centre,
        *,
        mu_static,
        mu_kinetic,
        k_penalty_n_m,
        k_tangential_n_m,
        damping_n_s_m=0.0,
        damping_tangential_n_s_m=0.0,
        restick_speed_m_s=0.002,
        max_force_n=DEFAULT_MAX_FORCE_N,
    ):
        R = np.asarray(R_robot_obj, dtype=float)
        c = np.asarray(centre, dtype=float)
        super().__init__(R[:, 2], float(R[:, 2] @ c), max_force_n)
        self.R, self.centre = R, c
        self.mu_s, self.mu_k = float(mu_static), float(mu_kinetic)
        self.k, self.c = float(k_penalty_n_m), float(damping_n_s_m)
        self.kt, self.ct = float(k_tangential_n_m), float(damping_tangential_n_s_m)
        self.v_restick = float(restick_speed_m_s)
        self.reset()

    def reset(self) -> None:
        self.anchor: np.ndarray | None = None
        self.sliding = False
        self.normal_force_n = 0.0
        self.tangential_force_n = 0.0

    def normal_force(self, d: float) -> float:
        return self.k * d if d > 0.0 else 0.0

    def force_robot(self, p_robot, v_robot) -> np.ndarray:
        q = (np.asarray(p_robot, dtype=float) - self.centre) @ self.R
        d = -q[2]
        if d <= 0.0:
            self.reset()
            return np.zeros(3)
        vq = np.asarray(v_robot, dtype=float) @ self.R
        fn = min(max(self.k * d - self.c * vq[2], 0.0), self.max_force_n)
        if self.anchor is None:
            self.anchor = q[:2].copy()
        ft = -self.kt * (q[:2] - self.anchor) - self.ct * vq[:2]
        ft_norm = math.hypot(ft[0], ft[1])
        speed = math.hypot(vq[0], vq[1])
        if self.sliding and speed < self.v_restick:
            self.sliding = False
        if not self.sliding and ft_norm > self.mu_s * fn:
            self.sliding = True
        if self.sliding:
            if speed > 1e-9:
                direction = -vq[:2] / speed
            else:
                direction = ft / ft_norm if ft_norm > 0 else np.zeros(2)
            ft = self.mu_k * fn * direction
            self.anchor = q[:2] + ft / self.kt  # drag the stick point so the spring holds μ_k·f_n
        self.normal_force_n, self.tangential_force_n = fn, math.hypot(ft[0], ft[1])
        F = self.R[:, 0] * ft[0] + self.R[:, 1] * ft[1] + self.normal * fn
        return saturate(F, self.max_force_n)


def make_law(obj, *, max_force_n: float = DEFAULT_MAX_FORCE_N):
    """The force law for one :class:`~vishap.world.scene.SceneObject`, from its mode and spec."""
    built = _make_law(obj, max_force_n)
    built.lambda_contact = tuple(float(v) for v in obj.mode.contact_gain)
    return built


def _make_law(obj, max_force_n: float):
    law = obj.mode.law
    if law.kind == "wall_spring":
        return WallSpring(obj.normal, obj.offset, stiffness_n_m=law.stiffness_n_m,
                          damping_n_s_m=law.damping_n_s_m, max_force_n=max_force_n)
    if law.kind == "button_click":
        s, o = obj.spec.stiffness, obj.spec
        return ButtonClick(
            obj.normal, obj.offset, trigger_depth_m=o.trigger_depth_m, travel_m=o.travel_m,
            k_resist_n_m=s.k_resist_n_m or law.k_resist_n_m, k_click_n_m=s.k_click_n_m or law.k_click_n_m,
            k_bottom_n_m=s.k_bottom_n_m or law.k_bottom_n_m, transition_m=law.transition_m,
            damping_n_s_m=law.damping_n_s_m, max_force_n=max_force_n,
        )
    if law.kind == "fabric_friction":
        surf = obj.spec.surface
        return FabricFriction(
            obj.R, obj.centre, mu_static=surf.mu_static, mu_kinetic=surf.mu_kinetic,
            k_penalty_n_m=law.k_penalty_n_m, k_tangential_n_m=law.k_tangential_n_m,
            damping_n_s_m=law.damping_n_s_m, damping_tangential_n_s_m=law.damping_tangential_n_s_m,
            max_force_n=max_force_n,
        )
    raise ValueError(f"no force law for {law.kind!r}")
