"""Building the core's servo side the same way in every mode: device, controller, guard, servo step.

Devices are opened by name through :func:`vishap.robot.drivers.open_device` (``sim``: the MuJoCo
PHANToM carrying the scene's passive object; a ``vishap.devices`` entry point; ``module:Class``: a
driver outside the package), re-exported here. :func:`make_servo_step` puts the controller (gains only from the gains file, limits only
from the device), the travel limiter and the target guard (the device's workspace box, a retreat
point under the scene's object's surface, out of the finger's reach) around it.
"""
from __future__ import annotations

import numpy as np

from vishap.robot.drivers import open_device
from vishap.runtime.core import ServoStep
from vishap.runtime.safety import TargetGuard

__all__ = ["open_device", "make_servo_step"]


def make_servo_step(device, scene, *, policy: str = "interpolate", travel=None, retreat_m: float = 0.02,
                    stale_after_s: float = 0.15, retreat_after_s: float = 0.5, engage_m: float = 0.0003) -> ServoStep:
    """The guarded servo step over ``device`` for ``scene`` (a :class:`vishap.world.scene.Scene`).

    ``travel`` is a :class:`~vishap.robot.travel.TravelLimiter` or None (unlimited travel).
    """
    from vishap.robot.controller import Controller
    from vishap.robot.gains import load_gains
    from vishap.robot.servo import ServoLoop

    gains, _ = load_gains()
    servo = ServoLoop(device, Controller(device.params, gains, limits=device.limits), policy=policy, travel=travel)
    lim = device.limits
    obj = scene.objects[0]
    mount = np.asarray(scene.passive_object.mount_offset_m, float)
    retreat = np.asarray(obj.centre, float) - retreat_m * np.asarray(obj.normal, float) - mount
    guard = TargetGuard(np.asarray(lim.workspace_min, float), np.asarray(lim.workspace_max, float), retreat,
                        stale_after_s=stale_after_s, retreat_after_s=retreat_after_s)
    return ServoStep(servo, guard, scene.objects, mount_offset=mount, engage_m=engage_m)
