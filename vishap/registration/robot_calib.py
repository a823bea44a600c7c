"""Camera-to-robot calibration procedure (VisHap §2.2, Eq. 3).

"We move the haptic device around in the field of view of the camera system and record more than
three pairs of coordinates of the end-effector in both the camera and haptic frames. Then R and t
are calculated as the optimal absolute orientation solution." Here:

1. :func:`select_poses` picks N end-effector targets that span the reachable box (its corners
   first — rotation accuracy grows with the spread of the points — then a seeded maximin fill);
2. :func:`measure` drives the arm to each (inverse kinematics), reads the joints, takes the
   end-effector position from forward kinematics (``p_robot``), renders/grabs a stereo pair,
   finds the green marker in both images (:mod:`vishap.registration.marker`) and triangulates
   it with the rig (``p_cam``);
3. :func:`solve` computes ``T_robot_cam`` by absolute orientation (closed form, optionally
   robust), optionally refined by minimising the marker's reprojection error in both images
   (the maximum-likelihood estimate under pixel noise: triangulated depth is much noisier than
   the image coordinates, which the 3-D closed form weighs equally);
4. :func:`report` gives VisHap's figure (mean error per axis of the fitted pairs, mm) and, when
   the truth is known (simulation), the rotation/translation error and the error of mapping
   points spread over the workspace.
"""
from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import least_squares

from vishap._core.errors import CalibrationError
from vishap._core.pose import from_rt, invert, matrix_to_rotvec, rotvec_to_matrix
from vishap.registration.marker import detect_marker
from vishap.registration.rigid import RigidTransform
from vishap.robot.params import WORKSPACE_MAX, WORKSPACE_MIN

__all__ = ["MARKER_RADIUS_M", "REACHABLE_BOX", "PoseDropped", "StopMeasuring", "select_poses", "Observations",
           "measure", "solve", "refine_reprojection", "report"]

# Radius of the calibration marker (the synthetic renderer's green sphere), metres.
MARKER_RADIUS_M = 0.005
# Reachable box shared by all areas (robot frame, metres; rows x, y, z): the arm's workspace.
REACHABLE_BOX = np.column_stack([WORKSPACE_MIN, WORKSPACE_MAX])


class PoseDropped(Exception):
    """Raised by ``move_to`` or ``grab`` in :func:`measure`: this pose is lost (the message says why)."""


class StopMeasuring(Exception):
    """Raised by ``move_to`` or ``grab`` in :func:`measure`: visit no more poses (source ended, user stopped)."""


def select_poses(n: int, seed: int = 0, *, box=REACHABLE_BOX, margin: float = 0.01,
                 reachable: Callable[[np.ndarray], bool] | None = None, candidates: int = 3000) -> np.ndarray:
    """``n`` end-effector targets (n, 3) spanning ``box`` shrunk by ``margin`` (metres).

    Greedy maximin over the box's 8 corners, its centre and ``candidates`` seeded uniform points:
    each new target is the candidate farthest from those already chosen, starting at a corner —
    so the corners come first, then the centre and the largest gaps. ``reachable(p)`` (e.g.
    inverse kinematics succeeds) filters the candidates.
    """
    if n < 3:
        raise CalibrationError(f"need at least 3 poses (VisHap records more than three), got {n}", field="poses")
    box = np.asarray(box, dtype=np.float64)
    lo, hi = box[:, 0] + margin, box[:, 1] - margin
    if np.any(hi <= lo):
        raise CalibrationError(f"margin {margin} m leaves an empty box", field="margin")
    rng = np.random.default_rng(seed)
    corners = np.array([[(lo, hi)[(i >> k) & 1][k] for k in range(3)] for i in range(8)])
    cand = np.vstack([corners, (lo + hi) / 2, lo + rng.random((candidates, 3)) * (hi - lo)])
    if reachable is not None:
        cand = cand[np.array([bool(reachable(p)) for p in cand], dtype=bool)]
    if len(cand) < n:
        raise CalibrationError(f"only {len(cand)} reachable targets in the box, {n} asked", field="poses")
    chosen = [0]
    dmin = np.linalg.norm(cand - cand[0], axis=1)
    for _ in range(n - 1):
        i = int(np.argmax(dmin))
        chosen.append(i)
        dmin = np.minimum(dmin, np.linalg.norm(cand - cand[i], axis=1))
    return cand[chosen]


