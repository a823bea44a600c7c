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
"""
from __future__ import annotations

import math

from vishap._core.errors import ConfigError

__all__ = ["TravelLimiter", "DEFAULT_SPEED_M_S", "DEFAULT_ACCEL_M_S2"]

#: The demos' limits, chosen on the wall demo (docs/robot.md, "Travel limits"): no heat limiting, the
#: meeting as fast as without limits.
DEFAULT_SPEED_M_S = 0.6
DEFAULT_ACCEL_M_S2 = 40.0
#: the smallest fraction of the acceleration limit left when the motors are hot
MIN_SCALE = 0.1

BRAKE = 0.8  # braking curve at 80 % of the acceleration limit: the margin a 1 ms step needs to stop on the target


class TravelLimiter:
    """Follow (x, v) targets with bounded speed and acceleration; scalar arithmetic for the 1 kHz loop."""

    __slots__ = ("max_speed", "max_accel", "settle_gain", "min_scale", "_x", "_v", "_t", "ready")

    def __init__(self, max_speed_m_s: float = DEFAULT_SPEED_M_S, max_accel_m_s2: float = DEFAULT_ACCEL_M_S2, *,
                 settle_gain_hz: float = 100.0, min_scale: float = MIN_SCALE):
        for name, v in (("max_speed_m_s", max_speed_m_s), ("max_accel_m_s2", max_accel_m_s2), ("settle_gain_hz", settle_gain_hz)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"must be a finite number > 0, got {v!r}", field=f"travel.{name}")
        self.max_speed = float(max_speed_m_s)
        self.max_accel = float(max_accel_m_s2)
        self.settle_gain = float(settle_gain_hz)  # 1/s: the closing speed's slope near the target
        if not 0.0 < min_scale <= 1.0:
            raise ConfigError(f"must be in (0, 1], got {min_scale!r}", field="travel.min_scale")
        self.min_scale = float(min_scale)
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

    def step(self, t: float, x: float, y: float, z: float, vx: float, vy: float, vz: float, scale: float = 1.0):
        """The limited target ``(x, y, z, vx, vy, vz)`` at time ``t`` toward the shaped one.

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
        s = min(self.max_speed, math.sqrt(2.0 * BRAKE * a * d), self.settle_gain * d)
        s = s / d if d > 1e-12 else 0.0
        dx, dy, dz = vx + s * ex - ux, vy + s * ey - uy, vz + s * ez - uz  # wanted minus current velocity
        dv = math.sqrt(dx * dx + dy * dy + dz * dz)
        lim = a * dt
        if dv > lim:
            k = lim / dv
            dx, dy, dz = dx * k, dy * k, dz * k
        ux, uy, uz = ux + dx, uy + dy, uz + dz
        self._x = (cx, cy, cz)
        self._v = (ux, uy, uz)
        return cx, cy, cz, ux, uy, uz
