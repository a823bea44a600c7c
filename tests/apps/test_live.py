import pytest

from vishap._core.errors import DeviceError
from vishap.apps.live import check_live, find_device_driver, parse_cameras


def test_live_names_every_missing_piece(tmp_path):
    with pytest.raises(DeviceError) as exc:
        check_live(cameras="97,98", rig=str(tmp_path / "rig.yaml"), calib=str(tmp_path / "cr.yaml"), device=None)
    msg = str(exc.value)
    assert len(msg.splitlines()) == 1
    for part in ("camera index 97", "camera index 98", "rig.yaml", "cr.yaml", "'phantom' driver"):
        assert part in msg


def test_camera_spec_and_driver_names():
    assert parse_cameras("0,1") == [0, 1] and parse_cameras("2") == [2]
    for bad in ("a,b", "0,1,2", "-1"):
        with pytest.raises(DeviceError, match="--cameras"):
            parse_cameras(bad)
    assert "unknown driver" in find_device_driver("nope")
