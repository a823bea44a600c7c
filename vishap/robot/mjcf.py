"""MuJoCo model (MJCF) of the PHANToM, generated from :mod:`vishap.robot.params`.

One source of truth: lengths, masses, joint limits, damping and the servo rate all come from a
:class:`PhantomParams`. The arm is a tree — turret (θ1) → upper arm (θ2) → forearm (relative
elbow joint ``θ3 − θ2``) → passive object — with the parallelogram's crank carried by motor 3's
tendon (its inertia as armature, its gravity torque applied by the plant), so that the first
moments, hence the gravity torques, equal Cavusoglu's Eq. 7 exactly (see
:attr:`PhantomParams.tree_bodies`). The third motor drives a fixed tendon ``θ2 + elbow = θ3``,
the PHANToM's absolute forearm angle, so actuator ``i`` applies the motor torque ``τ_i`` of joint
``θ_i`` (VisHap's convention), and the tendon limit is θ3's joint limit.

Contacts are disabled: the world's force laws act through the controller, not through MuJoCo
collisions.

The joints' Coulomb friction (``frictionloss``) is a near-hard constraint (``solimpfriction``
``FRICTION_SOLIMP``): with MuJoCo's default impedance (0.9) a force below the friction still lets a
joint creep (0.18 mm/s at the tip under half the friction), so an arm at rest never stopped and
dithered across encoder counts; at 0.999 it creeps 1.7 µm/s, and sliding friction is unchanged.
"""
from __future__ import annotations

from dataclasses import dataclass

from vishap.robot.params import DEFAULT, PhantomParams

__all__ = ["PassiveObject", "build_mjcf", "build_model", "FRICTION_SOLIMP"]

#: impedance (dmin, dmax, width) of the friction constraints: static friction that holds (see above)
FRICTION_SOLIMP = (0.999, 0.999, 0.001)


@dataclass(frozen=True)
class PassiveObject:
    """A real object attached to the end-effector (VisHap §2.1), centred on the tip.

    ``shape`` is ``"sphere"`` (``size_m = (radius,)``) or ``"plate"``/``"box"`` (``size_m`` = full
    edge lengths x, y, z in the forearm frame); ``mass_kg`` ≥ 0.
    """

    shape: str                                  # (the scene file's passive_object: its one home;
    size_m: tuple[float, ...]                   #  world.scene.PassiveObject.for_mujoco, demo_passive_object)
    mass_kg: float

    def __post_init__(self):
        from vishap._core.errors import ConfigError

        if self.shape not in ("sphere", "plate", "box"):
            raise ConfigError(f"expected 'sphere', 'plate' or 'box', got {self.shape!r}", field="passive_object.shape")
        if not (self.mass_kg >= 0.0):
            raise ConfigError(f"expected a mass ≥ 0 kg, got {self.mass_kg!r}", field="passive_object.mass_kg")
        need = 1 if self.shape == "sphere" else 3
        if len(self.size_m) != need or not all(s > 0 for s in self.size_m):
            raise ConfigError(f"expected {need} positive sizes for a {self.shape}, got {self.size_m!r}", field="passive_object.size_m")

    def inertia(self) -> tuple[float, float, float]:
        m = max(self.mass_kg, 1e-9)
        if self.shape == "sphere":
            i = 0.4 * m * self.size_m[0] ** 2
            return (i, i, i)
        x, y, z = self.size_m
        return (m * (y * y + z * z) / 12.0, m * (x * x + z * z) / 12.0, m * (x * x + y * y) / 12.0)


def _f(x: float) -> str:
    return repr(float(x))


