"""The 1 kHz servo cycle (VisHap §2.3; CHAI3D's read → compute → apply haptic cycle).

``ServoLoop.tick(t, X_d, extra_force_robot=None)``: read the device → shape the target → control
(Eq. 4–5, 8–9) with gravity compensation (Eq. 6–7) → limits → write the torques → step the device.

X_d arrives at the vision rate (20–60 Hz) while the servo runs at 1 kHz. :class:`TargetShaper`
bridges the gap with one of three policies (VisHap §2.3 names the problem and low-pass filters e
and ė; the policy is measured by ``vishap bench tracking``):

* ``hold`` — keep the latest sample, Ẋ_d = 0;
* ``interpolate`` — move linearly from the previous sample to the latest over one sample interval
  (smooth, one interval late);
* ``extrapolate`` — continue from the latest sample with the velocity of the last two samples,
  counted from the sample's capture time (making up for vision latency), for at most ``horizon``
  sample intervals past its arrival, then hold.

A new sample is recognised by a new ``t_sample`` (its capture time) when the caller gives one,
otherwise by a change of value, taken as captured on arrival (a target that stops moving then
stops being extrapolated after the horizon).
"""
from __future__ import annotations

import math

from vishap._core.errors import ConfigError
from vishap.robot.controller import Controller
from vishap.robot.device import Device
from vishap.robot.kinematics import tip_state_scalar
from vishap.robot.travel import TravelLimiter

__all__ = ["POLICIES", "TargetShaper", "ServoLoop"]

POLICIES = ("hold", "interpolate", "extrapolate")


class TargetShaper:
    """Turns X_d samples (vision rate) into a target position and velocity at any servo time."""

    def __init__(self, policy: str = "hold", *, horizon: float = 1.5, max_speed_m_s: float = 2.0):
        if policy not in POLICIES:
            raise ConfigError(f"expected one of {POLICIES}, got {policy!r}", field="servo.policy")
        self.policy = policy
        self._mode = POLICIES.index(policy)
        self.horizon = float(horizon)
        self.max_speed = float(max_speed_m_s)
        self.reset()

    def reset(self) -> None:
        self.n_samples = 0
        self.n_rejected = 0  # non-finite samples refused
        self._t1 = None  # capture time of the latest sample
        self._ta = None  # servo time at which it arrived
        self._x1 = None  # latest sample
        self._x0 = None  # previous sample
        self._v = (0.0, 0.0, 0.0)
        self._dt = 0.0
        self._last_raw = None
        self._last_ts = None

    def push(self, t: float, x: float, y: float, z: float, *, t_arrival: float | None = None) -> None:
        """A new sample ``(x, y, z)`` (m) captured at time ``t`` (s), arriving at ``t_arrival`` (default ``t``)."""
        ta = t if t_arrival is None else t_arrival
        self.n_samples += 1
        if self._x1 is None:
            self._x0 = self._x1 = (x, y, z)
            self._t1, self._ta = t, ta
            self._v = (0.0, 0.0, 0.0)
            self._dt = 0.0
            return
        dt = t - self._t1
        self._x0 = self._x1
        self._x1 = (x, y, z)
        if dt > 1e-9:
            x0 = self._x0
            vx, vy, vz = (x - x0[0]) / dt, (y - x0[1]) / dt, (z - x0[2]) / dt
            n2 = vx * vx + vy * vy + vz * vz
            if n2 > self.max_speed * self.max_speed:  # a jump (re-acquisition), not motion
                vx = vy = vz = 0.0
            self._v = (vx, vy, vz)
            self._dt = dt
        else:
            self._v = (0.0, 0.0, 0.0)
            self._dt = 0.0
        self._t1, self._ta = t, ta

    def offer(self, t: float, X_d, t_sample: float | None = None) -> None:
        """Push ``X_d`` at servo time ``t`` if it is a new sample.

        With ``t_sample`` (the capture time of the frame X_d came from) a sample is new when
        ``t_sample`` changes; without it, when the value changes (captured "now").
        """
        x, y, z = float(X_d[0]), float(X_d[1]), float(X_d[2])
        if not (math.isfinite(x) and math.isfinite(y) and math.isfinite(z)):
            self.n_rejected += 1  # no sample: the shaper keeps the last good one (before any, the servo holds)
            return
        if t_sample is not None:
            if t_sample != self._last_ts:
                self._last_ts = t_sample
                self.push(t_sample, x, y, z, t_arrival=t)
            return
        raw = (x, y, z)
        if raw != self._last_raw:
            self._last_raw = raw
            self.push(t, x, y, z)

    def rest(self):
        """Where the shaped target comes to rest unless a new sample arrives (None before the first):
        the newest sample (``hold``, ``interpolate``) or the end of the extrapolation horizon."""
        x1 = self._x1
        if x1 is None or self._mode != 2 or self._dt == 0.0:
            return x1
        hz = (self._ta - self._t1) + self.horizon * self._dt
        vx, vy, vz = self._v
        return x1[0] + vx * hz, x1[1] + vy * hz, x1[2] + vz * hz

    def at(self, t: float):
        """(x, y, z, vx, vy, vz) of the shaped target at servo time ``t``; None before the first sample.

        ``interpolate`` runs from the previous sample to the latest over one sample interval after
        the latest *arrived*; ``extrapolate`` predicts from the latest *capture* time (so it also
        makes up for the vision latency) up to ``horizon`` intervals past the arrival.
        """
        x1 = self._x1
        if x1 is None:
            return None
        mode = self._mode
        if mode == 0 or self._dt == 0.0:
            return x1[0], x1[1], x1[2], 0.0, 0.0, 0.0
        vx, vy, vz = self._v
        if mode == 1:  # interpolate from x0 to x1 over one interval after arrival
            el = t - self._ta
            if el >= self._dt:
                return x1[0], x1[1], x1[2], 0.0, 0.0, 0.0
            if el < 0.0:
                el = 0.0
            x0 = self._x0
            return x0[0] + vx * el, x0[1] + vy * el, x0[2] + vz * el, vx, vy, vz
        # extrapolate from the capture time, at most `horizon` intervals beyond the arrival
        el = t - self._t1
        hz = (self._ta - self._t1) + self.horizon * self._dt
        if el >= hz:
            return x1[0] + vx * hz, x1[1] + vy * hz, x1[2] + vz * hz, 0.0, 0.0, 0.0
        if el < 0.0:
            el = 0.0
        return x1[0] + vx * el, x1[1] + vy * el, x1[2] + vz * el, vx, vy, vz


