"""Issue 17 through the command line: output folders and files, progress bars, short summaries with
the JSON on request, and the stumbles of a new user."""
from __future__ import annotations

import json
import os
import re
import subprocess
import sys
import threading
from pathlib import Path

import cv2
import numpy as np
import pytest

import vishap
from vishap.cli import build_parser, main

#: commands that run long enough to need a progress bar (every benchmark too)
LONG = {"demo", "replay", "track", "eval vision", "eval fingertip", "calibrate stereo", "calibrate robot", "synth",
        "dataset build"}


def _leaves(parser, prefix=""):
    """(``"calibrate robot"``, parser) for every command that runs something."""
    subs = [a for a in parser._actions if a.__class__.__name__ == "_SubParsersAction"]
    if not subs:
        yield prefix.strip(), parser
        return
    for name, p in subs[0].choices.items():
        yield from _leaves(p, f"{prefix} {name}")


def _options(p) -> set[str]:
    return {o for a in p._actions for o in a.option_strings}


def _one_line(err: str) -> str:
    lines = err.strip().splitlines()
    assert len(lines) == 1 and "Traceback" not in err, err
    return lines[0]


def test_every_command_offers_json_quiet_and_overwrite():
    leaves = dict(_leaves(build_parser()))
    assert {"demo", "replay", "track", "eval fingertip", "calibrate robot", "bench tracking"} <= set(leaves)
    for name, p in leaves.items():
        opts = _options(p)
        assert "--json" in opts, f"{name}: no --json"
        if name in LONG or name.startswith("bench "):
            assert "--quiet" in opts, f"{name}: no --quiet"
        if "--out" in opts and name != "dataset build":  # a data set resumes instead
            assert "--overwrite" in opts, f"{name}: --out without --overwrite"


# ---------------------------------------------------------------- track and eval on a toy sequence
@pytest.fixture(scope="module")
def toy(tmp_path_factory):
    from vishap.vision.toy import write_sequence

    folder = tmp_path_factory.mktemp("toy") / "s1"
    write_sequence(folder, seed=1)
    return folder


def test_track_refuses_an_existing_or_bad_out_before_tracking(toy, tmp_path, capsys):
    out = tmp_path / "tracks.json"
    out.write_text("another run's tracks")
    assert main(["track", str(toy), "--out", str(out)]) == 2
    assert "--overwrite" in _one_line(capsys.readouterr().err) and out.read_text() == "another run's tracks"
    for bad, what in ((tmp_path, "is a folder"), (out / "x.json", "is a file")):
        assert main(["track", str(toy), "--out", str(bad)]) == 2
        assert what in _one_line(capsys.readouterr().err)
    assert main(["track", str(toy), "--out", str(out), "--overwrite"]) == 0
    text = capsys.readouterr().out
    assert len(text.splitlines()) <= 3 and "{" not in text and str(out) in text
    assert json.loads(out.read_text())["frames"] == 16
    assert sorted(p.name for p in tmp_path.iterdir()) == ["tracks.json"]


def test_progress_with_an_eta_only_on_a_terminal_and_not_when_quiet(toy, tmp_path, capsys, monkeypatch):
    assert main(["track", str(toy), "--out", str(tmp_path / "a.json")]) == 0
    assert "/16 [" not in capsys.readouterr().err  # a log or a pipe gets no bar
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    # redraw on every frame: the toy's 16 frames can pass within tqdm's default 0.1 s between redraws
    from tqdm import tqdm

    init = tqdm.__init__
    monkeypatch.setattr(tqdm, "__init__", lambda self, *a, **kw: init(self, *a, **{**kw, "mininterval": 0}))
    assert main(["track", str(toy), "--out", str(tmp_path / "b.json")]) == 0
    err = capsys.readouterr().err
    assert re.search(r"track: .* \d+/16 \[\d\d:\d\d<\d\d:\d\d", err), err  # elapsed<remaining: the ETA
    assert main(["eval", "vision", str(toy)]) == 0
    assert re.search(r"eval s1: .* \d+/16 \[\d\d:\d\d<", capsys.readouterr().err)
    assert main(["track", str(toy), "--out", str(tmp_path / "c.json"), "--quiet"]) == 0
    assert "/16 [" not in capsys.readouterr().err


