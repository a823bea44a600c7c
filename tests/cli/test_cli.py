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
    assert main(["rig", "new", "--out", str(path), "--baseline", "0.08"]) == 0
    rec = json.loads(capsys.readouterr().out)
    assert rec["baseline_m"] == pytest.approx(0.08)
    assert main(["rig", "show", str(path)]) == 0
    assert json.loads(capsys.readouterr().out)["image_size"] == [640, 480]


def test_errors_are_one_line(tmp_path, capsys):
    assert main(["rig", "show", str(tmp_path / "missing.yaml")]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and "missing.yaml" in err and "not found" in err
    assert main(["rig", "new", "--out", str(tmp_path / "r.yaml"), "--baseline", "-1"]) == 2
    assert "baseline" in capsys.readouterr().err
    assert not (tmp_path / "r.yaml").exists()
