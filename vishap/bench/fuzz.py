"""``vishap bench fuzz``: hostile inputs for every loader and the device path; count what breaks.

A case is a pure function of ``(seed, index)``: the loader or device-path entry it targets is
``index mod len(TARGETS)`` and its mutation is drawn from ``numpy.random.default_rng([seed, index])``,
so any case can be replayed alone (``vishap bench fuzz --replay INDEX``).

Loader cases start from a valid file the project ships or writes (rig, world/synthesis scenes,
skin model, tactile config, gains, camera-to-robot calibration, trajectories) and mutate it: a
number replaced by NaN, infinity, 1e300, 10⁴⁰⁰, zero, a negative, text or a nested list; a line
deleted, repeated or re-indented; the file truncated; junk bytes; YAML tags; deep nesting; alias
bombs. The outcome is *accepted*, *refused* (a :class:`~vishap._core.errors.VishapError`) or a
*crash* (any other exception). An accepted file that carried an injected NaN/inf, or whose loaded
object holds one, counts in ``accepted_nonfinite``.

Device-path cases drive ``saturate``, ``TargetGuard``, ``Controller.compute``, ``ServoLoop.tick``
and the live servo process's record intake (``LiveCycle.step``: the mailbox's values → the target
record → guard, law, controller, device) with NaN/inf/overflowing/future-stamped/all-zero inputs and
check what a device must never see: a non-finite or over-limit force, gravity compensation dropped,
a future-stamped target tracked, a target tracked after vision said the finger was lost, an arm that
moves on a NaN target from the first tick, a record no scene step writes (all zero among them)
taken for "nothing yet" or tracked, or an exception in the servo. Each violated property is a
``device_failure``.

Cases run in child processes (``--jobs``) that report one JSON line per case; a child killed by a
signal (SIGSEGV, SIGABRT) is a *native crash* of the case it was running, which is written to
``OUT/crashes/`` as a reproducer, and a new child carries on with the next case. A case that runs
longer than ``--case-timeout`` is a *hang*: its child is ended the same way.
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import re
import subprocess
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Callable
from pathlib import Path

import numpy as np

HELP = "fuzz every loader and the device-path inputs; count crashes, native crashes, accepted NaN/inf"
QUICK_ARGS = ["--cases", "3000"]

__all__ = ["HELP", "QUICK_ARGS", "add_arguments", "run", "TARGETS", "LOADERS", "DEVICE", "OPS", "TOKENS", "apply_ops",
           "make_case", "run_case", "check_saturate", "check_guard", "check_controller", "check_servo_holds",
           "check_live_record", "GUARD_CONFIG", "fuzz"]

_REPO = Path(__file__).resolve().parents[2]
_NUMBER = re.compile(r"(?<![\w.])[-+]?(?:\d+\.?\d*(?:[eE][-+]?\d+)?|\.\d+(?:[eE][-+]?\d+)?)(?![\w.])")
#: Replacement tokens for a number: (text, is it non-finite once parsed).
TOKENS: list[tuple[str, bool]] = [
    (".nan", True), (".inf", True), ("-.inf", True), (".NaN", True), (".Inf", True), ("1e400", True),
    ("-1e400", True), ("1" + "0" * 400, True), ("1e300", False), ("-1e300", False), ("1e-300", False),
    ("0", False), ("0.0", False), ("-1", False), ("-0.5", False), ("2e9", False), ("9223372036854775808", False),
    ('"x"', False), ("~", False), ("[]", False), ("{}", False), ("[1, 2]", False), ("true", False),
    ("!!timestamp 2024-13-45", False), ("!!binary AAA", False), ("!!python/object:os.system x", False),
    ("&a [*a]", False), ("[" * 200 + "]" * 200, False), ("0x1F", False), ("1_000", False), ("nan", True),
]
NONFINITE_TOKENS = {t for t, bad in TOKENS if bad}
_JUNK = [b"\x00", b"\xff\xfe", b"\x07", b": : :", b"]]]", b"{{", b"- - -", b"\t", b"%YAML:1.0\n", b"---\n",
         b"? [1]\n: 2\n", b"!!opencv-matrix", b"rows: 3\n", b"data: [", b"\r"]


# ------------------------------------------------------------------------------------ loaders
@dataclasses.dataclass(frozen=True)
class Target:
    name: str
    kind: str  # "loader" | "device"
    suffix: str = ".yaml"
    seed_text: Callable[[], str] | None = None
    load: Callable[[Path], object] | None = None
    device: Callable[[np.random.Generator], str | None] | None = None


def _read(rel: str) -> Callable[[], str]:
    return lambda: (_REPO / rel).read_text()


def _rig():
    from vishap._core.pose import rotvec_to_matrix
    from vishap.vision.rig import StereoRig

    K1 = np.array([[560.0, 0.0, 322.0], [0.0, 558.0, 241.5], [0.0, 0.0, 1.0]])
    return StereoRig((640, 480), K1, np.array([-0.21, 0.08, 0.0012, -0.0007, -0.012]), K1.copy(), np.zeros(5),
                     rotvec_to_matrix([0.004, -0.03, 0.002]), np.array([-0.0601, 0.0007, 0.0012]))


def _rig_text() -> str:
    """A rig file as ``vishap calibrate stereo`` writes it (RMS, board kind, pattern size, square)."""
    return _rig().with_calibration_info(rms_px=0.3, board="chessboard", board_size=(9, 6),
                                        square_m=0.025).to_filestorage_string()


def _rig_opencv_sample_text() -> str:
    """OpenCV's stereo_calib sample's two files (intrinsics.yml: M1 D1 M2 D2; extrinsics.yml: R T R1 R2
    P1 P2 Q) concatenated, with the image size the sample does not write."""
    import cv2

    rig = _rig()
    docs = []
    for names in ((("M1", rig.K_left), ("D1", rig.dist_left.reshape(1, -1)), ("M2", rig.K_right),
                   ("D2", rig.dist_right.reshape(1, -1))),
                  (("R", rig.R), ("T", rig.T.reshape(3, 1)), ("R1", rig.R1), ("R2", rig.R2), ("P1", rig.P1),
                   ("P2", rig.P2), ("Q", rig.Q))):
        fs = cv2.FileStorage(".yml", cv2.FILE_STORAGE_WRITE | cv2.FILE_STORAGE_MEMORY)
        for name, a in names:
            fs.write(name, np.ascontiguousarray(a, dtype=np.float64))
        docs.append(fs.releaseAndGetString())
    return docs[0] + "image_size: [ 640, 480 ]\n" + docs[1]


def _skin_text() -> str:
    from vishap.vision.skin_model import default_skin_model_path

    return default_skin_model_path().read_text()


def _call(spec: str, then: Callable | None = None) -> Callable[[Path], object]:
    """A loader ``"module:function"`` imported on first use (child processes import what they run)."""
    def load(p: Path):
        import importlib

        module, name = spec.split(":")
        fn = importlib.import_module(module)
        for part in name.split("."):
            fn = getattr(fn, part)
        out = fn(p)
        return out if then is None else then(out)

    return load


_load_rig = _call("vishap.vision.rig:StereoRig.load")
_load_world_scene = _call("vishap.world.scene:load_scene")
_load_synth_scene = _call("vishap.sim.scene_objects:load_scene_spec")
_load_skin = _call("vishap.vision.skin_model:SkinModel.load")
_load_tactile = _call("vishap.tactile.config:load_tactile_config")
_load_gains = _call("vishap.robot.gains:load_gains")
_load_camera_robot = _call("vishap.registration.camera_robot:load")
_load_trajectory = _call("vishap.sim.trajectory:load_trajectory", lambda r: r[0])
_load_modes = _call("vishap.world.modes:load_modes")


LOADERS = [
    Target("rig", "loader", ".yaml", _rig_text, _load_rig),
    Target("rig_opencv_sample", "loader", ".yml", _rig_opencv_sample_text, _load_rig),
    Target("world_scene_wall", "loader", ".yaml", _read("datasets/synthetic/scenes/wall.yaml"), _load_world_scene),
    Target("world_scene_button", "loader", ".yaml", _read("datasets/synthetic/scenes/button.yaml"), _load_world_scene),
    Target("world_scene_fabric", "loader", ".yaml", _read("datasets/synthetic/scenes/fabric.yaml"), _load_world_scene),
    Target("synth_scene", "loader", ".yaml", _read("datasets/synthetic/scenes/button.yaml"), _load_synth_scene),
    Target("skin_model", "loader", ".yaml", _skin_text, _load_skin),
    Target("tactile_config", "loader", ".yaml", _read("vishap/tactile/tactile.yaml"), _load_tactile),
    Target("gains", "loader", ".yaml", _read("vishap/robot/gains.yaml"), _load_gains),
    Target("camera_robot", "loader", ".yaml", _read("calib/camera_robot.yaml"), _load_camera_robot),
    Target("trajectory", "loader", ".yaml", _read("datasets/synthetic/trajectories/wall.yaml"), _load_trajectory),
    Target("modes", "loader", ".yaml", _read("vishap/world/modes.yaml"), _load_modes),
]


#: Mutation operators: a number replaced (the most telling, so 4 of 10 draws), a line deleted,
#: repeated or re-indented, the file truncated, junk inserted, a value made deep or self-referencing.
OPS = ("number", "number", "number", "number", "delete_line", "repeat_line", "indent", "truncate", "junk", "nest")


def apply_ops(text: str, ops) -> tuple[bytes, bool]:
    """Apply mutations ``ops`` — tuples ``(op, a, b, token)`` with ``op`` in :data:`OPS` and
    ``a``, ``b`` in [0, 1) choosing where — to ``text``; returns the bytes and whether a token
    meant to be non-finite was written."""
    nonfinite = False
    data = text
    for op, a, b, token in ops:
        lines = data.split("\n")
        i = min(int(a * len(lines)), len(lines) - 1)
        if op == "number":
            nums = list(_NUMBER.finditer(data))
            if nums:
                m = nums[min(int(a * len(nums)), len(nums) - 1)]
                data = data[: m.start()] + token + data[m.end():]
                nonfinite |= token in NONFINITE_TOKENS
        elif op == "delete_line" and len(lines) > 1:
            del lines[i]
            data = "\n".join(lines)
        elif op == "repeat_line":
            lines.insert(i, lines[i])
            data = "\n".join(lines)
        elif op == "indent":
            lines[i] = " " * int(b * 6) + lines[i].lstrip()
            data = "\n".join(lines)
        elif op == "truncate":
            data = data[: int(a * (len(data) + 1))]
        elif op == "junk":
            k = int(a * (len(data) + 1))
            data = data[:k] + _JUNK[min(int(b * len(_JUNK)), len(_JUNK) - 1)].decode("latin-1") + data[k:]
        elif op == "nest" and ":" in lines[i]:
            depth = (10, 100, 3000)[min(int(b * 3), 2)]
            lines[i] = lines[i].split(":")[0] + ": " + ("[" * depth + "]" * depth if b < 0.75 else "&r [*r]")
            data = "\n".join(lines)
    return data.encode("utf-8", "surrogateescape"), nonfinite


def _draw_ops(rng: np.random.Generator) -> list[tuple]:
    return [(OPS[int(rng.integers(len(OPS)))], float(rng.random()), float(rng.random()),
             TOKENS[int(rng.integers(len(TOKENS)))][0]) for _ in range(int(rng.integers(1, 4)))]


def _has_nonfinite(obj, depth: int = 0, seen: set | None = None) -> bool:
    """Whether a loaded object holds NaN or inf anywhere (floats, arrays, containers, dataclasses, models)."""
    seen = set() if seen is None else seen
    if depth > 8 or id(obj) in seen:
        return False
    if isinstance(obj, float):
        return not math.isfinite(obj)
    if isinstance(obj, np.ndarray):
        return obj.dtype.kind in "fc" and not bool(np.all(np.isfinite(obj)))
    if isinstance(obj, (np.floating,)):
        return not bool(np.isfinite(obj))
    if isinstance(obj, (str, bytes, int, bool)) or obj is None:
        return False
    seen.add(id(obj))
    if isinstance(obj, dict):
        return any(_has_nonfinite(v, depth + 1, seen) for v in obj.values())
    if isinstance(obj, (list, tuple)):
        return any(_has_nonfinite(v, depth + 1, seen) for v in obj)
    d = getattr(obj, "__dict__", None)
    if isinstance(d, dict):
        return any(_has_nonfinite(v, depth + 1, seen) for k, v in d.items() if not k.startswith("__"))
    return False


# ------------------------------------------------------------------------------------ device path
_HOSTILE = [math.nan, math.inf, -math.inf, 1e300, -1e300, 1e200, 1e154, -1e154, 0.0, 1e-300]


def _value(rng: np.random.Generator, sane: float) -> float:
    """Mostly a hostile value, sometimes a sane one near ``sane``."""
    if rng.random() < 0.35:
        return sane * (1.0 + 0.1 * rng.standard_normal())
    return float(_HOSTILE[int(rng.integers(len(_HOSTILE)))]) * (1 if rng.random() < 0.5 else -1)


def check_saturate(F, limit: float) -> str | None:
    """What is wrong with ``saturate(F, limit)`` (None when nothing): the output must be finite and
    within a valid limit, an overflowing finite force must end *at* the limit, not at zero, and an
    invalid limit (NaN, inf, ≤ 0) must not let a force through."""
    from vishap.world.force_laws import saturate

    F_in = np.array(F, dtype=float)
    try:
        out = saturate(F_in.copy(), limit)
    except (ValueError, ArithmeticError) as exc:
        if math.isfinite(limit) and limit > 0:
            return f"saturate raised {type(exc).__name__} for a valid limit {limit}"
        return None
    if not np.all(np.isfinite(out)):
        return f"saturate({F_in.tolist()}, {limit}) -> non-finite {np.asarray(out).tolist()}"
    n = math.hypot(*(float(v) for v in out))  # np.linalg.norm overflows above ~1e154
    ok_limit = math.isfinite(limit) and limit > 0
    if not ok_limit:
        return f"saturate passed force |F|={n:.3g} through an invalid limit {limit}" if n > 0 else None
    if n > limit * (1 + 1e-9):
        return f"saturate left |F|={n:.3g} above the limit {limit}"
    if np.all(np.isfinite(F_in)) and float(np.linalg.norm(F_in / 1e200)) * 1e200 > limit and n < 0.999 * limit:
        return f"saturate sent an overflowing force {F_in.tolist()} to |F|={n:.3g}, not the limit {limit}"
    return None


def _dev_saturate(rng):
    F = [_value(rng, 3.0) for _ in range(3)]
    limit = _value(rng, 8.5) if rng.random() < 0.5 else 8.5
    return check_saturate(F, limit)


GUARD_CONFIG = dict(box_lo=(-0.1, -0.1, -0.1), box_hi=(0.1, 0.1, 0.1), retreat_point=(0.0, 0.0, 0.05),
                    stale_after_s=0.15, retreat_after_s=0.5, min_confidence=0.2)


def check_guard(config: dict, inputs) -> str | None:
    """Build a ``TargetGuard`` from ``config`` (any non-finite value must be refused) and feed it
    ``inputs``: tuples ``(dt_s, X_d, age_s, confidence[, lost[, valid]])`` with the target made
    ``age_s`` before now (negative: stamped in the future). Every decision must be finite and inside
    the box, and a target from the future, one vision reported lost or one from a corrupt record is
    never tracked."""
    from vishap.runtime.safety import TargetGuard

    try:
        guard = TargetGuard(**{k: (np.array(v, dtype=float) if isinstance(v, tuple) else v) for k, v in config.items()})
    except (ValueError, TypeError):
        return None
    bad = [k for k, v in config.items() if not np.all(np.isfinite(np.asarray(v, dtype=float)))]
    if bad:
        return f"TargetGuard accepted a non-finite {bad[0]}={config[bad[0]]}"
    t = 1.0
    for dt, X, age, conf, *flags in inputs:
        lost, valid = (list(flags) + [False, True][len(flags):])[:2]
        t += dt
        d = guard.decide(t, X, t - age, conf, lost=lost, valid=valid)
        if not np.all(np.isfinite(d.X_d)) or np.any(d.X_d < guard.box_lo - 1e-12) or np.any(d.X_d > guard.box_hi + 1e-12):
            return f"TargetGuard gave {d.X_d.tolist()} for X={list(X)}, age={age}, confidence={conf}"
        if age < -1e-9 and math.isfinite(age) and d.action == "track":
            return f"TargetGuard tracked a target stamped {-age:.3g} s in the future"
        if lost and d.action == "track":
            return "TargetGuard tracked a target vision reported lost"
        if not valid and d.action == "track":
            return "TargetGuard tracked the content of a corrupt record"
    return None


def _dev_guard(rng):
    cfg = dict(GUARD_CONFIG)
    if rng.random() < 0.3:
        key = list(cfg)[int(rng.integers(len(cfg)))]
        v = cfg[key]
        cfg[key] = tuple(_value(rng, x) for x in v) if isinstance(v, tuple) else _value(rng, v)
    inputs = []
    for _ in range(int(rng.integers(1, 6))):
        age = -float(rng.choice([0.01, 1.0, 1e6])) if rng.random() < 0.3 else _value(rng, 0.01)
        inputs.append((0.001, [_value(rng, 0.02) for _ in range(3)], age, _value(rng, 0.9),
                       bool(rng.random() < 0.2), bool(rng.random() < 0.9)))
    return check_guard(cfg, inputs)


_CONTROLLER = {}


def check_controller(q, w, target, force) -> str | None:
    """Three ticks of ``Controller.compute`` at joint state ``q``, ``w`` toward ``target`` with an
    extra ``force``: torques finite and within the motor bound, and never all zero while the joint
    state is finite (zero would drop gravity compensation and let the arm fall). A finite force
    whose square overflows is commanded at the force limit in its own direction (or at a motor's
    peak torque, which scales the force as a whole), not dropped to zero or to gravity alone."""
    from vishap.robot.controller import Controller
    from vishap.robot.device import DeviceLimits
    from vishap.robot.gravity import gravity_torque

    if "c" not in _CONTROLLER:
        _CONTROLLER["c"] = Controller(limits=DeviceLimits.from_params())
    c = _CONTROLLER["c"]
    c.reset(0.0)
    tau = None
    for k in range(3):
        tau = c.compute(1.0 + 0.001 * k, *q, *w, *target, 0.0, 0.0, 0.0, *force)
    tau = np.asarray(tau, dtype=float)
    peak = DeviceLimits.from_params().max_torque_nm
    if not np.all(np.isfinite(tau)):
        return f"Controller.compute gave non-finite torque {tau.tolist()}"
    if np.any(np.abs(tau) > peak * (1 + 1e-9)):
        return f"Controller.compute gave |tau| {np.abs(tau).max():.3g} above {peak:.3g} N·m"
    if np.all(np.isfinite(q)) and np.all(np.isfinite(w)) and np.all(tau == 0.0) \
            and np.linalg.norm(gravity_torque(np.asarray(q, dtype=float))) > 1e-6:
        return f"Controller.compute commanded zero torque, dropping gravity compensation (target {list(target)}, force {list(force)})"
    f = np.asarray(force, dtype=float)
    # a force whose components' sum overflows is refused as non-finite input by the controller's
    # one-addition test (and counted): the property covers the forces it accepts
    with np.errstate(over="ignore"):
        overflows = not math.isfinite(float(np.sum((f / 1e150) ** 2)) * 1e300)
    if math.isfinite(float(f[0]) + float(f[1]) + float(f[2])) and np.all(np.isfinite(w)) and overflows:
        F = np.asarray(c.F_cmd, dtype=float)
        n = math.hypot(*F)
        at_motor = np.any(np.abs(tau) >= np.asarray(c._motor) * (1 - 1e-9))
        lim = DeviceLimits.from_params()
        at_limit = n >= min(lim.peak_force_n, lim.continuous_force_n) * (1 - 1e-9)
        cos = float(F @ (f / np.max(np.abs(f)))) / (n * float(np.linalg.norm(f / np.max(np.abs(f))))) if n > 0 else 0.0
        if not (at_limit or at_motor) or cos < 0.99:
            return (f"Controller.compute sent an overflowing force {f.tolist()} to F_cmd {F.tolist()} (|F| {n:.3g} N, "
                    f"cos {cos:.3f}), not to the limit along it")
    return None


def _dev_controller(rng):
    q = np.array([0.1, 0.3, -0.2]) + 0.2 * rng.standard_normal(3)
    w = [_value(rng, 0.1) for _ in range(3)] if rng.random() < 0.2 else [0.0, 0.0, 0.0]
    target = [_value(rng, 0.0) for _ in range(3)]
    force = [_value(rng, 0.0) for _ in range(3)] if rng.random() < 0.6 else [0.0, 0.0, 0.0]
    return check_controller(q.tolist(), w, target, force)


_SERVO = {}


def check_servo_holds(target, ticks: int = 200) -> str | None:
    """``ServoLoop.tick`` fed ``target`` (holding a NaN or inf) from the first tick must hold the arm
    where it is (within 5 mm) with a finite force."""
    from vishap.robot.build import build_servo

    if "s" not in _SERVO:
        _SERVO["s"] = build_servo()
    servo = _SERVO["s"]
    servo.device.reset()
    servo.controller.reset(0.0)
    servo.shaper.reset()
    p0 = np.asarray(servo.state().p_robot, dtype=float)
    X = np.array(target, dtype=float)
    for k in range(ticks):
        servo.tick(k * 1e-3, X)
    p = np.asarray(servo.state().p_robot, dtype=float)
    F = np.asarray(servo.controller.F_cmd, dtype=float)
    if not np.all(np.isfinite(F)):
        return f"ServoLoop commanded a non-finite force {F.tolist()}"
    moved = float(np.linalg.norm(p - p0))
    if not np.all(np.isfinite(p)) or moved > 0.005:
        return f"ServoLoop moved {moved * 1e3:.1f} mm on a target {list(target)} from the first tick, not holding"
    return None


def _dev_servo(rng):
    bad = [_value(rng, 0.0) for _ in range(3)]
    if all(math.isfinite(v) for v in bad):
        bad[int(rng.integers(3))] = math.nan
    return check_servo_holds(bad)


_LIVE = {}


def _is_scene_record(values, n_subjects: int) -> bool:
    """The fuzzer's own reading of what a scene step writes (independent of the code under test): a
    counter 1, 2, …; the calibrated, armed, imminent, in-contact and lost flags 0 or 1; a subject
    −1 … n−1."""
    from vishap.runtime.core import RECORD_SIZE

    v = [float(x) for x in values]
    if len(v) != RECORD_SIZE:
        return False
    whole = lambda x: math.isfinite(x) and x == int(x)  # noqa: E731
    return (whole(v[0]) and v[0] >= 1 and all(v[i] in (0.0, 1.0) for i in (6, 7, 9, 10, 18))
            and whole(v[8]) and -1 <= v[8] < n_subjects)


def check_live_record(values, ticks: int = 3) -> str | None:
    """The live servo process's intake (``LiveCycle.step``) fed ``values`` as the mailbox's newest
    record after a good one was tracked. It must never raise, its state must stay finite, and
    values no scene step writes (an all-zero record among them) must be counted as a fault and held
    on, never tracked nor taken for "nothing yet"."""
    from vishap.runtime.core import GUARD_CODES, RECORD_SIZE, TargetRecord

    if "c" not in _LIVE:
        from vishap.apps.config import DemoConfig
        from vishap.apps.live_loop import LiveCycle

        _LIVE["c"] = LiveCycle(DemoConfig(scene="wall").model_dump(), "sim", None)
        _LIVE["t"], _LIVE["seq"] = 0.0, 0
    cyc = _LIVE["c"]
    n_subjects = len(cyc.cycle.step.contact.objects)
    guard = cyc.cycle.step.guard
    good = TargetRecord(0, (0.20, 0.0, -0.13), 0.0, 1.0, True, True, 0, False, False)
    for _ in range(3):  # a good record, tracked: what follows starts a new episode
        _LIVE["t"] += 1e-3
        _LIVE["seq"] += 1
        good.seq, good.made_at = _LIVE["seq"], _LIVE["t"]
        state = cyc.step(_LIVE["t"], np.append(good.pack(), math.nan))
    if state[4] != GUARD_CODES["track"]:
        return f"LiveCycle did not track a good record (guard code {state[4]})"
    values = np.asarray(values, dtype=np.float64)
    bad0 = guard.counts.get("bad_record", 0)
    scene_record = _is_scene_record(values, n_subjects)
    try:
        for _ in range(ticks):
            _LIVE["t"] += 1e-3
            state = cyc.step(_LIVE["t"], np.append(values, math.nan))
            if not np.all(np.isfinite(state)):
                return f"LiveCycle's state turned non-finite on {values.tolist()}"
            if not scene_record and state[4] != GUARD_CODES["hold"]:
                name = {c: k for k, c in GUARD_CODES.items()}[int(state[4])]
                return f"LiveCycle answered a record no scene step writes with '{name}', not hold: {values.tolist()}"
    except Exception as exc:  # noqa: BLE001 - an exception in the servo process is the finding
        return f"LiveCycle raised {type(exc).__name__}: {exc} on {values.tolist()}"
    if not scene_record and guard.counts.get("bad_record", 0) != bad0 + 1:
        return f"LiveCycle counted {guard.counts.get('bad_record', 0) - bad0} faults for a corrupt record, not 1"
    if values.shape != (RECORD_SIZE,):
        return f"bad test input of shape {values.shape}"
    return None


def _dev_live_record(rng):
    from vishap.runtime.core import RECORD_SIZE, TargetRecord

    kind = rng.random()
    if kind < 0.25:
        return check_live_record(np.zeros(RECORD_SIZE))
    _LIVE["seq"] = _LIVE.get("seq", 0) + 1
    t = _LIVE.get("t", 0.0) + 1e-3
    rec = TargetRecord(_LIVE["seq"], tuple(0.02 * rng.standard_normal(3) + (0.2, 0.0, -0.13)), t, 0.9, True, True,
                       int(rng.integers(-1, 1)), bool(rng.random() < 0.5), bool(rng.random() < 0.5),
                       lost=bool(rng.random() < 0.3)).pack()
    if kind < 0.85:  # a few fields made hostile
        for i in rng.choice(RECORD_SIZE, size=int(rng.integers(1, 4)), replace=False):
            rec[i] = _value(rng, rec[i] if rec[i] else 1.0)
    elif kind < 0.95:
        rec = np.array([_value(rng, 1.0) for _ in range(RECORD_SIZE)])
    return check_live_record(rec)


DEVICE = [
    Target("saturate", "device", device=_dev_saturate),
    Target("target_guard", "device", device=_dev_guard),
    Target("controller", "device", device=_dev_controller),
    Target("servo_loop", "device", device=_dev_servo),
    Target("live_record", "device", device=_dev_live_record),
]
TARGETS = LOADERS + DEVICE


# ------------------------------------------------------------------------------------ one case
def make_case(seed: int, index: int) -> tuple[Target, bytes | None, bool, np.random.Generator]:
    """The target, file bytes (loaders), whether non-finite was injected and the case's generator."""
    target = TARGETS[index % len(TARGETS)]
    rng = np.random.default_rng([int(seed), int(index)])
    if target.kind != "loader":
        return target, None, False, rng
    data, nonfinite = apply_ops(_seed_text(target), _draw_ops(rng))
    return target, data, nonfinite, rng


