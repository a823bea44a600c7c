"""The system's core cycle, written once: the scene step and the servo step (VisHap §2.2–2.3).

Every way of running the system drives these two steps — the batch demo (simulated clock,
in-process hand-over), live mode (real clock, shared-memory mailbox between the vision process
and the real-time servo process), replay (the log's inputs) and the world benchmark (a camera
model as the source):

``SceneStep``  (vision rate)  fingertip in camera frame → registration (``T_robot_cam``, Eq. 3) →
               the pad point → :meth:`World.update` → a :class:`TargetRecord`;
``ServoStep``  (1 kHz)        the record → :class:`TargetGuard` (track / hold / retreat) →
               :class:`ContactRenderer` (the subject's force law and the object gain ᴼΛ, Eq. 8–9) →
               :class:`~vishap.robot.servo.ServoLoop` (controller, device).

The record carries everything the servo needs (end-effector target, capture time, confidence,
calibration, subject, imminent and in-contact flags) and what the system knows of the finger (the
world's predicted pad point and velocity), so the servo process never needs the scene's world —
only its force laws, built from the same scene file. It packs into a flat float array
(:meth:`TargetRecord.pack`) for the mailbox.

Conventions: the world's ``X_d`` is the contact point on the object's surface; the device controls
its end-effector, which carries the passive object's top face at ``ee + mount_offset`` (from the
scene file), so the end-effector target is ``X_d - mount_offset``. Vision locates the centre of the
fingertip's cap; the world is given the pad point (cap centre minus the cap radius along the
subject's normal).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from vishap._core.errors import ConfigError
from vishap.robot.device import DeviceState
from vishap.robot.kinematics import tip_state_scalar
from vishap.robot.object_gain import ENGAGED, FREE, SURFACE
from vishap.runtime.safety import TargetGuard, record_values_valid
from vishap.world.predictor import near_predictor

__all__ = ["TargetRecord", "SceneStep", "ContactRenderer", "HOLD_BAND_M", "RestPlay", "ServoStep",
           "ServoTick", "GUARD_CODES", "LAMBDA_CODES", "RECORD_SIZE", "finger_approach"]

#: the guard's action as logged (``idle``: no finger seen yet, the servo holds the arm where it is)
GUARD_CODES = {"track": 0, "hold": 1, "retreat": 2, "idle": 3}
#: the object gain's state as logged (``servo/lambda_state``)
LAMBDA_CODES = {FREE: 0, SURFACE: 1, ENGAGED: 2}
_NAN3 = (math.nan, math.nan, math.nan)
#: depth at which a law's stiffness at its surface is read (m): inside every law's first spring
_HOLD_PROBE_M = 1e-5
#: the band over the surface in which the renderer's hold leaves the face to the arm's own friction (m)
HOLD_BAND_M = 5e-5


@dataclass
class TargetRecord:
    """One scene-step output for the servo. Positions robot frame (m), times servo clock (s).

    ``seq`` counts records (0: none yet); ``armed`` is false until the first finger estimate (or a
    calibration fault) arrives — until then the servo holds the arm where it is. ``subject`` is the
    index of the subject in the scene's objects (−1: none). ``finger``/``finger_velocity`` are the
    world's estimate of the pad point at ``finger_t`` (NaN when it has none). ``lost``: vision
    reports the finger gone (no fingertip and no skin where it searched, or a dropped track; the
    guard holds at once) — a fingertip hidden while the finger is still there is not a loss
    (docs/runtime.md: holding on every missed frame parks the device where it hides the finger). ``valid`` is not packed: :meth:`unpack`
    sets it false for values no scene step writes (an all-zero record among them).
    """

    seq: int = 0
    X_ee: tuple = _NAN3
    made_at: float = -math.inf
    confidence: float = 0.0
    calibrated: bool = True
    armed: bool = False
    subject: int = -1
    imminent: bool = False
    in_contact: bool = False
    finger: tuple = _NAN3
    finger_velocity: tuple = _NAN3
    finger_t: float = math.nan
    lost: bool = False
    finger_fast: tuple = _NAN3  # the caps near the finger's own estimate at finger_t (predictor.near_predictor)
    finger_fast_velocity: tuple = _NAN3
    valid: bool = True

    def pack(self) -> np.ndarray:
        return np.array([self.seq, *self.X_ee, self.made_at, self.confidence, float(self.calibrated),
                         float(self.armed), self.subject, float(self.imminent), float(self.in_contact),
                         *self.finger, *self.finger_velocity, self.finger_t, float(self.lost),
                         *self.finger_fast, *self.finger_fast_velocity], dtype=np.float64)

    @classmethod
    def unpack(cls, a, n_subjects: int | None = None) -> TargetRecord:
        """The record packed in ``a``; never raises on numbers: values no scene step writes (a counter
        that is not a positive integer, a flag not 0/1, a subject not in −1..n_subjects−1) give
        ``TargetRecord(valid=False)``."""
        v = [float(x) for x in a]
        if len(v) != RECORD_SIZE or not record_values_valid(v[0], [v[i] for i in _FLAGS], v[8], n_subjects):
            return cls(valid=False)
        return cls(int(v[0]), tuple(v[1:4]), v[4], v[5], v[6] > 0.5, v[7] > 0.5, int(v[8]), v[9] > 0.5,
                   v[10] > 0.5, tuple(v[11:14]), tuple(v[14:17]), v[17], v[18] > 0.5, tuple(v[19:22]), tuple(v[22:25]))

    def finger_at(self, t: float):
        """The tracked pad point extrapolated to ``t`` and its velocity (NaN when unknown)."""
        p, v = np.asarray(self.finger, float), np.asarray(self.finger_velocity, float)
        return p + v * (t - self.finger_t), v


RECORD_SIZE = TargetRecord().pack().size
_FLAGS = (6, 7, 9, 10, 18)  # calibrated, armed, imminent, in_contact, lost


class SceneStep:
    """Registration and world update on the newest fingertip estimate (vision rate)."""

    def __init__(self, world, T_robot_cam, *, tip_radius_m: float, mount_offset):
        self.world = world
        self.T = None if T_robot_cam is None else np.asarray(T_robot_cam, float)
        self.tip_radius_m = float(tip_radius_m)
        self.mount = np.asarray(mount_offset, float).reshape(3)
        self.names = [o.name for o in world.scene.objects]
        self.normal = np.asarray(world.scene.objects[0].normal, float)
        self.armed = False
        self.seq = 0
        self._flags = (-1, False, False)  # subject, imminent, in_contact of the newest interaction
        self.record = TargetRecord()
        self.near = near_predictor(world.predictor)

    def pad_point(self, p_cam) -> np.ndarray:
        """Fingertip cap centre (camera frame) → pad point (robot frame)."""
        T = self.T
        return np.asarray(p_cam, float) @ T[:3, :3].T + T[:3, 3] - self.tip_radius_m * self.normal

    def step(self, t_sample: float, found: bool, p_cam, confidence: float, p_device, *, calibrated: bool = True,
             lost: bool | None = None):
        """One estimate captured at ``t_sample`` → ``(record, interaction or None, pad point)``.

        ``p_device`` is the device's contact point (end-effector + mount offset). Without a
        calibration the record says so (the guard retreats); a lost finger still updates the world
        (its predictor coasts) once the first finger was seen.
        """
        calibrated = calibrated and self.T is not None
        p_pad = np.full(3, np.nan)
        inter = None
        if calibrated:
            if found and np.all(np.isfinite(p_cam)):
                p_pad = self.pad_point(p_cam)
                inter = self.world.update(t_sample, p_pad, p_device)
                self.near.observe(t_sample, p_pad)
            elif not found and self.armed:
                inter = self.world.update(t_sample, None, p_device)
                self.near.observe(t_sample, None)
        if not self.armed and (not calibrated or found):
            self.armed = True
        X = _NAN3
        finger, v_f, t_f, near = _NAN3, _NAN3, math.nan, (_NAN3, _NAN3)
        if inter is not None:
            X = tuple(float(x) for x in np.asarray(inter.X_d, float) - self.mount)
            s = -1 if inter.object_name is None else self.names.index(inter.object_name)
            self._flags = (s, bool(inter.imminent), bool(inter.in_contact))
            if inter.finger is not None:
                finger, v_f = tuple(map(float, inter.finger)), tuple(map(float, inter.finger_velocity))
                t_f = float(inter.finger_t)
                near = tuple(tuple(map(float, x)) for x in self.near.state_at(t_f)) if self.near.ready else (_NAN3, _NAN3)
        self.seq += 1
        s, imminent, in_contact = self._flags
        self.record = TargetRecord(self.seq, X, float(t_sample), float(confidence), calibrated, self.armed,
                                   s, imminent, in_contact, finger, v_f, t_f, lost=self._lost(found, confidence, lost),
                                   finger_fast=near[0], finger_fast_velocity=near[1])
        return self.record, inter, p_pad

    @staticmethod
    def _lost(found: bool, confidence: float, lost: bool | None) -> bool:
        """Vision's report that the finger is gone (``lost``, from the pipeline); sources that give
        none (a camera model, an old log) count a finger lost once the tracker's confidence is 0."""
        if found:
            return False
        return bool(lost) if lost is not None else not confidence > 0.0