@dataclass
class Observations:
    """What :func:`measure` recorded, one row per target (NaN where the marker was not found)."""

    targets_robot: np.ndarray  # (N, 3) commanded targets
    p_robot: np.ndarray  # (N, 3) forward kinematics of the joints read back
    uv_left: np.ndarray  # (N, 2) marker centre, pixels (NaN when not found)
    uv_right: np.ndarray  # (N, 2)
    p_cam: np.ndarray  # (N, 3) triangulated marker centre (NaN when not found in both)
    reasons: list[str] = field(default_factory=list)  # '' or why pose i was dropped
    area_ratio: np.ndarray | None = None  # (N, 2) marker area / a full sphere's, left and right

    @property
    def ok(self) -> np.ndarray:
        return np.isfinite(self.p_cam).all(axis=1) & np.isfinite(self.p_robot).all(axis=1)

    def as_arrays(self) -> dict:
        out = {"targets_robot": self.targets_robot, "p_robot": self.p_robot, "uv_left": self.uv_left,
               "uv_right": self.uv_right, "p_cam": self.p_cam, "ok": self.ok}
        if self.area_ratio is not None:
            out["area_ratio"] = self.area_ratio
        return out


def measure(targets_robot, rig, *, move_to: Callable[[np.ndarray], np.ndarray | None],
            grab: Callable[[np.ndarray, np.ndarray], tuple[np.ndarray, np.ndarray]], needed: int | None = None,
            marker_radius_m: float | None = MARKER_RADIUS_M, area_range: tuple[float, float] = (0.94, 1.12)
            ) -> Observations:
    """Visit targets in order and record the marker in both frames.

    ``move_to(target) -> p_robot`` moves the arm (returns the forward-kinematics position of the
    joints read back, or ``None`` when it cannot reach); ``grab(p_robot, target) -> (left, right)``
    returns the stereo pair (BGR) taken there. Either may raise :class:`PoseDropped` (the pose is
    lost, for the reason given) or :class:`StopMeasuring` (no more poses: the observations end
    before that target). Visits every target, or with ``needed`` stops as
    soon as that many poses are usable (as an operator moves on to another pose when the marker
    is hidden); the observations cover the targets visited.

    With ``marker_radius_m``, a pose is dropped when the marker's covered area in either image —
    relative to a full sphere of that radius at the triangulated depth, and to the median of that
    ratio over the poses (which absorbs a constant bias of the detector, the blur or the radius)
    — is outside ``area_range``: the marker is partly hidden behind the arm, or merged with
    something green. (Measured on the synthetic renders at 480 and 640 px: full views 0.94–1.06
    of the median, views with a hidden edge 0.84–0.93 and a centre error of 0.2–0.55 px.)
    """
    targets = np.asarray(targets_robot, dtype=np.float64).reshape(-1, 3)
    n = len(targets)
    needed = n if needed is None else int(needed)
    p_robot = np.full((n, 3), np.nan)
    uv_l = np.full((n, 2), np.nan)
    uv_r = np.full((n, 2), np.nan)
    p_tri = np.full((n, 3), np.nan)
    area_ratio = np.full((n, 2), np.nan)
    found: list[str] = []
    visited = 0
    p_cam, reasons = p_tri, found
    for i, target in enumerate(targets):
        try:
            p = move_to(target)
            if p is None:
                visited = i + 1
                found.append("target not reachable")
                continue
            left, right = grab(p, target)
        except PoseDropped as exc:
            visited = i + 1
            found.append(str(exc))
            continue
        except StopMeasuring:
            break
        visited = i + 1
        p_robot[i] = p
        dl, dr = detect_marker(left), detect_marker(right)
        if dl:
            uv_l[i] = dl.uv
        if dr:
            uv_r[i] = dr.uv
        if not (dl and dr):
            found.append("; ".join(f"{side}: {d.reason}" for side, d in (("left", dl), ("right", dr)) if not d))
            continue
        p_tri[i] = rig.triangulate(uv_l[i], uv_r[i])[0]
        if marker_radius_m is not None:
            area_ratio[i] = _area_ratio(p_tri[i], rig, marker_radius_m, dl.area_px, dr.area_px)
        found.append("")
        p_cam, reasons = _area_check(p_tri[:visited], area_ratio[:visited], found, area_range,
                                     marker_radius_m is not None)
        if np.isfinite(p_cam).all(axis=1).sum() >= needed:
            break
    p_cam, reasons = _area_check(p_tri[:visited], area_ratio[:visited], found, area_range, marker_radius_m is not None)
    k = visited
    return Observations(targets[:k], p_robot[:k], uv_l[:k], uv_r[:k], p_cam, reasons, area_ratio[:k])


