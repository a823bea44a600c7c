"""Travel limits of the device target: a speed-, acceleration- and jerk-limited follower of X_d.

The servo's PD (Eq. 4) turns any jump of the target into a force step: a 20 mm jump at Kp 800 N/m
asks for 16 N, which the controller clips at the 8.5 N peak. The clipped travel heats the motors;
the heating estimate then holds the arm to its 1.4 N continuous force, and the contact that follows
is rendered soft (the arm sags under the finger). :class:`TravelLimiter` sits between the target
shaper and the controller and hands the controller a target it can follow without saturating: it
closes the gap to the shaped target at most at ``max_speed_m_s``, accelerating and braking at most
at ``max_accel_m_s2``, plus the target's own velocity. Once the gap is closed the output *is* the
target (a finger followed at constant speed is followed without lag), so contact rendering is
unchanged.

The acceleration itself changes by at most ``max_jerk_m_s3`` (an S-curve): the force the PD asks
for to move the light arm then has no steps. Switched in one tick (bang-bang), 40 m/s² on a
0.05–0.2 kg arm is a 2–8 N step, and through the controller's 30 Hz boxcar, whose first sidelobe
passes 22 % of 30–60 Hz, it was most of the approach's command ripple above 30 Hz (docs/robot.md).
The closing speed follows the jerk-limited braking curve (the speed a stop starting at zero
acceleration can shed within the distance left, on the distance left after the acceleration still
in hand has unwound), and the acceleration follows the wanted velocity on the matching curve plus
the braking curve's own rate: no overshoot, within every limit. What a jerk limit cannot do is
stop dead, so the output also brakes towards where the shaped target will stop (``rest``: the
newest sample the shaper is heading for) and towards the faces of the workspace box (``box``),
instead of overrunning a target that stops dead or the controller's clamp.

The output's speed — the closing speed *and* the target's own velocity together — never exceeds
``max_speed_m_s``. Near the finger it is capped further, in two parts (``finger_m``, ``gap_m`` and
``normal`` of :meth:`TravelLimiter.step`):

* within ``near_m`` (20 mm) of the estimated fingertip (the nearest of the estimates given: the
  world's and a faster one that follows a reach's start), plus ``margin_m`` for the estimate's error,
  the speed is at most ``near_speed_m_s`` (0.25 m/s), falling to it linearly from ``max_speed_m_s``
  ``near_m`` further out, so the device never sweeps past the finger fast;
* the speed *towards* the finger along the subject's normal falls linearly with the finger's height
  over the device's face (``gap_m``) from ``near_speed_m_s`` at ``near_m`` to ``touch_speed_m_s``
  (10 mm/s) at 1 mm, so the device touches down slowly.

:meth:`TravelLimiter.for_approach` is what the demos and live mode run: the jerk limit (1000 m/s³),
the caps on the finger's state 40 ms ahead (``lead_s``) with a 10 mm ``margin_m``, 0.22 m/s near
the finger (the arm overran its target's speed by up to 8 % there); the world's closed loop
(``bench world``) runs it too. The defaults leave the jerk unlimited and the caps on the distance now.

Sideways moves are left at the near-finger cap: a cap on the 3-D distance slowed the device's
last lateral correction and its run-up with the finger as much as the touch-down (docs/world.md).
Without a normal the whole speed follows the normal cap's ramp in the 3-D distance. The caps win
over the acceleration limit (a cap that falls faster than the device may brake is met at once; the
step is not kept as an acceleration, which the jerk limit would take 40 ms to unwind while the output
braked through zero and back away from its target).
"""
from __future__ import annotations

import math

from vishap._core.errors import ConfigError

__all__ = ["TravelLimiter", "DEFAULT_SPEED_M_S", "DEFAULT_ACCEL_M_S2", "DEFAULT_JERK_M_S3", "APPROACH_JERK_M_S3", "NEAR_M", "NEAR_SPEED_M_S", "TOUCH_SPEED_M_S"]

