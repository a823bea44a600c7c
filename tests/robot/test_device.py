"""The Device base: life cycle defaults (start, stop lets go, close, context manager) and describe()."""
from __future__ import annotations

import json

import numpy as np
import pytest

from vishap._core.errors import DeviceError
from vishap.robot.device import Device, DeviceLimits, DeviceState
from vishap.robot.params import DEFAULT


class Recorder(Device):
    """The four methods a driver must implement; records every torque command."""

    def __init__(self):
        self.params = DEFAULT
        self.limits = DeviceLimits.from_params(DEFAULT, max_stiffness_n_m=3500.0)
        self.sent = []
        self._t = 0.0

    @property
    def time(self):
        return self._t

    def read(self):
        return DeviceState(self._t, np.zeros(3), np.zeros(3), np.zeros(3), np.zeros(3))

    def command_torque(self, tau):
        self.sent.append(tuple(np.asarray(tau, dtype=float)))

    def step(self):
        self._t += self.params.dt


def test_context_manager_lets_go_on_exit_even_after_an_error():
    dev = Recorder()
    with pytest.raises(RuntimeError), dev:
        dev.command_torque_scalar(0.1, -0.2, 0.3)
        raise RuntimeError("the loop failed")
    assert dev.sent == [(0.1, -0.2, 0.3), (0.0, 0.0, 0.0)]  # the last command is zero torque


def test_describe_is_json_with_the_limits_and_capability():
    dev = Recorder()
    d = json.loads(json.dumps(dev.describe()))
    assert d["class"].endswith(":Recorder") and d["moves_itself"] is True and d["servo_rate_hz"] == 1000.0
    assert d["limits"]["peak_force_n"] == DEFAULT.peak_force_n and d["limits"]["max_stiffness_n_m"] == 3500.0
    assert d["limits"]["workspace_min"] == list(DEFAULT.workspace_min)


def test_check_torque_names_the_motor():
    dev = Recorder()
    lim = dev.limits.max_torque_nm
    dev.check_torque(lim, -lim, 0.0)
    with pytest.raises(DeviceError, match="motor 2"):
        dev.check_torque(0.0, lim * 1.01, 0.0)
    with pytest.raises(DeviceError, match="motor 3"):
        dev.check_torque(0.0, 0.0, float("nan"))
    with pytest.raises(DeviceError, match="non-finite"):
        dev.command_force([0.0, float("inf"), 0.0])
    assert dev.sent == []