def _area_check(p_tri, area_ratio, found, area_range, enabled):
    """Drop the poses whose marker area is off the median (see :func:`measure`)."""
    p_cam, reasons = p_tri.copy(), list(found)
    valid = np.isfinite(area_ratio).all(axis=1)
    if not enabled or valid.sum() < 3:
        return p_cam, reasons
    rel = area_ratio / np.median(area_ratio[valid], axis=0)
    for i in np.flatnonzero(valid):
        bad = [f"{side}: marker area {rel[i, k]:.2f} of the median: partly hidden?"
               for k, side in enumerate(("left", "right")) if not area_range[0] <= rel[i, k] <= area_range[1]]
        if bad:
            p_cam[i] = np.nan
            reasons[i] = "; ".join(bad)
    return p_cam, reasons


def _area_ratio(p_cam, rig, radius_m, area_left, area_right) -> np.ndarray:
    """Marker area in each image over that of a full sphere of ``radius_m`` at the triangulated depth."""
    out = np.full(2, np.nan)
    z_right = (rig.R @ p_cam + rig.T)[2]
    for k, (z, K, area) in enumerate(((p_cam[2], rig.K_left, area_left), (z_right, rig.K_right, area_right))):
        if z > radius_m:
            out[k] = area / (math.pi * K[0, 0] * K[1, 1] * radius_m**2 / (z * z - radius_m**2))
    return out


def refine_reprojection(T_robot_cam, p_robot, uv_left, uv_right, rig, *, loss: str = "linear",
                        f_scale_px: float = 0.5) -> np.ndarray:
    """``T_robot_cam`` minimising the marker's reprojection error in both images (pixels).

    Starts from ``T_robot_cam`` (e.g. the closed form) and optimises its 6 parameters with
    Levenberg–Marquardt on ``π(T_cam_robot · p_robot) − uv`` in the left and right images;
    with ``loss`` (a SciPy robust loss such as ``"soft_l1"``, scale ``f_scale_px``) a
    trust-region solver that lets a few poor detections count less.
    """
    T0 = invert(np.asarray(T_robot_cam, dtype=np.float64))  # T_cam_robot
    p_robot = np.asarray(p_robot, dtype=np.float64)
    target = np.hstack([uv_left, uv_right])
    x0 = np.concatenate([matrix_to_rotvec(T0[:3, :3]), T0[:3, 3]])

    def resid(x):
        p_cam = p_robot @ rotvec_to_matrix(x[:3]).T + x[3:]
        return (np.hstack(rig.project(p_cam)) - target).ravel()

    if loss == "linear":
        sol = least_squares(resid, x0, method="lm", x_scale=np.r_[np.full(3, 0.01), np.full(3, 0.001)])
    else:
        sol = least_squares(resid, x0, method="trf", loss=loss, f_scale=f_scale_px,
                            x_scale=np.r_[np.full(3, 0.01), np.full(3, 0.001)])
    if not np.all(np.isfinite(sol.x)):
        raise CalibrationError("reprojection refinement diverged")
    return invert(from_rt(rotvec_to_matrix(sol.x[:3]), sol.x[3:]))