class ContactRenderer:
    """The subject's force law and the object gain ᴼΛ at the device's contact point (Eq. 8–9).

    Λ and the servo's force scale come from :class:`~vishap.robot.object_gain.ObjectGainScheduler`
    (free → surface → engaged with hysteresis, a dwell and ≥ 20 ms blends; the force ramps up when
    tracking starts). The law acts while the scheduler renders the surface (an interaction is
    announced, the guard tracks or holds, the device has gone under the surface) and the device is
    under it. A law is reset when its object stops being the subject and when contact rendering ends.
    The laws are built from the objects' modes (:func:`~vishap.world.force_laws.make_law`, checked
    against what the device renders stably) unless ``laws`` gives them, one per object with its
    ``lambda_contact`` (the stability sweep's, which probes stiffnesses past that limit).

    While Λ releases the normal axis (surface or engaged) and the device is *above* the surface,
    nothing else would hold it there: the law only pushes out, the position servo no longer acts
    along the normal, and the light arm floats off (the law's own push launched it 1–6 mm above
    the surface in the demos, flipping Λ back to free and back, and a landing finger met a loose
    device that bounced off its pad). The renderer then holds the device at the surface from above
    (:attr:`F_hold`, pulling only, fading out over the last half of ``release_m``) with the law's own
    stiffness and damping at the surface, on the height beyond a band of :data:`HOLD_BAND_M`, plus
    the arm's Coulomb friction at the tip (``hold_friction_n``, from the device's parameters): above
    the band the pull overcomes the friction and brings the face into the band; inside it the hold
    gives only the damping of a face moving away (continuous with the law's at the surface and over
    the band's edge), and the arm's friction keeps the face where it is. A spring alone could bring
    the face only within ``hold_friction_n / k`` of the surface (50–114 µm on the demos' laws) and
    kept pulling there, so a landing finger's light push (0.03 N) unstuck the arm and the face fell
    away under the pad (contact made twice). The band is narrow because the demos' fingers come to
    rest at the surface: a face waiting higher is pushed down that far by the landing pad and, light,
    ran ahead of it (contact made twice on faces waiting 0.1 mm up). The friction's share grows over
    ``hold_ramp_m`` beyond the band (one encoder count at the tip, from the device's parameters), so
    the pull is continuous in the height the encoders read: switched on whole at the band's edge, a
    reading one count over it (a face 53 µm up under a pad landing at 1 mm/s) unstuck the arm, which
    slid 60 µm down and away from the pad (contact made twice).
    """

    def __init__(self, objects, *, max_force_n: float, engage_m: float = 0.0003, dt: float = 0.001,
                 hold_friction_n: float = 0.0, hold_ramp_m: float = 0.0, laws=None):
        from vishap.robot.object_gain import ObjectGainScheduler
        from vishap.world.force_laws import make_law

        for name, value, low in (("max_force_n", max_force_n, "> 0"), ("hold_friction_n", hold_friction_n, "≥ 0"),
                                 ("hold_ramp_m", hold_ramp_m, "≥ 0")):
            # a NaN here would reach the device as a NaN force in every held tick (the scheduler checks its own)
            try:
                v = float(value)
            except (TypeError, ValueError):
                v = math.nan
            if not (math.isfinite(v) and (v > 0.0 if low == "> 0" else v >= 0.0)):
                raise ConfigError(f"expected a finite number {low}, got {value!r}", field=name)
        self.objects = list(objects)
        if laws is None:
            self.laws = [make_law(o, max_force_n=max_force_n) for o in self.objects]
        elif len(laws) != len(self.objects):
            raise ConfigError(f"expected one law per object ({len(self.objects)}), got {len(laws)}", field="laws")
        else:  # built by the caller (the stability sweep's laws, stiffer than a scene may hold)
            self.laws = list(laws)
        self.gain = ObjectGainScheduler(engage_m=engage_m, dt=dt)
        self.subject = -1
        self.depth = math.nan  # the device's depth under the subject's surface at the last update (m)
        #: each law's stiffness and damping at its surface: the hold above it
        self._hold = [(law.normal_force(_HOLD_PROBE_M) / _HOLD_PROBE_M, float(getattr(law, "c", 0.0)))
                      for law in self.laws]
        self.hold_friction_n = float(hold_friction_n)
        self.hold_ramp_m = float(hold_ramp_m)
        self.F_hold = None  # the hold's force (robot frame, N) at the last update, or None

    def reset(self) -> None:
        for law in self.laws:
            law.reset()
        self.gain.reset()
        self.gain.set_subject(None)
        self.subject = -1
        self.depth = math.nan
        self.F_hold = None

    @property
    def law(self):
        return None if self.subject < 0 else self.laws[self.subject]

    @property
    def state_code(self) -> int:
        """The object gain's state as logged: 0 free, 1 surface, 2 engaged."""
        return LAMBDA_CODES[self.gain.state]

    def update(self, t: float, p_device, v_device, subject: int, imminent: bool, in_contact: bool, action: str,
               touch_in_s: float = math.inf):
        """``(F_law or None, Λ robot frame 3×3, force scale)`` for servo time ``t``; ``touch_in_s``: the
        predicted time until the tracked finger reaches the device's face (the scheduler's early handover)."""
        gain = self.gain
        if subject != self.subject:
            if self.subject >= 0:
                self.laws[self.subject].reset()
            self.subject = subject
            if subject >= 0:
                gain.set_subject(self.laws[subject].lambda_contact, self.objects[subject].R)
            else:
                gain.set_subject(None)
        law = self.law
        depth = math.nan if law is None else law.depth(p_device)
        self.depth = depth
        was_free = gain.state == FREE
        L, scale = gain.step(t, depth, imminent, in_contact, action, touch_in_s)
        F = law.force_robot(p_device, v_device) if gain.law_active else None
        if law is not None and not was_free and gain.state == FREE:
            law.reset()
        self.F_hold = None
        rel = gain.release_m
        if F is None and gain.state != FREE and -rel < depth <= 0.0:
            k, c = self._hold[self.subject]
            n = law.normal
            vn = float(n[0] * v_device[0] + n[1] * v_device[1] + n[2] * v_device[2])
            w = min(1.0, 2.0 * (rel + depth) / rel)  # 1 down to −release_m/2, then fading to 0 at −release_m
            excess = -depth - HOLD_BAND_M  # the height beyond the band
            if excess > 0.0:
                ramp = self.hold_ramp_m
                fr = self.hold_friction_n * (min(1.0, excess / ramp) if ramp > 0.0 else 1.0)
                f = min(0.0, -(k * excess + fr + c * vn) * w)  # pulls toward the surface only
            else:  # in the band: only the damping of a face moving away, continuous with the law's at the surface
                f = min(0.0, -c * vn * w)
            if f < 0.0:
                self.F_hold = (float(n[0]) * f, float(n[1]) * f, float(n[2]) * f)
        return F, L, scale