_SEEDS: dict[str, str] = {}
_CLEAN: dict[str, bool] = {}


def _seed_text(target: Target) -> str:
    if target.name not in _SEEDS:
        _SEEDS[target.name] = target.seed_text()
    return _SEEDS[target.name]


def run_case(seed: int, index: int, folder: Path) -> dict:
    """Run one case in this process; returns ``{"i", "target", "outcome", "detail"}``."""
    import warnings

    from vishap._core.errors import VishapError

    target, data, _, rng = make_case(seed, index)
    rec = {"i": index, "target": target.name, "outcome": "ok", "detail": ""}
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            if target.kind == "device":
                failure = target.device(rng)
                rec["outcome"], rec["detail"] = ("device_failure", failure) if failure else ("ok", "")
                return rec
            path = folder / f"case{target.suffix}"
            path.write_bytes(data)
            obj = target.load(path)
    except VishapError as exc:
        rec["outcome"] = "refused"
        rec["detail"] = str(exc)[-200:]
        return rec
    except RecursionError:
        rec["outcome"], rec["detail"] = "crash", "RecursionError"
        return rec
    except Exception as exc:  # noqa: BLE001 - counting what escapes is the point
        rec["outcome"] = "crash"
        rec["detail"] = f"{type(exc).__name__}: {' '.join(str(exc).split())[:200]}"
        return rec
    if target.name not in _CLEAN:  # a seed file's own infinities (none today) would not count
        p0 = folder / f"seed{target.suffix}"
        p0.write_text(_seed_text(target))
        _CLEAN[target.name] = not _has_nonfinite(target.load(p0))
    if _file_has_nonfinite(data) or (_CLEAN[target.name] and _has_nonfinite(obj)):
        rec["outcome"] = "accepted_nonfinite"
    return rec


