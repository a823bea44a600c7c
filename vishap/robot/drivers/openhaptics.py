"""OpenHaptics devices (PHANToM Premium, Touch) through pyOpenHaptics: the driver ``openhaptics``.

pyOpenHaptics (``pip install 'vishap[openhaptics]'``, needs 3D Systems' OpenHaptics and the device
driver, ``libHD``) wraps HDAPI with ctypes. HDAPI runs its own servo thread (the scheduler, 1 kHz)
and allows device state to be read and forces set only inside a scheduler callback, between
``hdBeginFrame`` and ``hdEndFrame``. This adapter therefore schedules one callback that, each
frame, copies the joint angles and the stylus position out and writes the newest force command in;
the vishap servo loop runs in its own thread and meets it through :meth:`step` (wait for the next
frame). Units and frames are converted here and nowhere else:

=============================  ==========================  ======================================
HDAPI (pyOpenHaptics)          unit / frame                vishap
=============================  ==========================  ======================================
``get_joints()``               rad, device joint order     ``q`` = ``joint_sign · q_hd + joint_offset_rad``
``get_transform()`` [3][0:3]   mm, device frame            ``p_robot`` check (m, robot frame)
``set_force(F)``               N, device frame             ``R_robot_hd.T @ F_robot``
HD_NOMINAL_MAX_FORCE           N                           ``limits.peak_force_n``
HD_NOMINAL_MAX_CONTINUOUS_…    N                           ``limits.continuous_force_n``
HD_NOMINAL_MAX_STIFFNESS       N/mm                        ``limits.max_stiffness_n_m`` (× 1000)
HD_USABLE_WORKSPACE_DIMENSIONS mm, min xyz then max xyz    ``limits.workspace_min/max`` (robot frame)
HD_UPDATE_RATE                 Hz                          ``params.servo_rate_hz``
=============================  ==========================  ======================================

The device frame (OpenHaptics: +x to the user's right, +y up, +z towards the user, origin near the
workspace centre) maps to the robot frame (+x from the base towards the user, +z up) by
``R_robot_hd``; the origin offset is measured at start-up from the first frame (forward kinematics
of the joints against the stylus position). From then on every frame checks that the two still
agree within ``kinematics_tolerance_m``: a wrong joint sign or offset, or an arm whose lengths are
not ``params``, is caught as soon as the arm moves and the device lets go.

Safety: commands are motor torques (the servo loop's) turned into a tip force through the arm's
Jacobian (``F = J⁻ᵀ τ``, Eq. 6); a non-finite torque or force is refused, a force above the
device's peak force is scaled down to it along its direction, and every error (a refused command,
a missed frame, the kinematics check, an HDAPI error that stops the scheduler) *lets go*: zero
force, scheduler stopped, device disabled, then :class:`DeviceError`.
"""
from __future__ import annotations

import ctypes
import importlib
import math
import threading
from dataclasses import replace

import numpy as np

from vishap._core.errors import DeviceError
from vishap.robot.device import Device, DeviceLimits, DeviceState
from vishap.robot.kinematics import jacobian, tip_state_scalar, torque_to_force_scalar
from vishap.robot.params import DEFAULT, PhantomParams

__all__ = ["OpenHapticsDevice", "R_ROBOT_HD"]

#: Robot axes in device axes: robot x = device z (towards the user), y = device x, z = device y (up).
R_ROBOT_HD = ((0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0))
_MM = 1e-3


def _vendor():
    """pyOpenHaptics' modules (hd, hd_define, hd_callback), or a DeviceError saying how to get them."""
    try:
        return tuple(importlib.import_module(f"pyOpenHaptics.{m}") for m in ("hd", "hd_define", "hd_callback"))
    except ImportError as exc:
        raise DeviceError(f"openhaptics: pyOpenHaptics cannot be imported ({exc}); install it with "
                          f"pip install 'vishap[openhaptics]' and 3D Systems' OpenHaptics (libHD)") from None
    except OSError as exc:  # the wrapper loads libHD at import
        raise DeviceError(f"openhaptics: OpenHaptics' libHD cannot be loaded ({exc})") from None


