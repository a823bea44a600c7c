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

from vishap.robot.params import DEFAULT

__all__ = ["WallSpring", "ButtonClick", "FabricFriction", "make_law", "saturate", "DEFAULT_MAX_FORCE_N"]

DEFAULT_MAX_FORCE_N = DEFAULT.peak_force_n  # the PHANToM Premium 1.0's peak force; the device's limits override it


def saturate(F: np.ndarray, max_force_n: float) -> np.ndarray:
    """Scale ``F`` (in place) so that its norm does not exceed ``max_force_n``.

    A finite force of any size keeps its direction and ends at the limit; a force with a NaN
    or infinite component (no direction) becomes zero, and so does any force under a limit that is
    not a positive finite number (a broken limit must not let force through).
    """
    if not (max_force_n > 0.0 and math.isfinite(max_force_n)):
        F[:] = 0.0
        return F
    n = math.hypot(F[0], F[1], F[2])
    if not math.isfinite(n):  # a NaN/inf component (no direction), or a norm beyond the float range
        if not (math.isfinite(F[0]) and math.isfinite(F[1]) and math.isfinite(F[2])):
            F[:] = 0.0
            return F
        F /= max(abs(F[0]), abs(F[1]), abs(F[2]))
        n = math.hypot(F[0], F[1], F[2])
        F /= n
        F *= max_force_n
    elif n > max_force_n:
        F /= n  # unit vector first: limit / n could underflow
        F *= max_force_n
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
        self._axes = tuple(tuple(float(v) for v in R[:, i]) for i in range(3))
        self._c = tuple(float(v) for v in c)
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
        # object-frame coordinates on floats (the hot path: no small-array NumPy calls)
        (xx, xy, xz), (yx, yy, yz), (nx, ny, nz) = self._axes
        px, py, pz = p_robot[0] - self._c[0], p_robot[1] - self._c[1], p_robot[2] - self._c[2]
        d = -(nx * px + ny * py + nz * pz)
        if d <= 0.0:
            self.reset()
            return np.zeros(3)
        qx, qy = xx * px + xy * py + xz * pz, yx * px + yy * py + yz * pz
        vx, vy, vz = float(v_robot[0]), float(v_robot[1]), float(v_robot[2])
        ux, uy, un = xx * vx + xy * vy + xz * vz, yx * vx + yy * vy + yz * vz, nx * vx + ny * vy + nz * vz
        fn = min(max(self.k * d - self.c * un, 0.0), self.max_force_n)
        if self.anchor is None:
            self.anchor = np.array([qx, qy])
        ax, ay = float(self.anchor[0]), float(self.anchor[1])
        fx, fy = -self.kt * (qx - ax) - self.ct * ux, -self.kt * (qy - ay) - self.ct * uy
        ft_norm = math.hypot(fx, fy)
        speed = math.hypot(ux, uy)
        if self.sliding and speed < self.v_restick:
            self.sliding = False
        if not self.sliding and ft_norm > self.mu_s * fn:
            self.sliding = True
        if self.sliding:
            if speed > 1e-9:
                ex, ey = -ux / speed, -uy / speed
            elif ft_norm > 0.0:
                ex, ey = fx / ft_norm, fy / ft_norm
            else:
                ex = ey = 0.0
            fk = self.mu_k * fn
            fx, fy = fk * ex, fk * ey
            self.anchor = np.array([qx + fx / self.kt, qy + fy / self.kt])  # drag the stick point: spring = μ_k·f_n
        self.normal_force_n, self.tangential_force_n = fn, math.hypot(fx, fy)
        F = np.array([xx * fx + yx * fy + nx * fn, xy * fx + yy * fy + ny * fn, xz * fx + yz * fy + nz * fn])
        return saturate(F, self.max_force_n)


def make_law(obj, *, max_force_n: float = DEFAULT_MAX_FORCE_N):
    """The force law for one :class:`~vishap.world.scene.SceneObject`, from its mode and spec.

    A law stiffer than the device renders stably at its damping (a scene's own key stiffness
    included) is refused with a :class:`~vishap._core.errors.ConfigError` naming the field."""
    from vishap.world.modes import check_stiffness, law_stiffnesses

    items = law_stiffnesses(obj.mode.law)
    if obj.mode.law.kind == "button_click":  # the scene's key may override the mode's springs
        s = obj.spec.stiffness
        items = [(f, getattr(s, f) or k, b) for f, k, b in items]
    check_stiffness(items, prefix=f"objects.{obj.name}.")
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
