"""The vision pipeline of VisHap §2.1: stereo pair → skin masks → fingertips → tracked tips → ``p_cam``.

Per frame and per camera: if the camera's tracker holds the finger, segment and search only a
window around the Kalman prediction; otherwise segment and search the full frame (re-detection).
The fingertip radius is ``r = K / z`` with ``K = f · tip_circle_m`` (focal length from the rig) and
``z`` the tracked depth (``z_default`` before the first 3-D fix). The two tips are triangulated on
the rectified images (epipolar and disparity checks, covariance).

The background model is learned from the first ``learn_frames`` frames automatically, or
explicitly with :meth:`VisionPipeline.learn_background`.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, replace

import numpy as np

from vishap._core.errors import ShapeError, VisionError
from vishap.vision.axis_disparity import AxisLevel
from vishap.vision.fingertip import FingertipConfig, detect_fingertips
from vishap.vision.rig import StereoRig
from vishap.vision.segment import SegmentConfig, Segmenter, snap_roi
from vishap.vision.skin_model import SkinModel
from vishap.vision.stereo import (RefineConfig, StereoConfig, StereoPoint, refine_tip_pair, triangulate_rectified_tip,
                                  triangulate_tip, with_covariance)
from vishap.vision.track import KalmanCV, TipTracker, TrackerConfig
from vishap.world.finger import TIP_RADIUS_M
from vishap.vision.view import search_tips

__all__ = ["PipelineConfig", "TipEstimate", "VisionPipeline"]


@dataclass(frozen=True)
class PipelineConfig:
    segment: SegmentConfig = field(default_factory=lambda: SegmentConfig(coarse=4))  # full frames through
    #   the coarse skin pass: the same masks on the standard sequences, several times less time per full frame
    fingertip: FingertipConfig = field(default_factory=FingertipConfig)
    tracker: TrackerConfig = field(default_factory=TrackerConfig)
    stereo: StereoConfig = field(default_factory=StereoConfig)
    refine: RefineConfig = field(default_factory=lambda: RefineConfig(method="axis"))  # the chosen pair's
    #   disparity also from the finger's side edges, levelled on the cap fits: 3-D RMS 1.95–2.48 → 1.43–2.01 mm
    #   on the standard sequences (docs/vision.md)
    tip_circle_m: float = 0.0048    # radius of the test circle at the fingertip (0.6 of an 8 mm cap): K = f · tip_circle_m
    z_default_m: float = 0.6        # depth used for r = K/z before the first 3-D fix
    z_search_m: tuple[float, ...] = (0.45, 0.8)  # other depths tried when a full-frame search fails
    finger_radius_m: float = TIP_RADIUS_M  # radius of the fingertip's cap (picks the index tip among candidates)
    max_candidates: int = 4         # fingertip candidates per view in a full-frame search
    acquire_radius_band: tuple[float, float] = (0.75, 1.06)  # cap radius / finger_radius_m accepted when
    #   (re)acquiring over the full frame; measured on renders: index tip 5–95 % 0.75–1.04, thumb/knuckles median 1.07
    learn_frames: int = 10
    recheck_frames: int = 15        # while tracking, search the full frame every this many frames (0: never);
    #   measured on the standard 'vishap synth' trajectories: fixes a lock on the wrong finger taken
    #   at the hand's entry (button approach 32.7 → 0.23 px), but on renders where the index goes
    #   behind the device's plate it can jump to the thumb
    recheck_young_frames: int = 3   # … every this many frames while the 3-D track is younger than recheck_frames
    #   frames: a lock on the wrong finger is taken when a track starts (the index hidden, a knuckle found)
    filtered_output: bool = True    # report Kalman-filtered tips (else the raw detections)
    disparity_q: float = 3e3        # … and the 3-D fix's disparity filtered by its own constant-velocity filter
    #   (px²/s³; 0: off). On the standard sequences 1e3 filters best (of 1e1…1e5), but its lag fails the
    #   wall demo's closed loop (law not active in every pressed tick); 3e3 keeps it (docs/vision.md)
    disparity_gate_px: float = 3.0  # a measured disparity this far from the filter's prediction restarts it
    full_search_on_miss: bool = True  # a miss in the window triggers a full-frame search of that view
    max_speed_m_s: float = 2.0      # gate of that search: how far the finger may have moved since its last hit
    recheck_jump_px: float = 12.0   # a recheck result this far from the track restarts the track there
    recheck_on_reject: bool = True  # no consistent pair with a view in tracked mode: search that view's full
    #   frame at once (its window may hold a wrong finger; see docs/vision.md)
    occluded_pairs: bool = True     # check pairs that may be cut by the device in one view as such (_occluded_pair)
    occluded_cap_ratio: float = 0.85  # a cap below this fraction of the other view's is taken as partly hidden
    occluded_min_cap_ratio: float = 0.6  # … and below this, too little of it shows to give a disparity
    occluded_track_held: bool = True  # … the 3-D track's age limit does not apply there while the
    #   reference view's 2-D track has held since the last 3-D fix (the finger hidden in one view only)
    reach_margin_m: float = 0.02    # 3-D gate: distance the finger may be from the last fix beyond max_speed_m_s·dt
    acquire_needs_cap_fit: bool = False  # a candidate must have a fitted cap circle to acquire over the full frame
    #   (the paper's test alone passes a straight skin edge: the back of the hand); off by default: see
    #   docs/vision.md. A recheck always needs one: it would replace a holding track
    track_max_age_s: float = 0.5    # a 3-D fix older than this no longer gates (the finger may be anywhere)
    confirm_within_s: float = 0.1   # a fix that starts a new 3-D track must be confirmed this soon
    confirm_new_tracks: bool = False  # hold back a fix that starts a new 3-D track until the next frame agrees
    #   (measured: 1 → 0 false detections on the wall demo frames; off by default: see docs/vision.md)
    tracking: bool = True           # False: always search the full frame


@dataclass
class TipEstimate:
    t: float
    found: bool
    p_cam: np.ndarray | None = None
    cov_cam: np.ndarray | None = None
    uv_left: np.ndarray | None = None
    uv_right: np.ndarray | None = None
    confidence: float = 0.0
    timings: dict = field(default_factory=dict)
    mode: str = "full"              # "learning", "full", "tracked" or "recheck" (left camera)
    reason: str = ""
    lost: bool = False              # no fingertip, and the finger is gone: no skin where both views searched
    #   for it, or a view's tracker dropped its track (a fingertip merely hidden, by the device or the
    #   object, leaves the rest of the finger in the window: not lost, the track coasts)


class VisionPipeline:
    """Fingertip in 3-D from stereo pairs; see the module docstring."""

    def __init__(self, rig: StereoRig, *, skin_model: SkinModel | None = None, config: PipelineConfig | None = None):
        self.rig = rig
        self.config = config or PipelineConfig()
        self.skin = skin_model if skin_model is not None else SkinModel.load()
        self.segmenters = {s: Segmenter(self.skin, self.config.segment) for s in ("left", "right")}
        self.trackers = {s: TipTracker(self.config.tracker) for s in ("left", "right")}
        self.K = float(rig.K_left[0, 0]) * self.config.tip_circle_m
        self._learn_buf: list = []
        self._z: float | None = None
        self._p3: np.ndarray | None = None  # last 3-D fix and its time (the 3-D track)
        self._t3 = 0.0
        self._pending = None                # (p, t) of a fix that would start a new 3-D track
        self._since_full = 0
        self._window_tips: set = set()      # ids of this frame's candidates measured in the tracking window
        self._fix_run = 0                   # consecutive frames with a 3-D fix (the 3-D track's age)
        self._size = rig.image_size
        self.background_warning = ""        # set when the learned background holds a hand (_hand_in_background)
        self._disp_kf: KalmanCV | None = None  # the 3-D fix's disparity filter (_filter_disparity)
        self._disp_t: float | None = None
        rc = self.config.refine
        # the side-edge axis's offset from the cap fits (_refine_pair; None: the fixed axis_weight mean)
        self.axis_level = (AxisLevel(rc.axis_level_s, rc.axis_sigma_px, rc.cap_sigma_px, rc.axis_prior_px)
                           if rc.method == "axis" and rc.axis_level_s > 0 else None)
        self._t_frame = 0.0                 # the frame being processed (the level's clock)
        self._refine_ms = 0.0
        self.refine_stats = [0, 0]          # chosen pairs whose refinement failed / succeeded

    # ------------------------------------------------------------------ background
    @property
    def learned(self) -> bool:
        return self.segmenters["left"].learned

    def learn_background(self, frames) -> None:
        """Learn both background models from an iterable of StereoFrames (or (left, right) pairs)."""
        lefts, rights = [], []
        for f in frames:
            l, r = (f.left, f.right) if hasattr(f, "left") else f
            self._check(l, r)
            lefts.append(l)
            rights.append(r)
        if not lefts:
            raise VisionError("learn_background: no frames given")
        self.segmenters["left"].learn(lefts)
        self.segmenters["right"].learn(rights)
        self.background_warning = self._hand_in_background()

    def _hand_in_background(self) -> str:
        """A warning when the learned background (left view) holds a hand: a skin region with a
        fingertip cap at its extreme point. The model is kept as learned (the caller
        decides: move the hand out of view and learn again); the warning is reported with every
        frame that finds no fingertip, since that is what such a background causes."""
        from vishap.vision.segment import binary_median
        from vishap.vision.view import hand_region, hand_tip

        seg = self.segmenters["left"]
        mask = binary_median(self.skin.mask(seg.mean_image), seg.config.median)
        region = hand_region(mask)
        if region is None:
            return ""
        end = hand_tip(region)
        radii = [self.K / z for z in (self.config.z_default_m, *self.config.z_search_m)]
        tips = [tp for tp in search_tips(region.label_mask, radii, self.config.fingertip, prior_uv=end, max_tips=1)
                if tp.cap_radius_px > 0 and np.hypot(*(tp.uv - end)) <= 2 * tp.cap_radius_px + 2]
        if not tips:
            return ""
        u, v = tips[0].uv
        return (f"the background was learned from frames with a hand in view (fingertip near ({u:.0f}, {v:.0f}) "
                f"in the left view): move the hand out of view and learn the background again")

    def reset_tracking(self) -> None:
        self.trackers = {s: TipTracker(self.config.tracker) for s in ("left", "right")}
        self._z = None
        self._p3 = self._pending = None
        self._disp_kf = None
        if self.axis_level is not None:
            self.axis_level.reset()

    def _check(self, left, right) -> None:
        for name, img in (("left", left), ("right", right)):
            if not isinstance(img, np.ndarray) or img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
                raise ShapeError(f"{name} image: expected uint8 BGR (H, W, 3), got "
                                 f"{getattr(img, 'dtype', type(img).__name__)} {getattr(img, 'shape', '')}")
            if (img.shape[1], img.shape[0]) != tuple(self._size):
                raise ShapeError(f"{name} image: expected {self._size[0]}×{self._size[1]} (the rig's size), "
                                 f"got {img.shape[1]}×{img.shape[0]}")

    # ------------------------------------------------------------------ per frame
    def process(self, frame) -> TipEstimate:
        """One StereoFrame (``t``, ``left``, ``right``) to a :class:`TipEstimate`."""
        t0 = time.perf_counter()
        t = float(frame.t)
        self._t_frame = t
        self._check(frame.left, frame.right)
        if not self.learned:
            self._learn_buf.append((frame.left, frame.right))
            if len(self._learn_buf) >= self.config.learn_frames:
                self.learn_background(self._learn_buf)
                self._learn_buf = []
            return TipEstimate(t, False, mode="learning", reason="learning the background",
                               timings={"total_ms": (time.perf_counter() - t0) * 1e3})
        timings: dict[str, float] = {}
        cands, modes = {}, {}
        self._window_tips = set()
        self._refine_ms = 0.0
        self._skin_px = {}                  # each view's searched mask (its skin is counted only when needed)
        self._masks = {}                    # per view: the skin mask the candidates came from, its origin
        for side, img in (("left", frame.left), ("right", frame.right)):
            cands[side], modes[side] = self._detect(side, img, t, timings)
        t1 = time.perf_counter()
        found, sp = self._choose_pair(cands, modes, t, (frame.left, frame.right))
        stuck = [s for s in ("left", "right") if modes[s] == "tracked"]
        if not sp.ok and self.config.recheck_on_reject and stuck and cands["left"] and cands["right"]:
            # candidates in both views but no consistent pair: a tracked window may hold a wrong
            # finger while the other view sees the tip; search the tracked view(s) over the full frame
            for side in stuck:
                cands[side], modes[side] = self._detect(side, getattr(frame, side), t, timings, recheck=True)
            found, sp = self._choose_pair(cands, modes, t, (frame.left, frame.right))
        for side in ("left", "right"):
            trk = self.trackers[side]
            if found[side] is not None and modes[side] == "recheck" and trk.tracking \
                    and np.hypot(*(found[side] - trk.kf.position)) > self.config.recheck_jump_px:
                trk.restart(t, found[side])  # the full-frame search found a better-ranked tip: move there
            else:
                trk.update(t, found[side])
        self._since_full = 0 if "tracked" not in modes.values() else self._since_full + 1
        timings["stereo_ms"] = (time.perf_counter() - t1) * 1e3
        timings["refine_ms"] = self._refine_ms
        timings["total_ms"] = (time.perf_counter() - t0) * 1e3
        conf = min(self.trackers["left"].confidence, self.trackers["right"].confidence)
        if sp.ok and self.config.filtered_output and all(self.trackers[s].kf.misses == 0 for s in ("left", "right")):
            # report the Kalman posteriors of both views (less pixel noise), triangulated the same way
            found = {s: self.trackers[s].kf.position.copy() for s in ("left", "right")}
            spf = triangulate_rectified_tip(self.rig, *(self.rig.rectify_point(*found[s].tolist(), s)
                                                       for s in ("left", "right")), self.config.stereo)
            if spf.ok and self.config.disparity_q > 0:
                spf = self._filter_disparity(spf, sp.disparity_px, t)
            sp = spf if spf.ok else sp
        elif not sp.ok:
            self._disp_kf = None
        if sp.ok and not self._confirmed(sp.p_cam, t):
            sp = StereoPoint(False, reason="new fingertip position, not yet confirmed by a second frame")
        self._fix_run = self._fix_run + 1 if sp.ok else 0
        if sp.ok:
            sp = with_covariance(self.rig, sp, self.config.stereo)  # (the pair checks leave it out)
            self._z = float(sp.p_cam[2])
            self._p3, self._t3 = np.asarray(sp.p_cam, dtype=np.float64), t
            return TipEstimate(t, True, sp.p_cam, sp.cov_cam, found["left"], found["right"], conf, timings, modes["left"])
        reason = sp.reason + (f"; {self.background_warning}" if self.background_warning else "")
        return TipEstimate(t, False, None, None, found["left"], found["right"], conf, timings, modes["left"], reason,
                           lost=self._finger_gone())

    def _finger_gone(self) -> bool:
        """Whether a frame without a fingertip means the finger is gone: a view's tracker dropped its
        track, or neither view's search region holds half a fingertip cap's area of skin."""
        if not all(self.trackers[s].tracking for s in ("left", "right")):
            return True
        r = self.K / (self._z if self._z is not None else self.config.z_default_m)
        cap_px = np.pi * r * r
        # the masks' skin is counted here only: most frames find a fingertip and never ask
        return all((int(np.count_nonzero(self._skin_px[s])) if s in self._skin_px else 0) < 0.5 * cap_px
                   for s in ("left", "right"))

    def _filter_disparity(self, spf: StereoPoint, disparity_px: float, t: float) -> StereoPoint:
        """The filtered pair ``spf`` with its disparity replaced by a constant-velocity Kalman
        estimate of the measured pair's disparity (``disparity_q``). The disparity noise of the two
        cap fits is white from frame to frame (lag-1 correlation 0.05–0.12 on the standard
        sequences) and the depth changes slowly, so it is filtered harder than the image positions.
        Restarts after a frame without a fix or a jump beyond ``disparity_gate_px``."""
        cfg = self.config
        kf = self._disp_kf
        if kf is not None and self._disp_t is not None and self._fix_run > 0:
            kf.predict(t - self._disp_t)
            if abs(disparity_px - kf.x[0]) > cfg.disparity_gate_px:
                kf = None
            else:
                kf.update(np.array([disparity_px]))
        else:
            kf = None
        if kf is None:
            kf = KalmanCV(1, q=cfg.disparity_q, r=2 * cfg.stereo.sigma_px ** 2)
            kf.reset([disparity_px])
        self._disp_kf, self._disp_t = kf, t
        d = float(kf.x[0])
        if not d * spf.disparity_px > 0:
            return spf
        # rectified with zero disparity at infinity (Q[3, 3] = 0): the point scales with 1/disparity
        # along its ray, so the pair's point is moved, not triangulated again
        scale = spf.disparity_px / d
        return StereoPoint(spf.ok, spf.p_cam * scale, spf.cov_cam * scale ** 2, d, spf.epipolar_px, spf.reason)

    def _refine_pair(self, images, tl, tr, sp):
        """The chosen pair's cap centres refined (stereo.refine_tip_pair, on the images or the views'
        skin masks); the masks' centres are kept when the refinement fails or its pair fails the stereo checks."""
        ts = time.perf_counter()
        ref = refine_tip_pair(self.rig, images[0], images[1], tl, tr, self.config.refine, masks=self._masks,
                              level=self.axis_level)
        if ref.ok and self.axis_level is not None and ref.axis_offset_px is not None:
            self.axis_level.add(self._t_frame, ref.axis_offset_px)
        out = {"left": tl.uv, "right": tr.uv}, sp
        if ref.ok:
            spr = (triangulate_tip(self.rig, ref.uv_left, ref.uv_right, self.config.stereo) if ref.rect_left is None
                   else triangulate_rectified_tip(self.rig, ref.rect_left, ref.rect_right, self.config.stereo,
                                                  covariance=False))
            if spr.ok:
                out = {"left": ref.uv_left, "right": ref.uv_right}, spr
        self._refine_ms += (time.perf_counter() - ts) * 1e3
        self.refine_stats[ref.ok] += 1
        return out

    def _choose_pair(self, cands: dict, modes: dict, t: float, images=None):
        """Pick the left/right tips: the best-ranked stereo-consistent pair.

        A view in tracked mode offers its one candidate (nearest the prediction); a view searched
        over the full frame offers several, ranked by the detector (score, then extremity: index
        tip before thumb and curled knuckles). A pair must pass :meth:`_match`; the pair with the
        lowest rank sum wins (ties: the larger extremity). Without a pair, a view whose track holds
        keeps its candidate nearest the track (the other view may be hidden), and the reason is the
        rejection of the best-ranked pair.
        """
        L, R = cands["left"], cands["right"]
        best, best_cost = None, np.inf
        rejected = []  # (rank sum, reason)
        rect = {s: [self.rig.rectify_point(*tp.uv.tolist(), s) for tp in cands[s]]
                for s in ("left", "right")}  # each candidate rectified once
        if L and R and len(L) * len(R) > 1:
            # pairs off each other's epipolar line by more than the widest check of _match (the
            # occluded-pair one: max_epipolar_px plus the larger cap radius) fail it there with
            # this reason: say so without the checks
            rows = {s: np.array([v for _, v in rect[s]]) for s in ("left", "right")}
            epi = np.abs(rows["left"][:, None] - rows["right"][None, :])
            slack = (np.maximum.outer([tp.cap_radius_px for tp in L], [tp.cap_radius_px for tp in R])
                     if self.config.occluded_pairs else 0.0)
            far = epi > self.config.stereo.max_epipolar_px + slack
        else:
            far = None
        for il, tl0 in enumerate(L):
            for ir, tr0 in enumerate(R):
                if far is not None and far[il, ir]:
                    rejected.append((il + ir, f"epipolar error {epi[il, ir]:.2f} px (candidates {il + 1} of {len(L)} "
                                              f"left, {ir + 1} of {len(R)} right)"))
                    continue
                tl, tr, sp, why = self._match(tl0, tr0, modes, t, rect["left"][il], rect["right"][ir])
                if why:
                    which = f" (candidates {il + 1} of {len(L)} left, {ir + 1} of {len(R)} right)" if len(L) * len(R) > 1 else ""
                    rejected.append((il + ir, why + which))
                    continue
                cost = il + ir - (tl.extremity_px + tr.extremity_px) / (1.0 + tl.extremity_px + tr.extremity_px) \
                    + 0.01 * sp.epipolar_px
                if cost < best_cost:
                    best, best_cost = (tl, tr, sp, tl is tl0 and tr is tr0), cost
        if best is not None:
            tl, tr, sp, whole = best
            if whole and images is not None and self.config.refine.method != "none":
                return self._refine_pair(images, tl, tr, sp)
            return {"left": tl.uv, "right": tr.uv}, sp
        if rejected:
            reason = min(rejected, key=lambda r: r[0])[1]
        else:
            reason = " and ".join(f"no fingertip in the {s} view" for s in ("left", "right") if not cands[s])
        found = {s: self._on_track(s, cands[s], modes[s]) for s in ("left", "right")}
        if found["left"] is not None and found["right"] is not None:  # both on their tracks but inconsistent
            bad = max(("left", "right"), key=lambda s: self._surprise(s, found[s]))
            found[bad] = None
        return found, StereoPoint(False, reason=reason)

    def _match(self, tl, tr, modes: dict, t: float, rl=None, rr=None):
        """Check one left/right pair: ``(tip_left, tip_right, StereoPoint, reason)``, reason "" if accepted
        (``rl``, ``rr``: the tips in the rectified images, if already known).

        The pair must pass the epipolar and disparity checks, and each fitted cap radius, scaled by
        its depth, must be within ``acquire_radius_band`` of ``finger_radius_m`` (0.5–1.6 when both
        views are tracked). A pair whose caps differ in radius (below ``occluded_cap_ratio``), or
        that misses the epipolar line by less than a cap radius, may be partly hidden in one view —
        in an encountered-type system the device stands where the finger is going and its arm often
        crosses the tip in one view — and is checked by :meth:`_occluded_pair` first. A recheck
        (which would replace a holding track) needs a fitted cap circle.
        """
        cfg = self.config
        cl, cr = tl.cap_radius_px, tr.cap_radius_px
        rect = {s: self.rig.rectify_points(np.asarray(tp.uv, dtype=np.float64).reshape(1, 2), s)[0] if r is None else r
                for s, tp, r in (("left", tl, rl), ("right", tr, rr))}
        sp = triangulate_rectified_tip(self.rig, rect["left"], rect["right"], cfg.stereo, covariance=False)
        odd = cl > 0 and cr > 0 and min(cl, cr) < cfg.occluded_cap_ratio * max(cl, cr)
        if cfg.occluded_pairs and (odd or (not sp.ok and sp.epipolar_px <= cfg.stereo.max_epipolar_px + max(cl, cr))):
            spo, tip, occ = self._occluded_pair(tl, tr, t, dict(rect))
            if tip is not None:
                tl, tr = (tip, tr) if occ == "left" else (tl, tip)
                return tl, tr, spo, ""
            if spo is not None:
                return tl, tr, spo, spo.reason
        if not sp.ok:
            return tl, tr, sp, sp.reason
        on_track = all(modes[s] == "tracked" or id(tp) in self._window_tips for s, tp in (("left", tl), ("right", tr)))
        lo, hi = (0.5, 1.6) if on_track else cfg.acquire_radius_band
        for side, tip in (("left", tl), ("right", tr)):
            needs_cap = (modes[side] == "recheck" and id(tip) not in self._window_tips) \
                or (cfg.acquire_needs_cap_fit and modes[side] == "full")
            if tip.cap_radius_px <= 0 and needs_cap:
                return tl, tr, sp, f"no cap circle fits the candidate in the {side} view"
            q = tip.cap_radius_px / self._px_per_m(side, sp.p_cam) / cfg.finger_radius_m
            if tip.cap_radius_px > 0 and not (lo <= q <= hi):
                return tl, tr, sp, f"cap radius {q:.2f} of a fingertip's in the {side} view (accepted {lo:.2f}–{hi:.2f})"
        return tl, tr, sp, ""

    def _occluded_pair(self, tl, tr, t: float, rect: dict):
        """A pair where one view's cap may be cut by an occluder: ``(StereoPoint, corrected tip, view)``;
        no tip when it is not handled so (the StereoPoint, if any, says why it was rejected).

        The other (reference) view must be tracked without a miss and show a cap of a fingertip's
        size; of two such views the one nearer its track's prediction (Mahalanobis) is the reference.
        Too little of the cap shows when the smaller fitted radius is below
        ``occluded_min_cap_ratio`` of the larger. The cut cap's centre is off by up to a cap radius
        (a cut fits a smaller or a flatter, larger circle); its row is replaced by the other view's rectified row (the
        tip lies on that epipolar line) and only its column (the disparity) is used. The 3-D
        point must be within reach of the 3-D track, and the pixel noise of the triangulation is
        raised by the row offset (covariance). The corrected tip is the 3-D point projected into
        the occluded view.
        """
        cfg = self.config
        tips = {"left": tl, "right": tr}
        reach_px = max(tl.cap_radius_px, tr.cap_radius_px)  # the tip is within a cap radius of any cap point
        epi = abs(rect["left"][1] - rect["right"][1])
        stereo = replace(cfg.stereo, sigma_px=float(np.hypot(cfg.stereo.sigma_px, epi)),
                         max_epipolar_px=cfg.stereo.max_epipolar_px + reach_px)
        sp0 = triangulate_rectified_tip(self.rig, rect["left"], rect["right"], stereo)
        if not sp0.ok:
            return None, None, None
        q = {s: tp.cap_radius_px / self._px_per_m(s, sp0.p_cam) / cfg.finger_radius_m for s, tp in tips.items()}
        lo, hi = cfg.acquire_radius_band
        held = [s for s in ("left", "right") if self.trackers[s].tracking and self.trackers[s].kf.misses == 0
                and lo <= q[s] <= hi]
        if not held:
            return None, None, None
        other = min(held, key=lambda s: self._surprise(s, tips[s].uv))
        occ = "right" if other == "left" else "left"
        c_occ, c_ref = tips[occ].cap_radius_px, tips[other].cap_radius_px
        if min(c_occ, c_ref) < cfg.occluded_min_cap_ratio * max(c_occ, c_ref):
            return StereoPoint(False, reason=f"cap mostly hidden in the {occ} view (radius {c_occ:.1f} px, "
                                             f"{c_ref:.1f} px in the {other} view)"), None, occ
        small = tips[occ]
        tip = replace(small)
        rect[occ] = np.array([rect[occ][0], rect[other][1]])  # on the other view's epipolar line
        sp = triangulate_rectified_tip(self.rig, rect["left"], rect["right"], stereo)
        if not sp.ok:
            return sp, None, occ
        held = cfg.occluded_track_held and self.trackers[other].held_since(self._t3)
        if not self._within_reach(sp.p_cam, t, max_age_s=np.inf if held else None):
            return StereoPoint(False, reason=f"cap partly hidden in the {occ} view and its 3-D point out of "
                                             f"reach of the 3-D track"), None, occ
        uv_l, uv_r = self.rig.project(sp.p_cam[None])
        tip.uv = (uv_l if occ == "left" else uv_r)[0]
        return sp, tip, occ

    def _px_per_m(self, side: str, p_cam) -> float:
        """Pixels per metre at the point ``p_cam`` (left camera frame) in one view: f / z."""
        if side == "left":
            return float(self.rig.K_left[0, 0]) / float(p_cam[2])
        return float(self.rig.K_right[0, 0]) / float((self.rig.R @ p_cam + self.rig.T)[2])

    def _within_reach(self, p_cam, t: float, fix=None, max_age_s: float | None = None) -> bool:
        """Could the finger have moved from the last 3-D fix (or ``fix = (p, t)``) to ``p_cam`` by
        time ``t`` (``max_speed_m_s`` plus ``reach_margin_m``)? False when there is no fix or it is
        older than ``max_age_s`` (default ``track_max_age_s``)."""
        p0, t0 = (self._p3, self._t3) if fix is None else fix
        age = self.config.track_max_age_s if max_age_s is None else max_age_s
        if p0 is None or t - t0 > age:
            return False
        reach = self.config.max_speed_m_s * max(0.0, t - t0) + self.config.reach_margin_m
        return bool(np.linalg.norm(np.asarray(p_cam) - p0) <= reach)

    def _confirmed(self, p_cam, t: float) -> bool:
        """Report ``p_cam``? Yes when it continues the 3-D track; a point that starts a track (first
        fix, a jump out of reach, a fix after ``track_max_age_s``) is held back until a frame within
        ``confirm_within_s`` confirms it within reach: a one-frame false match would send the device
        to a wrong target."""
        if not self.config.confirm_new_tracks or self._within_reach(p_cam, t):
            return True
        ok = self._pending is not None and self._within_reach(p_cam, t, self._pending, self.config.confirm_within_s)
        self._pending = None if ok else (np.asarray(p_cam, dtype=np.float64), t)
        return ok

    def _on_track(self, side: str, tips: list, mode: str):
        """Without a stereo pair: the candidate of a view whose track holds, if it is on the track."""
        trk = self.trackers[side]
        if not tips or not trk.tracking or mode == "full":
            return None
        if mode == "tracked":
            return tips[0].uv
        uv = min((tp.uv for tp in tips), key=lambda u: float(np.hypot(*(u - trk.kf.position))))
        return uv if np.hypot(*(uv - trk.kf.position)) <= self.config.recheck_jump_px else None

    def _surprise(self, side: str, uv) -> float:
        trk = self.trackers[side]
        return trk.kf.mahalanobis(uv) if trk.tracking else 0.0

    def _keep_track_measurement(self, tips: list, image, seg, window, pred, z) -> list:
        """In a periodic recheck: a full-frame candidate on the tracked finger (within
        ``recheck_jump_px`` of the window's detection) is replaced by the window's detection, so a
        recheck that finds the same finger measures it exactly as a tracked frame would; it only
        changes the track when it ranks another finger first."""
        cfg = self.config
        wr = snap_roi(window, seg.config.tile, self._size)
        found = detect_fingertips(seg.segment(image, wr), self.K / z, cfg.fingertip, prior_uv=pred, max_tips=1,
                                  origin=wr[:2])
        if not found:
            return tips
        w = found[0]
        k = int(np.argmin([np.hypot(*(tp.uv - w.uv)) for tp in tips]))
        if np.hypot(*(tips[k].uv - w.uv)) > cfg.recheck_jump_px:
            return tips
        w.extremity_px = tips[k].extremity_px  # keeps the full-frame ranking
        self._window_tips.add(id(w))
        return tips[:k] + [w] + tips[k + 1:]

    def _detect(self, side: str, image: np.ndarray, t: float, timings: dict, recheck: bool = False):
        """Candidates of one view and the mode ("full", "tracked" or "recheck"); ``recheck`` forces a
        full-frame search of a tracked view (its window measurement kept, see _keep_track_measurement)."""
        cfg = self.config
        trk = self.trackers[side]
        seg = self.segmenters[side]
        pred = trk.predict(t)  # the filter runs in every mode (filtered output); the window only when tracking
        if not cfg.tracking:
            pred = None
        z = self._z if self._z is not None else cfg.z_default_m
        r = self.K / z
        roi = trk.window(self._size, extra_px=2 * r * (1 + cfg.fingertip.delta_r_frac)) if pred is not None else None
        mode = "tracked" if roi is not None else "full"
        young = self._fix_run < cfg.recheck_frames and cfg.recheck_young_frames
        period = cfg.recheck_young_frames if young else cfg.recheck_frames
        window = None
        if roi is not None and (recheck or (period and self._since_full >= period)):
            window, roi, mode = roi, None, "recheck"  # a periodic full-frame search: escape a lock on the wrong finger
        if roi is None:
            roi = (0, 0, self._size[0], self._size[1])
        roi = snap_roi(roi, seg.config.tile, self._size)
        ts = time.perf_counter()
        # the mask only where it can hold skin, widened by the largest square ring searched (a
        # full frame: the same candidates without allocating and scanning all of it)
        pad = math.ceil((1 + cfg.fingertip.delta_r_frac) * self.K / min(z, *cfg.z_search_m)) + 2
        mask, org = seg.segment_region(image, roi, pad=pad)
        self._skin_px[side] = mask  # counted by _finger_gone, when a frame finds no fingertip
        td = time.perf_counter()
        prior = None if mode == "recheck" else pred
        n_max = 1 if mode == "tracked" else cfg.max_candidates
        if mode != "full" or self._z is not None:  # (image pixels from here on)
            tips = detect_fingertips(mask, self.K / z, cfg.fingertip, prior_uv=prior, max_tips=n_max, origin=org)
        else:  # first acquisition, depth unknown: candidates at each depth of the working range
            tips = search_tips(mask, [self.K / zz for zz in (z, *cfg.z_search_m)], cfg.fingertip, origin=org,
                               prior_uv=prior, max_tips=n_max)
        if window is not None and tips:
            tips = self._keep_track_measurement(tips, image, seg, window, pred, z)
        if not tips and mode == "tracked" and cfg.full_search_on_miss:
            # the finger left the window (fast motion): search this view's full frame now
            full = snap_roi((0, 0, self._size[0], self._size[1]), seg.config.tile, self._size)
            m_full = seg.segment(image, full)
            tips = detect_fingertips(m_full, self.K / z, cfg.fingertip, max_tips=cfg.max_candidates)
            # keep the finger's identity: only candidates the finger could have reached since its
            # last detection at max_speed_m_s (a thumb beside a hidden index tip is rejected)
            since = t - (trk.t_hit if trk.t_hit is not None else t)
            gate = 2 * r * (1 + cfg.fingertip.delta_r_frac) + cfg.max_speed_m_s * (since + 1 / 30) * self.rig.fx_px / z
            tips = [tp for tp in tips if np.hypot(*(tp.uv - pred)) <= gate]
            if tips:
                mode, mask, org = "recheck", m_full, full[:2]
        te = time.perf_counter()
        timings[f"segment_{side}_ms"] = timings.get(f"segment_{side}_ms", 0.0) + (td - ts) * 1e3
        timings[f"detect_{side}_ms"] = timings.get(f"detect_{side}_ms", 0.0) + (te - td) * 1e3
        self._masks[side] = (mask, org)
        return tips, mode