def _plain_loader():
    """A plain SafeLoader that also builds ``!!opencv-matrix`` nodes: the fuzzer's own view of a
    file, independent of the reader under test."""
    import yaml

    class Plain(yaml.SafeLoader):
        pass

    Plain.add_constructor("tag:yaml.org,2002:opencv-matrix", lambda loader, node: loader.construct_mapping(node, deep=True))
    return Plain


def _file_has_nonfinite(data: bytes) -> bool:
    """Whether the file, parsed as plain YAML, holds NaN or inf as a value (a NaN written in a
    comment or inside text does not count)."""
    import yaml

    text = "\n".join("" if ln.startswith("%YAML") else ln for ln in data.decode("utf-8", "replace").splitlines())
    try:
        docs = list(yaml.load_all(text, Loader=_plain_loader()))  # noqa: S506 - a SafeLoader subclass
    except Exception:  # noqa: BLE001 - a file the plain parser refuses holds no value to count
        return False
    return _has_nonfinite(docs)


def _worker(seed: int, start: int, stop: int) -> int:
    with tempfile.TemporaryDirectory(prefix="vishap-fuzz-") as d:
        folder = Path(d)
        for i in range(start, stop):
            print(json.dumps(run_case(seed, i, folder)), flush=True)
    return 0


# ------------------------------------------------------------------------------------ driver
def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--cases", type=int, default=100_000, help="number of cases (default 100000)")
    parser.add_argument("--seed", type=int, default=0, help="seed of every mutation (default 0)")
    parser.add_argument("--jobs", type=int, default=max(1, min(4, os.cpu_count() or 1)),
                        help="child processes running cases (default: up to 4)")
    parser.add_argument("--case-timeout", type=float, default=60.0, metavar="SECONDS",
                        help="a case running longer is a hang: its child is ended (default 60)")
    parser.add_argument("--replay", type=int, default=None, metavar="INDEX", help="run one case here and print it")


