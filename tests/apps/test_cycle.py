"""The 1 kHz cycle's finger models and the sleeve's contact sample (what the system knows)."""
import numpy as np
import pytest

from vishap.apps.cycle import RecordedFinger, TrackedFinger, contact_sample
from vishap.runtime.core import TargetRecord
from vishap.world.scene import load_scene


def test_recorded_finger_interpolates_on_the_recordings_clock():
    t = np.arange(5) / 30.0
    p = np.stack([0.2 + 0.3 * t, np.zeros(5), -0.15 + 0.0 * t], axis=1)  # 0.3 m/s along x
    v = np.tile([0.3, 0.0, 0.0], (5, 1))
    f = RecordedFinger(t, p, v)
    assert np.all(np.isnan(f.pad(0.05, TargetRecord())[0]))  # no clock yet: no finger
    f.offset = -1.0  # the recording's time = servo time - 1 s
    pad, vel = f.pad(1.05, TargetRecord())
    assert np.allclose(pad, [0.2 + 0.3 * 0.05, 0.0, -0.15]) and np.allclose(vel, [0.3, 0.0, 0.0])
    assert np.allclose(f.pad(9.0, TargetRecord())[0], p[-1])  # held at the end


def test_tracked_finger_is_the_records_prediction():
    rec = TargetRecord(3, finger=(0.2, 0.0, -0.14), finger_velocity=(0.0, 0.0, -0.1), finger_t=1.0)
    pad, vel = TrackedFinger().pad(1.02, rec)
    assert np.allclose(pad, [0.2, 0.0, -0.142]) and np.allclose(vel, [0.0, 0.0, -0.1])
    assert np.all(np.isnan(TrackedFinger().pad(1.0, TargetRecord())[0]))


def test_contact_sample_uses_the_device_in_contact_and_the_tracked_finger_before():
    obj = load_scene("wall").objects[0]
    rec = TargetRecord(3, finger=(0.21, 0.01, -0.14), finger_velocity=(0.0, 0.0, -0.2), finger_t=1.0)
    p_dev, v_dev = np.array([0.20, 0.0, -0.151]), np.array([0.05, 0.0, -0.01])
    apart = contact_sample(obj, 1.01, p_dev, v_dev, rec, np.zeros(3), None)
    assert not apart.in_contact and apart.normal_force_n == 0.0
    assert np.allclose(apart.position, obj.local([0.21, 0.01, -0.142])) and np.allclose(apart.velocity, [0, 0, -0.2])
    touching = contact_sample(obj, 1.01, p_dev, v_dev, rec, np.array([0.0, 0.0, 1.5]), None)
    assert touching.in_contact and touching.normal_force_n == pytest.approx(1.5)
    assert np.allclose(touching.position, obj.local(p_dev)) and np.allclose(touching.velocity, v_dev)
