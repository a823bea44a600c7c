"""Assemble a ready servo loop: MuJoCo plant + controller with the checked gains from ``gains.yaml``.

The device-limits record gets the file's ``max_stiffness_n_m`` (the stiffest wall measured stable),
so :meth:`Controller.set_lambda` clips object gains that would exceed it.
"""
from __future__ import annotations

import os

from vishap.robot.controller import Controller, Gains
from vishap.robot.gains import check_gains, load_gains
from vishap.robot.mjcf import PassiveObject
from vishap.robot.params import DEFAULT, PhantomParams
from vishap.robot.plant import MujocoPlant
from vishap.robot.servo import ServoLoop

__all__ = ["build_servo"]


def build_servo(
    passive_object: PassiveObject | None = None,
    *,
    policy: str = "hold",
    gains: Gains | None = None,
    gains_path: str | os.PathLike | None = None,
    params: PhantomParams = DEFAULT,
    substeps: int = 1,
    sensor: str = "exact",
    q0=None,
    travel=None,
) -> ServoLoop:
    """A :class:`ServoLoop` over a :class:`MujocoPlant` (``servo.device``, ``servo.controller``).

    ``gains`` (default: the file's) must lie inside the file's measured stable region.
    """
    file_gains, cfg = load_gains(gains_path)
    if gains is not None:
        check_gains(gains, cfg.stable_region, file=gains_path or "vishap/robot/gains.yaml")
    plant = MujocoPlant(
        params,
        passive_object=passive_object,
        substeps=substeps,
        sensor=sensor,
        q0=q0,
        max_stiffness_n_m=cfg.max_stiffness_n_m,
    )
    ctrl = Controller(plant.params, gains or file_gains, limits=plant.limits)
    return ServoLoop(plant, ctrl, policy=policy, travel=travel)