class RestPlay:
    """A sideways play (backlash) on the servo's target while a finger rests on the face.

    :meth:`apply` passes the target through unchanged unless it is told the finger rests on the face
    (the object gain renders the surface, the tracked pad is within ``near_m`` over the device's face and
    moves along it slower than ``rest_m_s`` — a finger landing while it moves sideways is followed, the
    world's run-up with it; once started, the play lasts while the surface is rendered and the finger
    stays near, so that a speed estimate hovering at ``rest_m_s`` does not switch it on and off, each
    switch-off a jump of the target); then the target's part along the surface moves only as far as it must to stay within
    ``play_m`` of the input (no jump when the play starts, smaller moves absorbed), its part along
    the normal passes. Why: under a resting finger the world's target follows each sample's
    projection of the finger (0.1–0.3 mm of jitter), and with Λ's normal released the lateral servo
    dragged the face sideways through the arm's friction, down and away from under the pad (contact
    made twice)."""

    def __init__(self, play_m: float = 0.0005, near_m: float = 0.002, rest_m_s: float = 0.020):
        self.play_m, self.near_m, self.rest_m_s = float(play_m), float(near_m), float(rest_m_s)
        self._a = None  # the target last given out while the play acts (None: it does not)

    def reset(self) -> None:
        self._a = None

    def apply(self, X, normal, gap_m: float, surface: bool, finger_velocity=(0.0, 0.0, 0.0)):
        """``X`` (3, or None) with the play applied; ``gap_m`` the tracked pad's height over the face
        (NaN: no finger), ``surface`` whether the object gain renders the surface, ``normal`` its normal,
        ``finger_velocity`` the tracked pad's (m/s)."""
        if X is None or normal is None or not (surface and gap_m < self.near_m):
            self._a = None
            return X
        a, n = self._a, normal
        if a is None:  # the play starts once the finger rests; it then lasts while the finger stays near
            u = finger_velocity
            un = u[0] * n[0] + u[1] * n[1] + u[2] * n[2]
            ux, uy, uz = u[0] - un * n[0], u[1] - un * n[1], u[2] - un * n[2]
            if ux * ux + uy * uy + uz * uz < self.rest_m_s * self.rest_m_s:
                self._a = X
            return X
        d = (X[0] - a[0], X[1] - a[1], X[2] - a[2])
        dn = d[0] * n[0] + d[1] * n[1] + d[2] * n[2]
        tx, ty, tz = d[0] - dn * n[0], d[1] - dn * n[1], d[2] - dn * n[2]  # the move along the surface
        m = math.sqrt(tx * tx + ty * ty + tz * tz)
        s = 1.0 - self.play_m / m if m > self.play_m else 0.0
        out = np.array((a[0] + s * tx + dn * n[0], a[1] + s * ty + dn * n[1], a[2] + s * tz + dn * n[2]))
        self._a = out
        return out


