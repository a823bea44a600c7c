"""The world update (VisHap §2.2 "Interaction with Objects", §2.3 control target X_d).

At vision rate, :meth:`World.update` takes the fingertip in the robot frame and

1. predicts its present position and velocity (latency-compensated, :mod:`~vishap.world.predictor`);
2. computes its distance to every object and picks the nearest as the interaction subject, with
   hysteresis (a rival must be ``hysteresis_m`` nearer) and never while the finger is in contact;
3. raises the "imminent interaction" notice below ``imminent_m``;
4. produces the device target ``X_d``: the projection of the fingertip onto the subject's surface,
   held *ahead* of the finger at the point where its predicted motion meets the surface
   (``handover``: ``hold`` freezes that point once the finger is within ``hold_m``; ``blend``
   slides it towards the finger's present projection; ``track`` uses the present projection).
   A button's target is its top centre (VisHap §2.3). In contact, a ``follow`` mode tracks the
   finger's projection (sliding). Near the finger the device waits still on the landing point and
   moves only as much as the landing needs, then runs up sideways with the finger (:class:`World`);
5. routes the device around objects: if the straight path of the device's passive face (its real
   size, ``passive_object.size_m``) to ``X_d`` would cut through any object's solid, ``X_d`` becomes a
   way-point above the obstacles.

The subject's force law is rendered at servo rate by the servo step
(:class:`vishap.runtime.core.ContactRenderer`), from the subject and flags the world announces.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from vishap._core.check import as_array
from vishap._core.errors import ConfigError
from vishap.world.predictor import (MeetingPoint, PathExtrapolator, ReachFit, contact_point, make_predictor,
                                    measurement_std_m)
from vishap.world.scene import Scene, SceneObject

__all__ = ["Interaction", "World", "HANDOVERS"]

HANDOVERS = ("hold", "blend", "track")
CONTACT_MODELS = ("ray", "path", "both", "reach", "all")
_UP = np.array([0.0, 0.0, 1.0])
#: the slowest closing speed the time left to a touch is computed with (m/s; the ray's own floor)
_MIN_CLOSING_M_S = 0.02
#: how far above an object's base the passive face may overlap its footprint: a face lying on the surface
#: the object stands on (the panel plane beside the shelf) touches the base, it does not pass through it
BASE_CONTACT_M = 0.001


@dataclass
class Interaction:
    """What the world tells the device and the tactile layer after one finger sample.

    ``depth`` is the fingertip's depth under the subject's surface (m; negative above it);
    ``normal`` the subject's outward unit normal (robot frame); ``X_d`` the device target (robot
    frame, m); ``via`` is True when ``X_d`` is a detour way-point rather than the contact target.
    ``finger``/``finger_velocity`` are the predicted fingertip (robot frame) at ``finger_t`` — what
    the system knows of the finger between two samples (None before the predictor is ready).
    """

    t: float
    object_name: str | None
    mode: str | None
    X_d: np.ndarray
    depth: float
    imminent: bool
    in_contact: bool
    normal: np.ndarray
    distances: dict[str, float] = field(default_factory=dict)
    predicted_contact: np.ndarray | None = None
    time_to_contact_s: float | None = None
    via: bool = False
    finger: np.ndarray | None = None
    finger_velocity: np.ndarray | None = None
    finger_t: float | None = None


class World:
    """The scene, the finger predictor, the current subject and its force law.

    Parameters (keyword-only): ``predictor`` (``kalman``, ``cv``, ``none`` or an object with
    ``observe``/``state_at``), ``handover`` (``hold``, ``blend``, ``track``), ``latency_s`` (age of a
    finger sample when it arrives: the prediction is made for ``t + latency_s``), ``imminent_m``,
    ``hysteresis_m``, ``hold_m``, ``horizon_s`` (furthest look-ahead), ``heading_horizon_s``
    (furthest look-ahead of the object the finger heads for), ``contact_margin_m``,
    ``path_margin_m`` and ``clearance_m`` for routing, ``contact_model``
    (``ray``: the predicted straight-line motion meets the surface; ``path``: the recent path is
    extrapolated in height; ``both``: the two fused by their variances; ``reach``: a minimum-jerk
    reach fitted to the samples, :class:`~vishap.world.predictor.ReachFit`; ``all``: ray, path and
    reach fused by their variances), ``engage_m`` (depth beyond which the mode's lateral contact gain applies).

    The approach near the finger (issue 16's "ready at the touch"): within ``lock_m`` of the surface
    the waiting point ignores moves under ``deadband_m``;
    ``freeze_s`` before the touch (the later of the reach fit's time and the straight line's at the closing
    speed; never by the height of one noisy sample) it is frozen on the newest sample's landing point
    (whole, not dead-banded against the plan) and stays latched while the finger is near — one sample seeing the touch,
    not yet felt by the device, does not release it either; it moves only when the landing would leave
    half the finger's room on the passive face (``inside_m`` inside its edge). Over the last ``runup_s``
    the target runs up sideways at the finger's fitted velocity so that the finger lands on a face
    moving with it, timed for when the servo reaches the sample (``latency_s`` + one sample interval +
    ``servo_lag_s``, the servo's own lag behind its target). Before the finger lands within ``horizon_s``
    the meeting point restarts from its projection, so that the first landing point within the horizon
    is weighed against it.

    The landing glide (``glide_m_s`` > 0, :meth:`_glide_to`): from the finger near (``lock_m``) until
    the device feels the finger, the target is not sent to each sample's landing point at once: it
    moves with the run-up (along the finger's fitted path when the fit is sure) and corrects towards
    the plan over the time left until ``settle_s`` before the touch, then at most ``glide_m_s`` faster
    than a finger seen sliding along the correction and never ahead of it (``glide_with_finger``; False:
    ``glide_m_s`` absolute). ``glide_m_s`` 0: the plan alone.
    """

    def __init__(
        self,
        scene: Scene,
        *,
        predictor="kalman",
        handover: str = "hold",
        latency_s: float = 0.0,
        imminent_m: float = 0.03,
        hysteresis_m: float = 0.005,
        hold_m: float = 0.004,
        horizon_s: float = 0.4,
        heading_horizon_s: float = 1.5,
        contact_margin_m: float = 0.0,
        path_margin_m: float = 0.003,
        clearance_m: float = 0.01,
        contact_model: str = "all",
        engage_m: float = 0.0003,
        lock_m: float = 0.010,
        freeze_s: float = 0.09,
        servo_lag_s: float = 0.03,
        inside_m: float = 0.010,
        runup_s: float = 0.06,
        deadband_m: float = 0.001,
        settle_s: float = 0.04,
        glide_m_s: float = 0.005,
        glide_with_finger: bool = True,
    ):
        if contact_model not in CONTACT_MODELS:
            raise ConfigError(f"contact_model must be one of {CONTACT_MODELS}, got {contact_model!r}", field="contact_model")
        self.contact_model = contact_model
        self.engage_m = float(engage_m)
        if handover not in HANDOVERS:
            raise ConfigError(f"handover must be one of {HANDOVERS}, got {handover!r}", field="handover")
        self.scene = scene
        self.predictor = make_predictor(predictor) if isinstance(predictor, str) else predictor
        # one figure for the fingertip's noise: the path and reach fits weigh the samples by the σ the
        # predictor assumes (the stereo model's in the demos, 3–4 mm), not by a smaller one of their own
        sigma = measurement_std_m(self.predictor)
        self.path = PathExtrapolator() if sigma is None else PathExtrapolator(meas_std_m=sigma)
        self.reach = ReachFit() if sigma is None else ReachFit(meas_std_m=sigma)
        self.handover = handover
        self.latency_s = float(latency_s)
        self.imminent_m, self.hysteresis_m, self.hold_m = float(imminent_m), float(hysteresis_m), float(hold_m)
        self.horizon_s, self.contact_margin_m = float(horizon_s), float(contact_margin_m)
        self.heading_horizon_s = float(heading_horizon_s)
        self.moving_m_s = 0.05  # finger speed above which a subject chosen by heading is kept
        self.path_margin_m, self.clearance_m = float(path_margin_m), float(clearance_m)
        self.meeting = MeetingPoint()
        self.lock_m, self.runup_s = float(lock_m), float(runup_s)
        self.freeze_s, self.servo_lag_s = float(freeze_s), float(servo_lag_s)
        # the room the finger has on the passive face: how far from its centre it may land and still be
        # ``inside_m`` inside its edge. Once frozen, the waiting point moves only when the landing would
        # leave half of it (the other half is for the prediction's remaining error); the run-up never
        # takes more than that half either. Before, near the finger, moves under ``deadband_m`` are noise.
        self.replan_m = max(0.5 * (scene.passive_object.half_size_m - float(inside_m)), 0.0)
        # routing moves the whole face, not its centre: every solid is grown sideways by its half width
        self.face_m = scene.passive_object.half_size_m
        self.deadband_m = float(deadband_m)
        if not (np.isfinite(settle_s) and settle_s >= 0.0):
            raise ConfigError(f"settle_s must be a finite number >= 0, got {settle_s!r}", field="settle_s")
        if not (np.isfinite(glide_m_s) and glide_m_s >= 0.0):
            raise ConfigError(f"glide_m_s must be a finite number >= 0 (0: no glide), got {glide_m_s!r}", field="glide_m_s")
        self.settle_s, self.glide_m_s = float(settle_s), float(glide_m_s)
        self.glide_with_finger = bool(glide_with_finger)
        tops = [o.centre + o.R[:, :2] @ (o.half * np.array(s)) for o in scene.objects for s in
                ((1, 1), (1, -1), (-1, 1), (-1, -1))]
        self.z_safe = float(max(p[2] for p in tops)) + self.clearance_m
        self.reset()

    def reset(self) -> None:
        self.subject: SceneObject | None = None
        self.held: np.ndarray | None = None
        self.plan: np.ndarray | None = None  # the landing point the device waits on near the finger
        self._run = None  # the run-up's (touch time, tangential velocity)
        self._glide = None  # the landing glide's last (servo time, target, subject) (:meth:`_glide_to`)
        self.X_d: np.ndarray | None = None
        self._via = False  # the last X_d was a routing way-point
        self.subject_prev: SceneObject | None = None  # the subject of the last X_d
        self._lift_xy: np.ndarray | None = None  # where the lift off an object's top started (:meth:`_route`)
        self._t_last: float | None = None
        self._interval = 0.0  # spacing of the finger samples (s)
        self.p_meas: np.ndarray | None = None  # the latest measured fingertip
        self._seen = 0  # how many successive measured samples were at the subject's surface
        self.meeting.reset()
        self.path.reset()
        self.reach.reset()
        self._by_heading = False
        if hasattr(self.predictor, "reset"):
            self.predictor.reset()

    # -- vision rate -------------------------------------------------------------------------------
    def update(self, t: float, p_robot_finger, p_robot_device=None) -> Interaction:
        """Fuse one fingertip sample (robot frame, m; ``None`` when vision lost it) taken at ``t``."""
        if p_robot_finger is not None:
            p_robot_finger = as_array(p_robot_finger, (3,), "p_robot_finger")
        if self._t_last is not None and 0.0 < t - self._t_last < 0.2:
            self._interval = t - self._t_last
        self._t_last = t
        self.predictor.observe(t, p_robot_finger)
        self.path.observe(t, p_robot_finger)
        if self.contact_model in ("reach", "all") or self.runup_s > 0.0:
            self.reach.observe(t, p_robot_finger)
        if p_robot_finger is not None:
            self.p_meas = p_robot_finger
        if not self.predictor.ready:
            X = self.X_d if self.X_d is not None else self.scene.objects[0].centre.copy()
            return Interaction(t, None, None, X.copy(), float("-inf"), False, False, _UP.copy())
        p, v = self.predictor.state_at(t + self.latency_s)
        distances = {o.name: o.signed_distance(p) for o in self.scene.objects}
        subj = self._choose(distances, self._heading_to(p, v), float(np.linalg.norm(v)) > self.moving_m_s)
        h = subj.height(p)
        if p_robot_finger is not None:  # successive measured samples at the surface (a touch seen)
            self._seen = self._seen + 1 if subj.height(p_robot_finger) <= self.contact_margin_m else 0
        depth = -h
        in_contact = depth >= -self.contact_margin_m and subj.inside_extent(p, self.contact_margin_m)
        imminent = distances[subj.name] < self.imminent_m
        c, tau = contact_point(p, v, subj.normal, subj.offset, horizon_s=self.horizon_s)
        c = subj.project(c)
        fit = self.path.contact(subj.centre, subj.R) if self.contact_model in ("path", "both", "all") and tau is not None else None
        use_ray = self.contact_model != "path" or fit is None
        # near the finger: under the lock height (or time), and above the surface or, when the extrapolated
        # finger is already under it, over the object itself (a finger passing beside it is not landing)
        near = h < self.lock_m and (
            h > -self.contact_margin_m or subj.inside_extent(p, self.path_margin_m))
        runup = self.runup_s > 0.0 and self.replan_m > 0.0
        reach = None
        glide = self.glide_m_s > 0.0
        if (self.contact_model in ("reach", "all") or (runup and (near or (glide and tau is not None)))) and self.p_meas is not None \
                and subj.height(self.p_meas) > 0.0:
            reach = self.reach.contact(subj.centre, subj.R)
        if reach is not None and self.contact_model == "reach":
            c = subj.project(reach[0])
        elif tau is None and not near:
            # not landing within the horizon: no meeting point yet. It restarts from the finger's projection,
            # a guess that the finger lands under itself within a third of its height (the median
            # sideways-to-height ratio of the approaches bench world draws: 0.34), so that the first
            # prediction within the horizon is weighed against it instead of being taken whole (the wall
            # demo's straight-down approaches: one noisy sideways velocity put the landing point 4–7 mm off)
            self.meeting.reset()
            if hasattr(self.predictor, "cov_at"):
                var_p = np.trace(self.predictor.cov_at(t + self.latency_s)[:3, :3]) / 3
                self.meeting.update(subj.project(p), 0.0, var_p + (max(h, 0.0) / 3.0) ** 2, 0.0)
        # (a finger slowing to a stop near the surface lands under itself: its projections keep being
        # fused, so one noisy sample does not become the landing point)
        else:
            if use_ray and hasattr(self.predictor, "cov_at"):  # fuse successive predictions by their uncertainty
                P = self.predictor.cov_at(t + self.latency_s)
                c = self.meeting.update(c, tau or 0.0, np.trace(P[:3, :3]) / 3, np.trace(P[3:, 3:]) / 3)
            if fit is not None:  # the path's own extrapolation, fused by its variance
                c = self.meeting.update(fit[0], 0.0, fit[1], 0.0)
            if reach is not None and self.contact_model == "all":
                c = self.meeting.update(reach[0], 0.0, reach[1], 0.0)
            c = subj.project(c)
        confirmed = in_contact and self._touch_confirmed(subj, p, p_robot_device)
        # frozen by the time left to the touch, not by height (a 3–4 mm noisy sample can put the extrapolated
        # finger within hold_m while it is 8 mm and 300 ms away): the later of the fitted reach's touch and
        # the straight line's at the present closing speed (at least ``_MIN_CLOSING_M_S``). Both come early
        # on a decelerating finger — the line by its speed, the fit by its end-depth prior, which for a
        # finger slowing to a stop at the surface puts the crossing a third of the reach too early
        closing = max(-float(subj.normal @ v), _MIN_CLOSING_M_S)
        t_left = t_line = max(h, 0.0) / closing
        if reach is not None and self.reach.t_touch is not None:
            t_left = max(t_left, self.reach.t_touch - t - self.latency_s)
        # once frozen, the landing point stays latched while the finger stays near (the finger is committed
        # to its landing): a later, longer time left (a reach fit re-timed by a noisy sample, a finger
        # slowing down) does not release it back to the latest prediction within the last 100 ms
        frozen = near and (t_left < self.freeze_s or self.held is not None)
        X = self._target(subj, p, c, h, confirmed, near, frozen)
        X_plan = X
        ran = not confirmed and runup and near
        if ran:
            X = X + self._runup(t, subj, reach)
        if not confirmed:
            X = self._face_clear(X, subj)
        # from the finger near (``lock_m``; started at the first predicted landing within the horizon, the
        # spread cost bench world's wall 6 mm of landing error at 0.2–0.3 m/s and its force–depth R²)
        if glide and not self._felt(subj, p_robot_device) and (near or confirmed):
            # (the shorter of the two times left: a poor reach fit re-timed the demos' touch 0.6 s late)
            X = self._glide_to(t, subj, X, min(t_left, t_line), ran, reach, X_plan)
        else:
            self._glide = None
        via = False
        start = p_robot_device if p_robot_device is not None else self.X_d
        if start is not None:
            routed = self._route(np.asarray(start, dtype=float), X, subj)
            via = routed is not X
            X = routed
        self.X_d, self._via, self.subject_prev = X, via, subj
        return Interaction(t, subj.name, subj.mode_name, X.copy(), depth, imminent, in_contact,
                           subj.normal.copy(), distances, c, tau, via, np.array(p, float), np.array(v, float),
                           t + self.latency_s)

    def _heading_to(self, p, v) -> SceneObject | None:
        """The object whose surface patch the finger's straight-line motion meets first (or None)."""
        best, best_tau = None, self.heading_horizon_s
        for o in self.scene.objects:
            c, tau = contact_point(p, v, o.normal, o.offset, horizon_s=self.heading_horizon_s)
            if tau is not None and tau < best_tau and o.inside_extent(c, self.path_margin_m):
                best, best_tau = o, tau
        return best

    def _choose(self, distances: dict[str, float], heading: SceneObject | None = None, moving: bool = False) -> SceneObject:
        """Nearest object with hysteresis; an object the finger heads for wins early and is kept while
        the finger keeps moving (``moving``) even when a neighbour it passes is nearer."""
        best = min(self.scene.objects, key=lambda o: distances[o.name])
        cur = self.subject
        if cur is None:
            return self._set_subject(best)
        if distances[cur.name] <= self.contact_margin_m:
            return cur  # never switch while touching the current subject
        if heading is not None and heading is not cur:
            self._set_subject(heading)
            self._by_heading = True
            return heading
        if heading is cur or best is cur:
            return cur
        if self._by_heading and moving:
            return cur  # a finger on its way to the object it headed for: a passing neighbour does not take over
        if distances[best.name] < distances[cur.name] - self.hysteresis_m:
            self._by_heading = False
            return self._set_subject(best)
        return cur

    def _set_subject(self, obj: SceneObject) -> SceneObject:
        if obj is not self.subject:
            self.subject, self.held, self.plan = obj, None, None
            self.meeting.reset()
        return obj

    def _runup(self, t: float, subj: SceneObject, reach) -> np.ndarray:
        """The device's tangential run-up before the touch: it moves sideways at the finger's own
        tangential velocity at the touch (the fitted reach, :class:`ReachFit`) over the last
        ``runup_s`` before it, ending on the landing point, so that the finger lands on a face that
        moves with it instead of sliding onto a still one. The run-up (touch time and velocity) is
        frozen with the meeting point. The offset is for the time the servo reaches this sample: its
        age (``latency_s``) plus one sample interval (the servo interpolates towards the newest sample
        over one interval). Zero without a fit; never longer than the re-plan room (none on a face with
        no room to land off its centre). A key runs up too, ending on its centre: a finger coming in
        obliquely lands on a keycap that moves with it (issue 16's readiness) and stays ≥ 10 mm inside
        its edge."""
        if self._run is None or self.held is None:
            tt = self.reach.t_touch
            if reach is None or tt is None:
                return np.zeros(3)
            # a fitted reach that ended before the newest sample, with the finger still seen above the
            # surface, is not this reach (a finger at rest, then a fast move: one minimum-jerk reach
            # fitted over both); its velocity is no run-up (the wall demo's straight-down approach got
            # 25 mm/s sideways from it, a 1.5 mm jump of the waiting face 70 ms before the touch)
            self._run = (tt, np.zeros(3) if tt < t else self.reach.tangential_velocity_at(tt))
        return self._runup_at(self._servo_time(t))

    def _servo_time(self, t: float) -> float:
        """When the servo reaches a target made from the sample of time ``t``: ``latency_s`` + one
        sample interval + ``servo_lag_s`` later."""
        return t + self.latency_s + self._interval + self.servo_lag_s

    def _within_room(self, du: np.ndarray) -> np.ndarray:
        """A run-up offset ``du`` shortened to the re-plan room (``replan_m``) where it is longer."""
        n = float(np.linalg.norm(du))
        return du * (self.replan_m / n) if n > self.replan_m else du

    def _runup_at(self, t_use: float) -> np.ndarray:
        """The run-up's offset from the landing point at servo time ``t_use`` (zero without one)."""
        if self._run is None:
            return np.zeros(3)
        tt, v = self._run
        return self._within_room(v * float(np.clip(t_use - tt, -self.runup_s, self.runup_s)))

    def _glide_to(self, t: float, subj: SceneObject, X: np.ndarray, t_left: float, ran: bool, reach,
                  X_plan: np.ndarray) -> np.ndarray:
        """The landing glide: the target moves from the last one towards the plan ``X`` no faster than
        the landing needs. Each sample is for the time the servo reaches it, ``tau`` (``latency_s`` + one
        sample interval + ``servo_lag_s``). The move along the surface is the run-up's own motion from
        the last sample's ``tau`` to this one (:meth:`_runup_path`: the finger's fitted path, carried),
        plus a correction towards the plan spread evenly over the time left until ``settle_s`` before
        the touch (the line's time left at the closing speed, the shorter of the two estimates) and,
        once that is less than one sample interval, at most ``glide_m_s`` — the device is then still
        relative to the finger's motion when it lands. Ends once the device feels the finger.

        Why: a device taking each new landing point within one sample interval was still swinging back
        from a wild one at the touch (the demos' real vision put the landing point 10–35 mm off for a
        few frames at the start of a fast descent: ``still_tangential``), and under a finger landing at
        3 mm/s it moved each 0.5–1.5 mm re-plan at 25–50 mm/s, which shook the light arm's face by
        40–90 µm along the normal (contact made and broke twice)."""
        tau = self._servo_time(t)
        g = self._glide
        if g is None or g[2] is not subj:
            if self.X_d is None or self._via or self.subject_prev is not subj:
                self._glide = (tau, X.copy(), subj)
                return X
            g = (tau - self._interval, self.X_d, subj)  # from the last target, towards this one
        tau0, X0, _ = g
        off = self._runup_path(subj, reach)
        if off is not None:  # the run-up along the finger's fitted path
            o = off(tau)
            X = self._face_clear(X_plan + o, subj)
            base = X0 + (o - off(tau0))
        else:
            base = X0 + (self._runup_at(tau) - self._runup_at(tau0) if ran else 0.0)
        base = base - subj.normal * float(subj.normal @ (base - X))  # on X's level along the normal
        d = X - base
        n = float(np.linalg.norm(d))
        step = max(tau - tau0, 0.0)
        left = t_left + self.latency_s - (tau - t) - self.settle_s  # from the servo reaching this sample
        lim = self.glide_m_s * step
        if left > step:
            lim = max(lim, n * step / left)
        elif self.glide_with_finger and reach is not None and n > 0.0 and step > 0.0:
            # the time left is up but the finger still slides in along the correction (a decelerating
            # finger lands later than the line says): the creep may keep its pace — the fitted reach's,
            # which models the deceleration (the straight line's velocity lags it by the latency) — so
            # that the device moves no faster than glide_m_s relative to it (less what the run-up moves)
            # — only for a finger seen to slide that way: its measured samples moved more than half the
            # re-plan room along the correction over the last 0.3 s (a straight-down finger's fitted
            # sideways velocity is noise: the wall demo's fast second touches then failed still_tangential)
            # — and never ahead of the finger itself where the servo gets there (the fitted reach at
            # tau): a plan overshooting the landing on noisy samples is not chased past the finger (the
            # fabric demo's seed 1: 1.3 mm past the landing, then back at glide_m_s against the run-up)
            vf = self.reach.tangential_velocity_at(tau)
            if vf is not None and self._slid_along(d / n, 0.3) > 0.5 * self.replan_m:
                pace = float(vf @ d) / n - float((base - X0) @ d) / n / step
                ahead = float((subj.centre + self.reach.tangential_at(tau) - base) @ d) / n
                lim += min(max(pace, 0.0) * step, max(ahead, 0.0))
        out = base + d * (lim / n) if n > lim else X.copy()
        self._glide = (tau, out.copy(), subj)
        return out

    def _slid_along(self, u: np.ndarray, span_s: float) -> float:
        """How far the finger's measured samples moved along the unit vector ``u`` over the last
        ``span_s`` (the reach fit's consistent samples; 0 with fewer than two)."""
        got = [(t, p) for t, p in self.reach.consistent() if t >= self.reach.samples[-1][0] - span_s] \
            if self.reach.samples else []
        return float((got[-1][1] - got[0][1]) @ u) if len(got) >= 2 else 0.0

    def _runup_path(self, subj: SceneObject, reach):
        """The run-up as a function of servo time from the fitted reach (:class:`ReachFit`), or None:
        the offset from the landing point along the finger's fitted tangential path, ``u(max(τ, T −
        runup_s)) − u(T)`` with ``T`` the fitted touch — still before the last ``runup_s``, then moving
        with the finger's fitted (decelerating) motion, on the landing point at the touch, and never
        further from it than the re-plan room. Refitted at every sample (the straight run-up keeps the
        first fit's velocity: 13 mm/s for a finger that landed at 38 mm/s in bench world's wall
        approach 2). None without a fit, with a fitted reach that ended before now (not this reach), or
        with a fit whose touch point is less sure than half the re-plan room (σ; the demos' real vision
        gave 10–12 mm fits of a straight-down finger 14 mm sideways)."""
        fit, tt = self.reach, self.reach.t_touch
        if (reach is None or tt is None or self._t_last is None or tt < self._t_last
                or reach[1] > (0.5 * self.replan_m) ** 2):
            return None
        end = fit.tangential_at(tt)

        def off(tau):
            return self._within_room(fit.tangential_at(max(tau, tt - self.runup_s)) - end)
        return off

    def _felt(self, subj: SceneObject, p_robot_device) -> bool:
        """The device pushed under the subject's surface by more than ``engage_m``: the touch felt."""
        return p_robot_device is not None and subj.height(np.asarray(p_robot_device, dtype=float)) < -self.engage_m

    def _touch_confirmed(self, subj: SceneObject, p, p_robot_device) -> bool:
        """The touch seen, not only predicted: the device is pushed under the surface by more than
        ``engage_m`` (the touch felt), or the latest *measured* fingertip is at the surface. Until then
        the meeting point is held — the straight-line prediction of the present overshoots a
        decelerating finger. One sample seen at the surface does not release a latched landing point that
        the finger (predicted at ``p``) lands on within the re-plan room: a noisy sample reads the finger
        at the surface up to 150 ms before the touch, and following its projection from then on moved
        the waiting face sideways under the landing finger. A second one in a row does (a finger resting
        on the surface lightly, without pushing the device, is then centred as before)."""
        if self._felt(subj, p_robot_device):
            return True
        if self._seen == 0:
            return False
        return self.held is None or self._seen >= 2 or _tangential(subj.project(p) - self.held, subj.normal) > self.replan_m

    def _target(self, subj: SceneObject, p, c, h: float, in_contact: bool, near: bool = False,
                frozen: bool | None = None) -> np.ndarray:
        if subj.mode.target == "centre":
            return subj.centre.copy()
        proj = subj.project(p)
        if in_contact:
            self.held = self.plan = None
            return proj
        if self.handover == "track":
            return proj
        if self.handover == "blend":
            w = np.clip((h - self.hold_m) / max(self.imminent_m - self.hold_m, 1e-9), 0.0, 1.0)
            return w * c + (1.0 - w) * proj
        if frozen is None:
            frozen = self.hold_m > h > -self.contact_margin_m
        if frozen:  # hold the meeting point, do not chase noise (nor the extrapolated finger under the surface)
            if self.held is None:  # the freeze takes the newest sample's landing point whole: the dead-banded plan
                # was made up to 100 ms earlier, from samples 1–3 mm short of a slowing finger's landing
                self.held = self.plan = np.array(c, dtype=float)
            elif self.replan_m > 0.0 and _tangential(c - self.held, subj.normal) > self.replan_m:
                self.held, self._run = c, None  # re-planned only to keep the finger on the face
            return self.held.copy()
        self.held = None
        self._run = None
        if near:  # near the finger: move only when the landing needs it
            return self._plan_to(c, subj).copy()
        self.plan = None
        return c

    def _plan_to(self, c: np.ndarray, subj: SceneObject) -> np.ndarray:
        """The waiting point near the finger: ``c`` once it lies more than ``deadband_m`` sideways from
        the last one (smaller moves are noise), else the last one."""
        if self.plan is None or _tangential(c - self.plan, subj.normal) > self.deadband_m:
            self.plan = c
        return self.plan

    def _route(self, start: np.ndarray, X: np.ndarray, subj: SceneObject) -> np.ndarray:
        """``X`` if the straight path from ``start`` is clear; else a way-point. Leaving the top of an
        object (its face over it) for a target off it, the device first lifts by ``path_margin_m`` (a
        fast sideways move dips) straight up from the target it was last sent to, if that is over the
        object, else from the device (latched for the whole lift: a lift point under the device's own
        xy fed the device's sideways lag back into its target), then moves at that level until the
        way down to ``X`` is clear (the whole face off a raised object's edge, not up into the
        finger's way); failing that, a way-point above all obstacles."""
        m = self.path_margin_m
        on = [o for o in self.scene.objects if o.inside_extent(start, self.face_m) and abs(o.height(start)) < m]
        leaving = [o for o in on if not o.inside_extent(X)]
        if not leaving and self._clear(start, X):
            return X
        level = max([start[2]] + [o.project(start)[2] + m for o in on])
        if leaving and start[2] < level - 0.5 * m:
            # the lift's xy is latched where it starts, on the last target (where the device was
            # heading): one under the device's own xy fed its sideways lag back, and a jerk-limited
            # output swung ±1 mm at 60–90 mm/s around it
            if self._lift_xy is None:
                prev = self.X_d
                over = prev is not None and any(o.inside_extent(prev, self.face_m) for o in on)
                self._lift_xy = (prev if over else start)[:2].copy()
            return np.array([self._lift_xy[0], self._lift_xy[1], level])
        self._lift_xy = None
        for u in (0.25, 0.5, 0.75, 1.0):
            via = start + (X - start) * u
            via[2] = level
            if via[2] > X[2] and self._clear(start, via) and self._clear(via, X):
                return via
        if self._clear(start, X):
            return X
        above = X.copy()
        above[2] = max(self.z_safe, X[2])
        if self._clear(start, above):
            return above
        up = start.copy()
        up[2] = max(self.z_safe, start[2])
        return up

    def _face_clear(self, X: np.ndarray, subj: SceneObject) -> np.ndarray:
        """``X`` moved along the subject's surface until the face waiting there is clear of every other
        object standing beside and above it (a landing point next to the shelf's side would put the
        face into the shelf: no path reaches it). The finger then lands off the face's centre; the move
        is never more than the face's half width (the finger still lands on it)."""
        m = self.path_margin_m + self.face_m
        for o in self.scene.objects:
            if o is subj:
                continue
            q = o.local(X)
            if not -o.depth_m - BASE_CONTACT_M < q[2] < 0.0:
                continue
            out = o.half + m - np.abs(q[:2])  # how far the face reaches into the solid along each axis
            if np.any(out <= 0.0):
                continue
            k = int(np.argmin(out))
            d = o.R[:, k] * (out[k] if q[k] >= 0.0 else -out[k])
            d -= subj.normal * float(subj.normal @ d)
            if np.linalg.norm(d) <= self.face_m:
                X = X + d
        return X

    def _clear(self, a, b) -> bool:
        """No object's solid on the path of the passive face from a to b (each solid grown sideways by
        the face's half width and ``path_margin_m``: the square face swept along a→b meets the solid
        exactly when a→b meets the grown one); an object that already holds ``a`` may be left."""
        m = self.path_margin_m + self.face_m
        return not any(
            o.segment_hits(a, b, margin=m, top_clearance=-0.0005, bottom_clearance=BASE_CONTACT_M)
            for o in self.scene.objects
            if not o.segment_hits(a, a, margin=0.0, top_clearance=-0.0005)
        )


def _tangential(d, normal) -> float:
    """Length of ``d``'s part along the surface of unit ``normal``."""
    return float(np.linalg.norm(d - normal * float(normal @ d)))
