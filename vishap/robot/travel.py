"""Travel limits of the device target: a velocity- and acceleration-limited follower of X_d.

The servo's PD (Eq. 4) turns any jump of the target into a force step: a 20 mm jump at Kp 800 N/m
asks for 16 N, which the controller clips at the 8.5 N peak. The clipped travel heats the motors;
the heating estimate then holds the arm to its 1.4 N continuous force, and the contact that follows
is rendered soft (the arm sags under the finger). :class:`TravelLimiter` sits between the target
shaper and the controller and hands the controller a target it can follow without saturating: it
closes the gap to the shaped target at most at ``max_speed_m_s``, accelerating and braking at most
at ``max_accel_m_s2`` (braking on the √(2·a·d) curve so that it stops on the target without
overshoot), plus the target's own velocity. Once the gap is closed the output *is* the target (a
finger followed at constant speed is followed without lag), so contact rendering is unchanged.

The output's speed — the closing speed *and* the target's own velocity together — never exceeds
``max_speed_m_s``. Near the finger it is capped further: given the distance from the device to the
estimated fingertip (``finger_m`` of :meth:`TravelLimiter.step`), the cap falls linearly from
``near_speed_m_s`` (0.25 m/s) at ``near_m`` (20 mm) to ``touch_speed_m_s`` (10 mm/s) 1 mm from it, so
the device never sweeps past the finger fast and touches down slowly. The cap wins over the
acceleration limit (a cap that falls faster than the device may brake is met at once).
"""
from __future__ import annotations

import math

from vishap._core.errors import ConfigError

__all__ = ["TravelLimiter", "DEFAULT_SPEED_M_S", "DEFAULT_ACCEL_M_S2", "NEAR_M", "NEAR_SPEED_M_S", "TOUCH_SPEED_M_S"]

#: The demos' limits, chosen on the wall demo (docs/robot.md, "Travel limits"): no heat limiting, the
#: meeting as fast as without limits.
DEFAULT_SPEED_M_S = 0.6
DEFAULT_ACCEL_M_S2 = 40.0
#: within this distance of the fingertip the device's speed is capped (issue 16: ≤ 0.25 m/s within 20 mm)
NEAR_M = 0.020
NEAR_SPEED_M_S = 0.25
#: the cap within TOUCH_M of the finger: the device touches down at most this fast
TOUCH_SPEED_M_S = 0.010
TOUCH_M = 0.001
#: the smallest fraction of the acceleration limit left when the motors are hot
MIN_SCALE = 0.1

BRAKE = 0.8  # braking curve at 80 % of the acceleration limit: the margin a 1 ms step needs to stop on the target


