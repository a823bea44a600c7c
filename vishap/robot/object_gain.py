"""The object-gain scheduler: when Λ (VisHap Eq. 8–9) changes, and how the servo's force ramps.

The object gain ``Λ`` decides which axes the position servo still holds: the identity in free
motion, λ_z = 0 once the world's force law renders the surface (it gives the normal force), and the
mode's own lateral gains (``contact_gain``) once the finger has pushed the device in. Switching Λ
on a depth threshold tick by tick makes it chatter (encoder noise alone moves the measured depth by
tens of µm), and every flip of Λ with the PD error built up while the axis was released is a force
step. :class:`ObjectGainScheduler` turns the world's per-tick facts into a Λ that changes at most
twice per approach, never faster than a ``ramp_s`` linear blend, plus a force-scale factor that
ramps the servo force up after every hold or retreat and when tracking starts.

States, and what moves between them (``depth`` is the device's depth under the subject's surface,
positive inside; the law renders while the world announces an imminent or current interaction):

* ``FREE`` (Λ = I) → ``SURFACE`` when the law acts and ``depth > surface_on_m``, or earlier, while
  the device waits at the surface (``depth > −release_m``) and the finger is predicted to touch it
  within ``ramp_s`` (``touch_in_s``): the blend then ends about when the finger lands, so the touch
  meets the law alone rather than the position servo's stiffness and damping fading out under it;
* ``SURFACE`` (Λ = diag(1, 1, 0): the law gives the normal force, the servo keeps the lateral
  position) → ``ENGAGED`` when ``depth > engage_m`` has held for ``engage_s``: a finger pushing the
  device in holds it there for hundreds of ms, whereas the device's own bounce on the law's spring
  (a 60 g tip on 800 N/m: half a period 27 ms) or a dip while it travels sideways at the surface
  crosses ``engage_m`` for a few ticks only (3–16 ms in the wall demos) — and engaging on it releases
  the wall's lateral axes (its ``contact_gain`` is 0) and flips Λ twice more as the device comes back;
* ``ENGAGED`` (Λ = the mode's ``contact_gain``) → ``SURFACE`` only when ``depth < engage_m −
  hysteresis_m``;
* ``SURFACE`` / ``ENGAGED`` → ``FREE`` when ``depth < −release_m`` or the law stops acting (no
  interaction announced, or the guard neither tracks nor holds).

Every change waits until ``dwell_s`` has passed since the previous one (hysteresis keeps noise from
crossing a threshold back; the dwell keeps a real but brief excursion from flipping Λ twice), except
a change to ``FREE`` because the guard retreats or the interaction ended, which happens at once. A
new subject ends the interaction with the old one: if the device is not at the new subject's
surface when it is named (``depth < −release_m``), Λ goes back to free at once too. The world never
switches the subject under a touching finger, so what the dwell guards against cannot happen there,
and waiting it out kept the old surface's released normal while the world routed the device to the
new subject (the panel: 50 ms dwell + 25 ms blend from the shelf to a key 20 mm lower, and the lift
over the shelf's edge started only then).
Each change blends linearly from the Λ in force at that tick to the new one over ``ramp_s``
(≥ 20 ms); a change during a blend starts from where the blend is.

The force scale weighs the servo's PD and law force (never the gravity compensation). It is 0
while the guard is idle (no finger seen yet), and restarts from 0 each time the guard starts or
resumes tracking in free motion (after a hold or a retreat), rising linearly to 1 over ``force_ramp_s``, so the
error built up against a target that jumped meanwhile is never delivered as a step. The controller
blends: the force it was giving when the scale restarted fades out with ``1 − scale`` as the new
one fades in (``Controller.force_scale``), so the restart itself is no step either (a scale that
simply fell to 0 dropped the held force, 0.9–1.0 N in the wall demos, in one tick). During a hold
or retreat it keeps rising to 1 (the device must hold or leave).

The servo step calls it once per tick, after the world's contact rendering::

    sched = ObjectGainScheduler(dt=params.dt)          # once
    sched.set_subject(law.lambda_contact, R_robot_obj) # when the world's subject changes (or None)
    ...
    # each tick: depth = law.depth(p_robot_device) (nan when no subject), action = guard action
    L, scale = sched.step(t, depth, interaction.imminent, interaction.in_contact, action)
    ctrl.set_lambda_robot(L)      # L: 3×3 tuple of tuples, robot frame (cheap when unchanged)
    ctrl.force_scale = scale      # multiplies the PD and law force (not the gravity compensation)

``sched.state`` (``"free"``, ``"surface"``, ``"engaged"``), ``sched.n_changes`` and
``sched.changing`` (a blend in progress) are public for logs and tests. ``sched.law_active`` tells
whether the world's law should be applied this tick (the same test the state machine uses).
"""
from __future__ import annotations

