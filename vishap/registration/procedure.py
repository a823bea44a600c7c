"""Camera-to-robot calibration on a device and a stereo source: one procedure, simulated or real (VisHap §2.2).

``vishap calibrate robot --device NAME --cameras SPEC --rig FILE --poses N --out FILE`` and
``vishap calibrate robot --sim`` (the ``sim`` device and the rendered cameras) both run
:func:`run_calibration`:

1. the pose sequence (:func:`pose_targets`: maximin over the device's workspace, filtered by the
   arm's reach) — beyond N, where to go instead when the marker is hidden at a pose;
2. :class:`DevicePoser` brings the end-effector to each target: a device that moves itself
   (:attr:`Device.moves_itself`) is driven there by the servo loop (the controller with the gains
   file, the travel limiter); one that cannot is placed by a person, asked by ``prompt`` — in both
   cases the pose counts once the end-effector has held still (``Settle``) and ``p_robot`` is the
   mean forward kinematics of the joints read over that still window;
3. the stereo pair is the next frame(s) of the source, taken while the device holds the pose; a
   device that moved meanwhile loses the pose;
4. :mod:`vishap.registration.robot_calib` detects the marker, triangulates, solves (closed form,
   then refined on the reprojection error) and reports; with the truth (simulation) against it.
"""
from __future__ import annotations

import sys
from collections import deque
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from vishap._core.errors import CalibrationError, ShapeError
from vishap.registration import camera_robot
from vishap.registration.robot_calib import PoseDropped, StopMeasuring, measure, report, select_poses, solve

__all__ = ["Settle", "DevicePoser", "pose_targets", "Truth", "calibrate", "run_calibration"]


@dataclass(frozen=True)
class Settle:
    """When a pose counts: the tip stayed within ``still_m`` (per axis, peak to peak) for ``window_s``.

    ``reach_m``: a device that moves itself must also be that close to its target;
    ``timeout_s``: give the pose up after this long (device time). The defaults were chosen on the
    simulated arm (encoder 1.5e-4 rad): the arm is still creeping when it first holds 0.2 mm for
    0.1 s — the window's mean position then lies 0.02–0.07 mm from where the pair shows it (median
    0.056 mm over 12 poses); 0.1 mm for 0.2 s brings that to 0.014 mm (max 0.021), below the
    encoder's own quantisation.
    """

    still_m: float = 1e-4
    window_s: float = 0.2
    reach_m: float = 5e-3
    timeout_s: float = 10.0


class DevicePoser:
    """Brings a :class:`~vishap.robot.device.Device` to calibration poses and reads where it is.

    ``prompt(index, target_robot)`` is called for a device that cannot move itself: it returns once a
    person has placed the end-effector near ``target_robot`` (m, robot frame); it may raise
    :class:`StopMeasuring` to end the session. While a person places it, the device gets zero force.
    """

    def __init__(self, device, *, prompt: Callable[[int, np.ndarray], None] | None = None,
                 settle: Settle = Settle(), gains_path=None):
        self.device = device
        self.settle = settle
        self.prompt = prompt
        self._l1, self._l2 = device.params.l1, device.params.l2
        self._window = max(2, int(round(settle.window_s * device.params.servo_rate_hz)))
        self.loop = None
        if device.moves_itself:
            from vishap.robot.controller import Controller
            from vishap.robot.gains import load_gains
            from vishap.robot.servo import ServoLoop
            from vishap.robot.travel import TravelLimiter

            gains, _ = load_gains(gains_path)
            self.loop = ServoLoop(device, Controller(device.params, gains, limits=device.limits), travel=TravelLimiter())
        elif prompt is None:
            raise CalibrationError("the device cannot move itself and there is no one to place it (no prompt)",
                                   field="device")
        self.visited = 0  # targets asked for so far
        self._target = None

    def _tip(self) -> tuple[float, float, float]:
        from vishap.robot.kinematics import tip_state_scalar

        return tip_state_scalar(*self.device.read_scalar(), self._l1, self._l2)[:3]

    def _tick(self) -> None:
        if self.loop is not None:
            self.loop.tick(self.device.time, self._target)
        else:
            self.device.command_torque_scalar(0.0, 0.0, 0.0)
            self.device.step()

    def hold(self) -> np.ndarray:
        """Keep holding the pose until the tip has been still for the window; its mean position (m)."""
        s = self.settle
        recent: deque = deque(maxlen=self._window)
        t_end = self.device.time + s.timeout_s
        while self.device.time < t_end:
            self._tick()
            recent.append(self._tip())
            if len(recent) < self._window:
                continue
            w = np.asarray(recent)
            if np.max(np.ptp(w, axis=0)) > s.still_m:
                continue
            p = w.mean(axis=0)
            if self.loop is None or np.linalg.norm(p - self._target) <= s.reach_m:
                return p
        if self.loop is not None:
            raise PoseDropped(f"did not settle within {s.reach_m * 1e3:.0f} mm of the target in {s.timeout_s:g} s")
        raise PoseDropped(f"the end-effector did not hold still (within {s.still_m * 1e3:.2f} mm for "
                          f"{s.window_s:g} s) in {s.timeout_s:g} s")

    def move_to(self, target) -> np.ndarray:
        """Bring the end-effector to ``target`` (m, robot frame); where it is, from the joints read."""
        self._target = np.asarray(target, dtype=np.float64)
        if self.loop is None:
            self.device.command_torque_scalar(0.0, 0.0, 0.0)
            self.prompt(self.visited, self._target)
        self.visited += 1
        return self.hold()

    def check_still(self, p_robot) -> None:
        """After the pair: the device is still where it was read (else the pose is dropped)."""
        self._tick()
        moved = float(np.linalg.norm(np.asarray(self._tip()) - p_robot))
        if moved > 2 * self.settle.still_m:
            raise PoseDropped(f"the end-effector moved {moved * 1e3:.2f} mm while the pair was taken")


