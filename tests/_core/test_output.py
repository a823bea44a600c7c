"""Output folders written whole: vishap._core.output (issue 17, item 2)."""
from __future__ import annotations

import os
import signal
import subprocess
import sys

import pytest

from vishap._core.errors import ConfigError
from vishap._core.output import check_output_file, output_dir


def _names(folder):
    return sorted(p.name for p in folder.iterdir())


def test_writes_into_a_hidden_sibling_then_renames(tmp_path):
    out = tmp_path / "a" / "b" / "out"
    with output_dir(out) as folder:
        assert folder.path.parent == out.parent and folder.path.name.startswith(".out.tmp-")
        assert not out.exists()
        (folder.path / "x.txt").write_text("1")
    assert folder.final == out and _names(out) == ["x.txt"] and _names(out.parent) == ["out"]
    assert oct(out.stat().st_mode & 0o777) != oct(0o700)  # an ordinary folder, not mkdtemp's 0700


def test_non_empty_out_is_refused_and_kept(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "keep.txt").write_text("mine")
    with pytest.raises(ConfigError, match="not empty.*--overwrite"):
        with output_dir(out):
            pass
    assert _names(out) == ["keep.txt"] and _names(tmp_path) == ["out"]
    with output_dir(tmp_path / "empty_ok"):
        pass


def test_overwrite_swaps_only_at_the_end(tmp_path):
    out = tmp_path / "out"
    out.mkdir()
    (out / "old.txt").write_text("old")
    with pytest.raises(RuntimeError):
        with output_dir(out, overwrite=True) as folder:
            (folder.path / "new.txt").write_text("new")
            raise RuntimeError("failed half way")
    assert _names(out) == ["old.txt"] and _names(tmp_path) == ["out"]
    with output_dir(out, overwrite=True) as folder:
        (folder.path / "new.txt").write_text("new")
    assert _names(out) == ["new.txt"] and _names(tmp_path) == ["out"]


def test_failure_removes_only_what_it_created(tmp_path):
    """A failed run into a new parent must not delete another run's finished output put there meanwhile."""
    parent = tmp_path / "runs"
    with pytest.raises(KeyboardInterrupt):
        with output_dir(parent / "mine") as folder:
            (folder.path / "half.png").write_text("x")
            (parent / "other").mkdir()  # another run finished beside it
            (parent / "other" / "result.json").write_text("{}")
            raise KeyboardInterrupt
    assert _names(tmp_path) == ["runs"] and _names(parent) == ["other"]
    assert (parent / "other" / "result.json").read_text() == "{}"
    with pytest.raises(RuntimeError):
        with output_dir(tmp_path / "new1" / "new2" / "out"):
            raise RuntimeError
    assert _names(tmp_path) == ["runs"]  # its own empty parents went with it


def test_two_runs_into_one_out_never_replace_each_other(tmp_path):
    out = tmp_path / "out"
    with pytest.raises(ConfigError, match="another run wrote this folder meanwhile.*out-2"):
        with output_dir(out) as late:
            with output_dir(out) as early:
                (early.path / "who").write_text("early")
            (late.path / "who").write_text("late")
    assert (out / "who").read_text() == "early" and (tmp_path / "out-2" / "who").read_text() == "late"
    assert _names(tmp_path) == ["out", "out-2"]


@pytest.mark.parametrize("setup, match", [("file", "not a folder"), ("under_file", "is a file")])
def test_out_onto_or_under_a_file(tmp_path, setup, match):
    f = tmp_path / "file"
    f.write_text("data")
    with pytest.raises(ConfigError, match=match):
        with output_dir(f if setup == "file" else f / "sub"):
            pass
    assert _names(tmp_path) == ["file"] and f.read_text() == "data"


@pytest.mark.skipif(os.geteuid() == 0, reason="root writes into read-only folders")
def test_read_only_parent(tmp_path):
    ro = tmp_path / "ro"
    ro.mkdir()
    ro.chmod(0o555)
    try:
        with pytest.raises(ConfigError, match="cannot write"):
            with output_dir(ro / "out"):
                pass
    finally:
        ro.chmod(0o755)


def test_refuses_to_overwrite_the_current_folder(tmp_path, monkeypatch):
    (tmp_path / "x").write_text("precious")
    monkeypatch.chdir(tmp_path)
    with pytest.raises(ConfigError, match="refusing"):
        with output_dir(".", overwrite=True):
            pass
    assert (tmp_path / "x").read_text() == "precious"


@pytest.mark.parametrize("sig", [signal.SIGTERM, signal.SIGINT])
def test_signal_leaves_no_temporary_folder(tmp_path, sig):
    # a job started in the background inherits SIGINT ignored; a user's terminal delivers it as KeyboardInterrupt
    code = ("import signal, sys, time\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
            "from vishap._core.output import output_dir\n"
            "with output_dir(sys.argv[1]) as f:\n    (f.path / 'frame.png').write_text('x')\n"
            "    print('ready', flush=True)\n    time.sleep(60)\n")
    proc = subprocess.Popen([sys.executable, "-c", code, str(tmp_path / "out")], stdout=subprocess.PIPE, text=True)
    assert proc.stdout.readline().strip() == "ready"
    assert len(list(tmp_path.iterdir())) == 1  # the hidden temporary folder
    proc.send_signal(sig)
    rc = proc.wait(timeout=30)
    assert rc != 0
    assert list(tmp_path.iterdir()) == []


def test_check_output_file(tmp_path):
    f = tmp_path / "rig.yaml"
    f.write_text("x")
    with pytest.raises(ConfigError, match="exists.*--overwrite"):
        check_output_file(f)
    assert check_output_file(f, overwrite=True) == f
    with pytest.raises(ConfigError, match="is a folder"):
        check_output_file(tmp_path)
    with pytest.raises(ConfigError, match="is a file"):
        check_output_file(f / "sub.yaml")


def test_check_output_folder_refuses_before_anything_is_made(tmp_path, monkeypatch):
    from vishap._core.output import check_output_folder

    full = tmp_path / "full"
    full.mkdir()
    (full / "x").write_text("1")
    with pytest.raises(ConfigError, match="not empty"):
        check_output_folder(full)
    assert check_output_folder(tmp_path / "a" / "b") == tmp_path / "a" / "b"
    assert _names(tmp_path) == ["full"]  # nothing created
    # a folder the user may not write into (simulated: the tests may run as root, who may write anywhere)
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if str(p) == str(tmp_path) else real(p, mode))
    with pytest.raises(ConfigError, match="not writable"):
        check_output_folder(tmp_path / "new")
    with pytest.raises(ConfigError, match="not writable"):
        with output_dir(tmp_path / "new"):
            pass
    assert _names(tmp_path) == ["full"]
