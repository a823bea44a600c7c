"""The simulated PHANToM: a torque-driven MuJoCo model stepped at the servo rate (VisHap §2.3).

:class:`MujocoPlant` is a :class:`~vishap.robot.device.Device`. Each :meth:`MujocoPlant.step`
advances one servo period (1 ms) in ``substeps`` physics steps with the last command held (a
zero-order hold, as a real amplifier does). Optional ``delay_ticks`` delays every command by whole
servo periods (transport delay, for the stability study). An external tip force (the finger) can
be applied with :meth:`MujocoPlant.apply_tip_force`.
"""
from __future__ import annotations

from collections import deque

import mujoco
import numpy as np

from vishap._core.errors import DeviceError, ShapeError
from vishap.robot import kinematics
from vishap.robot.device import Device, DeviceLimits, DeviceState
from vishap.robot.mjcf import PassiveObject, build_mjcf
from vishap.robot.params import DEFAULT, PhantomParams

__all__ = ["MujocoPlant"]


class MujocoPlant(Device):
    """PHANToM arm in MuJoCo, gravity on, carrying ``passive_object`` at the tip.

    Parameters
    ----------
    params:
        Arm constants; ``params.m_tip`` is replaced by the passive object's mass.
    passive_object:
        The object at the tip (``None`` for a bare tip).
    substeps:
        Physics steps per servo period (≥ 1). Use several (e.g. 10) when studying stiff walls:
        one step per period can hide instability.
    delay_ticks:
        Whole servo periods by which each command is delayed before it reaches the motors.
    q0:
        Initial joint angles (rad); home ``(0, 0, 0)`` by default.
    sensor:
        ``"exact"`` reads MuJoCo's joint angles and rates; ``"encoder"`` quantises the angles to
        ``encoder_resolution_rad`` and estimates rates by the backward difference over one servo
        period, as a real PHANToM driver does.
    """

    def __init__(
        self,
        params: PhantomParams = DEFAULT,
        *,
        passive_object: PassiveObject | None = None,
        substeps: int = 1,
        delay_ticks: int = 0,
        q0=None,
        max_stiffness_n_m: float | None = None,
        sensor: str = "exact",
        encoder_resolution_rad: float = 1.5e-4,
    ):
        m_tip = 0.0 if passive_object is None else passive_object.mass_kg
        self.params = params.with_tip_mass(m_tip)
        self.passive_object = passive_object
        self.substeps = int(substeps)
        self.model = mujoco.MjModel.from_xml_string(
            build_mjcf(self.params, substeps=self.substeps, passive_object=passive_object)
        )
        self.data = mujoco.MjData(self.model)
        self.limits = DeviceLimits.from_params(self.params, max_stiffness_n_m=max_stiffness_n_m)
        self.dt = self.params.dt
        lim = self.limits.max_torque_nm
        self.model.actuator_ctrlrange[:] = (-lim, lim)
        self.model.actuator_ctrllimited[:] = 1
        # cached views into mjData: no attribute look-ups on the hot path
        self._qpos = self.data.qpos
        self._qvel = self.data.qvel
        self._ctrl = self.data.ctrl
        self._qfrc_applied = self.data.qfrc_applied
        self._m = self.model
        self._d = self.data
        self._mj_step = mujoco.mj_step
        self._site_tip = mujoco.mj_name2id(self.model, mujoco.mjtObj.mjOBJ_SITE, "tip")
        if delay_ticks < 0:
            raise ValueError(f"delay_ticks: expected ≥ 0, got {delay_ticks!r}")
        self.delay_ticks = int(delay_ticks)
        self._pending: deque | None = deque([(0.0, 0.0, 0.0)] * self.delay_ticks) if self.delay_ticks else None
        if sensor not in ("exact", "encoder"):
            raise ValueError(f"sensor: expected 'exact' or 'encoder', got {sensor!r}")
        self.sensor = sensor
        self._res = float(encoder_resolution_rad)
        if sensor == "encoder" and not self._res > 0:
            raise ValueError(f"encoder_resolution_rad: expected > 0, got {encoder_resolution_rad!r}")
        self._enc = None  # (θ1, θ2, θ3, θ̇1, θ̇2, θ̇3) of the encoder model
        self._t = 0.0
        self.reset(q0)

    # -- Device --------------------------------------------------------------------------------
    @property
    def time(self) -> float:
        return self._t

    def reset(self, q=None, *, t: float = 0.0) -> None:
        """Put the arm at rest at joint angles ``q`` (rad, default home) and device time ``t``."""
        q = np.zeros(3) if q is None else np.asarray(q, dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(q)):
            raise ShapeError(f"q: expected finite joint angles, got {q.tolist()}")
        mujoco.mj_resetData(self.model, self.data)
        self._qpos[:] = (q[0], q[1], q[2] - q[1])
        self._qvel[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self._t = float(t)
        if self.sensor == "encoder":
            self._enc = self._encoder_angles() + (0.0, 0.0, 0.0)
        if self._pending is not None:
            self._pending = deque([(0.0, 0.0, 0.0)] * self.delay_ticks)

    def read(self) -> DeviceState:
        t1, t2, t3, w1, w2, w3 = self.read_scalar()
        q = np.array([t1, t2, t3])
        qd = np.array([w1, w2, w3])
        return DeviceState(self._t, q, qd, kinematics.fk(q, self.params), kinematics.jacobian(q, self.params) @ qd)

    def read_scalar(self) -> tuple[float, float, float, float, float, float]:
        if self._enc is not None:
            return self._enc
        a, b, c = self._qpos.tolist()
        wa, wb, wc = self._qvel.tolist()
        return (a, b, b + c, wa, wb, wb + wc)

    def _encoder_angles(self) -> tuple[float, float, float]:
        a, b, c = self._qpos.tolist()
        r = self._res
        return (round(a / r) * r, round(b / r) * r, round((b + c) / r) * r)

    def command_torque(self, tau) -> None:
        tau = np.asarray(tau, dtype=np.float64).reshape(3)
        self.command_torque_scalar(float(tau[0]), float(tau[1]), float(tau[2]))

    def command_torque_scalar(self, tau1: float, tau2: float, tau3: float) -> None:
        # the one check every command passes: finite and within the motor bound
        lim = self.limits.max_torque_nm
        if not (-lim <= tau1 <= lim and -lim <= tau2 <= lim and -lim <= tau3 <= lim):
            self.check_torque(tau1, tau2, tau3)  # raises DeviceError naming the motor
        if self._pending is not None:
            self._pending.append((tau1, tau2, tau3))
            tau1, tau2, tau3 = self._pending.popleft()
        ctrl = self._ctrl
        ctrl[0] = tau1
        ctrl[1] = tau2
        ctrl[2] = tau3

    def step(self) -> None:
        self._mj_step(self._m, self._d, self.substeps)
        self._t += self.dt
        if self._enc is not None:
            e = self._enc
            a, b, c = self._encoder_angles()
            k = 1.0 / self.dt
            self._enc = (a, b, c, (a - e[0]) * k, (b - e[1]) * k, (c - e[2]) * k)

    # -- simulation extras ----------------------------------------------------------------------
    def apply_tip_force(self, F_robot) -> None:
        """Apply an external force (N, robot frame) at the tip until changed (the finger's push).

        Evaluated through the tip Jacobian at the current configuration: ``qfrc = Eᵀ Jᵀ F``.
        """
        F = np.asarray(F_robot, dtype=np.float64).reshape(3)
        if not np.all(np.isfinite(F)):
            raise DeviceError(f"apply_tip_force: non-finite force {F.tolist()}")
        a, b, c = self._qpos.tolist()
        t1, t2, t3 = a, b, b + c
        tau = kinematics.jacobian((t1, t2, t3), self.params).T @ F
        self._qfrc_applied[:] = (tau[0], tau[1] + tau[2], tau[2])

    def tip_position(self) -> np.ndarray:
        """Tip site position from MuJoCo (m, robot frame) — an independent check of :func:`fk`."""
        return self.data.site_xpos[self._site_tip].copy()

    def check_state(self) -> None:
        """Raise :class:`DeviceError` if the simulation diverged (non-finite state)."""
        if not (np.all(np.isfinite(self._qpos)) and np.all(np.isfinite(self._qvel))):
            raise DeviceError(f"simulation diverged at t={self._t:.4f} s (non-finite joint state)")

    def __repr__(self) -> str:
        return (
            f"MujocoPlant(m_tip={self.params.m_tip} kg, substeps={self.substeps}, "
            f"delay_ticks={self.delay_ticks}, sensor={self.sensor!r})"
        )

