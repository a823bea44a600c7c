import pytest

from vishap._core.errors import DeviceError
from vishap.apps.live import check_live, source_spec


def test_live_names_every_missing_piece(tmp_path):
    with pytest.raises(DeviceError) as exc:
        check_live(cameras="97,98", rig=str(tmp_path / "rig.yaml"), calib=str(tmp_path / "cr.yaml"),
                   device="nopkg_xyz.drivers:Arm")
    msg = str(exc.value)
    assert len(msg.splitlines()) == 1
    for part in ("camera index 97", "camera index 98", "rig.yaml", "cr.yaml", "nopkg_xyz.drivers:Arm"):
        assert part in msg, part


def test_live_takes_the_source_specs_of_vishap_track(tmp_path):
    assert source_spec("0,1") == "cam:0,1" and source_spec("2") == "cam:2"
    assert source_spec("sbs:a.mp4") == "sbs:a.mp4" and source_spec("a.mp4,b.mp4") == "a.mp4,b.mp4"
    with pytest.raises(DeviceError, match="--cameras"):
        source_spec("0,1,2")
    with pytest.raises(DeviceError, match="missing.*a.mp4.*b.mp4"):
        check_live(cameras=f"{tmp_path}/a.mp4,{tmp_path}/b.mp4", rig=None, calib=None, device="sim")
    # a recorded folder brings its own rig; without --calib the simulated calibration runs (sim device)
    folder = tmp_path / "rec"
    folder.mkdir()
    (folder / "rig.yaml").write_text("x")
    spec, rig, calib, device = check_live(cameras=str(folder), rig=None, calib=None, device=None)
    assert spec == str(folder) and rig == folder / "rig.yaml" and calib is None and device == "sim"
    with pytest.raises(DeviceError, match="--calib is needed for cameras, videos or a real device"):
        check_live(cameras=str(folder), rig=None, calib=None, device="vishap.robot.plant:MujocoPlant")
    with pytest.raises(DeviceError, match="--calib is needed"):  # real cameras: no simulated calibration
        check_live(cameras="cam:0,1", rig=None, calib=None, device="sim")


def test_live_servo_cycle_runs_a_driver_named_module_class():
    """A device given as module:Class (no simulated finger: a real finger would press it) runs the same
    servo cycle: the guard tracks a fresh record and the log rows have the demo's schema."""
    import numpy as np

    from vishap.apps.config import DemoConfig
    from vishap.apps.live_loop import LiveCycle
    from vishap.runtime.core import TargetRecord

    cyc = LiveCycle(DemoConfig(scene="wall").model_dump(), "vishap.robot.plant:MujocoPlant", None)
    assert cyc.finger is None and type(cyc.cycle.step.device).__name__ == "MujocoPlant"
    goal = (0.20, 0.0, -0.13)
    for k in range(300):
        t = k * 1e-3
        rec = TargetRecord(1 + k // 30, goal, t, 1.0, True, True, 0, False, False)
        state = cyc.step(t, np.append(rec.pack(), np.nan))
    assert state[4] == 0 and state[5] == rec.seq  # tracking the newest record
    res = cyc.finish()
    servo = res["channels"]["servo"].arrays()
    assert len(servo["t"]) == 300 and np.all(servo["guard"][1:] == 0)
    assert np.all(np.isfinite(servo["F_cmd"])) and res["peak_force_n"] == 8.5
    assert len(res["channels"]["tactile"]) == 300


def test_live_mode_says_when_it_cannot_show_the_augmented_view(monkeypatch, capsys):
    from vishap.apps.live_loop import _live_view

    monkeypatch.delenv("DISPLAY", raising=False)
    monkeypatch.delenv("WAYLAND_DISPLAY", raising=False)
    ar, view = _live_view(None, None, None, None)
    assert ar is None and not view.available
    assert "AR view is not shown live" in capsys.readouterr().err