def _spawn(seed: int, start: int, stop: int) -> subprocess.Popen:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join([str(_REPO), env.get("PYTHONPATH", "")]).rstrip(os.pathsep)
    return subprocess.Popen([sys.executable, "-m", "vishap.bench.fuzz", "--worker", str(seed), str(start), str(stop)],
                            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True, env=env)


def fuzz(cases: int, seed: int = 0, jobs: int = 1, *, crash_dir: Path | None = None, progress: bool = False,
         case_timeout_s: float = 60.0) -> dict:
    """Run ``cases`` cases in ``jobs`` child processes; returns the record (see the module docstring)."""
    from tqdm import tqdm

    if cases < 1:
        from vishap._core.errors import ConfigError

        raise ConfigError(f"expected at least 1 case, got {cases}", field="--cases")
    jobs = max(1, min(int(jobs), cases))
    bounds = np.linspace(0, cases, jobs + 1).astype(int)
    pending = [(int(a), int(b)) for a, b in zip(bounds, bounds[1:]) if b > a]
    results: dict[int, dict] = {}
    t0 = time.perf_counter()
    # on a terminal a live bar; in a log a line every half minute
    bar = tqdm(total=cases, desc="fuzz", unit="case", disable=not progress, mininterval=0.1 if sys.stderr.isatty() else 30)
    import selectors

    sel = selectors.DefaultSelector()
    running = {}
    hung: dict = {}
    for a, b in pending:
        proc = _spawn(seed, a, b)
        running[proc] = [a, b, a]  # start, stop, next expected index
        sel.register(proc.stdout, selectors.EVENT_READ, proc)
    last = {proc: time.monotonic() for proc in running}
    while running:
        now = time.monotonic()
        for proc in list(running):  # a case that runs on and on is a hang: end that child
            if proc.poll() is None and now - last.get(proc, now) > case_timeout_s:
                hung[proc] = True
                proc.kill()
        for key, _ in sel.select(timeout=1.0):
            proc = key.data
            line = proc.stdout.readline()
            if line:
                last[proc] = time.monotonic()
                try:
                    rec = json.loads(line)
                except json.JSONDecodeError:
                    continue
                results[rec["i"]] = rec
                running[proc][2] = rec["i"] + 1
                bar.update(1)
                continue
            sel.unregister(proc.stdout)
            rc = proc.wait()
            a, b, nxt = running.pop(proc)
            if nxt < b:  # died before finishing: the case it was on crashed the interpreter (or hung)
                target, data, _, _ = make_case(seed, nxt)
                if hung.pop(proc, False):
                    outcome, detail = "hang", f"no answer within {case_timeout_s:g} s"
                else:
                    outcome = "native_crash"
                    detail = f"child process ended with {'signal ' + str(-rc) if rc < 0 else 'code ' + str(rc)}"
                results[nxt] = {"i": nxt, "target": target.name, "outcome": outcome, "detail": detail}
                bar.update(1)
                if crash_dir is not None and data is not None:
                    crash_dir.mkdir(parents=True, exist_ok=True)
                    (crash_dir / f"case{nxt}_{target.name}{target.suffix}").write_bytes(data)
                if nxt + 1 < b:
                    new = _spawn(seed, nxt + 1, b)
                    running[new] = [nxt + 1, b, nxt + 1]
                    last[new] = time.monotonic()
                    sel.register(new.stdout, selectors.EVENT_READ, new)
    bar.close()
    wall = time.perf_counter() - t0
    return summarize(results, cases=cases, seed=seed, wall_s=wall)


