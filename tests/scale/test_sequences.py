"""``vishap synth --seeds``: per-seed bytes equal single runs, manifest checksums, resuming."""
from __future__ import annotations

import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from vishap._core.errors import ConfigError
from vishap.cli import main
from vishap.scale import Job, build_sequences, spec_parameters
from vishap.sim.sequence import SequenceSpec

pytestmark = pytest.mark.render

OPTS = ["--scene", "wall", "--frames", "3", "--hand-free", "1", "--resolution", "160x120", "--quiet"]


def _digest(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _single(tmp_path: Path, seed: int) -> dict[str, str]:
    out = tmp_path / f"single-{seed}"
    assert main(["synth", *OPTS, "--seed", str(seed), "--out", str(out)]) == 0
    return _digest(out)


def _manifest(out: Path) -> dict:
    return json.loads((out / "manifest.json").read_text())


def test_two_ray_workers_write_the_bytes_of_single_runs(tmp_path, capsys):
    out = tmp_path / "set"
    assert main(["synth", *OPTS, "--seeds", "0:3", "--workers", "2", "--out", str(out), "--json"]) == 0
    summary = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert summary["built"] == 3 and summary["engine"]["mode"] == "local-ray" and summary["engine"]["workers"] == 2
    m = _manifest(out)
    assert sorted(m["sequences"]) == ["seed-000000", "seed-000001", "seed-000002"]
    assert m["parameters"]["seeds"] == [0, 3] and "seed" not in m["parameters"]
    for s in range(3):
        got = _digest(out / f"seed-{s:06d}")
        assert got == _single(tmp_path, s)
        entry = m["sequences"][f"seed-{s:06d}"]
        assert entry["files"] == got and entry["parameters"]["seed"] == s and entry["frames"] == 3
    assert sorted(p.name for p in out.iterdir()) == [".vishap-build.lock", "manifest.json",
                                                     "seed-000000", "seed-000001", "seed-000002"]


def _jobs(seeds, **kw):
    jobs = []
    for s in seeds:
        spec = SequenceSpec(scene="wall", frames=2, seed=s, width=160, height=120, hand_free_frames=1, **kw)
        jobs.append(Job(f"seed-{s:06d}", spec, spec_parameters(spec)))
    return jobs


def test_rerun_skips_finished_and_redoes_damaged_or_unrecorded(tmp_path):
    out = tmp_path / "set"
    first = build_sequences(_jobs(range(3)), out, workers=1, progress=False)
    assert len(first["built"]) == 3
    clean = {s: _digest(out / f"seed-{s:06d}") for s in range(3)}
    inode0 = (out / "seed-000000" / "gt.npz").stat().st_ino

    again = build_sequences(_jobs(range(3)), out, workers=1, progress=False)
    assert again["built"] == [] and len(again["skipped"]) == 3

    (out / "seed-000001" / "left" / "000001.png").write_bytes(b"half")  # a damaged file
    m = _manifest(out)
    del m["sequences"]["seed-000002"]  # stopped between the rename and the manifest
    (out / "manifest.json").write_text(json.dumps(m))
    stale = out / ".seed-000000.tmp-killed"  # a killed run's temporary folder
    (stale / "left").mkdir(parents=True)
    (stale / "left" / "000000.png").write_bytes(b"x")

    redo = build_sequences(_jobs(range(3)), out, workers=1, progress=False)
    assert redo["built"] == ["seed-000001", "seed-000002"] and redo["skipped"] == ["seed-000000"]
    assert {s: _digest(out / f"seed-{s:06d}") for s in range(3)} == clean
    assert (out / "seed-000000" / "gt.npz").stat().st_ino == inode0
    assert not stale.exists()
    assert set(_manifest(out)["sequences"]) == {"seed-000000", "seed-000001", "seed-000002"}


def test_a_killed_build_resumes_to_the_same_bytes(tmp_path):
    out = tmp_path / "set"
    argv = [sys.executable, "-m", "vishap", "synth", *OPTS, "--frames", "4", "--seeds", "0:3", "--workers", "1",
            "--out", str(out)]
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    try:
        deadline = time.monotonic() + 240
        while time.monotonic() < deadline and proc.poll() is None:
            if (out / "manifest.json").exists() and len(_manifest(out)["sequences"]) >= 1:
                break
            time.sleep(0.05)
        assert proc.poll() is None, "the build finished before it could be stopped"
        os.kill(proc.pid, signal.SIGKILL)
    finally:
        proc.wait()
    done_before = set(_manifest(out)["sequences"])
    assert 1 <= len(done_before) < 3
    assert main(["synth", *OPTS, "--frames", "4", "--seeds", "0:3", "--workers", "1", "--out", str(out)]) == 0
    m = _manifest(out)
    assert set(m["sequences"]) == {"seed-000000", "seed-000001", "seed-000002"}
    assert sorted(p.name for p in out.iterdir() if p.name.startswith(".seed")) == []
    ref = tmp_path / "ref"
    assert main(["synth", *OPTS, "--frames", "4", "--seeds", "0:3", "--workers", "1", "--out", str(ref)]) == 0
    for s in range(3):
        assert _digest(out / f"seed-{s:06d}") == _digest(ref / f"seed-{s:06d}")


def test_other_parameters_or_a_foreign_folder_are_errors(tmp_path):
    out = tmp_path / "set"
    build_sequences(_jobs([0]), out, workers=1, progress=False)
    with pytest.raises(ConfigError, match="seed-000000 was built with other parameters.*lighting"):
        build_sequences(_jobs([0], lighting="step"), out, workers=1, progress=False)
    foreign = tmp_path / "foreign"
    foreign.mkdir()
    (foreign / "notes.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not empty and has no manifest.json"):
        build_sequences(_jobs([0]), foreign, workers=1, progress=False)
    assert sorted(p.name for p in foreign.iterdir()) == [".vishap-build.lock", "notes.txt"]


@pytest.mark.slow
def test_simulated_two_node_cluster_writes_identical_bytes(tmp_path):
    import ray
    from ray.cluster_utils import Cluster

    jobs = _jobs([0, 1]) + _jobs([2], store="video")  # the compact store travels and matches too
    here = tmp_path / "here"
    build_sequences(jobs, here, workers=1, progress=False)
    cluster = Cluster(initialize_head=True, head_node_args={"num_cpus": 1})
    try:
        cluster.add_node(num_cpus=1)
        cluster.wait_for_nodes()
        there = tmp_path / "there"
        summary = build_sequences(jobs, there, workers=None, address=cluster.address, progress=False)
    finally:
        ray.shutdown()
        cluster.shutdown()
    assert summary["engine"]["mode"] == "cluster" and summary["engine"]["nodes"] == 2
    assert summary["engine"]["workers"] == 2
    nodes = {e["node"] for e in _manifest(there)["sequences"].values()}
    assert len(nodes) == 2  # sequences built on both nodes
    assert "left.mkv" in _digest(there / "seed-000002")
    for s in (0, 1, 2):
        assert _digest(there / f"seed-{s:06d}") == _digest(here / f"seed-{s:06d}")
