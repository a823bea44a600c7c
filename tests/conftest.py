"""Shared fixtures: a seeded random generator, a small family of stereo rigs, and a module written
outside the package (a user's driver) put on ``sys.path``."""
from __future__ import annotations

import os

os.environ.setdefault("PYOPENGL_PLATFORM", "egl")

import numpy as np
import pytest

from vishap.vision.rig import StereoRig


@pytest.fixture
def module_outside(tmp_path, monkeypatch):
    """``write(name, source)``: a module ``name`` in ``tmp_path``, importable for this test only."""
    import importlib
    import sys

    written = []

    def write(name: str, source: str):
        (tmp_path / f"{name}.py").write_text(source)
        monkeypatch.syspath_prepend(str(tmp_path))
        written.append(name)
        return importlib.import_module(name)

    yield write
    for name in written:
        sys.modules.pop(name, None)


@pytest.fixture
def rng() -> np.random.Generator:
    return np.random.default_rng(1234)


@pytest.fixture
def ideal_rig() -> StereoRig:
    """640×480, 60° horizontal field of view, 60 mm baseline, no distortion."""
    return StereoRig.from_fov(640, 480, 60.0, 0.06)


@pytest.fixture
def distorted_rig() -> StereoRig:
    """A realistic calibrated rig: different intrinsics, distortion, a slight toe-in and offset."""
    from vishap._core.pose import rotvec_to_matrix

    K1 = np.array([[560.0, 0.0, 322.0], [0.0, 558.0, 241.5], [0.0, 0.0, 1.0]])
    K2 = np.array([[552.0, 0.0, 317.0], [0.0, 553.5, 238.0], [0.0, 0.0, 1.0]])
    return StereoRig(
        image_size=(640, 480),
        K_left=K1,
        dist_left=np.array([-0.21, 0.08, 0.0012, -0.0007, -0.012]),
        K_right=K2,
        dist_right=np.array([-0.19, 0.05, -0.0004, 0.0009, 0.0]),
        R=rotvec_to_matrix([0.004, -0.03, 0.002]),
        T=np.array([-0.0601, 0.0007, 0.0012]),
    )
