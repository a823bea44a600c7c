"""The simulated PHANToM: a torque-driven MuJoCo model stepped at the servo rate (VisHap §2.3).

:class:`MujocoPlant` is a :class:`~vishap.robot.device.Device`. Each :meth:`MujocoPlant.step`
advances one servo period (1 ms) in ``substeps`` physics steps with the last command held (a
zero-order hold, as a real amplifier does). Optional ``delay_ticks`` delays every command by whole
servo periods (transport delay, for the stability study); ``jitter_s`` (measured servo tick
durations, s) delays each command by one of them drawn at random, down to a physics substep — the
servo's measured jitter as a delay. Each motor's amplifier saturates at its peak torque
(``params.motor_peak_torque_nm``, the current limit); joints carry Coulomb friction
(``params.coulomb_friction_n`` at the tip). An external tip force (the finger) can be applied with
:meth:`MujocoPlant.apply_tip_force`.
"""
from __future__ import annotations

import math
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
        encoder_resolution_rad: float | None = None,
        jitter_s=None,
        seed: int = 0,
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
        self._res = float(params.encoder_resolution_rad if encoder_resolution_rad is None else encoder_resolution_rad)
        if sensor == "encoder" and not self._res > 0:
            raise ValueError(f"encoder_resolution_rad: expected > 0, got {encoder_resolution_rad!r}")
        self._enc = None  # (θ1, θ2, θ3, θ̇1, θ̇2, θ̇3) of the encoder model
        self._amp = tuple(float(v) for v in self.params.motor_peak_torque_nm)
        self._crank_g = float(self.params.crank_gravity_nm)  # the crank's gravity, applied each period
        self._tip_qfrc = (0.0, 0.0, 0.0)
        self.n_amp_saturated = 0
        self._jitter = None
        if jitter_s is not None:
            j = np.asarray(jitter_s, dtype=np.float64).ravel()
            if j.size == 0 or not np.all(np.isfinite(j)) or np.any(j < 0):
                raise ValueError(f"jitter_s: expected finite delays ≥ 0 s, got {j.size} values")
            self._jitter = j
            self._rng = np.random.default_rng(seed)
        self._late: deque = deque()  # (time the command reaches the motors, τ) with jitter
        self._t_last_apply = 0.0
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
        self._tip_qfrc = (0.0, 0.0, 0.0)
        self._qpos[:] = (q[0], q[1], q[2] - q[1])
        self._qvel[:] = 0.0
        mujoco.mj_forward(self.model, self.data)
        self._t = float(t)
        if self.sensor == "encoder":
            self._enc = self._encoder_angles() + (0.0, 0.0, 0.0)
        if self._pending is not None:
            self._pending = deque([(0.0, 0.0, 0.0)] * self.delay_ticks)
        self._late.clear()
        self._t_last_apply = self._t

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
        a1, a2, a3 = self._amp  # the amplifiers' current limits
        if tau1 > a1 or tau1 < -a1 or tau2 > a2 or tau2 < -a2 or tau3 > a3 or tau3 < -a3:
            self.n_amp_saturated += 1
            tau1, tau2, tau3 = min(max(tau1, -a1), a1), min(max(tau2, -a2), a2), min(max(tau3, -a3), a3)
        if self._jitter is not None:  # the command reaches the motors once the tick that made it is over
            d = float(self._jitter[self._rng.integers(self._jitter.size)])
            ta = max(self._t + d, self._t_last_apply)  # ticks run one after another
            self._t_last_apply = ta
            self._late.append((ta, (tau1, tau2, tau3)))
            return
        ctrl = self._ctrl
        ctrl[0] = tau1
        ctrl[1] = tau2
        ctrl[2] = tau3

    def step(self) -> None:
        # the crank's gravity torque on θ3 (it is not a body of the tree), with the finger's push
        b, c = self._qpos[1], self._qpos[2]
        tg = -self._crank_g * math.sin(b + c)
        f = self._tip_qfrc
        qf = self._qfrc_applied
        qf[0] = f[0]
        qf[1] = f[1] + tg
        qf[2] = f[2] + tg
        if self._late:
            self._step_jittered()
        else:
            self._mj_step(self._m, self._d, self.substeps)
        self._t += self.dt
        if self._enc is not None:
            e = self._enc
            a, b, c = self._encoder_angles()
            k = 1.0 / self.dt
            self._enc = (a, b, c, (a - e[0]) * k, (b - e[1]) * k, (c - e[2]) * k)

    def _step_jittered(self) -> None:
        """One period in substeps, each late command switched in at the first substep it has reached."""
        h = self.dt / self.substeps
        late, ctrl = self._late, self._ctrl
        done = 0
        while done < self.substeps:
            t_sub = self._t + done * h
            while late and late[0][0] <= t_sub + 1e-12:
                ctrl[:] = late.popleft()[1]
            # run until the next command is due (or the period ends)
            n = self.substeps - done
            if late:
                n = min(n, max(1, int(math.ceil((late[0][0] - t_sub) / h - 1e-9))))
            self._mj_step(self._m, self._d, n)
            done += n

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
        self._tip_qfrc = (float(tau[0]), float(tau[1] + tau[2]), float(tau[2]))

    def apparent_mass(self, q=None) -> np.ndarray:
        """Eigenvalues (kg, ascending) of the tip's apparent mass ``(J M⁻¹ Jᵀ)⁻¹`` at joint angles
        ``q`` (default: the current ones), from MuJoCo's own mass matrix; the state is left as it was."""
        m, d = self._m, self._d
        saved = self._qpos.copy()
        if q is not None:
            q = np.asarray(q, dtype=np.float64).reshape(3)
            self._qpos[:] = (q[0], q[1], q[2] - q[1])
        mujoco.mj_forward(m, d)
        M = np.zeros((m.nv, m.nv))
        mujoco.mj_fullM(m, d, M)
        jp = np.zeros((3, m.nv))
        mujoco.mj_jacSite(m, d, jp, None, self._site_tip)
        ev = np.linalg.eigvalsh(np.linalg.inv(jp @ np.linalg.solve(M, jp.T)))
        self._qpos[:] = saved
        mujoco.mj_forward(m, d)
        return ev

    def true_tip_state(self) -> tuple[np.ndarray, np.ndarray]:
        """The tip's true position (m) and velocity (m/s), robot frame, from MuJoCo's joint state — what
        a simulated finger touches, whatever the sensor model reads (``read`` is the encoder's view)."""
        a, b, c = self._qpos.tolist()
        wa, wb, wc = self._qvel.tolist()
        q = (a, b, b + c)
        return kinematics.fk(q, self.params), kinematics.jacobian(q, self.params) @ np.array((wa, wb, wb + wc))

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