#: The demos' limits, chosen on the wall demo (docs/robot.md, "Travel limits"): no heat limiting, the
#: meeting as fast as without limits.
DEFAULT_SPEED_M_S = 0.6
DEFAULT_ACCEL_M_S2 = 40.0
#: the limiter's default jerk: none (the acceleration may switch in one tick, as before the jerk limit)
DEFAULT_JERK_M_S3 = math.inf
#: within this distance of the fingertip the device's speed is capped (issue 16: ≤ 0.25 m/s within 20 mm)
NEAR_M = 0.020
NEAR_SPEED_M_S = 0.25

# The approach configuration (:meth:`TravelLimiter.for_approach`, what the demos and live mode run):
#: the jerk limit: the force the PD asks for to accelerate the arm rises over a/j (40 ms at 40 m/s²)
#: instead of in one tick, so travel puts no steps through the controller's 30 Hz boxcar (docs/robot.md)
APPROACH_JERK_M_S3 = 1000.0
#: how far ahead (s) the caps near the finger look: the device follows this output ≈ 30 ms late
#: (the boxcar's half interval, Eq. 5's low-pass, the PD), and the finger keeps moving meanwhile
APPROACH_LEAD_S = 0.040
#: what the estimated fingertip's distance may be too long by (m): the world's estimate in the wall
#: demos, extrapolated to the servo tick, was up to 11–15 mm further than the true pad (p99; p90
#: 5–7 mm; median 0), and the device then crossed the true 20 mm at 0.3–0.37 m/s. Most of that was its
#: velocity lagging a reach's start; with the caps' own faster estimate beside it (the nearer wins,
#: world.predictor.near_predictor) it is p90 3.5 mm, p99 14 mm within 35 mm of the finger; the largest (15–21 mm)
#: in a reach's first 100 ms, when no filter knows yet that the finger has started (docs/robot.md)
APPROACH_MARGIN_M = 0.010
#: the output's cap near the finger: 12 % under the goal, the most the arm overran its target's speed
#: in the demos while the PD took up the lag of a turn (0.26–0.27 m/s measured with the cap at 0.25)
APPROACH_NEAR_SPEED_M_S = 0.22
#: the cap within TOUCH_M of the finger: the device touches down at most this fast
TOUCH_SPEED_M_S = 0.010
TOUCH_M = 0.001
#: the smallest fraction of the acceleration limit left when the motors are hot
MIN_SCALE = 0.1

BRAKE = 0.8  # braking curves at 80 % of the acceleration and jerk limits: the margin a 1 ms step needs to stop on the target
#: the velocity loop's gain in units of the position loop's (settle_gain): 4 makes the two critically damped
VELOCITY_GAIN = 4.0


