import pytest

from vishap._core.errors import ConfigError, VishapError
from vishap.apps import DemoConfig
from vishap.apps.assemble import calibrate, make_rig
from vishap.apps.replay import replay


def test_an_unreadable_calibration_file_stops_the_run(tmp_path):
    """A mistyped --calib is one error naming the file, not a run with the device retreating throughout."""
    cfg = DemoConfig(scene="wall", calib=str(tmp_path / "nope.yaml"))
    with pytest.raises(VishapError, match="nope.yaml"):
        calibrate(cfg, make_rig(cfg), tmp_path)
    (tmp_path / "junk.yaml").write_text("format: something else\n")
    cfg = DemoConfig(scene="wall", calib=str(tmp_path / "junk.yaml"))
    with pytest.raises(VishapError, match="junk.yaml"):
        calibrate(cfg, make_rig(cfg), tmp_path)


def test_replay_refuses_what_is_not_a_demo_log(tmp_path):
    with pytest.raises(ConfigError, match="log not found"):
        replay(tmp_path)
    import numpy as np

    np.savez(tmp_path / "log.npz", x=np.zeros(3))
    with pytest.raises(ConfigError, match="meta"):
        replay(tmp_path)
