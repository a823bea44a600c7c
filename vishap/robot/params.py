"""PHANToM Premium 1.0 constants: the one source of truth for kinematics, gravity and the MuJoCo model.

Masses and lengths are Cavusoglu, Feygin & Tendick's identified parameters ("A critical study of
the mechanical and electrical properties of the PHANToM haptic interface", 2002), as cited by
VisHap §2.3 ("Gravity Compensation", Eq. 7). Device limits are the manufacturer's figures quoted
in VisHap §1 (workspace) and SensAble's data sheet (peak 8.5 N, continuous ≈ 1.4 N).

Joint angles (radians), robot frame (metres, z up, x from the base towards the user, origin at
the joint-1/joint-2 axes):

* ``q[0]`` = θ1, base yaw about +z;
* ``q[1]`` = θ2, elevation of the upper arm (link l1) above the horizontal;
* ``q[2]`` = θ3, absolute angle of the forearm (link l2) from the downward vertical, positive
  towards +x (the PHANToM's parallelogram drives θ3 directly, not relative to θ2).

Home ``q = 0`` puts the tip at ``(l1, 0, -l2) = (0.215, 0, -0.170)``.
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

__all__ = ["PhantomParams", "DEFAULT", "WORKSPACE_MIN", "WORKSPACE_MAX", "GRAVITY"]

GRAVITY = 9.81  # m/s², acts along -z of the robot frame

#: Reachable box shared by every area (robot frame, metres).
WORKSPACE_MIN = (0.10, -0.065, -0.20)
WORKSPACE_MAX = (0.30, 0.065, -0.04)


@dataclass(frozen=True)
class PhantomParams:
    """Geometry, masses and limits of a PHANToM Premium 1.0 (SI units)."""

    # Cavusoglu et al. 2002, Table / §4 (gravity parameters)
    m_a: float = 0.0202  # kg, link a (forearm, CoM at 0.5·l2 from the elbow)
    m_c: float = 0.0249  # kg, link c (parallelogram coupler, CoM at 0.5·l1 along l1 and l3 along l2)
    m_be: float = 0.2359  # kg, links b+e (upper arm with its counterweight, CoM at l5 along l1)
    m_df: float = 0.1906  # kg, links d+f (θ3 drive crank with its counterweight, CoM at -l6 along l2)
    l1: float = 0.215  # m, upper arm (shoulder to elbow)
    l2: float = 0.170  # m, forearm (elbow to tip)
    l3: float = 0.0325  # m, crank length of the parallelogram
    l5: float = -0.0368  # m, CoM offset of links b+e along l1 (negative: behind the shoulder)
    l6: float = 0.0527  # m, CoM offset of links d+f opposite to l2
    g: float = GRAVITY  # m/s²
    #: mass of the passive object carried at the tip (kg); VisHap §2.3 adjusts m_a for it
    m_tip: float = 0.0

    # joint limits (rad): θ1, θ2, θ3, and the parallelogram angle θ3 - θ2 (elbow, cannot fold)
    # (the reachable box needs θ1 ±0.58, θ2 −0.31…0.65, θ3 −0.74…0.71, θ3 − θ2 −1.05…0.94)
    q_min: tuple[float, float, float] = (-1.0, -0.50, -1.00)
    q_max: tuple[float, float, float] = (1.0, 0.90, 1.00)
    elbow_min: float = -1.30  # rad, θ3 - θ2 (−π/2 would stretch the arm straight: singular)
    elbow_max: float = 1.20  # rad

    # actuation limits (SensAble data sheet; VisHap §1)
    peak_force_n: float = 8.5
    continuous_force_n: float = 1.4
    #: time constant (s) of the motor-heating estimate that enforces the continuous force
    thermal_tau_s: float = 10.0
    workspace_min: tuple[float, float, float] = WORKSPACE_MIN
    workspace_max: tuple[float, float, float] = WORKSPACE_MAX

    # dynamics of the simulated arm beyond Cavusoglu's gravity parameters. Cavusoglu et al. give
    # masses and first moments; the link inertias are slender rods, and the turret inertia and the
    # motors' reflected inertias are fitted (least squares on log mass) so that the tip's apparent
    # mass lies near the data sheet's "apparent mass at tip < 75 g": 0.044 / 0.060 / 0.070 kg at
    # (0.2, 0, −0.12) m (docs/robot.md gives the range over the workspace; MujocoPlant.apparent_mass)
    joint_damping: float = 2.0e-4  # N·m·s/rad, capstan/bearing viscous friction per joint
    #: kg·m², reflected rotor inertia of motors 1, 2, 3 (motor 3 drives θ3, the tendon θ2 + elbow)
    armature: tuple[float, float, float] = (4.0e-5, 1.1e-3, 8.0e-4)
    turret_inertia: float = 1.1e-3  # kg·m², base yaw (θ1) inertia excluding the arm
    #: kg·m², pitch inertia of the lumped upper arm and forearm about their centres of mass
    upper_arm_inertia: float = 0.2608 * 0.12**2 / 12.0  # (m_be + m_c) · (0.12 m)² / 12
    forearm_inertia: float = 0.0202 * 0.170**2 / 12.0  # m_a · l2² / 12
    #: N, Coulomb (backdrive) friction at the tip — data sheet 0.04 N; applied per joint as the
    #: torque it takes at the joint's lever (θ1: the nominal radius; θ2: l1; θ3: l2)
    coulomb_friction_n: float = 0.04
    #: m, the radius at which the yaw joint's friction torque is taken
    nominal_radius_m: float = 0.215
    #: rad, encoder resolution: the data sheet's nominal position resolution 0.03 mm at the nominal radius
    encoder_resolution_rad: float = 1.5e-4
    #: N·m, per-motor peak torque (amplifier current limit × torque constant, at the joint): the peak
    #: force at each joint's lever in the nominal pose (θ1: the nominal radius, θ2: l1, θ3: l2); the
    #: motors' type is not in the data sheet, so these are the figures the peak force implies
    motor_peak_torque_nm: tuple[float, float, float] = (8.5 * 0.215, 8.5 * 0.215, 8.5 * 0.170)
    #: A, amplifier current limits (peak, continuous) and N·m/A, torque constant referred to each joint
    amp_peak_current_a: float = 6.0
    amp_continuous_current_a: float = 1.0
    #: N/m, the data sheet's closed-loop stiffness (3.5 N/mm): no virtual stiffness may exceed it
    datasheet_stiffness_n_m: float = 3500.0
    servo_rate_hz: float = 1000.0

    @property
    def dt(self) -> float:
        """Servo period (s)."""
        return 1.0 / self.servo_rate_hz

    @property
    def tip_resolution_m(self) -> float:
        """m, one encoder count at the tip: the nominal position resolution (0.03 mm)."""
        return self.encoder_resolution_rad * self.nominal_radius_m

    @property
    def gravity_coefficients(self) -> tuple[float, float]:
        """Eq. 7 coefficients (N·m) of cos θ2 and sin θ3, including the tip object.

        With ``m_tip = 0`` these are exactly g·(l1·m_a + 0.5·l1·m_c + m_be·l5) and
        g·(0.5·m_a·l2 + m_c·l3 − m_df·l6).
        """
        c2 = self.g * (self.l1 * self.m_a + 0.5 * self.l1 * self.m_c + self.m_be * self.l5 + self.l1 * self.m_tip)
        c3 = self.g * (0.5 * self.m_a * self.l2 + self.m_c * self.l3 - self.m_df * self.l6 + self.l2 * self.m_tip)
        return c2, c3

    def with_tip_mass(self, m_tip: float) -> PhantomParams:
        """The same arm carrying a passive object of ``m_tip`` kg at the tip."""
        return replace(self, m_tip=float(m_tip))

    def with_adjusted_m_a(self, m_object: float) -> PhantomParams:
        """VisHap's approximation: fold an attached object's mass into ``m_a`` (no separate tip mass)."""
        return replace(self, m_a=self.m_a + float(m_object), m_tip=0.0)

    @property
    def tree_bodies(self) -> dict[str, tuple[float, float]]:
        """(mass kg, CoM offset m) of the two rigid bodies of the simulated tree, and the crank.

        A parallelogram is a closed chain; the MuJoCo model is a tree: the upper arm (m_be, with the
        coupler's m_c at 0.5·l1) follows θ2 with its CoM at ``d_u`` along l1; the forearm (m_a) follows
        θ3 with its CoM at 0.5·l2 from the elbow. The θ3 drive crank with its counterweight (m_df at
        −l6) and the coupler's offset along it (m_c at l3) turn about the shoulder with θ3: their
        inertia ``crank_inertia`` rides on motor 3's tendon as armature, and their gravity torque
        ``crank_gravity_nm``·sin θ3 is applied by the plant. First moments, hence gravity torques,
        equal Eq. 7 exactly; the second moments follow the links instead of being a by-product of
        lumping (a lumped tree put 0.045 kg 0.17 m above the elbow and made the tip 3× heavier).
        """
        m_u = self.m_be + self.m_c
        d_u = (self.m_be * self.l5 + 0.5 * self.l1 * self.m_c) / m_u
        return {"upper_arm": (m_u, d_u), "forearm": (self.m_a, 0.5 * self.l2)}

    @property
    def crank_inertia(self) -> float:
        """Inertia (kg·m²) about the shoulder of the parts turning with θ3: m_df at l6, m_c at l3."""
        return self.m_df * self.l6**2 + self.m_c * self.l3**2

    @property
    def crank_gravity_nm(self) -> float:
        """The crank's share of Eq. 7's sin θ3 coefficient (N·m): g·(m_c·l3 − m_df·l6)."""
        return self.g * (self.m_c * self.l3 - self.m_df * self.l6)

    @property
    def motor_kt_nm_a(self) -> tuple[float, float, float]:
        """Torque constant referred to each joint (N·m/A): peak torque at the amplifier's peak current."""
        return tuple(t / self.amp_peak_current_a for t in self.motor_peak_torque_nm)

    @property
    def motor_continuous_torque_nm(self) -> tuple[float, float, float]:
        """Per-motor torque at the amplifier's continuous current (N·m)."""
        return tuple(k * self.amp_continuous_current_a for k in self.motor_kt_nm_a)

    @property
    def joint_friction_nm(self) -> tuple[float, float, float]:
        """Coulomb friction torque of joints θ1, θ2, θ3 (N·m) giving ``coulomb_friction_n`` at the tip."""
        f = self.coulomb_friction_n
        return (f * self.nominal_radius_m, f * self.l1, f * self.l2)

    @property
    def q_min_array(self) -> np.ndarray:
        return np.asarray(self.q_min, dtype=np.float64)

    @property
    def q_max_array(self) -> np.ndarray:
        return np.asarray(self.q_max, dtype=np.float64)


DEFAULT = PhantomParams()