class ServoLoop:
    """Device + controller + target shaping: one :meth:`tick` per servo period.

    ``extra_force_robot`` passed to :meth:`tick` (the force law's, from the core's
    :class:`~vishap.runtime.core.ServoStep`) is added to the controller's output. Until the first
    target arrives the arm holds the position it had at the first tick.
    """

    def __init__(
        self,
        device: Device,
        controller: Controller,
        *,
        policy: str = "hold",
        horizon: float = 1.5,
        travel: TravelLimiter | None = None,
    ):
        self.device = device
        self.controller = controller
        self.shaper = TargetShaper(policy, horizon=horizon)
        self.travel = travel  # optional speed/acceleration limits between the shaper and the controller
        lim = controller.limits
        self._box = (tuple(float(v) for v in lim.workspace_min), tuple(float(v) for v in lim.workspace_max))
        if travel is not None:  # the limiter brakes to stay inside the workspace, not only its input
            travel.box = self._box
        self.n_ticks = 0
        self._read = device.read_scalar
        self._write = device.command_torque_scalar
        self._step = device.step
        self._compute = controller.compute
        self._at = self.shaper.at
        self._offer = self.shaper.offer
        self._l1, self._l2 = device.params.l1, device.params.l2

    @property
    def policy(self) -> str:
        return self.shaper.policy

    def tick(self, t: float, X_d=None, extra_force_robot=None, *, t_sample: float | None = None,
             finger_m: float | None = None, gap_m: float | None = None, normal=None, finger=None, joints=None) -> None:
        """One servo cycle at time ``t`` (s) toward ``X_d`` (m, robot frame) plus an extra force (N).

        ``finger_m``: the device's distance to the estimated fingertip (m, if known), for the travel
        limiter's speed cap near the finger; ``gap_m``/``normal`` its height over the device's face
        along the subject's normal, for the cap on the speed towards it; ``finger`` the estimated pad point
        and velocity at ``t`` in the target's coordinates, for the same caps ahead of time. ``joints``: the six joint
        readings this tick already took (the core's step reads once), else read here."""
        q1, q2, q3, w1, w2, w3 = self._read() if joints is None else joints
        if X_d is not None:
            self._offer(t, X_d, t_sample)
        tg = self._at(t)
        travel = self.travel
        if tg is None or (travel is not None and not travel.ready):
            px, py, pz, vx, vy, vz = tip_state_scalar(q1, q2, q3, w1, w2, w3, self._l1, self._l2)
            if tg is None:  # no target yet: hold where the arm is
                self.shaper.push(t, px, py, pz)
                tg = self._at(t)
            if travel is not None and not travel.ready:  # travel starts from where the arm is
                travel.reset(px, py, pz, vx, vy, vz)
        if travel is not None:  # travel spends force only while the motors have heat budget left
            tg = self._inside(*tg)
            rest = self.shaper.rest()
            tg = travel.step(t, *tg, self.controller.thermal_headroom, finger_m=finger_m, gap_m=gap_m, normal=normal,
                             finger=finger, rest=self._inside(*rest, 0.0, 0.0, 0.0))
        if extra_force_robot is None:
            tau = self._compute(t, q1, q2, q3, w1, w2, w3, *tg)
        else:
            tau = self._compute(
                t, q1, q2, q3, w1, w2, w3, *tg,
                float(extra_force_robot[0]), float(extra_force_robot[1]), float(extra_force_robot[2]),
            )
        self._write(*tau)
        self._step()
        self.n_ticks += 1

    def _inside(self, x, y, z, vx, vy, vz):
        """The shaped target clamped to the workspace box (its velocity out of the box dropped), so the
        travel limiter brakes to the box's edge itself: clamped only after it by the controller, the
        target stopped dead at the edge and the arm, arriving at the travel speed, overran the box into
        the controller's wall (a 1 N swing in 10 ms where the first move's target lay 4 mm outside)."""
        (x0, y0, z0), (x1, y1, z1) = self._box
        if x < x0 or x > x1:
            x, vx = min(max(x, x0), x1), 0.0
        if y < y0 or y > y1:
            y, vy = min(max(y, y0), y1), 0.0
        if z < z0 or z > z1:
            z, vz = min(max(z, z0), z1), 0.0
        return x, y, z, vx, vy, vz

    def state(self):
        """The device's current :class:`DeviceState` (allocates; not for the hot path)."""
        return self.device.read()
