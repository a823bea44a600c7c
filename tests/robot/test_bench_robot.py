"""``vishap bench robot`` produces its record and chart (a smoke run; speed is not tested)."""
import argparse
import json

from vishap.bench import robot as bench_robot


def test_bench_robot_record(tmp_path):
    args = argparse.Namespace(out=str(tmp_path), ticks=400, rounds=2, policy="hold")
    rec = bench_robot.run(args)
    for key in ("servo_cycle_us_median", "bare_mujoco_step_us_median", "realtime_factor"):
        assert rec[key] > 0
    assert rec["realtime_factor"] == 1000.0 / rec["servo_cycle_us_median"]
    assert (tmp_path / "robot.png").stat().st_size > 1000
    json.dumps(rec)
