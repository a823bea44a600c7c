"""The OpenHaptics adapter against a stand-in of pyOpenHaptics that records every call.

The stand-in is a PHANToM whose joint angles the test sets; its scheduler thread runs the adapter's
callback every 0.5 ms as HDAPI's does, reports the stylus position from the same arm geometry in
HDAPI's frame and millimetres, and records every ``set_force``.
"""
from __future__ import annotations

import ctypes
import math
import sys
import threading
import time
import types

import numpy as np
import pytest

from vishap._core.errors import DeviceError
from vishap.robot import kinematics
from vishap.robot.params import DEFAULT

R = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # robot axes in device axes
ORIGIN_ROBOT = np.array([0.215, 0.0, -0.11])  # where the device frame's origin sits in the robot frame (m)
CODES = {"HD_UPDATE_RATE": 0x2600, "HD_NOMINAL_MAX_STIFFNESS": 0x2602, "HD_NOMINAL_MAX_FORCE": 0x2603,
         "HD_NOMINAL_MAX_CONTINUOUS_FORCE": 0x2604, "HD_USABLE_WORKSPACE_DIMENSIONS": 0x2551}


class FakeHD:
    """pyOpenHaptics' hd / hd_define / hd_callback, over a simulated arm."""

    def __init__(self, *, peak=7.9, cont=1.75, k_n_mm=2.31, rate=1000.0, ws_mm=(-80, -60, -40, 80, 60, 40)):
        self.calls: list[tuple] = []
        self.forces: list[tuple] = []
        self.props = {CODES["HD_UPDATE_RATE"]: [rate], CODES["HD_NOMINAL_MAX_FORCE"]: [peak],
                      CODES["HD_NOMINAL_MAX_CONTINUOUS_FORCE"]: [cont],
                      CODES["HD_NOMINAL_MAX_STIFFNESS"]: [k_n_mm], CODES["HD_USABLE_WORKSPACE_DIMENSIONS"]: list(ws_mm)}
        self.q = np.array([0.1, 0.2, -0.1])  # the arm's true joint angles (rad, vishap's convention)
        self.dq = np.zeros(3)  # how far the arm turns in each scheduler frame (rad)
        self.joint_sign = np.ones(3)  # how the device reports them (a wrong mapping: set a -1)
        self.error = False
        self.callbacks = []
        self.running = False
        self._thread = None
        self.lock = threading.Lock()

    # hd ------------------------------------------------------------------------------------------
    def init_device(self, name):
        self.calls.append(("init_device", name))
        return 7

    def get_model(self):
        return "PHANTOM Premium 1.0 (stand-in)"

    def _get_doublev(self, code, dtype):
        self.calls.append(("_get_doublev", code))
        return dtype(*self.props[code])

    def enable_force(self):
        self.calls.append(("enable_force",))

    def start_scheduler(self):
        self.calls.append(("start_scheduler",))
        self.running = True
        self._thread = threading.Thread(target=self._run, daemon=True)
        self._thread.start()

    def stop_scheduler(self):
        self.calls.append(("stop_scheduler",))
        self.running = False
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(1.0)

    def close_device(self, handle):
        self.calls.append(("close_device", handle))

    def get_joints(self):
        with self.lock:
            return (ctypes.c_double * 3)(*(self.q * self.joint_sign))

    def get_transform(self):
        with self.lock:
            p_hd_mm = R.T @ (kinematics.fk(self.q) - ORIGIN_ROBOT) * 1e3
        T = ((ctypes.c_double * 4) * 4)()
        for i in range(3):
            T[i][i] = 1.0
            T[3][i] = p_hd_mm[i]
        T[3][3] = 1.0
        return T

    def set_force(self, F):
        self.forces.append(tuple(float(f) for f in F))

    def get_current_device(self):
        return 7

    def begin_frame(self, handle):
        pass

    def end_frame(self, handle):
        pass

    # hd_callback ---------------------------------------------------------------------------------
    def hd_callback(self, fn):
        def wrapped():
            fn()
            return 0 if self.error else 1  # HD_CALLBACK_DONE on an error, as pyOpenHaptics' wrapper
        return wrapped

    def hdAsyncSheduler(self, callback):
        self.calls.append(("hdAsyncSheduler",))
        self.callbacks.append(callback)

    def _run(self):
        while self.running:
            with self.lock:
                self.q = self.q + self.dq
            self.callbacks = [cb for cb in self.callbacks if cb() == 1]
            time.sleep(0.0005)

    def install(self, monkeypatch):
        pkg = types.ModuleType("pyOpenHaptics")
        hd = types.ModuleType("pyOpenHaptics.hd")
        for name in ("init_device", "get_model", "_get_doublev", "enable_force", "start_scheduler", "stop_scheduler",
                     "close_device", "get_joints", "get_transform", "set_force", "get_current_device",
                     "begin_frame", "end_frame"):
            setattr(hd, name, getattr(self, name))
        define = types.ModuleType("pyOpenHaptics.hd_define")
        for k, v in CODES.items():
            setattr(define, k, v)
        define.HD_INVALID_HANDLE = 0xFFFFFFFF
        cb = types.ModuleType("pyOpenHaptics.hd_callback")
        cb.hd_callback = self.hd_callback
        cb.hdAsyncSheduler = self.hdAsyncSheduler
        for name, mod in (("pyOpenHaptics", pkg), ("pyOpenHaptics.hd", hd), ("pyOpenHaptics.hd_define", define),
                          ("pyOpenHaptics.hd_callback", cb)):
            monkeypatch.setitem(sys.modules, name, mod)
        return self


