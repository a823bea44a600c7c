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
``max_speed_m_s``. Near the finger it is capped further, in two parts (``finger_m``, ``gap_m`` and
``normal`` of :meth:`TravelLimiter.step`):

* within ``near_m`` (20 mm) of the estimated fingertip the speed is at most ``near_speed_m_s``
  (0.25 m/s), falling to it linearly from ``max_speed_m_s`` at twice that distance, so the device
  never sweeps past the finger fast;
* the speed *towards* the finger along the subject's normal falls linearly with the finger's height
  over the device's face (``gap_m``) from ``near_speed_m_s`` at ``near_m`` to ``touch_speed_m_s``
  (10 mm/s) at 1 mm, so the device touches down slowly.

Sideways moves are left at 0.25 m/s near the finger: a cap on the 3-D distance slowed the device's
last lateral correction and its run-up with the finger as much as the touch-down (docs/world.md).
Without a normal the whole speed follows the normal cap's ramp in the 3-D distance. The caps win
over the acceleration limit (a cap that falls faster than the device may brake is met at once).
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

    def anchor(self, px: float, py: float, pz: float, vx: float, vy: float, vz: float, L) -> None:
        """Where the object gain ``L`` (3×3 robot frame, nested sequence) has released the servo, the
        limiter's state follows the arm (``p``, ``v``): ``x ← x + (I − L)(p − x)``, the same for the
        velocity. While the finger pushes the device in or drags it sideways the target stays on the
        surface or under the finger's estimate; without this, the servo would take the device back to
        it on the PD's spring the moment the gain returns (0.3–0.5 m/s a few millimetres from the
        lifting finger); with it, the device goes back at the travel speeds and the caps near the
        finger."""
        r0, r1, r2 = L
        if not self.ready or (r0[0] == r1[1] == r2[2] == 1.0 and r0[1] == r0[2] == r1[0] == r1[2] == r2[0] == r2[1] == 0.0):
            return
        x, v = self._x, self._v
        ex, ey, ez = px - x[0], py - x[1], pz - x[2]
        fx, fy, fz = vx - v[0], vy - v[1], vz - v[2]
        self._x = (x[0] + ex - (r0[0] * ex + r0[1] * ey + r0[2] * ez), x[1] + ey - (r1[0] * ex + r1[1] * ey + r1[2] * ez),
                   x[2] + ez - (r2[0] * ex + r2[1] * ey + r2[2] * ez))
        self._v = (v[0] + fx - (r0[0] * fx + r0[1] * fy + r0[2] * fz), v[1] + fy - (r1[0] * fx + r1[1] * fy + r1[2] * fz),
                   v[2] + fz - (r2[0] * fx + r2[1] * fy + r2[2] * fz))

    def cap_at(self, finger_m: float | None) -> float:
        """The speed cap (m/s) at ``finger_m`` metres from the fingertip (None: unknown, ``max_speed``):
        ``near_speed`` within ``near_m``, rising linearly to ``max_speed`` at twice that."""
        if finger_m is None or not math.isfinite(finger_m) or finger_m >= 2.0 * self.near_m:
            return self.max_speed
        f = max(finger_m - self.near_m, 0.0) / self.near_m
        return min(self.max_speed, self.near_speed + f * (self.max_speed - self.near_speed))

    def normal_cap_at(self, gap_m: float | None) -> float:
        """The cap (m/s) on the speed towards the finger along the normal when its pad is ``gap_m``
        over the device's face (None: unknown, ``max_speed``): ``near_speed`` at ``near_m`` falling
        linearly to ``touch_speed`` at 1 mm (and down to 1 mm under the face; further under, none)."""
        if gap_m is None or not math.isfinite(gap_m) or gap_m >= self.near_m or gap_m < -TOUCH_M:
            return self.max_speed  # (a finger under the face: moving up the normal is moving away from it)
        f = max(gap_m - TOUCH_M, 0.0) / (self.near_m - TOUCH_M)
        return min(self.max_speed, self.touch_speed + f * (self.near_speed - self.touch_speed))

    def step(self, t: float, x: float, y: float, z: float, vx: float, vy: float, vz: float, scale: float = 1.0,
             finger_m: float | None = None, gap_m: float | None = None, normal=None):
        """The limited target ``(x, y, z, vx, vy, vz)`` at time ``t`` toward the shaped one.

        ``finger_m``: the distance (m) from the device to the estimated fingertip, if known; it
        caps the output's speed near the finger (:meth:`cap_at`). ``gap_m`` and ``normal`` (a unit
        3-vector): the finger's height over the device's face along the subject's normal; they cap
        the speed towards the finger along it (:meth:`normal_cap_at`) while the finger is within
        ``near_m``. With ``finger_m`` but no
        normal, the whole speed is held to the normal cap at the distance ``finger_m``.

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
        if normal is None:
            nx = ny = nz = 0.0
            capn = math.inf
            if finger_m is not None:
                cap = min(cap, self.normal_cap_at(finger_m))
        else:
            nx, ny, nz = normal
            near = finger_m is not None and finger_m < self.near_m  # (a finger beside the device is not over its face)
            capn = self.normal_cap_at(gap_m) if near else math.inf
        self.speed_cap = cap
        s = min(self.max_speed, math.sqrt(2.0 * BRAKE * a * d), self.settle_gain * d)
        s = s / d if d > 1e-12 else 0.0
        wx, wy, wz = vx + s * ex, vy + s * ey, vz + s * ez  # wanted velocity: the target's plus closing
        wn = math.sqrt(wx * wx + wy * wy + wz * wz)
        if wn > cap:  # the output is never faster than the cap, the target's own velocity included
            k = cap / wn
            wx, wy, wz = wx * k, wy * k, wz * k
        wn = wx * nx + wy * ny + wz * nz
        if wn > capn:  # towards the finger along the normal: slower as the gap closes
            wn -= capn
            wx, wy, wz = wx - wn * nx, wy - wn * ny, wz - wn * nz
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
        un = ux * nx + uy * ny + uz * nz
        if un > capn:
            un -= capn
            ux, uy, uz = ux - un * nx, uy - un * ny, uz - un * nz
        self._x = (cx, cy, cz)
        self._v = (ux, uy, uz)
        return cx, cy, cz, ux, uy, uz
