"""Small synthetic sequences (160×120, exact pixels) rendered with and without the device."""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np
import pytest

from vishap.ar import device_geometry
from vishap.robot import kinematics


@dataclass
class Frames:
    prep: object
    render: object          # the renderer with the device
    render_free: object     # the same scene without it (ground truth of deletion)
    geometry: object

    def state(self, t: float):
        from vishap.sim.sequence import frame_state

        return frame_state(self.prep, float(t))[0]

    def without_device(self, state):
        return replace(state, device_points_robot=None, ee_robot=None, passive_object=None)

    @staticmethod
    def q(state) -> np.ndarray:
        return kinematics.ik(state.ee_robot)  # the joint angles the encoders report


@pytest.fixture
def frames_factory():
    made = []

    def make(scene: str = "wall", *, seed: int = 3, rig=None, size=(160, 120)) -> Frames:
        from vishap.sim.renderer import StereoRenderer
        from vishap.sim.sequence import SequenceSpec, prepare

        p = prepare(SequenceSpec(scene=scene, frames=200, seed=seed, width=size[0], height=size[1], rig=rig,
                                 effects=False))
        r = StereoRenderer(p.rig, p.T_robot_cam, p.scene_spec, seed=seed, effects=None)
        r0 = StereoRenderer(p.rig, p.T_robot_cam, p.scene_spec, seed=seed, effects=None)
        made.extend([r, r0])
        geo = device_geometry("phantom_premium_1_0", passive_size_m=p.passive.size_m,
                              mount_offset_robot=p.passive.mount_offset_robot)
        return Frames(p, r, r0, geo)

    yield make
    for r in made:
        r.close()