def solve(obs: Observations, rig=None, *, robust: bool = False, refine: bool = False) -> RigidTransform:
    """``T_robot_cam`` from the observations: absolute orientation (src = camera, dst = robot).

    ``robust``: least-median-of-squares with inlier refit (drops wrong detections).
    ``refine``: then minimise the reprojection error in both images (needs ``rig``; soft-L1
    loss with a 0.3 px scale, so a marker detection spoiled by partial occlusion counts less).
    Returns a falsy :class:`RigidTransform` with ``reason`` when the poses are degenerate.
    """
    ok = obs.ok
    if ok.sum() < 3:
        return RigidTransform.failed(f"the marker was measured at only {int(ok.sum())} pose(s); need at least 3")
    p_cam, p_robot = obs.p_cam[ok], obs.p_robot[ok]
    fit = (RigidTransform.from_estimate_robust(p_cam, p_robot) if robust
           else RigidTransform.from_estimate(p_cam, p_robot))
    if not fit or not refine:
        return fit
    if rig is None:
        raise CalibrationError("reprojection refinement needs the rig")
    keep = fit.inliers if fit.inliers is not None else np.ones(len(p_cam), bool)
    T = refine_reprojection(fit.T, p_robot[keep], obs.uv_left[ok][keep], obs.uv_right[ok][keep], rig,
                            loss="soft_l1", f_scale_px=0.3)
    return RigidTransform(R=T[:3, :3], t=T[:3, 3], p_src=p_cam, p_dst=p_robot, inliers=keep)


def report(fit: RigidTransform, obs: Observations, T_true=None, *, rig=None, box=REACHABLE_BOX) -> dict:
    """VisHap's figure and, with the true transform, the errors against it.

    ``per_axis_error_mm``: mean |T p_cam − p_robot| per robot axis over the poses used (what
    VisHap reports, < 0.5 mm). With ``T_true``: ``rotation_error_deg``, ``translation_error_mm``
    and ``workspace_per_axis_error_mm`` / ``workspace_max_error_mm``: the error of mapping points
    on a 5×5×5 grid of ``box`` with the estimate instead of the truth. With ``rig``:
    ``reprojection_rms_px``, the RMS image distance between the detected marker and the robot
    position mapped back into both images.
    """
    if not fit:
        raise CalibrationError(f"camera-to-robot calibration failed: {fit.reason}")
    rep = fit.error_report()
    out = {
        "poses": int(len(obs.targets_robot)),
        "poses_used": int(rep["pairs"]),
        "poses_dropped": [{"index": i, "reason": r} for i, r in enumerate(obs.reasons) if r],
        "per_axis_error_mm": rep["per_axis_error_mm"],
        "rms_mm": rep["rms_mm"],
        "max_mm": rep["max_mm"],
    }
    if rig is not None:
        ok = obs.ok
        keep = fit.inliers if fit.inliers is not None else np.ones(int(ok.sum()), bool)
        p_cam = fit.inverse().apply(obs.p_robot[ok][keep])
        uv = np.hstack(rig.project(p_cam)) - np.hstack([obs.uv_left[ok][keep], obs.uv_right[ok][keep]])
        out["reprojection_rms_px"] = float(np.sqrt(np.mean(uv.reshape(-1, 2) ** 2) * 2))
    if T_true is not None:
        T_true = np.asarray(T_true, dtype=np.float64)
        out.update(fit.compare(T_true))
        box = np.asarray(box, dtype=np.float64)
        g = np.stack(np.meshgrid(*[np.linspace(a, b, 5) for a, b in box], indexing="ij"), -1).reshape(-1, 3)
        p_cam = g @ invert(T_true)[:3, :3].T + invert(T_true)[:3, 3]
        err = (fit.apply(p_cam) - g) * 1e3
        out["workspace_per_axis_error_mm"] = np.mean(np.abs(err), axis=0).tolist()
        out["workspace_max_error_mm"] = float(np.max(np.linalg.norm(err, axis=1)))
    return out
