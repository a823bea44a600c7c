"""The long sweeps through the engine: the same record from their cases run one after another in
this process and as Ray tasks on 2 workers (issue 18, item 3)."""
from __future__ import annotations

import argparse
import io
import json
from pathlib import Path

import numpy as np
import pytest

from vishap.bench._common import to_jsonable
from vishap.scale import map_cases


@pytest.fixture(scope="module")
def ray_two_cpus():
    """One local Ray instance with 2 CPUs for the module: ``workers=2`` uses it (and leaves it
    running), so each test pays for Ray's start once."""
    import ray

    ray.init(num_cpus=2, include_dashboard=False, log_to_driver=False, configure_logging=False)
    yield
    ray.shutdown()


def _args(module, argv, out):
    p = argparse.ArgumentParser()
    module.add_arguments(p)
    args = p.parse_args(argv)
    args.out = str(out)
    return args


def _record(module, argv, out, drop=()) -> str:
    rec = to_jsonable(module.run(_args(module, argv, out)))
    for k in ("machine", *drop):
        rec.pop(k)
    return json.dumps(rec, sort_keys=True)


def test_sweeps_default_to_this_process_and_take_the_engine_options():
    from vishap.bench import stability
    from vishap.scale.cli import default_workers

    assert default_workers(_args(stability, [], ".")) == 1
    assert default_workers(_args(stability, ["--workers", "3"], ".")) == 3
    assert default_workers(_args(stability, ["--address", "head:6379"], ".")) is None


@pytest.mark.parametrize("bench", ["stability", "world", "vision_stability", "servo_quality"])
def test_a_sweep_given_an_unreachable_cluster_stops_with_one_error(bench, tmp_path, capsys):
    import socket

    from vishap.cli import main

    with socket.socket() as s:  # a port nobody listens on
        s.bind(("127.0.0.1", 0))
        address = f"127.0.0.1:{s.getsockname()[1]}"
    out = tmp_path / "out"
    argv = ["bench", bench, "--address", address, "--out", str(out)]
    argv += {"stability": ["--quick"], "world": ["--approaches", "1", "--policy-approaches", "1", "--scenes", "wall"],
             "vision_stability": ["--quick"], "servo_quality": ["--seeds", "0", "--scenes", "wall"]}[bench]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"cannot reach the Ray cluster at {address}" in err and err.count("\n") == 1
    assert not out.exists()


def test_stability_sweep_on_two_workers_equals_serial(ray_two_cpus):
    from vishap.bench.stability import run_sweeps

    serial = run_sweeps(2, quick=True, workers=1)
    parallel = run_sweeps(2, quick=True, workers=2)
    assert len(serial) == 12 and {r["sweep"] for r in serial} == {"kp_kv", "filter", "rate", "delay", "contact", "wall"}
    assert json.dumps(to_jsonable(parallel)) == json.dumps(to_jsonable(serial))


def test_world_approaches_on_two_workers_equal_serial(ray_two_cpus, tmp_path):
    from vishap.bench import world

    argv = ["--scenes", "wall", "--approaches", "1", "--policy-approaches", "1"]
    drop = ("servo_cost_us", "wall_time_s", "charts")
    serial = _record(world, argv, tmp_path / "a", drop)
    assert json.loads(serial)["approaches"] == 1 and len(json.loads(serial)["policies"]) == len(world.POLICIES)
    assert _record(world, [*argv, "--workers", "2"], tmp_path / "b", drop) == serial


def test_vision_stability_on_two_workers_equals_serial(ray_two_cpus, tmp_path, monkeypatch):
    from vishap.bench import vision_stability as vs

    monkeypatch.setattr(vs, "SWEEPS", {"occlusion_frames": vs.SWEEPS["occlusion_frames"]})
    argv = ["--quick", "--frames", "6"]
    serial = _record(vs, argv, tmp_path / "a", ("chart",))
    rows = json.loads(serial)["sweeps"]
    assert [r["value"] for r in rows["occlusion_frames"]] == [0, 30]
    assert rows["occlusion_frames"][0]["full frame"]["detection_rate"] > 0.5
    assert rows["occlusion_frames"][1]["tracked window"]["recovery_frames"] is not None
    assert _record(vs, [*argv, "--workers", "2"], tmp_path / "b", ("chart",)) == serial


@pytest.mark.render
def test_demo_seed_sweep_on_two_workers_equals_serial(ray_two_cpus, tmp_path):
    """The demos of ``bench servo_quality``'s seed sweep: every simulated channel and summary field
    equal; only the measured compute times (ms, µs, wall seconds) differ between runs."""
    from vishap.bench.servo_quality import demo_files

    # the committed calibration (its rig is 640x480): no calibration run, quicker
    calib = str(Path(__file__).resolve().parents[2] / "calib" / "camera_robot.yaml")
    cases = [{"scene": "wall", "seed": s, "substeps": 10, "encoder": "encoder", "video": False, "save_frames": False,
              "frames": 12, "width": 640, "height": 480, "calib": calib} for s in (0, 1)]
    serial = map_cases(demo_files, cases, workers=1)
    parallel = map_cases(demo_files, cases, workers=2)
    timed = ("_ms", "_us", "wall_s", "realtime_factor", "servo_overruns")
    for a, b in zip(serial, parallel):
        assert sorted(a) == sorted(b) and {"log.npz", "summary.json"} <= set(a)
        la, lb = np.load(io.BytesIO(a["log.npz"])), np.load(io.BytesIO(b["log.npz"]))
        kept = [k for k in la.files if not k.endswith(timed)]
        assert len(kept) > 50
        for k in kept:
            assert np.array_equal(la[k], lb[k], equal_nan=la[k].dtype.kind == "f"), k
        sa, sb = (json.loads(x["summary.json"]) for x in (a, b))
        keep = [k for k in sa if not any(t in k for t in timed)]
        assert {k: sa[k] for k in keep} == {k: sb[k] for k in keep}
    assert [json.loads(x["summary.json"])["seed"] for x in parallel] == [0, 1]  # in the cases' order