class TravelLimiter:
    """Follow (x, v) targets with bounded speed, acceleration and jerk; scalar arithmetic for the 1 kHz loop."""

    __slots__ = ("max_speed", "max_accel", "max_jerk", "settle_gain", "min_scale", "near_m", "near_speed",
                 "touch_speed", "lead_s", "margin_m", "box", "_far", "_x", "_v", "_a", "_t", "ready", "speed_cap")

    def __init__(self, max_speed_m_s: float = DEFAULT_SPEED_M_S, max_accel_m_s2: float = DEFAULT_ACCEL_M_S2,
                 max_jerk_m_s3: float = DEFAULT_JERK_M_S3, *, settle_gain_hz: float = 100.0, min_scale: float = MIN_SCALE,
                 near_m: float = NEAR_M, near_speed_m_s: float = NEAR_SPEED_M_S, touch_speed_m_s: float = TOUCH_SPEED_M_S,
                 lead_s: float = 0.0, margin_m: float = 0.0):
        if not (isinstance(max_jerk_m_s3, (int, float)) and max_jerk_m_s3 > 0 and max_jerk_m_s3 == max_jerk_m_s3):
            raise ConfigError(f"must be a number > 0 (inf: unlimited), got {max_jerk_m_s3!r}", field="travel.max_jerk_m_s3")
        for name, v in (("max_speed_m_s", max_speed_m_s), ("max_accel_m_s2", max_accel_m_s2), ("settle_gain_hz", settle_gain_hz),
                        ("near_m", near_m - TOUCH_M), ("near_speed_m_s", near_speed_m_s), ("touch_speed_m_s", touch_speed_m_s)):
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0):
                raise ConfigError(f"must be a finite number > 0, got {v!r}", field=f"travel.{name}")
        self.max_speed = float(max_speed_m_s)
        self.max_accel = float(max_accel_m_s2)
        self.max_jerk = float(max_jerk_m_s3)
        if not (isinstance(lead_s, (int, float)) and math.isfinite(lead_s) and lead_s >= 0):
            raise ConfigError(f"must be a finite number ≥ 0, got {lead_s!r}", field="travel.lead_s")
        self.lead_s = float(lead_s)
        if not (isinstance(margin_m, (int, float)) and math.isfinite(margin_m) and margin_m >= 0):
            raise ConfigError(f"must be a finite number ≥ 0, got {margin_m!r}", field="travel.margin_m")
        self.margin_m = float(margin_m)
        #: ``((x0, y0, z0), (x1, y1, z1))``: the workspace box (m) the output brakes to stay inside, or None
        self.box = None
        self._far = _far(self.max_speed, self.max_accel, self.max_jerk)
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
        self._a = (0.0, 0.0, 0.0)
        self._t = None
        self.ready = False

    @classmethod
    def for_approach(cls, max_speed_m_s: float = DEFAULT_SPEED_M_S, max_accel_m_s2: float = DEFAULT_ACCEL_M_S2):
        """The approach configuration: the jerk limit, the caps near the finger on its state
        ``APPROACH_LEAD_S`` ahead with ``APPROACH_MARGIN_M`` for the estimate's error, 0.22 m/s near it.
        What the demos, live mode and the world's closed loop run (``apps.assemble.make_servo_side``).
        On the panel's routed moves the jerk-limited device reached the third key late while the
        object gain kept the shelf's released normal through its dwell after the subject switch; a
        new subject now releases it at once (:class:`~vishap.robot.object_gain.ObjectGainScheduler`)."""
        return cls(max_speed_m_s, max_accel_m_s2, APPROACH_JERK_M_S3, near_speed_m_s=APPROACH_NEAR_SPEED_M_S,
                   lead_s=APPROACH_LEAD_S, margin_m=APPROACH_MARGIN_M)

    def reset(self, x, y, z, vx=0.0, vy=0.0, vz=0.0) -> None:
        """Start from the arm's own position and velocity (m, m/s)."""
        self._x = (float(x), float(y), float(z))
        self._v = (float(vx), float(vy), float(vz))
        self._a = (0.0, 0.0, 0.0)
        self._t = None
        self.ready = True

    def anchor(self, px: float, py: float, pz: float, vx: float, vy: float, vz: float, L) -> None:
        """Where the object gain ``L`` (3×3 robot frame, nested sequence) has released the servo, the
        limiter's state follows the arm (``p``, ``v``): ``x ← x + (I − L)(p − x)``, the same for the
        velocity; the acceleration keeps only the part where the gain holds. While the finger pushes the device in or drags it sideways the target stays on the
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
        a = self._a
        self._a = (r0[0] * a[0] + r0[1] * a[1] + r0[2] * a[2], r1[0] * a[0] + r1[1] * a[1] + r1[2] * a[2],
                   r2[0] * a[0] + r2[1] * a[1] + r2[2] * a[2])

    def cap_at(self, finger_m: float | None) -> float:
        """The speed cap (m/s) at ``finger_m`` metres from the estimated fingertip (None: unknown,
        ``max_speed``): ``near_speed`` within ``near_m`` + ``margin_m``, rising linearly to ``max_speed``
        ``near_m`` further out."""
        if finger_m is None or not math.isfinite(finger_m):
            return self.max_speed
        f = (finger_m - self.near_m - self.margin_m) / self.near_m
        if f >= 1.0:
            return self.max_speed
        f = max(f, 0.0)
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
             finger_m: float | None = None, gap_m: float | None = None, normal=None, finger=None, rest=None):
        """The limited target ``(x, y, z, vx, vy, vz)`` at time ``t`` toward the shaped one.

        ``finger_m``: the distance (m) from the device to the estimated fingertip, if known; it
        caps the output's speed near the finger (:meth:`cap_at`). ``gap_m`` and ``normal`` (a unit
        3-vector): the finger's height over the device's face along the subject's normal; they cap
        the speed towards it along the normal (:meth:`normal_cap_at`) while the finger is within
        ``near_m``. With ``finger_m`` but no normal, the whole speed is held to the normal cap at the
        distance ``finger_m``. ``finger`` (optional): the estimated pad point and its velocity
        ``(x, y, z, vx, vy, vz)`` at ``t`` in the target's coordinates, or a tuple of several such
        estimates of the same finger; the caps then also act on the finger as each puts it ``lead_s``
        from now against this output, where the device will be by then (the nearest wins), so the
        device has slowed down *before* it is near the finger.
        ``rest`` (optional): the point where the moving target will stop unless a new sample moves it
        on (the shaper's newest sample); the output's speed towards it stays one it can stop from
        there, so a target that stops dead is not overrun (with bounded jerk the output cannot stop
        dead with it).

        ``scale`` (0…1) scales the acceleration and jerk limits: the servo passes the motors' thermal
        headroom, so travel spends force only while there is heat budget left for rendering contact
        (never below ``min_scale``: the device still gets where it must, more slowly). A non-finite
        target is passed on untouched for the controller to reject; the limiter's own state stays finite."""
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
        ax, ay, az = self._a
        ex, ey, ez = x - cx, y - cy, z - cz
        d = math.sqrt(ex * ex + ey * ey + ez * ez)
        sc = min(1.0, max(scale, self.min_scale))
        a, j = self.max_accel * sc, self.max_jerk * sc
        # the caps near the finger
        if normal is None:
            nx = ny = nz = 0.0
        else:
            nx, ny, nz = normal
        if finger is not None and self.lead_s > 0.0:  # the finger lead_s ahead, against where the device will be then
            L = self.lead_s
            for fx, fy, fz, fvx, fvy, fvz in (finger if isinstance(finger[0], tuple) else (finger,)):
                rx, ry, rz = fx + fvx * L - cx, fy + fvy * L - cy, fz + fvz * L - cz
                dp = math.sqrt(rx * rx + ry * ry + rz * rz)
                if dp < math.inf:  # a non-finite estimate says nothing (its NaN gap would lift the normal cap)
                    finger_m = dp if finger_m is None or not finger_m < dp else finger_m
                    if normal is not None and (gap_m is None or not gap_m < -TOUCH_M):
                        # a finger predicted through the face is landing on it, not under it
                        gp = max(rx * nx + ry * ny + rz * nz, 0.0)
                        gap_m = gp if gap_m is None or not gap_m < gp else gap_m
        cap = self.cap_at(finger_m)
        if normal is None:
            capn = math.inf
            if finger_m is not None:
                cap = min(cap, self.normal_cap_at(finger_m))
        else:
            near = finger_m is not None and finger_m < self.near_m + self.margin_m  # (a finger beside the device is not over its face)
            capn = self.normal_cap_at(gap_m) if near else math.inf
        self.speed_cap = cap
        # the closing speed: linear near the target, the jerk-limited stopping curve further out, capped;
        # and its rate of change as the distance closes (fed forward to the acceleration)
        if d > 1e-12:
            ix, iy, iz = ex / d, ey / d, ez / d
        else:
            ix = iy = iz = 0.0
        ba, bj = BRAKE * a, BRAKE * j
        closing = (ux - vx) * ix + (uy - vy) * iy + (uz - vz) * iz  # the output's speed towards the target
        s, slope = _braking_speed(d, closing, ax * ix + ay * iy + az * iz, ba, bj)
        lin = self.settle_gain * d
        if lin <= s:
            s, slope = lin, self.settle_gain
        if s >= self.max_speed:
            s, slope = self.max_speed, 0.0
        af = -slope * closing  # d(s)/dt = s'(d)·ḋ
        afx, afy, afz = af * ix, af * iy, af * iz
        wx, wy, wz = vx + s * ix, vy + s * iy, vz + s * iz  # wanted velocity: the target's plus closing
        if rest is not None:  # a target that will stop: never faster towards where it stops than the
            ex, ey, ez = rest[0] - cx, rest[1] - cy, rest[2] - cz  # output can stop there too
            d = math.sqrt(ex * ex + ey * ey + ez * ez)
            if 1e-12 < d < self._far:
                ex, ey, ez = ex / d, ey / d, ez / d
                ur = ux * ex + uy * ey + uz * ez
                s, slope = _braking_speed(d, ur, ax * ex + ay * ey + az * ez, ba, bj)
                wr = wx * ex + wy * ey + wz * ez
                if wr > s:
                    wr -= s
                    wx, wy, wz = wx - wr * ex, wy - wr * ey, wz - wr * ez
                    af = -slope * ur
                    afx, afy, afz = af * ex, af * ey, af * ez
        box = self.box
        if box is not None:  # towards a face of the box no faster than the arm can stop before it
            far = self._far
            (x0, y0, z0), (x1, y1, z1) = box
            if wx > 0.0 and x1 - cx < far:
                wx, afx = _brake_to(x1 - cx, wx, ux, ax, afx, ba, bj)
            elif wx < 0.0 and cx - x0 < far:
                wx, afx = _brake_to(cx - x0, wx, ux, ax, afx, ba, bj)
            if wy > 0.0 and y1 - cy < far:
                wy, afy = _brake_to(y1 - cy, wy, uy, ay, afy, ba, bj)
            elif wy < 0.0 and cy - y0 < far:
                wy, afy = _brake_to(cy - y0, wy, uy, ay, afy, ba, bj)
            if wz > 0.0 and z1 - cz < far:
                wz, afz = _brake_to(z1 - cz, wz, uz, az, afz, ba, bj)
            elif wz < 0.0 and cz - z0 < far:
                wz, afz = _brake_to(cz - z0, wz, uz, az, afz, ba, bj)
        wn = math.sqrt(wx * wx + wy * wy + wz * wz)
        if wn > cap:  # never faster than the cap, the target's own velocity included
            k = cap / wn
            wx, wy, wz = wx * k, wy * k, wz * k
            afx = afy = afz = 0.0
        wn = wx * nx + wy * ny + wz * nz
        if wn > capn:  # towards the finger along the normal: slower as the gap closes
            wn -= capn
            wx, wy, wz = wx - wn * nx, wy - wn * ny, wz - wn * nz
        # the wanted acceleration: towards the wanted velocity on a curve that reaches it with zero
        # acceleration at the jerk limit (no speed overshoot), plus the closing speed's own rate
        dx, dy, dz = wx - ux, wy - uy, wz - uz
        dv = math.sqrt(dx * dx + dy * dy + dz * dz)
        if dv > 1e-12:
            g = min(a, math.sqrt(2.0 * BRAKE * j * dv), VELOCITY_GAIN * self.settle_gain * dv) / dv
            dx, dy, dz = afx + g * dx, afy + g * dy, afz + g * dz
        else:
            dx, dy, dz = afx, afy, afz
        an = math.sqrt(dx * dx + dy * dy + dz * dz)
        if an > a:
            k = a / an
            dx, dy, dz = dx * k, dy * k, dz * k
        # the acceleration moves towards it at most at the jerk limit: the force the PD asks for has no steps
        dx, dy, dz = dx - ax, dy - ay, dz - az
        jn = math.sqrt(dx * dx + dy * dy + dz * dz)
        lim = j * dt
        if jn > lim:
            k = lim / jn
            dx, dy, dz = dx * k, dy * k, dz * k
        ax, ay, az = ax + dx, ay + dy, az + dz
        ux, uy, uz = ux + ax * dt, uy + ay * dt, uz + az * dt
        # A cap that fell faster than the device may brake is met at once: the velocity steps down to
        # it. The step is not an acceleration the output goes on with: kept as one (up to the 40 m/s²
        # limit), the jerk limit then took a/j (40 ms) to unwind it, and the braking ran on through
        # zero, sending the device back away from its target under the landing finger (the world's
        # wall approach, the caps 10 mm early for the estimate's error). What stays of the acceleration
        # is what does not push past the cap: its braking part.
        un = math.sqrt(ux * ux + uy * uy + uz * uz)
        if un > cap:
            k = cap / un
            ux, uy, uz = ux * k, uy * k, uz * k
            an = (ax * ux + ay * uy + az * uz) / (un * k)
            if an > 0.0:
                ax, ay, az = ax - an * ux / cap, ay - an * uy / cap, az - an * uz / cap
        un = ux * nx + uy * ny + uz * nz
        if un > capn:
            un -= capn
            ux, uy, uz = ux - un * nx, uy - un * ny, uz - un * nz
            an = ax * nx + ay * ny + az * nz
            if an > 0.0:
                ax, ay, az = ax - an * nx, ay - an * ny, az - an * nz
        self._x = (cx, cy, cz)
        self._v = (ux, uy, uz)
        self._a = (ax, ay, az)
        return cx, cy, cz, ux, uy, uz


def _brake_to(d: float, w: float, u: float, acc: float, af: float, a: float, j: float) -> tuple[float, float]:
    """One axis's wanted velocity ``w`` (and its fed-forward rate ``af``) held to what can still stop
    within ``d`` along the sign of ``w`` (``u``, ``acc``: the output's velocity and acceleration)."""
    sg = 1.0 if w > 0.0 else -1.0
    s, slope = _braking_speed(d, sg * u, sg * acc, a, j)
    if sg * w > s:
        return sg * s, -slope * u
    return w, af


def _braking_speed(d: float, v: float, acc: float, a: float, j: float) -> tuple[float, float]:
    """``(s, ds/dd)``: :func:`_stopping_speed` for a device closing at ``v`` with acceleration ``acc``
    towards a point ``d`` ahead. While a positive ``acc`` unwinds at the jerk limit the device still
    gains acc²/2j of speed over v·acc/j + acc³/3j² of the distance: it must brake on what is left."""
    if acc <= 0.0:
        return _stopping_speed(d, a, j)
    tau = acc / j
    s, slope = _stopping_speed(d - max(v, 0.0) * tau - acc * tau * tau / 3.0, a, j)
    return max(s - 0.5 * acc * tau, 0.0), slope


def _stopping_speed(d: float, a: float, j: float) -> tuple[float, float]:
    """``(s, ds/dd)``: the highest speed from which a stop with acceleration ≤ ``a`` and jerk ≤ ``j``,
    starting at zero acceleration, ends within ``d`` — the jerk-limited form of the braking curve
    √(2·a·d). A stop from ``s`` takes ``s·√(s/j)`` while the peak deceleration √(s·j) stays under
    ``a`` (``s`` ≤ a²/j), else ``s²/(2a) + s·a/(2j)``."""
    if d <= 0.0:
        return 0.0, 0.0
    if d * j * j <= a * a * a:
        s = (j * d * d) ** (1.0 / 3.0)
        return s, 2.0 * s / (3.0 * d)
    r = a * a / j
    s = 0.5 * (math.sqrt(r * r + 8.0 * a * d) - r)
    return s, 1.0 / (s / a + 0.5 * r / a)


def _far(v_max: float, a: float, j: float) -> float:
    """Beyond this distance (m) from a face of the box no braking towards it can be due yet: the
    longest stop, over the speeds up to ``v_max`` and the acceleration the velocity loop can have in
    hand at each (its own curve: a² ≤ 2·BRAKE·j·(v_max − v)), with a 50 % margin."""
    worst = 0.0
    ba, bj = BRAKE * a, BRAKE * j
    for k in range(21):
        v = v_max * k / 20.0
        acc = min(a, math.sqrt(2.0 * bj * (v_max - v)))
        tau = acc / bj
        d, s = v * tau + acc * tau * tau / 3.0, v + 0.5 * acc * tau
        worst = max(worst, d + s * s / (2.0 * ba) + s * ba / (2.0 * bj))
    return 1.5 * worst + 1e-3
