import argparse
import json

import pytest

from vishap._core.errors import ConfigError
from vishap.bench import all as bench_all
from vishap.cli.demo import parse_fault, parse_travel


def test_index_links_every_chart_and_json(tmp_path):
    (tmp_path / "alpha").mkdir()
    (tmp_path / "alpha" / "alpha.json").write_text(json.dumps({"x_us": 1.5, "name": "a", "big": [1, 2]}))
    (tmp_path / "alpha" / "speed.png").write_bytes(b"\x89PNG")
    (tmp_path / "beta").mkdir()
    (tmp_path / "beta" / "stderr.txt").write_text("boom")
    results = [
        {"name": "alpha", "command": "bench alpha --out x", "ok": True, "returncode": 0, "wall_s": 1.0, "error": None},
        {"name": "beta", "command": "bench beta --out y", "ok": False, "returncode": 1, "wall_s": 0.5, "error": ["boom"]},
    ]
    md, html = bench_all.write_index(tmp_path, results)
    text = md.read_text()
    assert "(alpha/speed.png)" in text and "(alpha/alpha.json)" in text and "| x_us | 1.5 |" in text
    assert "FAILED (boom)" in text and "beta/stderr.txt" in text
    h = html.read_text()
    assert "src='alpha/speed.png'" in h and "href='alpha/alpha.json'" in h


def test_all_never_runs_itself_and_rejects_unknown(tmp_path):
    assert "all" not in bench_all.bench_names()
    args = argparse.Namespace(out=str(tmp_path), only="no_such_bench", skip="", timeout=5.0, full=False)
    with pytest.raises(ConfigError, match="no_such_bench"):
        bench_all.run(args)


def test_parse_fault():
    assert parse_fault("nan:1.0:1.5") == {"kind": "nan", "t_start": 1.0, "t_end": 1.5}
    with pytest.raises(argparse.ArgumentTypeError, match="finger_lost"):
        parse_fault("meteor:1:2")
    with pytest.raises(argparse.ArgumentTypeError):
        parse_fault("nan:a:b")


def test_parse_travel():
    assert parse_travel("0.6,40") == {"travel_speed_m_s": 0.6, "travel_accel_m_s2": 40.0}
    assert parse_travel("off") == {"travel_speed_m_s": None}
    with pytest.raises(argparse.ArgumentTypeError, match="SPEED,ACCEL"):
        parse_travel("fast")


def test_quick_args_prefer_the_modules_own_setting():
    import types

    def with_quick(p):
        p.add_argument("--quick", action="store_true")

    def with_ticks(p):
        p.add_argument("--ticks", type=int)
        p.add_argument("--rounds", type=int)

    assert bench_all.quick_args("x", types.SimpleNamespace(QUICK_ARGS=["--n", "3"], add_arguments=with_quick)) == ["--n", "3"]
    assert bench_all.quick_args("x", types.SimpleNamespace(add_arguments=with_quick)) == ["--quick"]
    assert bench_all.quick_args("robot", types.SimpleNamespace(add_arguments=with_ticks))[:1] == ["--ticks"]
    assert bench_all.quick_args("robot", types.SimpleNamespace(add_arguments=lambda p: None)) == []
