"""The encountered-type device (VisHap §2.3): PHANToM kinematics, gravity model, plant and controller.

Modules: :mod:`params` (constants, one source of truth), :mod:`kinematics` (fk, Jacobian, ik,
Eq. 6), :mod:`gravity` (Eq. 7), :mod:`mjcf` (MuJoCo model from the params), :mod:`device` (the
Device interface and limits), :mod:`plant` (MuJoCo plant), :mod:`controller` (Eq. 4–5, 8–9),
:mod:`servo` (the 1 kHz cycle and X_d gap policies), :mod:`gains` (stable-region gain loader),
:mod:`build` (:func:`build_servo`: plant + controller with the checked gains).
"""
from vishap.robot.build import build_servo
from vishap.robot.controller import Controller, Gains
from vishap.robot.device import Device, DeviceLimits, DeviceState
from vishap.robot.mjcf import PassiveObject
from vishap.robot.params import DEFAULT, PhantomParams
from vishap.robot.plant import MujocoPlant
from vishap.robot.servo import POLICIES, ServoLoop, TargetShaper

__all__ = [
    "PhantomParams",
    "DEFAULT",
    "Device",
    "DeviceLimits",
    "DeviceState",
    "PassiveObject",
    "MujocoPlant",
    "Controller",
    "Gains",
    "ServoLoop",
    "TargetShaper",
    "POLICIES",
    "build_servo",
]