def pose_targets(n_poses: int, seed: int, *, box, reachable: Callable[[np.ndarray], bool],
                 design: str = "maximin") -> np.ndarray:
    """The pose sequence: ``max(3n, n + 12)`` targets (the ones beyond n replace hidden poses).

    ``design``: ``maximin`` (:func:`select_poses`), ``random`` (uniform in the box) or ``cluster``
    (uniform in a 4 cm cube at the box centre) — the comparisons of ``vishap bench registration``.
    """
    box = np.asarray(box, dtype=np.float64)
    m = max(3 * n_poses, n_poses + 12)
    if design == "maximin":
        return select_poses(m, seed, box=box, reachable=reachable)
    if design not in ("random", "cluster"):
        raise CalibrationError(f"pose design must be maximin, random or cluster, got {design!r}", field="design")
    rng = np.random.default_rng([seed, 0xD5])
    lo, hi = box[:, 0] + 0.01, box[:, 1] - 0.01
    if design == "cluster":
        c = (lo + hi) / 2
        lo, hi = c - 0.02, c + 0.02
    cand = lo + rng.random((4 * m, 3)) * (hi - lo)
    return cand[[reachable(p) for p in cand]][:m]


def reachable_by(params) -> Callable[[np.ndarray], bool]:
    """``p_robot -> bool``: inverse kinematics succeeds within the joint limits of ``params``."""
    from vishap.robot import kinematics

    def reachable(p) -> bool:
        try:
            q = kinematics.ik(np.asarray(p, dtype=np.float64), params)
        except ShapeError:
            return False
        return kinematics.within_joint_limits(q, params)

    return reachable


@dataclass
class Truth:
    """What a simulation knows and the procedure never uses to decide: the true ``T_robot_cam`` and
    the true end-effector shown in each frame (frame index → m, robot frame)."""

    T_robot_cam: np.ndarray
    ee_by_frame: dict


def calibrate(device, source, rig, *, n_poses: int, seed: int = 0, prompt=None, robust: bool = False,
              design: str = "maximin", frames_per_pose: int = 1, settle: Settle = Settle(),
              truth: Truth | None = None, gains_path=None, progress: bool = False) -> dict:
    """Measure ``n_poses`` usable poses of ``device`` seen by ``source`` (a StereoSource) and solve
    (``progress``: a bar over the poses visited, on stderr on a terminal).

    Returns ``closed_form`` and ``reprojection_refined`` reports, ``fit`` (the refined transform),
    ``observations`` (arrays per visited pose, with the camera frame each used), ``poses_visited``;
    with ``truth`` also the marker's image error and the triangulation error against it.
    """
    if frames_per_pose < 1:
        raise CalibrationError(f"expected ≥ 1, got {frames_per_pose}", field="frames_per_pose")
    box = np.column_stack([device.limits.workspace_min, device.limits.workspace_max])
    targets = pose_targets(n_poses, seed, box=box, reachable=reachable_by(device.params), design=design)
    poser = DevicePoser(device, prompt=prompt, settle=settle, gains_path=gains_path)
    frames = iter(source)
    frame_of_pose: dict[int, int] = {}  # pose index → the camera frame its pair came from

    def grab(p_robot, target):
        frame = None
        for _ in range(frames_per_pose):
            frame = next(frames, None)
            if frame is None:
                raise StopMeasuring(f"the camera source {getattr(source, 'name', '')!r} ended")
        poser.check_still(p_robot)
        frame_of_pose[poser.visited - 1] = frame.index
        return frame.left, frame.right

    from vishap._core.results import progress as bar

    device.start()
    try:
        with bar(total=len(targets), desc="calibrate robot", unit="pose", quiet=not progress) as shown:
            def move_to(target):
                shown.update(1)
                return poser.move_to(target)

            obs = measure(targets, rig, move_to=move_to, grab=grab, needed=n_poses)
    finally:
        device.stop()
    frame_index = np.array([frame_of_pose.get(i, -1) for i in range(len(obs.targets_robot))], dtype=int)
    out: dict = {"poses": int(n_poses), "poses_visited": len(obs.targets_robot), "seed": int(seed), "design": design}
    T_true = None if truth is None else truth.T_robot_cam
    fits = {}
    for name, refine in (("closed_form", False), ("reprojection_refined", True)):
        fit = solve(obs, rig, robust=robust, refine=refine)
        if not fit:
            raise CalibrationError(f"camera-to-robot calibration failed: {fit.reason}; "
                                   f"dropped poses: {[r for r in obs.reasons if r]}")
        fits[name] = fit
        out[name] = report(fit, obs, T_true, rig=rig, box=box)
    out["fit"] = fits["reprojection_refined"]
    out["observations"] = {**{k: v.tolist() for k, v in obs.as_arrays().items()}, "reasons": list(obs.reasons),
                           "frame_index": frame_index.tolist()}
    if truth is not None:
        out.update(_against_truth(obs, frame_index, truth, rig))
    return out