@pytest.fixture
def fake(monkeypatch):
    f = FakeHD().install(monkeypatch)
    yield f
    f.running = False


@pytest.fixture
def device(fake):
    from vishap.robot.drivers import open_device

    dev = open_device("vishap.robot.drivers.openhaptics:OpenHapticsDevice")
    yield dev
    dev.close()


def _frames(dev, n=3):
    for _ in range(n):
        dev.step()


def test_limits_come_from_the_device_at_start_up(fake, device):
    lim = device.limits
    assert lim.peak_force_n == 7.9 and lim.continuous_force_n == 1.75
    assert lim.max_stiffness_n_m == pytest.approx(2310.0)  # 2.31 N/mm
    assert device.params.peak_force_n == 7.9 and device.params.servo_rate_hz == 1000.0
    # HDAPI's usable workspace (mm, device frame) in the robot frame: x from the device's z, y from x, z from y
    assert lim.workspace_min == pytest.approx(tuple(ORIGIN_ROBOT + [-0.040, -0.080, -0.060]))
    assert lim.workspace_max == pytest.approx(tuple(ORIGIN_ROBOT + [0.040, 0.080, 0.060]))
    assert lim.max_torque_nm == pytest.approx(7.9 * (DEFAULT.l1 + DEFAULT.l2))
    asked = {c[1] for c in fake.calls if c[0] == "_get_doublev"}
    assert set(CODES.values()) <= asked
    # nothing was pushed before start(): every frame so far wrote zero force
    assert fake.forces and all(f == (0.0, 0.0, 0.0) for f in fake.forces)
    assert device.moves_itself is False


def test_units_and_frames(fake, device):
    with fake.lock:
        fake.q = np.array([0.3, 0.1, 0.25])
    _frames(device)
    s = device.read()
    assert np.allclose(s.q, fake.q) and np.allclose(s.p_robot, kinematics.fk(fake.q), atol=1e-12)
    assert np.allclose(device.p_device_robot(), s.p_robot, atol=1e-9)  # mm → m and the frame mapping agree
    device.start()
    device.command_force([1.0, 2.0, 3.0])  # N, robot frame
    _frames(device)
    assert fake.forces[-1] == pytest.approx((2.0, 3.0, 1.0))  # device frame: x = robot y, y = robot z, z = robot x
    # a torque command is the same force through the Jacobian (τ = Jᵀ F)
    tau = kinematics.jacobian(s.q).T @ np.array([-0.5, 0.25, 1.5])
    device.command_torque(tau)
    _frames(device)
    assert fake.forces[-1] == pytest.approx((0.25, 1.5, -0.5), abs=1e-9)


def test_rates_are_the_backward_difference_over_one_frame(fake, device):
    # the arm turns by the same step in every frame: the difference over the last frame is that step
    # however many frames the scheduler ran before the read (a one-off jump is seen only if exactly one did)
    _frames(device)
    with fake.lock:
        fake.dq = np.array([1e-3, 0.0, -2e-3])
    _frames(device, 2)
    w = device.read_scalar()[3:]
    assert w == pytest.approx((1.0, 0.0, -2.0), rel=1e-6)  # rad per 1 ms frame → rad/s


