"""The servo object a live run puts in its real-time process: guard → servo loop → device.

Each 1 ms step reads the newest target record published by the world at vision rate,
``[x, y, z, made_at, confidence, calibrated]`` (robot frame, metres, seconds), lets the
:class:`~vishap.runtime.safety.TargetGuard` decide whether to track, hold or retreat, and runs one
:class:`~vishap.robot.servo.ServoLoop` tick on the device. It returns the state record
``[t, px, py, pz, action, fault]`` (a view reused every step; copy to keep; action: 0 track, 1 hold, 2 retreat; fault: index into
``FAULTS`` + 1, 0 for none) for the other loops to read.
"""
from __future__ import annotations

import numpy as np

from vishap.robot.controller import Controller
from vishap.robot.kinematics import tip_state_scalar
from vishap.robot.params import DEFAULT, WORKSPACE_MAX, WORKSPACE_MIN
from vishap.robot.plant import MujocoPlant
from vishap.robot.servo import ServoLoop
from vishap.robot.travel import TravelLimiter
from vishap.runtime.safety import Fault, TargetGuard

__all__ = ["TARGET_SIZE", "STATE_SIZE", "ACTIONS", "FAULTS", "DeviceServo", "make_sim_device_servo", "target_record"]

TARGET_SIZE = 6
STATE_SIZE = 6
ACTIONS = ("track", "hold", "retreat")
FAULTS = tuple(f.value for f in Fault)
#: Where the arm waits when it must get out of the way: high above the objects' plane.
RETREAT_POINT = (0.20, 0.0, -0.05)


def target_record(X_d, made_at: float, confidence: float, calibrated: bool = True) -> np.ndarray:
    """Pack a world output for the servo's mailbox."""
    x = np.asarray(X_d, dtype=float).reshape(3)
    return np.array([x[0], x[1], x[2], made_at, confidence, 1.0 if calibrated else 0.0])


class DeviceServo:
    """Guarded servo over any :class:`~vishap.robot.device.Device`."""

    def __init__(self, device, controller: Controller, *, policy: str = "hold", guard: TargetGuard | None = None,
                 travel: TravelLimiter | None = None):
        self.loop = ServoLoop(device, controller, policy=policy, travel=travel)
        self.guard = guard or TargetGuard(WORKSPACE_MIN, WORKSPACE_MAX, RETREAT_POINT)
        self._out = np.zeros(STATE_SIZE)
        self._action_code = {a: i for i, a in enumerate(ACTIONS)}
        self._fault_code = {f: i + 1 for i, f in enumerate(Fault)}
        self._read = device.read_scalar
        self._l1, self._l2 = device.params.l1, device.params.l2

    def step(self, t: float, record) -> np.ndarray:
        x, y, z, made_at, conf, calibrated = record.tolist() if hasattr(record, "tolist") else record
        out = self._out
        if made_at == 0.0 and conf == 0.0:  # nothing published yet: hold where the arm is
            self.loop.tick(t, None)
            out[4], out[5] = 1.0, 0.0
        else:
            gx, gy, gz, action, fault = self.guard.decide_scalar(t, x, y, z, made_at, conf, calibrated > 0.5)
            self.loop.tick(t, (gx, gy, gz))
            out[4] = self._action_code[action]
            out[5] = 0.0 if fault is None else self._fault_code[fault]
        out[0] = t
        # tip from the device's own joint readings (any Device, not only the MuJoCo plant)
        out[1:4] = tip_state_scalar(*self._read(), self._l1, self._l2)[:3]
        return out


def make_sim_device_servo(policy: str = "hold") -> DeviceServo:
    """A guarded servo over the MuJoCo PHANToM with default gains (picklable factory for live runs)."""
    plant = MujocoPlant(DEFAULT)
    return DeviceServo(plant, Controller(DEFAULT), policy=policy, travel=TravelLimiter())