class OpenHapticsDevice(Device):
    """A PHANToM-class OpenHaptics device as a vishap :class:`Device` (see the module docstring).

    Parameters
    ----------
    device_name:
        HDAPI device name (``"Default Device"`` or one configured in Phantom Configuration).
    params:
        Arm geometry and masses (the PHANToM Premium 1.0 by default); the force limits and the
        servo rate are replaced by what the device reports.
    R_robot_hd, joint_sign, joint_offset_rad:
        Frame and joint mapping from HDAPI's conventions to :mod:`vishap.robot.params`' (checked
        against the device's own kinematics every frame, see ``kinematics_tolerance_m``).
    moves_itself:
        Whether calibration may drive the arm to its poses (``False``: the user places the stylus).
    frame_timeout_s:
        How long :meth:`step` waits for the next scheduler frame before letting go.
    """

    def __init__(self, device_name: str = "Default Device", *, params: PhantomParams = DEFAULT,
                 R_robot_hd=R_ROBOT_HD, joint_sign=(1.0, 1.0, 1.0), joint_offset_rad=(0.0, 0.0, 0.0),
                 kinematics_tolerance_m: float = 0.005, moves_itself: bool = False, frame_timeout_s: float = 0.05):
        self._hd, self._def, self._cb = _vendor()
        self.R_robot_hd = np.asarray(R_robot_hd, dtype=np.float64).reshape(3, 3)
        if not np.allclose(self.R_robot_hd @ self.R_robot_hd.T, np.eye(3), atol=1e-9) or np.linalg.det(self.R_robot_hd) < 0:
            raise DeviceError(f"openhaptics: R_robot_hd must be a proper rotation, got {self.R_robot_hd.tolist()}")
        self._sign = tuple(float(s) for s in joint_sign)
        self._offset = tuple(float(o) for o in joint_offset_rad)
        self.kinematics_tolerance_m = float(kinematics_tolerance_m)
        self.moves_itself = bool(moves_itself)
        self.frame_timeout_s = float(frame_timeout_s)
        self._lock = threading.Condition()
        self._frames = 0  # scheduler frames completed
        self._seen = 0  # frames the servo loop has stepped to
        self._q_hd = (0.0, 0.0, 0.0)
        self._q_hd_prev = None
        self._p_hd_mm = (0.0, 0.0, 0.0)
        self._F_hd = (0.0, 0.0, 0.0)  # the force the next frame writes (N, device frame)
        self._armed = False  # force output allowed (between start and stop)
        self._closed = False
        self._fault: str | None = None
        self.n_clamped = 0  # commands scaled down to the peak force
        self._t = 0.0
        self._origin_robot = None

        hd = self._hd
        handle = hd.init_device(device_name)
        if handle is None or handle == self._def.HD_INVALID_HANDLE:
            raise DeviceError(f"openhaptics: cannot initialise device {device_name!r} (is it connected and configured?)")
        self._handle = handle
        self.device_name = device_name
        try:
            self.model = str(hd.get_model())
            rate = self._get(self._def.HD_UPDATE_RATE, 1)[0]
            peak = self._get(self._def.HD_NOMINAL_MAX_FORCE, 1)[0]
            cont = self._get(self._def.HD_NOMINAL_MAX_CONTINUOUS_FORCE, 1)[0]
            k_n_mm = self._get(self._def.HD_NOMINAL_MAX_STIFFNESS, 1)[0]
            ws_mm = self._get(self._def.HD_USABLE_WORKSPACE_DIMENSIONS, 6)
            for name, v in (("update rate", rate), ("peak force", peak), ("continuous force", cont),
                            ("stiffness", k_n_mm)):
                if not (math.isfinite(v) and v > 0):
                    raise DeviceError(f"openhaptics: device {device_name!r} reports a {name} of {v!r}")
            if cont > peak:
                raise DeviceError(f"openhaptics: continuous force {cont} N above the peak force {peak} N")
            self.params = replace(params, peak_force_n=peak, continuous_force_n=cont, servo_rate_hz=rate)
            self._callback = self._cb.hd_callback(self._frame)  # keep a reference: ctypes calls it
            self._cb.hdAsyncSheduler(self._callback)
            hd.enable_force()
            hd.start_scheduler()
            self._wait_frames(2, 1.0)  # joints and position, and one earlier reading for the rates
            q = self._q_locked()
            with self._lock:
                p_hd = np.asarray(self._p_hd_mm) * _MM
            p_fk = np.array(tip_state_scalar(*q, 0.0, 0.0, 0.0, self.params.l1, self.params.l2)[:3])
            self._origin_robot = p_fk - self.R_robot_hd @ p_hd
            corners = np.array([[ws_mm[i if (c >> k) & 1 == 0 else i + 3] for k, i in enumerate(range(3))]
                                for c in range(8)]) * _MM
            ws_robot = corners @ self.R_robot_hd.T + self._origin_robot
            self.limits = DeviceLimits(
                peak_force_n=peak, continuous_force_n=cont,
                workspace_min=tuple(ws_robot.min(axis=0).tolist()), workspace_max=tuple(ws_robot.max(axis=0).tolist()),
                q_min=tuple(self.params.q_min), q_max=tuple(self.params.q_max),
                max_torque_nm=peak * (self.params.l1 + self.params.l2), max_stiffness_n_m=k_n_mm * 1e3)
        except BaseException:
            self.close()
            raise

    # -- HDAPI side (the scheduler thread) ------------------------------------------------------
    def _get(self, code: int, n: int) -> list[float]:
        """``hdGetDoublev(code)`` for ``n`` doubles (pyOpenHaptics has public getters only for state)."""
        return list(self._hd._get_doublev(code, ctypes.c_double * n))

    def _frame(self) -> None:
        """One scheduler frame (inside hdBeginFrame/hdEndFrame): state out, force in."""
        hd = self._hd
        j = hd.get_joints()
        T = hd.get_transform()
        with self._lock:
            self._q_hd_prev = self._q_hd if self._frames else None
            self._q_hd = (float(j[0]), float(j[1]), float(j[2]))
            self._p_hd_mm = (float(T[3][0]), float(T[3][1]), float(T[3][2]))
            F = self._F_hd if self._armed and self._fault is None else (0.0, 0.0, 0.0)
            self._frames += 1
            self._lock.notify_all()
        hd.set_force(list(F))

    # -- vishap side (the servo thread) ---------------------------------------------------------
    def _wait_frames(self, count: int, timeout_s: float) -> None:
        """Wait until the scheduler has completed ``count`` frames in all; let go after ``timeout_s``."""
        with self._lock:
            ok = self._lock.wait_for(lambda: self._frames >= count, timeout=timeout_s)
            self._seen = self._frames
        if not ok:
            self._let_go(f"no servo frame from the HD scheduler within {timeout_s * 1e3:.0f} ms")

    def _q_locked(self) -> tuple[float, float, float]:
        with self._lock:
            q = self._q_hd
        s, o = self._sign, self._offset
        return (s[0] * q[0] + o[0], s[1] * q[1] + o[1], s[2] * q[2] + o[2])

    def _let_go(self, reason: str):
        """Zero force, scheduler stopped, device disabled; then raise :class:`DeviceError`."""
        with self._lock:
            if self._fault is None:
                self._fault = reason
        self.close()
        raise DeviceError(f"openhaptics {self.device_name!r}: {reason}; the device let go (zero force, disabled)")

    @property
    def time(self) -> float:
        return self._t

    def read_scalar(self) -> tuple[float, float, float, float, float, float]:
        s, o = self._sign, self._offset
        with self._lock:
            q, qp = self._q_hd, self._q_hd_prev
        t = (s[0] * q[0] + o[0], s[1] * q[1] + o[1], s[2] * q[2] + o[2])
        if qp is None:
            return (*t, 0.0, 0.0, 0.0)
        k = self.params.servo_rate_hz  # backward difference over one frame, as the MuJoCo plant's encoder model
        return (*t, s[0] * (q[0] - qp[0]) * k, s[1] * (q[1] - qp[1]) * k, s[2] * (q[2] - qp[2]) * k)

    def read(self) -> DeviceState:
        t1, t2, t3, w1, w2, w3 = self.read_scalar()
        px, py, pz, vx, vy, vz = tip_state_scalar(t1, t2, t3, w1, w2, w3, self.params.l1, self.params.l2)
        return DeviceState(self._t, np.array([t1, t2, t3]), np.array([w1, w2, w3]), np.array([px, py, pz]),
                           np.array([vx, vy, vz]))

    def p_device_robot(self) -> np.ndarray:
        """The stylus position HDAPI reports, in the robot frame (m): the check on the joint mapping."""
        with self._lock:
            p = np.asarray(self._p_hd_mm) * _MM
        return self.R_robot_hd @ p + self._origin_robot

    def command_torque(self, tau) -> None:
        tau = np.asarray(tau, dtype=np.float64).reshape(3)
        self.command_torque_scalar(float(tau[0]), float(tau[1]), float(tau[2]))

    def command_torque_scalar(self, tau1: float, tau2: float, tau3: float) -> None:
        try:
            self.check_torque(tau1, tau2, tau3)
        except DeviceError as exc:
            self._let_go(str(exc))
        t1, t2, t3 = self._q_locked()
        F = torque_to_force_scalar(t1, t2, t3, tau1, tau2, tau3, self.params.l1, self.params.l2)
        if F is None:
            if tau1 == tau2 == tau3 == 0.0:
                F = (0.0, 0.0, 0.0)
            else:
                self._let_go(f"torque {(tau1, tau2, tau3)} N·m at a singular configuration {(t1, t2, t3)}")
        self._set_force_robot(F)

    def command_force(self, F_robot) -> None:
        F = np.asarray(F_robot, dtype=np.float64).reshape(3)
        self._set_force_robot((float(F[0]), float(F[1]), float(F[2])))

    def _set_force_robot(self, F) -> None:
        fx, fy, fz = F
        if not (math.isfinite(fx) and math.isfinite(fy) and math.isfinite(fz)):
            self._let_go(f"refusing a non-finite force {[fx, fy, fz]} N")
        n = math.sqrt(fx * fx + fy * fy + fz * fz)
        peak = self.limits.peak_force_n
        if n > peak:
            s = peak / n
            fx, fy, fz = fx * s, fy * s, fz * s
            self.n_clamped += 1
        R = self.R_robot_hd  # device frame = Rᵀ · robot frame
        F_hd = (R[0, 0] * fx + R[1, 0] * fy + R[2, 0] * fz, R[0, 1] * fx + R[1, 1] * fy + R[2, 1] * fz,
                R[0, 2] * fx + R[1, 2] * fy + R[2, 2] * fz)
        with self._lock:
            if self._fault is not None or self._closed:
                raise DeviceError(f"openhaptics {self.device_name!r}: the device has let go ({self._fault or 'closed'})")
            self._F_hd = F_hd

    def step(self) -> None:
        """Wait for the next scheduler frame, then check the joint mapping against the stylus position."""
        if self._fault is not None or self._closed:
            raise DeviceError(f"openhaptics {self.device_name!r}: the device has let go ({self._fault or 'closed'})")
        self._wait_frames(self._seen + 1, self.frame_timeout_s)  # at once when frames were missed: catch up
        self._t = self._seen / self.params.servo_rate_hz
        q = self._q_locked()
        p_fk = tip_state_scalar(*q, 0.0, 0.0, 0.0, self.params.l1, self.params.l2)[:3]
        err = float(np.linalg.norm(np.asarray(p_fk) - self.p_device_robot()))
        if err > self.kinematics_tolerance_m:
            self._let_go(f"the joints (forward kinematics) and the stylus position disagree by {err * 1e3:.1f} mm "
                         f"(> {self.kinematics_tolerance_m * 1e3:.1f} mm): wrong joint_sign/joint_offset_rad or arm "
                         f"lengths")

    def jacobian(self) -> np.ndarray:
        """The tip Jacobian (m/rad) at the current joints."""
        return jacobian(self._q_locked(), self.params)

    # -- life cycle ---------------------------------------------------------------------------
    def start(self) -> None:
        """Allow force output (the frames write zero force until then)."""
        if self._fault is not None or self._closed:
            raise DeviceError(f"openhaptics {self.device_name!r}: the device has let go ({self._fault or 'closed'})")
        with self._lock:
            self._F_hd = (0.0, 0.0, 0.0)
            self._armed = True

    def stop(self) -> None:
        """Zero force from the next frame on; waits for that frame (while the scheduler runs)."""
        with self._lock:
            self._armed = False
            self._F_hd = (0.0, 0.0, 0.0)
            running = not self._closed and getattr(self, "_callback", None) is not None
            target = self._frames + 1
            if running:
                self._lock.wait_for(lambda: self._frames >= target, timeout=self.frame_timeout_s)

    def close(self) -> None:
        """Let go (zero force), stop the scheduler and disable the device; idempotent."""
        if self._closed:
            return
        try:
            self.stop()
            if getattr(self, "_callback", None) is not None:
                self._hd.stop_scheduler()
        finally:
            self._closed = True
            if getattr(self, "_handle", None) is not None:
                self._hd.close_device(self._handle)

    def describe(self) -> dict:
        return {**super().describe(), "model": getattr(self, "model", ""), "device_name": self.device_name}

    def __repr__(self) -> str:
        return f"OpenHapticsDevice({self.device_name!r}, model={getattr(self, 'model', '?')!r})"