_KIND = re.compile(r"/\S+|[-+]?(?:\d[\d.e+-]*|inf|nan)|\[[^\]]*\]|'[^']*'")


def summarize(results: dict[int, dict], *, cases: int, seed: int, wall_s: float) -> dict:
    by = Counter(r["outcome"] for r in results.values())
    per_target: dict[str, Counter] = {}
    examples: dict[str, dict] = {}
    for r in sorted(results.values(), key=lambda r: r["i"]):
        per_target.setdefault(r["target"], Counter())[r["outcome"]] += 1
        if r["outcome"] not in ("ok", "refused"):
            key = f"{r['target']}:{r['outcome']}:{_KIND.sub('#', r['detail'].split(' (')[0])[:80]}"
            examples.setdefault(key, {"case": r["i"], "target": r["target"], "outcome": r["outcome"],
                                      "detail": r["detail"], "count": 0})
            examples[key]["count"] += 1
    return {
        "cases": len(results),
        "crashes": by["crash"],
        "native_crashes": by["native_crash"],
        "accepted_nonfinite": by["accepted_nonfinite"],
        "device_failures": by["device_failure"],
        "hangs": by["hang"],
        "refused": by["refused"],
        "accepted": by["ok"],
        "seed": seed,
        "requested_cases": cases,
        "wall_s": round(wall_s, 2),
        "per_target": {k: dict(v) for k, v in sorted(per_target.items())},
        "findings": sorted(examples.values(), key=lambda e: -e["count"]),
    }