def build_mjcf(params: PhantomParams = DEFAULT, *, substeps: int = 1, passive_object: PassiveObject | None = None) -> str:
    """MJCF text of the arm; physics ``timestep = 1 / (servo_rate_hz · substeps)``.

    The passive object's mass must equal ``params.m_tip`` (pass ``params.with_tip_mass(...)``) so
    that the controller's gravity model and the simulation agree; this is checked.
    """
    if substeps < 1:
        raise ValueError(f"substeps: expected an integer ≥ 1, got {substeps!r}")
    m_obj = 0.0 if passive_object is None else passive_object.mass_kg
    if abs(m_obj - params.m_tip) > 1e-12:
        raise ValueError(f"passive object mass {m_obj} kg differs from params.m_tip {params.m_tip} kg")
    p = params
    bodies = p.tree_bodies
    m_u, d_u = bodies["upper_arm"]
    m_f, d_f = bodies["forearm"]
    a3 = p.armature[2] + p.crank_inertia  # the crank turns with θ3: its inertia rides on motor 3
    # inertias about the lumped CoMs (fitted to the data sheet's apparent mass, see params)
    iu = p.upper_arm_inertia
    if_ = p.forearm_inertia
    ts = 1.0 / (p.servo_rate_hz * substeps)
    fr1, fr2, fr3 = p.joint_friction_nm
    a1, a2 = p.armature[0], p.armature[1]

    fimp = " ".join(_f(v) for v in FRICTION_SOLIMP)

    def joint(arm: float, fric: float) -> str:
        return f'damping="{_f(p.joint_damping)}" armature="{_f(arm)}" frictionloss="{_f(fric)}" solimpfriction="{fimp}"'
    vis = 'contype="0" conaffinity="0" group="1"'

    obj = ""
    if passive_object is not None:
        ix, iy, iz = passive_object.inertia()
        if passive_object.shape == "sphere":
            geom = f'<geom name="passive_object" type="sphere" size="{_f(passive_object.size_m[0])}" {vis} rgba="0.6 0.6 0.6 1"/>'
        else:
            hx, hy, hz = (0.5 * s for s in passive_object.size_m)
            geom = f'<geom name="passive_object" type="box" size="{_f(hx)} {_f(hy)} {_f(hz)}" {vis} rgba="0.6 0.6 0.6 1"/>'
        inertial = (
            f'<inertial pos="0 0 0" mass="{_f(m_obj)}" diaginertia="{_f(ix)} {_f(iy)} {_f(iz)}"/>' if m_obj > 0 else ""
        )
        obj = f"""
          <body name="passive_object" pos="0 0 {_f(-p.l2)}">
            {inertial}
            {geom}
          </body>"""

    return f"""<mujoco model="phantom_premium_1_0">
  <compiler angle="radian" autolimits="true"/>
  <option timestep="{_f(ts)}" gravity="0 0 {_f(-p.g)}" integrator="Euler">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <geom name="base" type="cylinder" pos="0 0 {_f(-0.5 * p.l2)}" size="0.04 0.01" {vis} rgba="0.2 0.2 0.2 1"/>
    <body name="turret" pos="0 0 0">
      <joint name="theta1" type="hinge" axis="0 0 1" range="{_f(p.q_min[0])} {_f(p.q_max[0])}" {joint(a1, fr1)}/>
      <inertial pos="0 0 0" mass="0.2" diaginertia="{_f(p.turret_inertia)} {_f(p.turret_inertia)} {_f(p.turret_inertia)}"/>
      <geom type="cylinder" fromto="0 0 {_f(-0.5 * p.l2)} 0 0 0" size="0.02" {vis} rgba="0.2 0.2 0.2 1"/>
      <body name="upper_arm" pos="0 0 0">
        <joint name="theta2" type="hinge" axis="0 -1 0" range="{_f(p.q_min[1])} {_f(p.q_max[1])}" {joint(a2, fr2)}/>
        <inertial pos="{_f(d_u)} 0 0" mass="{_f(m_u)}" diaginertia="1e-5 {_f(iu)} {_f(iu)}"/>
        <geom type="capsule" fromto="0 0 0 {_f(p.l1)} 0 0" size="0.006" {vis} rgba="0.3 0.3 0.3 1"/>
        <body name="forearm" pos="{_f(p.l1)} 0 0">
          <joint name="elbow" type="hinge" axis="0 -1 0" range="{_f(p.elbow_min)} {_f(p.elbow_max)}" {joint(0.0, 0.0)}/>
          <inertial pos="0 0 {_f(-d_f)}" mass="{_f(m_f)}" diaginertia="{_f(if_)} {_f(if_)} 1e-6"/>
          <geom type="capsule" fromto="0 0 0 0 0 {_f(-p.l2)}" size="0.004" {vis} rgba="0.3 0.3 0.3 1"/>
          <site name="tip" pos="0 0 {_f(-p.l2)}" size="0.003"/>{obj}
        </body>
      </body>
    </body>
  </worldbody>
  <tendon>
    <fixed name="theta3" range="{_f(p.q_min[2])} {_f(p.q_max[2])}" armature="{_f(a3)}" frictionloss="{_f(fr3)}" solimpfriction="{fimp}">
      <joint joint="theta2" coef="1"/>
      <joint joint="elbow" coef="1"/>
    </fixed>
  </tendon>
  <actuator>
    <motor name="motor1" joint="theta1"/>
    <motor name="motor2" joint="theta2"/>
    <motor name="motor3" tendon="theta3"/>
  </actuator>
</mujoco>
"""


def build_model(params: PhantomParams = DEFAULT, *, substeps: int = 1, passive_object: PassiveObject | None = None):
    """Compiled ``mujoco.MjModel`` of :func:`build_mjcf`."""
    import mujoco

    return mujoco.MjModel.from_xml_string(build_mjcf(params, substeps=substeps, passive_object=passive_object))