class TravelLimiter:
    """Follow (x, v) targets with bounded speed and acceleration; scalar arithmetic for the 1 kHz loop."""

    __slots__ = ("max_speed", "max_accel", "settle_gain", "min_scale", "near_m", "near_speed", "touch_speed",
                 "_x", "_v", "_t", "ready", "speed_cap")

    def __init__(self, max_speed_m_s: float = DEFAULT_SPEED_M_S, max_accel_m_s2: float = DEFAULT_ACCEL_M_S2, *,
                 settle_gain_hz: float = 100.0, min_scale: float = MIN_SCALE, near_m: float = NEAR_M,
                 near_speed_m_s: float = NEAR_SPEED_M_S, touch_speed_m_s: float = TOUCH_SPEED_M_S):
        for name, v in (("max_speed_m_s", max_speed_m_s), ("max_accel_m_s2", max_accel_m_s2), ("settle_gain_hz", settle_gain_hz),
                        ("near_m", near_m - TOUCH_M), ("near_speed_m_s", near_speed_m_s), ("touch_speed_m_s", touch_speed_m_s)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"must be a finite number > 0, got {v!r}", field=f"travel.{name}")
        self.max_speed = float(max_speed_m_s)
        self.max_accel = float(max_accel_m_s2)
        self.settle_gain = float(settle_gain_hz)  # 1/s: the closing speed's slope near the target
        if not 0.0 < min_scale <= 1.0:
            raise ConfigError(f"must be in (0, 1], got {min_scale!r}", field="travel.min_scale")
        self.min_scale = float(min_scale)
        if touch_speed_m_s > near_speed_m_s:
            raise ConfigError(f"must be ≤ near_speed_m_s ({near_speed_m_s}), got {touch_speed_m_s!r}", field="travel.touch_speed_m_s")
        self.near_m, self.near_speed, self.touch_speed = float(near_m), float(near_speed_m_s), float(touch_speed_m_s)
        self.speed_cap = self.max_speed  # the cap applied at the last step (m/s)
        self._x = (0.0, 0.0, 0.0)
        self._v = (0.0, 0.0, 0.0)
        self._t = None
        self.ready = False

    def reset(self, x, y, z, vx=0.0, vy=0.0, vz=0.0) -> None:
        """Start from the arm's own position and velocity (m, m/s)."""
        self._x = (float(x), float(y), float(z))
        self._v = (float(vx), float(vy), float(vz))
        self._t = None
        self.ready = True

    def cap_at(self, finger_m: float | None) -> float:
        """The speed cap (m/s) at ``finger_m`` metres from the fingertip (None: unknown, ``max_speed``)."""
        if finger_m is None or not math.isfinite(finger_m) or finger_m >= self.near_m:
            return self.max_speed
        f = max(finger_m - TOUCH_M, 0.0) / (self.near_m - TOUCH_M)
        return min(self.max_speed, self.touch_speed + f * (self.near_speed - self.touch_speed))

    def step(self, t: float, x: float, y: float, z: float, vx: float, vy: float, vz: float, scale: float = 1.0,
             finger_m: float | None = None):
        """The limited target ``(x, y, z, vx, vy, vz)`` at time ``t`` toward the shaped one.

        ``finger_m``: the distance (m) from the device to the estimated fingertip, if known; it
        caps the output's speed near the finger (:meth:`cap_at`).

        ``scale`` (0…1) scales the acceleration limit: the servo passes the motors' thermal headroom,
        so travel spends force only while there is heat budget left for rendering contact (never below
        ``min_scale``: the device still gets where it must, more slowly). A non-finite target is
        passed on untouched for the controller to reject; the limiter's own state stays finite."""
        if not math.isfinite(x + y + z + vx + vy + vz):
            return x, y, z, vx, vy, vz
        if not self.ready:
            self.reset(x, y, z, vx, vy, vz)
        dt = 0.0 if self._t is None else t - self._t
        self._t = t
        cx, cy, cz = self._x
        ux, uy, uz = self._v
        if dt <= 0.0:
            return cx, cy, cz, ux, uy, uz
        cx, cy, cz = cx + ux * dt, cy + uy * dt, cz + uz * dt  # advance to now, then steer
        ex, ey, ez = x - cx, y - cy, z - cz
        d = math.sqrt(ex * ex + ey * ey + ez * ez)
        a = self.max_accel * min(1.0, max(scale, self.min_scale))
        # closing speed: linear near the target, the braking curve further out, capped
        cap = self.cap_at(finger_m)
        self.speed_cap = cap
        s = min(self.max_speed, math.sqrt(2.0 * BRAKE * a * d), self.settle_gain * d)
        s = s / d if d > 1e-12 else 0.0
        wx, wy, wz = vx + s * ex, vy + s * ey, vz + s * ez  # wanted velocity: the target's plus closing
        wn = math.sqrt(wx * wx + wy * wy + wz * wz)
        if wn > cap:  # the output is never faster than the cap, the target's own velocity included
            k = cap / wn
            wx, wy, wz = wx * k, wy * k, wz * k
        dx, dy, dz = wx - ux, wy - uy, wz - uz
        dv = math.sqrt(dx * dx + dy * dy + dz * dz)
        lim = a * dt
        if dv > lim:
            k = lim / dv
            dx, dy, dz = dx * k, dy * k, dz * k
        ux, uy, uz = ux + dx, uy + dy, uz + dz
        un = math.sqrt(ux * ux + uy * uy + uz * uz)
        if un > cap:  # a cap that fell faster than the device may brake: met at once
            k = cap / un
            ux, uy, uz = ux * k, uy * k, uz * k
        self._x = (cx, cy, cz)
        self._v = (ux, uy, uz)
        return cx, cy, cz, ux, uy, uz
