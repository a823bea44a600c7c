"""Finding drivers: ``sim``, the ``vishap.devices`` entry points, and ``module:Class`` outside the package."""
from __future__ import annotations

import json
import textwrap
import tomllib
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.robot.device import Device
from vishap.robot.drivers import ENTRY_POINT_GROUP, open_device, registered, resolve
from vishap.world.scene import demo_passive_object

# A driver written by someone else: a point mass on three orthogonal linear axes standing in for the
# arm, commanded through the same interface (torques → Jacobian-transpose force).
OUTSIDE_DRIVER = textwrap.dedent('''
    import numpy as np
    from vishap.robot import kinematics
    from vishap.robot.device import Device, DeviceLimits, DeviceState
    from vishap.robot.params import DEFAULT

    class KinematicArm(Device):
        """Joints integrate the commanded torque as velocity (a stiff admittance); records commands."""

        def __init__(self, gain=0.5, q0=(0.0, 0.1, 0.0)):
            self.params = DEFAULT
            self.limits = DeviceLimits.from_params(DEFAULT)
            self.q = np.array(q0, dtype=float)
            self.qd = np.zeros(3)
            self.tau = np.zeros(3)
            self.gain = gain
            self.commands = []
            self.closed = False
            self._t = 0.0

        @property
        def time(self):
            return self._t

        def read(self):
            return DeviceState(self._t, self.q.copy(), self.qd.copy(), kinematics.fk(self.q),
                               kinematics.jacobian(self.q) @ self.qd)

        def command_torque(self, tau):
            tau = np.asarray(tau, dtype=float)
            self.check_torque(*tau)
            self.tau = tau
            self.commands.append(tau.copy())

        def step(self):
            self.qd = self.gain * self.tau
            self.q = self.q + self.qd * self.params.dt
            self._t += self.params.dt

        def close(self):
            super().close()
            self.closed = True

    def make(**kw):
        return KinematicArm(**kw)

    class NotADevice:
        pass
''')


@pytest.fixture
def outside(module_outside, tmp_path):
    module_outside("labdrivers", OUTSIDE_DRIVER)
    return tmp_path


def test_sim_is_the_mujoco_plant_with_kwargs_passed_through():
    from vishap.robot.plant import MujocoPlant

    dev = open_device("sim", passive_object=replace(demo_passive_object(), mass_kg=0.02), sensor="encoder")
    assert type(dev) is MujocoPlant and dev.params.m_tip == 0.02 and dev.sensor == "encoder"
    from vishap.robot.gains import load_gains

    # the stiffness limit a real device reports at start-up: for the plant, the gains file's measured one
    assert dev.limits.max_stiffness_n_m == load_gains()[1].max_stiffness_n_m is not None
    assert open_device("sim", max_stiffness_n_m=500.0).limits.max_stiffness_n_m == 500.0
    assert dev.moves_itself
    dev.start()
    dev.command_torque_scalar(0.1, 0.1, 0.1)
    dev.close()  # lets go: the plant's motors get zero
    assert np.all(dev.data.ctrl == 0.0)


def test_unknown_name_lists_the_known_ones():
    with pytest.raises(ConfigError, match=r"unknown device 'phantom' \(known: .*sim"):
        open_device("phantom")


def test_unimportable_module_is_named():
    with pytest.raises(ConfigError, match="cannot import module 'no_such_driver_pkg'"):
        open_device("no_such_driver_pkg:Arm")
    with pytest.raises(ConfigError, match="has no 'Nope'"):
        resolve("vishap.robot.plant:Nope")


def test_a_driver_outside_the_package_runs_by_module_class(outside):
    """Opened by 'module:Class' and driven by the servo loop like the plant."""
    from vishap.robot.controller import Controller
    from vishap.robot.servo import ServoLoop

    dev = open_device("labdrivers:KinematicArm", gain=2.0)
    assert isinstance(dev, Device) and dev.gain == 2.0
    loop = ServoLoop(dev, Controller(dev.params, limits=dev.limits))
    p0 = dev.read().p_robot
    target = p0 + np.array([0.0, 0.0, 0.01])
    for _ in range(200):
        loop.tick(dev.time, target)
    assert len(dev.commands) == 200 and dev.time == pytest.approx(0.2)
    assert dev.read().p_robot[2] > p0[2] + 1e-4  # the loop moved it towards the target
    dev.close()
    assert dev.closed and np.all(dev.tau == 0.0)
    assert isinstance(open_device("labdrivers:make"), Device)  # a factory works too


def test_a_non_device_is_refused(outside):
    with pytest.raises(ConfigError, match="not a vishap.robot.device.Device"):
        open_device("labdrivers:NotADevice")
    with pytest.raises(ConfigError, match="bad arguments"):
        open_device("labdrivers:KinematicArm", no_such_option=1)


def test_entry_point_group_registers_names(outside):
    """A package registering ``[project.entry-points."vishap.devices"] lab = "labdrivers:KinematicArm"``."""
    dist = outside / "labdrivers-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: labdrivers\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\nlab = labdrivers:KinematicArm\n")
    assert registered()["lab"] == "labdrivers:KinematicArm"
    assert type(open_device("lab")).__name__ == "KinematicArm"
    with pytest.raises(ConfigError, match="known: .*lab.*sim"):
        open_device("nope")


def test_pyproject_registers_the_openhaptics_adapter():
    root = Path(__file__).resolve().parents[2]
    table = tomllib.loads((root / "pyproject.toml").read_text())["project"]["entry-points"][ENTRY_POINT_GROUP]
    from vishap.robot.drivers.openhaptics import OpenHapticsDevice

    assert resolve(table["openhaptics"]) is OpenHapticsDevice
    # the vendor package is an extra, not a dependency of the main install
    project = tomllib.loads((root / "pyproject.toml").read_text())["project"]
    assert not any("openhaptics" in d.lower() for d in project["dependencies"])
    assert any("pyopenhaptics" in d.lower() for d in project["optional-dependencies"]["openhaptics"])


def test_vishap_devices_lists_sim_with_its_limits(capsys, outside):
    from vishap.cli import main

    dist = outside / "labdrivers-0.1.dist-info"
    dist.mkdir()
    (dist / "METADATA").write_text("Metadata-Version: 2.1\nName: labdrivers\nVersion: 0.1\n")
    (dist / "entry_points.txt").write_text(f"[{ENTRY_POINT_GROUP}]\nbroken = no_such_driver_pkg:Arm\n")
    assert main(["devices", "--json"]) == 0
    rows = json.loads(capsys.readouterr().out)
    assert rows["sim"]["limits"]["peak_force_n"] == 8.5 and rows["sim"]["moves_itself"] is True
    assert "no_such_driver_pkg" in rows["broken"]["unavailable"]