def finger_approach(rec: TargetRecord, t: float, p_device, normal):
    """``(distance m, time to touch s, height m)`` of the record's tracked finger (extrapolated to ``t``)
    from the device's contact point: the travel limiter's speed caps and the object gain's early
    handover. The height is the pad's over the device's face along ``normal`` (NaN without one).

    The time to touch is the pad's height over the device's face along the subject's ``normal``
    over its closing speed (0 once at or under the face; infinite when not closing, without a
    subject or without a finger estimate; NaN distance then too)."""
    ft = rec.finger_t
    if ft != ft:
        return math.nan, math.inf, math.nan
    el = t - ft
    f, v = rec.finger, rec.finger_velocity
    dx, dy, dz = f[0] + v[0] * el - p_device[0], f[1] + v[1] * el - p_device[1], f[2] + v[2] * el - p_device[2]
    dist = math.sqrt(dx * dx + dy * dy + dz * dz)
    if normal is None:
        return dist, math.inf, math.nan
    n = normal
    h = dx * n[0] + dy * n[1] + dz * n[2]
    closing = -(v[0] * n[0] + v[1] * n[1] + v[2] * n[2])
    return dist, 0.0 if h <= 0.0 else h / closing if closing > 0.0 else math.inf, h


@dataclass
class ServoTick:
    """What one servo step did (for the log and the tactile layer)."""

    action: str
    X_ee: np.ndarray | None
    F_law: np.ndarray | None
    state: object            # the DeviceState read at the start of the tick
    p_device: np.ndarray     # contact point: end-effector + mount offset
    fault: object = None
    lambda_state: int = 0    # LAMBDA_CODES
    force_scale: float = 1.0
    finger_m: float = math.nan  # the device's distance to the tracked finger (m; NaN: unknown)
    pressed: bool = False    # the device felt the finger pushing it in (the guard's input)
    touch_in_s: float = math.inf  # the predicted time until the tracked finger lands on the device's face


