"""The scale-out engine: addresses, unreachable clusters, and map_cases against a serial run."""
from __future__ import annotations

import os
import socket
import time

import numpy as np
import pytest

from vishap._core.errors import ConfigError
from vishap.cli import main
from vishap.scale import ClusterError, map_cases
from vishap.scale.cli import seed_range
from vishap.scale.engine import engine, parse_address


def _free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_parse_address():
    assert parse_address("10.0.0.5:6379") == ("10.0.0.5", 6379)
    assert parse_address("ray://head.example:10001") == ("head.example", 10001)
    assert parse_address("auto") is None
    for bad in ("head", "head:", ":6379", "head:99999", "head:port"):
        with pytest.raises(ConfigError, match="HOST:PORT"):
            parse_address(bad)


def test_seed_range():
    assert seed_range("3:7") == range(3, 7)
    for bad in ("7", "7:3", "3:3", "-1:2", "a:b"):
        with pytest.raises(Exception, match="A:B|A < B"):
            seed_range(bad)


def test_unreachable_cluster_is_an_error_and_nothing_is_written(tmp_path, capsys):
    address = f"127.0.0.1:{_free_port()}"
    out = tmp_path / "set"
    t0 = time.monotonic()
    argv = ["synth", "--scene", "wall", "--frames", "2", "--resolution", "160x120", "--seeds", "0:2",
            "--address", address, "--quiet", "--out", str(out)]
    assert main(argv) == 2
    err = capsys.readouterr().err
    assert f"cannot reach the Ray cluster at {address}" in err and err.count("\n") == 1
    assert not out.exists()
    with pytest.raises(ClusterError, match="cannot reach"):
        map_cases(_case, [1, 2], address=address)
    assert time.monotonic() - t0 < 30  # the probe, not Ray's minutes of retries


def test_workers_without_seeds_is_an_error(tmp_path, capsys):
    out = tmp_path / "seq"
    assert main(["synth", "--scene", "wall", "--frames", "2", "--workers", "2", "--quiet", "--out", str(out)]) == 2
    assert "give --seeds A:B" in capsys.readouterr().err
    assert not out.exists()


def _case(seed: int):
    """A case whose result depends on its seed only; the longer cases come first, so a parallel run
    finishes them out of order."""
    time.sleep(0.05 * (6 - seed))
    return {"seed": seed, "draw": np.random.default_rng(seed).normal(size=3).tolist()}


def _case_with_worker(seed: int):
    return _case(seed), os.getpid(), os.environ.get("LP_NUM_THREADS")


def test_map_cases_serial_and_two_ray_workers_agree_in_order():
    cases = list(range(6))
    serial = map_cases(_case, cases, workers=1)
    assert [r["seed"] for r in serial] == cases
    ray_out = map_cases(_case_with_worker, cases, workers=2)
    assert [r[0] for r in ray_out] == serial
    assert os.getpid() not in {r[1] for r in ray_out}  # ran in Ray's workers, not here
    assert {r[2] for r in ray_out} == {"1"}  # renderer threads pinned per worker


def test_a_local_run_starts_its_own_instance_whatever_address_the_environment_names(monkeypatch):
    # RAY_ADDRESS names a cluster nobody runs: a local run (no --address) must not try to join it
    # (Ray would join, or fail on the CPU count), and the variable is the user's again afterwards
    dead = f"127.0.0.1:{_free_port()}"
    monkeypatch.setenv("RAY_ADDRESS", dead)
    with engine(workers=2) as e:
        described = e.describe()
    assert described["mode"] == "local-ray" and described["cluster_cpus"] == 2.0
    assert os.environ["RAY_ADDRESS"] == dead