def _against_truth(obs, frame_index, truth: Truth, rig) -> dict:
    """The marker centre's image error and the triangulation error against the true end-effector."""
    ok = obs.ok & (frame_index >= 0)
    p_true = np.array([truth.ee_by_frame[int(f)] for f in frame_index[ok]]).reshape(-1, 3)
    T = np.asarray(truth.T_robot_cam, dtype=np.float64)
    p_cam = (p_true - T[:3, 3]) @ T[:3, :3]
    uv_l, uv_r = rig.project(p_cam)
    err = np.concatenate([np.linalg.norm(uv_l - obs.uv_left[ok], axis=1), np.linalg.norm(uv_r - obs.uv_right[ok], axis=1)])
    tri = np.linalg.norm(obs.p_cam[ok] - p_cam, axis=1) * 1e3
    return {"marker_error_px": {"median": float(np.median(err)), "max": float(np.max(err))},
            "triangulation_error_mm": {"median": float(np.median(tri)), "max": float(np.max(tri))}}


def run_calibration(device, source, rig, *, n_poses: int, seed: int = 0, prompt=None, robust: bool = False,
                    frames_per_pose: int = 1, truth: Truth | None = None, out=None, poses_out=None,
                    describe: dict | None = None, progress: bool = False) -> dict:
    """``vishap calibrate robot``: calibrate, save ``out`` (tied to ``rig``) and return the JSON record."""
    res = calibrate(device, source, rig, n_poses=n_poses, seed=seed, prompt=prompt, robust=robust,
                    frames_per_pose=frames_per_pose, truth=truth, progress=progress)
    fit = res.pop("fit")
    main = res["reprojection_refined"]
    record = {
        "poses": n_poses,
        "poses_visited": res["poses_visited"],
        "poses_used": main["poses_used"],
        "per_axis_error_mm": main["per_axis_error_mm"],
        "rms_mm": main["rms_mm"],
        "reprojection_rms_px": main.get("reprojection_rms_px"),
        "method": "closed-form absolute orientation refined on reprojection error" + (" (robust)" if robust else ""),
        "closed_form": res["closed_form"],
        "poses_dropped": main["poses_dropped"],
        "pose_set_robot": [[round(v, 5) for v in p] for p in res["observations"]["targets_robot"]],
        "image_size": [int(rig.image_size[0]), int(rig.image_size[1])],
        **(describe or {}),
    }
    if truth is not None:
        for k in ("rotation_error_deg", "translation_error_mm", "workspace_per_axis_error_mm"):
            record[k] = main[k]
        record["marker_error_px"] = res["marker_error_px"]
        record["triangulation_error_mm"] = res["triangulation_error_mm"]
    if out is not None:
        camera_robot.save(out, fit.T, {k: v for k, v in record.items() if k != "pose_set_robot"}, rig=rig)
        record["out"] = str(out)
    if poses_out is not None:  # atomically, as the calibration file: never a half-written file
        import io

        from vishap._core.config import write_atomic

        extra = {} if truth is None else {"T_true": truth.T_robot_cam}
        buf = io.BytesIO()
        np.savez(buf, **{k: np.asarray(v) for k, v in res["observations"].items()}, T_robot_cam=fit.T, **extra)
        write_atomic(poses_out, buf.getvalue())
        record["poses_out"] = str(poses_out)
    return record


def _ask(question: str) -> str:
    sys.stderr.write(question)
    sys.stderr.flush()
    line = sys.stdin.readline()
    if not line:
        raise StopMeasuring("no more answers (end of input)")
    return line


def console_prompt(n_poses: int, *, ask: Callable[[str], str] | None = None) -> Callable[[int, np.ndarray], None]:
    """A prompt for a person placing the device: the target in millimetres, Enter when in place, q to stop.

    ``ask`` (default: the question on stderr, the answer from stdin, so that stdout keeps only the
    JSON record) shows the question and returns the answer.
    """

    def prompt(index: int, target_robot: np.ndarray) -> None:
        x, y, z = (float(v) * 1e3 for v in target_robot)
        answer = (ask or _ask)(f"pose {index + 1} (need {n_poses} usable): place the marker near x={x:.0f} "
                               f"y={y:.0f} z={z:.0f} mm (robot frame), hold it still, press Enter (q: stop) ")
        if answer.strip().lower() in ("q", "quit"):
            raise StopMeasuring("stopped by the user")

    return prompt