def test_eval_summary_is_short_and_json_keeps_its_keys(toy, capsys):
    assert main(["eval", "vision", str(toy)]) == 0
    text = capsys.readouterr().out
    assert len(text) < 400 and "{" not in text and "detected" in text
    assert main(["eval", "vision", str(toy), "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert {"frames", "detection_rate", "tip3d_rms_mm", "ms_per_pair", "folder"} <= set(rec)


def test_eval_fingertip_out_is_refused_before_the_photos_are_read(toy, tmp_path, capsys):
    labels = tmp_path / "labels.csv"
    labels.write_text("frame,u,v\n0,10,10\n")
    f = tmp_path / "a_file"
    f.write_text("x")
    assert main(["eval", "fingertip", str(toy), "--labels", str(labels), "--detector", "paper", "--out", str(f)]) == 2
    assert "not a folder" in _one_line(capsys.readouterr().err)
    full = tmp_path / "res"
    full.mkdir()
    (full / "mine.csv").write_text("keep")
    assert main(["eval", "fingertip", str(toy), "--labels", str(labels), "--detector", "paper",
                 "--out", str(full)]) == 2
    assert "not empty" in _one_line(capsys.readouterr().err) and (full / "mine.csv").read_text() == "keep"


# ---------------------------------------------------------------- calibration
def _blank(path, w, h):
    cv2.imwrite(str(path), np.full((h, w), 128, np.uint8))


def test_calibrate_stereo_names_the_image_of_another_size(tmp_path, capsys):
    for i, (w, h) in enumerate([(160, 120), (160, 120), (200, 150)]):
        _blank(tmp_path / f"left_{i}.png", w, h)
        _blank(tmp_path / f"right_{i}.png", w, h)
    argv = ["calibrate", "stereo", "--left", str(tmp_path / "left_*.png"), "--right", str(tmp_path / "right_*.png"),
            "--board", "9x6", "--square", "0.02", "--out", str(tmp_path / "rig.yaml")]
    assert main(argv) == 2
    err = _one_line(capsys.readouterr().err)
    assert "left_2.png" in err and "200x150" in err and "left_0.png" in err and "160x120" in err
    _blank(tmp_path / "right_1.png", 200, 150)
    _blank(tmp_path / "left_2.png", 160, 120)
    _blank(tmp_path / "right_2.png", 160, 120)
    assert main(argv) == 2
    err = _one_line(capsys.readouterr().err)
    assert "right_1.png" in err and "left_1.png" in err
    assert not (tmp_path / "rig.yaml").exists()


def test_calibrate_stereo_shows_progress_over_the_pairs(tmp_path, capsys, monkeypatch):
    for i in range(3):
        _blank(tmp_path / f"left_{i}.png", 160, 120)
        _blank(tmp_path / f"right_{i}.png", 160, 120)
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["calibrate", "stereo", "--left", str(tmp_path / "left_*.png"), "--right", str(tmp_path / "right_*.png"),
                 "--board", "9x6", "--square", "0.02", "--out", str(tmp_path / "rig.yaml")]) == 2
    err = capsys.readouterr().err
    assert re.search(r"calibrate stereo: .* \d+/3 \[\d\d:\d\d<", err), err
    assert "found in both images of only 0 of 3 pairs" in err


@pytest.mark.render
def test_calibrate_robot_shows_progress_over_the_poses(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["calibrate", "robot", "--sim", "--poses", "4", "--size", "320x240",
                 "--out", str(tmp_path / "c.yaml")]) == 0
    captured = capsys.readouterr()
    assert re.search(r"calibrate robot: .* \d+/\d+ \[\d\d:\d\d<", captured.err), captured.err
    assert captured.out.startswith("camera-to-robot calibration from 4 of 4 poses") and "{" not in captured.out


def test_calibrate_refuses_an_existing_out_before_calibrating(tmp_path, capsys):
    mine = tmp_path / "rig.yaml"
    mine.write_text("another calibration")
    assert main(["calibrate", "stereo", "--left", str(tmp_path / "none*.png"), "--right", str(tmp_path / "x*.png"),
                 "--board", "9x6", "--square", "0.02", "--out", str(mine)]) == 2
    assert "--overwrite" in _one_line(capsys.readouterr().err)
    for extra in (["--out", str(mine)], ["--out", str(tmp_path / "c.yaml"), "--poses-out", str(mine)],
                  ["--out", str(mine / "c.yaml")]):
        assert main(["calibrate", "robot", "--sim", "--poses", "4", *extra]) == 2
        err = _one_line(capsys.readouterr().err)
        assert "rig.yaml" in err and ("exists" in err or "is a file" in err)
    assert mine.read_text() == "another calibration" and sorted(p.name for p in tmp_path.iterdir()) == ["rig.yaml"]


# ---------------------------------------------------------------- the demo and its replay
def _run_on_a_terminal(argv, cwd, size=(40, 120)):
    """Run ``vishap ARGV`` with stderr on a pseudo-terminal of ``size`` (rows, columns), as a user sees
    it; (rc, stdout, stderr)."""
    import fcntl
    import pty
    import struct
    import termios

    master, slave = pty.openpty()
    fcntl.ioctl(slave, termios.TIOCSWINSZ, struct.pack("HHHH", size[0], size[1], 0, 0))
    root = str(Path(vishap.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    proc = subprocess.Popen([sys.executable, "-m", "vishap", *argv], cwd=cwd, stdout=subprocess.PIPE, stderr=slave,
                            env=env)
    os.close(slave)
    chunks = []

    def drain():
        while True:
            try:
                data = os.read(master, 4096)
            except OSError:  # the child closed the terminal
                return
            if not data:
                return
            chunks.append(data)

    reader = threading.Thread(target=drain)
    reader.start()
    out, _ = proc.communicate(timeout=600)
    reader.join(timeout=30)
    os.close(master)
    return proc.returncode, out.decode(), b"".join(chunks).decode(errors="replace")


def test_progress_on_a_terminal_that_reports_no_size(toy, tmp_path):
    rc, out, err = _run_on_a_terminal(["track", str(toy), "--out", str(tmp_path / "t.json")], tmp_path, size=(0, 0))
    assert rc == 0 and re.search(r"track: .* \d+/16 \[\d\d:\d\d<", err), err


@pytest.fixture(scope="module")
def demo(tmp_path_factory):
    """``vishap demo wall --out wall`` run by a user in a folder that already holds an empty ``wall``."""
    cwd = tmp_path_factory.mktemp("user")
    (cwd / "wall").mkdir()
    rc, out, err = _run_on_a_terminal(["demo", "wall", "--frames", "12", "--no-video", "--out", "wall"], cwd)
    return cwd, rc, out, err


@pytest.mark.render
def test_demo_wall_out_wall_shows_progress_and_a_short_summary(demo):
    cwd, rc, out, err = demo
    assert rc == 0, err
    assert re.search(r"demo wall: .* \d+/12 \[\d\d:\d\d<", err), err  # tqdm, with the ETA
    assert "frame 1/12" not in err  # not the hand-made counter
    assert len(out.splitlines()) <= 8 and "{" not in out, out
    assert "summary.json" in out and str(cwd / "wall") in out
    summary = json.loads((cwd / "wall" / "summary.json").read_text())
    assert summary["frames"] == 12
    # 12 frames are all hand-free background frames: nothing to detect is no rate, not a rate of 0
    assert summary["tip_visible_frames"] == 0 and summary["detection_rate"] is None
    assert sorted(p.name for p in cwd.iterdir()) == ["wall"]


@pytest.mark.render
def test_replay_help_names_only_what_replay_writes(demo, tmp_path, capsys, monkeypatch):
    cwd = demo[0]
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    helptext = " ".join(build_parser()._subparsers._group_actions[0].choices["replay"].format_help().split())
    named = set(re.findall(r"[\w.]+\.(?:npz|json)", helptext)) - {"log.npz"}  # log.npz is the input
    assert named, helptext
    assert main(["replay", str(cwd / "wall"), "--out", str(tmp_path / "r"), "--json"]) == 0
    captured = capsys.readouterr()
    assert re.search(r"replay: .* \d+/12 \[\d\d:\d\d<", captured.err), captured.err
    rec = json.loads(captured.out)
    assert rec["identical"], rec
    written = {p.name for p in (tmp_path / "r").iterdir()}
    assert named <= written, (named, written)
    assert json.loads((tmp_path / "r" / "replay.json").read_text())["identical"]


@pytest.mark.render
def test_replay_out_is_written_whole_and_never_over_another_run(demo, tmp_path, capsys):
    cwd = demo[0]
    full = tmp_path / "r"
    full.mkdir()
    (full / "replay.json").write_text("another run")
    assert main(["replay", str(cwd / "wall"), "--out", str(full)]) == 2
    assert "not empty" in _one_line(capsys.readouterr().err) and (full / "replay.json").read_text() == "another run"
    f = tmp_path / "file"
    f.write_text("x")
    for bad, what in ((f, "not a folder"), (f / "sub", "is a file")):
        assert main(["replay", str(cwd / "wall"), "--out", str(bad)]) == 2
        assert what in _one_line(capsys.readouterr().err)
    assert main(["replay", str(cwd / "wall"), "--out", str(full), "--overwrite"]) == 0
    text = capsys.readouterr().out
    assert text.startswith(f"replay of {cwd / 'wall'} (wall): identical") and "{" not in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file", "r"]


@pytest.mark.render
def test_a_mistyped_calib_stops_the_demo_at_once(tmp_path, capsys):
    out = tmp_path / "run"
    assert main(["demo", "wall", "--frames", "12", "--no-video", "--calib", str(tmp_path / "camera_robt.yaml"),
                 "--out", str(out)]) == 2
    assert "camera_robt.yaml" in _one_line(capsys.readouterr().err)
    assert list(tmp_path.iterdir()) == []


@pytest.mark.render
def test_demo_out_onto_a_file_is_one_error(tmp_path, capsys):
    f = tmp_path / "wall"
    f.write_text("x")
    assert main(["demo", "wall", "--frames", "12", "--no-video", "--out", str(f)]) == 2
    assert "not a folder" in _one_line(capsys.readouterr().err) and f.read_text() == "x"


# ---------------------------------------------------------------- benchmarks
def test_bench_tracking_policy_chart_has_no_empty_panel(tmp_path, monkeypatch):
    """The quick run is 1 s long: the trace panel must still show the finger and the three policies."""
    import argparse

    from vishap.bench import tracking

    plotted = {}
    real = tracking.save_figure

    def keep(fig, path):
        plotted[Path(path).name] = [sum(len(line.get_xdata()) for line in ax.lines) + len(ax.patches)
                                    for ax in fig.axes]
        return real(fig, path)

    monkeypatch.setattr(tracking, "save_figure", keep)
    tracking.run(argparse.Namespace(out=str(tmp_path), gains=None, latency_ms=30.0, duration=1.0, quick=True))
    panels = plotted["tracking_policies.png"]
    assert len(panels) == 3 and all(n > 0 for n in panels), panels


def test_bench_shows_progress_over_its_cases(tmp_path, capsys, monkeypatch):
    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    assert main(["bench", "tracking", "--quick", "--out", str(tmp_path / "b")]) == 0
    assert re.search(r"bench tracking: policies: .* \d+/3 \[\d\d:\d\d<", capsys.readouterr().err)
    assert main(["bench", "tracking", "--quick", "--quiet", "--out", str(tmp_path / "c")]) == 0
    captured = capsys.readouterr()
    assert "/3 [" not in captured.err
    assert "tracking.json" in captured.out and "{" not in captured.out


def test_bench_registration_shows_progress_over_its_parts(tmp_path, capsys, monkeypatch):
    from tqdm import tqdm

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    init = tqdm.__init__  # redraw on every part, however quick
    monkeypatch.setattr(tqdm, "__init__", lambda self, *a, **kw: init(self, *a, **{**kw, "mininterval": 0}))
    assert main(["bench", "registration", "--trials", "2", "--no-render", "--out", str(tmp_path / "r")]) == 0
    err = capsys.readouterr().err
    assert re.search(r"bench registration: .* [1-5]/5 \[\d\d:\d\d<", err), err
    assert (tmp_path / "r" / "registration.json").is_file()


@pytest.mark.render
def test_bench_synth_shows_progress_over_its_parts(tmp_path, capsys, monkeypatch):
    from tqdm import tqdm

    monkeypatch.setattr(sys.stderr, "isatty", lambda: True)
    init = tqdm.__init__  # redraw on every part, however quick
    monkeypatch.setattr(tqdm, "__init__", lambda self, *a, **kw: init(self, *a, **{**kw, "mininterval": 0}))
    assert main(["bench", "synth", "--pairs", "2", "--resolution", "160x120", "--vis-resolution", "160x120",
                 "--vis-stride", "40", "--scenes", "wall,button", "--out", str(tmp_path / "s")]) == 0
    err = capsys.readouterr().err
    assert re.search(r"bench synth: .* [1-3]/3 \[\d\d:\d\d<", err), err
    rec = json.loads((tmp_path / "s" / "synth.json").read_text())
    assert list(rec["visibility"]) == ["wall", "button"]


@pytest.mark.render
def test_a_terminated_demo_leaves_nothing_behind(tmp_path, sig="SIGTERM"):
    import signal
    import time

    root = str(Path(vishap.__file__).resolve().parents[1])
    env = {**os.environ, "PYTHONPATH": os.pathsep.join([root, os.environ.get("PYTHONPATH", "")])}
    (tmp_path / "runs").mkdir()
    proc = subprocess.Popen([sys.executable, "-m", "vishap", "demo", "wall", "--frames", "60", "--no-video",
                             "--out", str(tmp_path / "runs" / "new" / "wall")], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 120
    while not list((tmp_path / "runs").glob("new/.wall.tmp-*/*")) and time.monotonic() < deadline:
        time.sleep(0.1)  # until the run has written something into its temporary folder
    assert proc.poll() is None, proc.communicate()
    proc.send_signal(getattr(signal, sig))
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, err
    assert "Traceback" not in err and list((tmp_path / "runs").iterdir()) == []


@pytest.mark.parametrize("argv", [["track", "{toy}"], ["skin", "fit", "{toy}"], ["rig", "new"],
                                  ["calibrate", "stereo", "--left", "l*.png", "--right", "r*.png", "--board", "9x6",
                                   "--square", "0.02"]])
def test_a_file_out_onto_a_folder_or_under_a_file_is_one_error(argv, toy, tmp_path, capsys):
    argv = [a.format(toy=toy) for a in argv]
    f = tmp_path / "file"
    f.write_text("x")
    for bad, what in ((tmp_path, "is a folder"), (f / "out.yaml", "is a file")):
        assert main([*argv, "--out", str(bad)]) == 2
        assert what in _one_line(capsys.readouterr().err)
    assert f.read_text() == "x" and sorted(p.name for p in tmp_path.iterdir()) == ["file"]