def run(args: argparse.Namespace) -> dict:
    out = Path(args.out)
    if args.replay is not None:
        with tempfile.TemporaryDirectory(prefix="vishap-fuzz-") as d:
            return run_case(args.seed, args.replay, Path(d))
    return fuzz(args.cases, args.seed, args.jobs, crash_dir=out / "crashes",
                progress=not getattr(args, "quiet", False), case_timeout_s=args.case_timeout)


def summary_lines(rec: dict) -> list[str]:
    """The terminal summary of a fuzz record."""
    if "cases" not in rec:
        return [f"case {rec['i']} ({rec['target']}): {rec['outcome']} {rec['detail']}"]
    lines = [f"{rec['cases']} cases in {rec['wall_s']} s: {rec['crashes']} crashes, {rec['native_crashes']} native "
             f"crashes, {rec['hangs']} hangs, {rec['accepted_nonfinite']} accepted NaN/inf, "
             f"{rec['device_failures']} device failures"]
    for f in rec["findings"][:8]:
        lines.append(f"  {f['count']:>6} x {f['target']} {f['outcome']}: {f['detail'][:100]} (replay: --replay {f['case']})")
    return lines


if __name__ == "__main__":  # the child process of :func:`fuzz`
    if len(sys.argv) == 5 and sys.argv[1] == "--worker":
        sys.exit(_worker(int(sys.argv[2]), int(sys.argv[3]), int(sys.argv[4])))
    sys.exit("usage: python -m vishap.bench.fuzz --worker SEED START STOP")
