import pytest

from vishap._core.errors import ConfigError
from vishap.apps import DemoConfig
from vishap.apps.assemble import calibrate, make_rig
from vishap.apps.replay import replay


def test_missing_calibration_is_reported_not_fatal(tmp_path, capsys):
    cfg = DemoConfig(scene="wall", calib=str(tmp_path / "nope.yaml"))
    T, report = calibrate(cfg, make_rig(cfg), tmp_path)
    assert T is None and "nope.yaml" in report["error"]
    assert "nope.yaml" in capsys.readouterr().err


def test_replay_refuses_what_is_not_a_demo_log(tmp_path):
    with pytest.raises(ConfigError, match="log not found"):
        replay(tmp_path)
    import numpy as np

    np.savez(tmp_path / "log.npz", x=np.zeros(3))
    with pytest.raises(ConfigError, match="meta"):
        replay(tmp_path)