def test_never_more_than_the_peak_force_and_never_nan(fake, device):
    device.start()
    device.command_force([100.0, 0.0, 0.0])
    _frames(device)
    assert math.dist(fake.forces[-1], (0, 0, 0)) == pytest.approx(7.9)
    assert fake.forces[-1] == pytest.approx((0.0, 0.0, 7.9))  # scaled along its direction
    assert device.n_clamped == 1
    F = np.array(fake.forces)
    assert np.all(np.isfinite(F)) and np.all(np.linalg.norm(F, axis=1) <= 7.9 + 1e-9)


@pytest.mark.parametrize("bad", ["nan_force", "inf_torque", "over_torque"])
def test_an_error_lets_go(fake, device, bad):
    device.start()
    device.command_force([0.0, 0.0, 2.0])
    _frames(device)
    assert fake.forces[-1] != (0.0, 0.0, 0.0)
    with pytest.raises(DeviceError, match="let go"):
        if bad == "nan_force":
            device.command_force([float("nan"), 0.0, 0.0])
        elif bad == "inf_torque":
            device.command_torque_scalar(0.0, float("inf"), 0.0)
        else:
            device.command_torque_scalar(0.0, 10 * device.limits.max_torque_nm, 0.0)
    assert fake.forces[-1] == (0.0, 0.0, 0.0)  # the last frame written before the device was disabled
    names = [c[0] for c in fake.calls]
    assert names.count("stop_scheduler") == 1 and names.count("close_device") == 1
    assert all(np.isfinite(fake.forces).ravel())
    with pytest.raises(DeviceError, match="let go"):
        device.step()
    with pytest.raises(DeviceError):
        device.command_force([0.0, 0.0, 1.0])


def test_close_lets_go_once(fake, device):
    device.start()
    device.command_force([0.0, 1.0, 0.0])
    _frames(device)
    device.close()
    assert fake.forces[-1] == (0.0, 0.0, 0.0)
    device.close()
    names = [c[0] for c in fake.calls]
    assert names.index("stop_scheduler") < names.index("close_device")
    assert names.count("close_device") == 1


def test_a_scheduler_error_lets_go(fake, device):
    device.start()
    device.command_force([0.0, 0.0, 1.0])
    _frames(device)
    fake.error = True  # the HDAPI callback wrapper returns HD_CALLBACK_DONE: no more frames
    with pytest.raises(DeviceError, match="no servo frame"):
        _frames(device, 200)
    assert ("close_device", 7) in fake.calls


def test_a_wrong_joint_mapping_is_caught_when_the_arm_moves(fake, device):
    _frames(device)
    with fake.lock:
        fake.joint_sign = np.array([-1.0, 1.0, 1.0])  # the device reports θ1 with the other sign
        fake.q = np.array([0.3, 0.2, -0.1])
    with pytest.raises(DeviceError, match="disagree"):
        _frames(device)
    assert ("close_device", 7) in fake.calls


def test_under_the_servo_loop(fake, device):
    """The controller's commands reach the device as finite forces within the peak (holding a target)."""
    from vishap.robot.controller import Controller
    from vishap.robot.servo import ServoLoop

    loop = ServoLoop(device, Controller(device.params, limits=device.limits))
    device.start()
    target = kinematics.fk(fake.q) + np.array([0.0, 0.0, 0.02])
    for _ in range(50):
        loop.tick(device.time, target)
    F = np.array(fake.forces[-20:])
    assert np.all(np.isfinite(F)) and np.all(np.linalg.norm(F, axis=1) <= 7.9 + 1e-9)
    assert np.any(np.abs(F[:, 1]) > 0.05)  # pushes up (device y) towards the target above


def test_missing_vendor_package_names_it(monkeypatch):
    from vishap.robot.drivers import open_device

    monkeypatch.setitem(sys.modules, "pyOpenHaptics", None)
    monkeypatch.setitem(sys.modules, "pyOpenHaptics.hd", None)
    with pytest.raises(DeviceError, match="pyOpenHaptics.*vishap\\[openhaptics\\]"):
        open_device("vishap.robot.drivers.openhaptics:OpenHapticsDevice")