import math

from vishap._core.errors import ConfigError

__all__ = ["ObjectGainScheduler", "FREE", "SURFACE", "ENGAGED", "SURFACE_GAIN"]

FREE, SURFACE, ENGAGED = "free", "surface", "engaged"
#: ᴼΛ while the law renders the surface but the finger has not pushed the device in yet: the law
#: gives the normal force, the servo keeps the device on its lateral target
SURFACE_GAIN = (1.0, 1.0, 0.0)
#: the shortest blend the issue allows between two Λ (s)
MIN_RAMP_S = 0.020

_TRACKING = ("track", "hold")  # guard actions under which the world's law renders contact
_I3 = ((1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0))


def _rotated(diag, R) -> tuple:
    """``R · diag(λ) · Rᵀ`` as a 3×3 tuple of tuples (R ``None``: the object frame is the robot's)."""
    if R is None:
        return tuple(tuple(float(diag[i]) if i == j else 0.0 for j in range(3)) for i in range(3))
    return tuple(
        tuple(sum(float(R[i][k]) * float(diag[k]) * float(R[j][k]) for k in range(3)) for j in range(3)) for i in range(3)
    )


class ObjectGainScheduler:
    """Λ with hysteresis, dwell and ramps, and the servo's force-scale ramp; one :meth:`step` per tick.

    Parameters (SI units): ``surface_on_m`` (depth that starts surface rendering), ``engage_m``
    (depth that applies the mode's lateral gains, the world's ``engage_m``), ``hysteresis_m``
    (how far back above ``engage_m`` the device must come to leave ``ENGAGED``), ``engage_s`` (how long
    the device must stay deeper than ``engage_m`` before ``ENGAGED``), ``release_m``
    (height above the surface that ends contact rendering), ``dwell_s`` (least time between two
    changes), ``ramp_s`` (the blend of each change, ≥ 20 ms), ``force_ramp_s`` (the force scale's
    rise), ``dt`` (the servo period, for the blend's last tick).
    """

    def __init__(self, *, surface_on_m: float = 0.0001, engage_m: float = 0.0003, hysteresis_m: float = 0.0003,
                 engage_s: float = 0.030, release_m: float = 0.001, dwell_s: float = 0.050, ramp_s: float = 0.025,
                 force_ramp_s: float = 0.100, dt: float = 0.001):
        vals = {"surface_on_m": surface_on_m, "engage_m": engage_m, "hysteresis_m": hysteresis_m, "engage_s": engage_s,
                "release_m": release_m, "dwell_s": dwell_s, "ramp_s": ramp_s, "force_ramp_s": force_ramp_s, "dt": dt}
        for name, v in vals.items():
            if isinstance(v, bool) or not isinstance(v, (int, float)) or not math.isfinite(v) or v < 0:
                raise ConfigError(f"expected a finite number ≥ 0, got {v!r}", field=f"object_gain.{name}")
        if ramp_s < MIN_RAMP_S:
            raise ConfigError(f"expected ≥ {MIN_RAMP_S} s (a Λ step is a force step), got {ramp_s!r}",
                              field="object_gain.ramp_s")
        if engage_m <= surface_on_m:
            raise ConfigError(f"expected engage_m > surface_on_m ({surface_on_m}), got {engage_m!r}",
                              field="object_gain.engage_m")
        if not dt > 0:
            raise ConfigError(f"expected a servo period > 0, got {dt!r}", field="object_gain.dt")
        self.surface_on_m, self.engage_m, self.hysteresis_m = float(surface_on_m), float(engage_m), float(hysteresis_m)
        self.release_m, self.dwell_s, self.ramp_s = float(release_m), float(dwell_s), float(ramp_s)
        self.engage_s = float(engage_s)
        self.force_ramp_s, self.dt = float(force_ramp_s), float(dt)
        self._contact_gain = (0.0, 0.0, 0.0)
        self._R = None
        self.reset()

    def reset(self) -> None:
        """Free motion, no change pending, force scale 0 until the guard tracks."""
        self.state = FREE
        self.n_changes = 0
        self._now = 0.0
        self._t_change = -math.inf
        self._L_from = self._L_to = self._L = _I3
        self._scale = 0.0
        self._scale_t0 = None  # when the force ramp started (None: idle)
        self._last_action = "idle"
        self._deep_t0 = None  # since when the device has been deeper than engage_m (None: it is not)
        self._switched = False  # the subject changed since the last step: its interaction is a new one
        self.law_active = False
        self.changing = False

    def set_subject(self, contact_gain=None, R_robot_obj=None) -> None:
        """The subject's ``ᴼΛ`` diagonal in contact (``law.lambda_contact``) and its rotation.

        ``None`` (no subject) falls back to free motion at the next :meth:`step`; so does a new subject
        whose surface the device is not at (the old one's interaction is over: no dwell)."""
        self._switched = True
        if contact_gain is None:
            self._contact_gain = None
            self._R = None
            return
        g = tuple(float(v) for v in contact_gain)
        if len(g) != 3 or not all(math.isfinite(v) for v in g):
            raise ConfigError(f"expected three finite gains, got {contact_gain!r}", field="object_gain.contact_gain")
        self._contact_gain = g
        self._R = None if R_robot_obj is None else tuple(tuple(float(v) for v in row) for row in R_robot_obj)
        if self.state != FREE:  # the targets of the current state change with the subject
            self._begin(self.state, self._now, force=True)

    # -- per tick ----------------------------------------------------------------------------------
    def step(self, t: float, depth_m: float, imminent: bool, in_contact: bool, action: str = "track",
             touch_in_s: float = math.inf):
        """``(Λ 3×3 robot frame as a tuple of tuples, force scale in [0, 1])`` for servo time ``t``.

        ``depth_m``: the device's depth under the subject's surface (m, positive inside; NaN or
        None when there is no subject); ``imminent`` / ``in_contact``: the world's flags;
        ``action``: the guard's (``"track"``, ``"hold"``, ``"retreat"``, ``"idle"``);
        ``touch_in_s``: the predicted time until the tracked finger reaches the device's face (s;
        infinite when unknown or not closing)."""
        self._now = t
        d = depth_m if depth_m is not None and math.isfinite(depth_m) else -math.inf
        announced = (imminent or in_contact) and action in _TRACKING and self._contact_gain is not None
        st = self.state
        since = t - self._t_change
        if d > self.engage_m:
            if self._deep_t0 is None:
                self._deep_t0 = t
        else:
            self._deep_t0 = None
        if not announced or d < -self.release_m:
            new = FREE
        elif st == FREE:
            new = SURFACE if d > self.surface_on_m or (touch_in_s <= self.ramp_s and d > -self.release_m) else FREE
        elif st == SURFACE:
            pushed = self._deep_t0 is not None and t - self._deep_t0 >= self.engage_s - 0.5 * self.dt
            new = ENGAGED if pushed else SURFACE
        else:
            new = SURFACE if d < self.engage_m - self.hysteresis_m else ENGAGED
        switched, self._switched = self._switched, False
        if new != st:
            # retreat, interaction over, or a new subject the device is not at: release at once
            urgent = new == FREE and (not announced or switched)
            if urgent or since >= self.dwell_s:
                self._begin(new, t)
        self.law_active = self.state != FREE and d > 0.0
        # the Λ blend
        if self.changing:
            s = (t - self._t_change) / self.ramp_s
            if s >= 1.0 - 0.5 * self.dt / self.ramp_s:
                self._L = self._L_to
                self.changing = False
            else:
                s = max(s, 0.0)
                a, b = self._L_from, self._L_to
                self._L = tuple(tuple(a[i][j] + s * (b[i][j] - a[i][j]) for j in range(3)) for i in range(3))
        # the force-scale ramp: restarts at 0 each time the guard (re)starts tracking
        if action == "idle":
            self._scale, self._scale_t0, self._last_action = 0.0, None, action
        else:
            # a resume while the law renders the surface (the finger on the device) keeps the force:
            # ramping it from 0 would drop the surface under the finger
            if self._scale_t0 is None or (action == "track" and self._last_action != "track" and st == FREE):
                self._scale_t0 = t
            self._last_action = action
            el = t - self._scale_t0
            self._scale = 1.0 if el >= self.force_ramp_s else max(0.0, el / self.force_ramp_s)
        return self._L, self._scale

    @property
    def lambda_robot(self):
        """The Λ (3×3 tuple of tuples, robot frame) returned by the last :meth:`step`."""
        return self._L

    @property
    def force_scale(self) -> float:
        return self._scale

    # -- internals ---------------------------------------------------------------------------------
    def _target(self, state: str):
        if state == FREE or self._contact_gain is None:
            return _I3
        return _rotated(SURFACE_GAIN if state == SURFACE else self._contact_gain, self._R)

    def _begin(self, state: str, t: float, *, force: bool = False) -> None:
        to = self._target(state)
        if state != self.state:
            self.n_changes += 1
        self.state = state
        self._t_change = t
        if to != self._L or force:
            self._L_from = self._L
            self._L_to = to
            self.changing = to != self._L