class ServoStep:
    """Guard → force law and Λ → controller → device: the one place the system renders contact.

    Before the guard decides, the step tells it whether the device feels the finger: the law was
    rendering on the previous tick and the device is pushed in deeper than ``press_m`` under the
    subject's surface (a real device knows this from its own encoders; no camera is involved).
    The travel limiter is given the device's distance to the tracked finger (the record's pad point
    extrapolated to now), so the device slows down near the finger. Under a finger resting on the face
    the target's sideways jitter is taken up by a play (:class:`RestPlay`).
    """

    def __init__(self, servo, guard: TargetGuard, objects, *, mount_offset, engage_m: float = 0.0003,
                 press_m: float = 0.0005, play: RestPlay | None = None, laws=None):
        self.servo = servo
        self.device = servo.device
        self.controller = servo.controller
        self.guard = guard
        self.mount = np.asarray(mount_offset, float).reshape(3)
        self.press_m = float(press_m)
        params = self.device.params
        self.contact = ContactRenderer(objects, max_force_n=float(self.device.limits.peak_force_n), engage_m=engage_m,
                                       dt=float(params.dt), hold_friction_n=float(params.coulomb_friction_n),
                                       hold_ramp_m=float(params.tip_resolution_m), laws=laws)
        self.play = RestPlay() if play is None else play
        self.last_action = "idle"
        self._key = None
        self._retreat_key = None
        self._rendering = False
        self._normals = [tuple(float(x) for x in o.normal) for o in self.contact.objects]
        self._read_scalar = self.device.read_scalar
        self._l1, self._l2 = self.device.params.l1, self.device.params.l2
        self._tip = tip_state_scalar
        self._time = lambda: float(self.device.time)
        self._last = (None, None, None)  # the newest read(): its state, joint readings and tip state

    def reset(self) -> None:
        """Start a new run on the same device: guard, laws, object gain and target keys forgotten."""
        self.guard.reset()
        self.contact.reset()
        self.play.reset()
        self.last_action = "idle"
        self._key = self._retreat_key = None
        self._rendering = False

    def read(self):
        """The device state and its contact point (the caller may act on the plant before :meth:`tick`).

        From the device's scalar fast path and the arm's kinematics (as :class:`ServoLoop` reads it),
        not :meth:`Device.read`, which costs about as much as the rest of the tick.
        """
        joints = q1, q2, q3, w1, w2, w3 = self._read_scalar()
        tip = px, py, pz, vx, vy, vz = self._tip(q1, q2, q3, w1, w2, w3, self._l1, self._l2)
        p = np.array((px, py, pz))
        dev = DeviceState(self._time(), np.array((q1, q2, q3)), np.array((w1, w2, w3)), p, np.array((vx, vy, vz)))
        # the tick acts on this one reading: a driver's state may change between two reads
        self._last = (dev, joints, tip)
        return dev, p + self.mount

    def tick(self, t: float, rec: TargetRecord, dev=None) -> ServoTick:
        if dev is None:
            dev, p_dev = self.read()
        else:
            p_dev = np.asarray(dev.p_robot, float) + self.mount
        last, joints, tip = self._last
        if dev is not last:  # a state the caller made itself: read from it, not from the device
            joints, tip = None, (*dev.p_robot, *dev.v_robot)
        fault = None
        law = self.contact.law
        pressed = self._rendering and law is not None and law.depth(p_dev) > self.press_m
        if rec.armed or not rec.valid:
            gx, gy, gz, action, fault = self.guard.decide_scalar(t, *rec.X_ee, rec.made_at, rec.confidence,
                                                                 rec.calibrated, pressed, rec.lost, rec.valid)
            X_ee = np.array((gx, gy, gz))
        else:
            action, X_ee = "idle", None
        normal = None if rec.subject < 0 else self._normals[rec.subject]
        finger_m, touch_in, gap = finger_approach(rec, t, p_dev, normal)
        F_law, L, scale = self.contact.update(t, p_dev, dev.v_robot, rec.subject, rec.imminent, rec.in_contact, action,
                                              touch_in)
        self._rendering = F_law is not None
        X_ee = self.play.apply(X_ee, normal, gap, self.contact.gain.state != FREE, rec.finger_velocity)
        ctrl = self.controller
        ctrl.set_lambda_robot(L)
        if self.servo.travel is not None:  # travel resumes from the arm where Λ let go
            self.servo.travel.anchor(*tip, L)
        ctrl.force_scale = scale
        # the shaper takes a new sample when its key changes: a new record's capture time while
        # tracking, the moment a retreat began while retreating, the previous key while holding
        if action == "track":
            key = rec.made_at
        elif action == "retreat":
            if self.last_action != "retreat":
                self._retreat_key = t
            key = self._retreat_key
        else:
            key = self._key
        self._key, self.last_action = key, action
        extra = F_law if F_law is not None else self.contact.F_hold
        finger = None
        if finger_m == finger_m:  # the tracked pad point and velocity now, in the end-effector's coordinates
            (fx, fy, fz), v, m, el = rec.finger, rec.finger_velocity, self.mount, t - rec.finger_t
            finger = (fx + v[0] * el - m[0], fy + v[1] * el - m[1], fz + v[2] * el - m[2], *v)
            (gx, gy, gz), w = rec.finger_fast, rec.finger_fast_velocity
            if gx == gx:  # and the caps' own, faster estimate: the nearer of the two wins
                finger = (finger, (gx + w[0] * el - m[0], gy + w[1] * el - m[1], gz + w[2] * el - m[2], *w))
        self.servo.tick(t, None if key is None else X_ee, extra, t_sample=key, finger_m=finger_m, gap_m=gap,
                        normal=normal, finger=finger, joints=joints)
        return ServoTick(action, X_ee, F_law, dev, p_dev, fault, self.contact.state_code, scale, finger_m, pressed,
                         touch_in)
