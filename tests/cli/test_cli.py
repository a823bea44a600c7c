import json
import subprocess
import sys

import pytest

from vishap import __version__
from vishap.cli import build_parser, main


def test_version_and_help():
    out = subprocess.run([sys.executable, "-m", "vishap", "--version"], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == f"vishap {__version__}"
    out = subprocess.run([sys.executable, "-m", "vishap", "--help"], capture_output=True, text=True, check=True)
    assert "rig" in out.stdout


def test_every_subcommand_and_option_is_described():
    """Each subcommand has a help line in the top-level listing and each of its options a help text
    that its own --help shows (an option added without one fails here)."""
    parser = build_parser()
    sub = next(a for a in parser._actions if a.dest == "command")
    listed = {a.dest: a.help for a in sub._choices_actions}
    assert {"demo", "replay", "track", "bench"} <= set(sub.choices)
    for name, p in sub.choices.items():
        assert listed.get(name), f"{name}: no help line in 'vishap --help'"
        text = " ".join(p.format_help().split())
        for action in p._actions:
            if action.dest == "help" or not action.option_strings:
                continue
            assert action.help, f"{name} {action.option_strings[0]}: no help text"
            assert action.option_strings[-1] in text, (name, action.option_strings)


def test_rig_new_and_show(tmp_path, capsys):
    path = tmp_path / "rig.yaml"
    assert main(["rig", "new", "--out", str(path), "--baseline", "0.08", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["baseline_m"] == pytest.approx(0.08)
    assert main(["rig", "show", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["image_size"] == [640, 480]


def test_errors_are_one_line(tmp_path, capsys):
    assert main(["rig", "show", str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "missing.yaml" in err and "not found" in err
    assert main(["rig", "new", "--out", str(tmp_path / "r.yaml"), "--baseline", "-1"]) == 2
    assert "baseline" in capsys.readouterr().err
    assert not (tmp_path / "r.yaml").exists()


# ---------------------------------------------------------------- issue 17: output, summaries, bad --out
def test_bare_vishap_exits_non_zero_with_help(capsys):
    assert main([]) == 2
    assert "COMMAND" in capsys.readouterr().err
    out = subprocess.run([sys.executable, "-m", "vishap"], capture_output=True, text=True)
    assert out.returncode == 2 and "usage: vishap" in out.stderr


def test_a_short_summary_and_json_only_with_the_flag(tmp_path, capsys):
    """The terminal, a pipe or a log gets a few readable lines; the record is JSON only with --json."""
    path = tmp_path / "rig.yaml"
    assert main(["rig", "new", "--out", str(path)]) == 0
    assert "{" not in capsys.readouterr().out
    assert main(["rig", "show", str(path)]) == 0
    text = capsys.readouterr().out
    assert text.startswith(f"rig {path}: 640x480 px, fx 554.3 px (60.0° horizontal), baseline 60.0 mm")
    assert len(text) < 300 and "{" not in text
    assert main(["rig", "show", str(path), "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["baseline_m"] == pytest.approx(0.06)


def test_rig_new_refuses_to_replace_a_file_and_names_bad_paths(tmp_path, capsys):
    import os
    import stat

    path = tmp_path / "rig.yaml"
    old = os.umask(0o022)
    try:
        assert main(["rig", "new", "--out", str(path)]) == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(path.stat().st_mode) == 0o644  # group-readable calibration file
    before = path.read_bytes()
    assert main(["rig", "new", "--out", str(path), "--baseline", "0.1"]) == 2
    assert "exists" in capsys.readouterr().err and path.read_bytes() == before
    assert main(["rig", "new", "--out", str(path), "--baseline", "0.1", "--overwrite"]) == 0
    capsys.readouterr()
    for bad, what in ((tmp_path, "is a folder"), (path / "x.yaml", "is a file")):
        assert main(["rig", "new", "--out", str(bad)]) == 2
        err = capsys.readouterr().err.strip()
        assert len(err.splitlines()) == 1 and what in err, err


def _contact_npz(path, **edit):
    import numpy as np

    from vishap.tactile.scenarios import press, to_arrays

    d = to_arrays(press(0.05))
    d.update(edit)
    np.savez(path, **d)
    return path


def test_tactile_render_out_is_written_whole(tmp_path, capsys):
    npz = _contact_npz(tmp_path / "c.npz")
    out = tmp_path / "render"
    out.mkdir()
    (out / "mine.txt").write_text("keep")
    argv = ["tactile", "render", "--input", str(npz), "--no-plots", "--out", str(out)]
    assert main(argv) == 2
    assert "not empty" in capsys.readouterr().err and sorted(p.name for p in out.iterdir()) == ["mine.txt"]
    assert main(argv + ["--overwrite", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["out"] == str(out.absolute()) and "render.json" in rec["files"]
    assert json.loads((out / "render.json").read_text())["samples"] == rec["samples"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.npz", "render"]
    assert main(["tactile", "render", "--input", str(npz), "--out", str(npz)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "not a folder" in err


def test_tactile_render_refuses_nan_contacts_and_junk_npz(tmp_path, capsys):
    import numpy as np

    from vishap.tactile.scenarios import press, to_arrays

    force = to_arrays(press(0.05))["normal_force_n"].astype(float)
    force[3] = np.nan
    npz = _contact_npz(tmp_path / "c.npz", normal_force_n=force)
    assert main(["tactile", "render", "--input", str(npz), "--out", str(tmp_path / "o")]) == 2
    err = capsys.readouterr().err
    assert "normal_force_n" in err and "NaN" in err and not (tmp_path / "o").exists()
    junk = tmp_path / "junk.npz"
    junk.write_bytes(b"PK\x03\x04 not a zip")
    assert main(["tactile", "render", "--input", str(junk), "--out", str(tmp_path / "o")]) == 2
    assert "junk.npz" in capsys.readouterr().err


def test_bench_refuses_a_non_empty_out(tmp_path, capsys):
    out = tmp_path / "b"
    out.mkdir()
    (out / "earlier.json").write_text("{}")
    assert main(["bench", "fuzz", "--cases", "1", "--jobs", "1", "--out", str(out)]) == 2
    assert "not empty" in capsys.readouterr().err and (out / "earlier.json").read_text() == "{}"


@pytest.mark.render
def test_failed_synth_keeps_what_another_run_wrote_in_its_new_parent(tmp_path, monkeypatch, capsys):
    import vishap.sim.writer as w

    parent = tmp_path / "runs"
    real = w.render_frames

    def failing(p, r):
        for i, item in enumerate(real(p, r)):
            if i == 1:
                (parent / "other").mkdir()  # another run finished meanwhile
                (parent / "other" / "gt.npz").write_text("done")
                raise KeyboardInterrupt
            yield item

    monkeypatch.setattr(w, "render_frames", failing)
    argv = ["synth", "--scene", "wall", "--frames", "3", "--resolution", "160x120", "--quiet", "--out",
            str(parent / "mine")]
    assert main(argv) == 130
    assert sorted(p.name for p in tmp_path.iterdir()) == ["runs"]
    assert sorted(p.name for p in parent.iterdir()) == ["other"] and (parent / "other" / "gt.npz").is_file()


@pytest.mark.render
def test_demo_writes_its_folder_whole_and_refuses_a_non_empty_one(tmp_path, capsys):
    out = tmp_path / "wall"
    assert main(["demo", "wall", "--frames", "12", "--no-video", "--no-frames", "--out", str(out), "--json"]) == 0
    assert (out / "summary.json").is_file() and (out / "log.npz").is_file()
    assert json.loads(capsys.readouterr().out) == json.loads((out / "summary.json").read_text())  # --json: the record
    before = (out / "summary.json").read_bytes()
    assert main(["demo", "wall", "--frames", "12", "--no-video", "--no-frames", "--out", str(out)]) == 2
    assert "--overwrite" in capsys.readouterr().err
    assert (out / "summary.json").read_bytes() == before  # another run's output is never touched
    assert sorted(p.name for p in tmp_path.iterdir()) == ["wall"]  # no temporary folder left behind
