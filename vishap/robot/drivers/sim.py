"""The driver ``sim``: the MuJoCo plant, reporting the stiffness limit measured for it.

The plant's own constructor leaves ``limits.max_stiffness_n_m`` unset; the gains file holds the
stiffest wall measured stable on it (docs/robot.md), which is what a real device reports as its
nominal maximum stiffness at start-up. Every keyword argument goes to
:class:`vishap.robot.plant.MujocoPlant` unchanged.
"""
from __future__ import annotations

from vishap.robot.plant import MujocoPlant

__all__ = ["sim_device"]


def sim_device(**kwargs) -> MujocoPlant:
    """``MujocoPlant(**kwargs)`` with ``max_stiffness_n_m`` from the gains file unless given."""
    if "max_stiffness_n_m" not in kwargs:
        from vishap.robot.gains import load_gains

        kwargs["max_stiffness_n_m"] = load_gains()[1].max_stiffness_n_m
    return MujocoPlant(**kwargs)
