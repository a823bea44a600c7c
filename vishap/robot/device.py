"""The haptic-device interface (VisHap §2.1 "haptic device"; CHAI3D's generic device as a model).

A :class:`Device` reads joint state and accepts motor torques or a tip force; the MuJoCo plant
(:class:`vishap.robot.plant.MujocoPlant`, the driver ``sim``) implements it and so does every driver
found by :func:`vishap.robot.drivers.open_device` (docs/devices.md). :class:`DeviceLimits` is the
record of what the hardware can do (peak and continuous force, workspace, joint limits, the
stiffness the servo can render stably), reported once the device is open.

The life cycle follows the haptics SDKs (OpenHaptics HDAPI: ``hdInitDevice`` → ``hdEnable
(HD_FORCE_OUTPUT)`` + ``hdStartScheduler`` → frames → ``hdStopScheduler`` + ``hdDisableDevice``;
Force Dimension: ``dhdOpen`` → ``dhdEnableForce`` → ``dhdClose``): constructing a device opens it
and reads its limits, :meth:`Device.start` enables force output, :meth:`Device.stop` lets go (zero
force, forces disabled) and :meth:`Device.close` stops and releases it. All quantities are SI in the
robot frame; an adapter converts from its SDK's units and frame.

Besides the array methods, a device offers float fast paths (:meth:`Device.read_scalar`,
:meth:`Device.command_torque_scalar`) used by the 1 kHz servo loop; their defaults fall back on the
array methods, so a new driver only has to implement :meth:`read`, :meth:`command_torque`,
:meth:`step` and :attr:`time` (and :meth:`stop` / :meth:`close` when it holds hardware).
"""
from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass

import numpy as np

from vishap._core.errors import DeviceError
from vishap.robot import kinematics
from vishap.robot.params import DEFAULT, PhantomParams

__all__ = ["DeviceLimits", "DeviceState", "Device"]


@dataclass(frozen=True)
class DeviceLimits:
    """What the device can do (SI units, robot frame)."""

    peak_force_n: float
    continuous_force_n: float
    workspace_min: tuple[float, float, float]
    workspace_max: tuple[float, float, float]
    q_min: tuple[float, float, float]
    q_max: tuple[float, float, float]
    #: torque bound per motor (N·m) — the peak force at full reach, a hardware backstop
    max_torque_nm: float
    #: largest virtual stiffness (N/m) inside the measured stable region (``gains.yaml``)
    max_stiffness_n_m: float | None = None

    def as_dict(self) -> dict:
        """The limits as plain JSON-ready values (SI units)."""
        return {k: (list(v) if isinstance(v, tuple) else v) for k, v in self.__dict__.items()}

    @classmethod
    def from_params(cls, params: PhantomParams = DEFAULT, *, max_stiffness_n_m: float | None = None) -> DeviceLimits:
        return cls(
            peak_force_n=params.peak_force_n,
            continuous_force_n=params.continuous_force_n,
            workspace_min=tuple(params.workspace_min),
            workspace_max=tuple(params.workspace_max),
            q_min=tuple(params.q_min),
            q_max=tuple(params.q_max),
            max_torque_nm=params.peak_force_n * (params.l1 + params.l2),
            max_stiffness_n_m=max_stiffness_n_m,
        )


@dataclass(frozen=True)
class DeviceState:
    """One reading: time (s), joint angles (rad) and rates (rad/s), tip position (m) and velocity (m/s)."""

    t: float
    q: np.ndarray
    qd: np.ndarray
    p_robot: np.ndarray
    v_robot: np.ndarray


class Device(ABC):
    """A 3-DOF haptic device commanded by motor torques (θ1, θ2, θ3 as in :mod:`params`).

    Threading: one thread (the servo loop) calls :meth:`read` / :meth:`read_scalar`, the command
    methods and :meth:`step` once per servo period; :meth:`stop` and :meth:`close` may come from
    any thread and must leave the device commanding zero force.
    """

    params: PhantomParams
    limits: DeviceLimits
    #: Capability: ``True`` when the servo loop may drive the device to a pose on its own (the
    #: calibration moves it); ``False`` when a person places it (the calibration prompts).
    moves_itself: bool = True

    @abstractmethod
    def read(self) -> DeviceState:
        """The latest joint state."""

    @abstractmethod
    def command_torque(self, tau) -> None:
        """Apply motor torques ``tau`` (3,) in N·m until the next command. Refuses NaN/inf."""

    @abstractmethod
    def step(self) -> None:
        """Advance one servo period (a simulation steps; a driver waits for its next cycle)."""

    @property
    @abstractmethod
    def time(self) -> float:
        """Device time (s) of the latest reading."""

    # -- life cycle (defaults for a device without hardware behind it) ------------------------
    def start(self) -> None:
        """Enable force output (HDAPI ``hdEnable(HD_FORCE_OUTPUT)``, Force Dimension ``dhdEnableForce``)."""

    def stop(self) -> None:
        """Let go: command zero torque and disable force output; :meth:`start` may follow."""
        self.command_torque_scalar(0.0, 0.0, 0.0)

    def close(self) -> None:
        """:meth:`stop`, then release the device; a second call does nothing."""
        self.stop()

    def __enter__(self):
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.close()

    def describe(self) -> dict:
        """Name, capability and limits (what ``vishap devices`` prints)."""
        return {"class": f"{type(self).__module__}:{type(self).__qualname__}", "moves_itself": bool(self.moves_itself),
                "servo_rate_hz": float(self.params.servo_rate_hz), "limits": self.limits.as_dict()}

    # -- derived and fast paths -------------------------------------------------------------
    def command_force(self, F_robot) -> None:
        """Apply the tip force ``F_robot`` (N, robot frame) through Eq. 6, ``τ = Jᵀ F``."""
        F = np.asarray(F_robot, dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(F)):
            raise DeviceError(f"command_force: refusing a non-finite force {F.tolist()}")
        self.command_torque(kinematics.force_to_torque(self.read().q, F, self.params))

    def read_scalar(self) -> tuple[float, float, float, float, float, float]:
        """(θ1, θ2, θ3, θ̇1, θ̇2, θ̇3) as floats."""
        s = self.read()
        return (float(s.q[0]), float(s.q[1]), float(s.q[2]), float(s.qd[0]), float(s.qd[1]), float(s.qd[2]))

    def command_torque_scalar(self, tau1: float, tau2: float, tau3: float) -> None:
        """:meth:`command_torque` on floats."""
        self.command_torque(np.array([tau1, tau2, tau3]))

    def check_torque(self, tau1: float, tau2: float, tau3: float) -> None:
        """Raise :class:`DeviceError` unless all three torques are finite and within ``max_torque_nm``."""
        lim = self.limits.max_torque_nm
        for i, v in enumerate((tau1, tau2, tau3)):
            if not math.isfinite(v) or abs(v) > lim * (1.0 + 1e-9):
                raise DeviceError(f"motor {i + 1}: refusing torque {v!r} N·m (finite, |τ| ≤ {lim:.3g} expected)")
