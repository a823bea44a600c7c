"""`vishap bench vision --quick` (the setting `vishap bench all` runs) end to end on a tiny sequence."""
import json

from vishap.cli import main
from vishap.vision.toy import write_sequence


def test_bench_vision_quick_runs_and_writes_its_record(tmp_path):
    write_sequence(tmp_path / "toy", seed=3, frames=16, learn=4)
    out = tmp_path / "out"
    assert main(["bench", "vision", "--quick", "--data", str(tmp_path / "toy"), "--frames", "16", "--out", str(out)]) == 0
    rec = json.loads((out / "vision.json").read_text())
    seq = rec["sequences"]["toy"]
    assert set(seq["pipeline"]) == {"tracked window", "full frame", "tracked, no periodic recheck"}
    assert seq["pipeline"]["tracked window"]["detection_rate"] > 0.5
    assert "GSOC + skin + median" not in seq["segmentation"]  # the quick setting leaves the slow peer out
    assert (out / "vision_speed_accuracy.png").is_file() and (out / "vision_detector_constants.png").is_file()


def test_bench_vision_speed_section_reports_cpu_time_by_mode(tmp_path):
    """The speed section: CPU ms per pair for the full-frame search and each tracking mode met."""
    write_sequence(tmp_path / "toy", seed=3, frames=16, learn=4)
    out = tmp_path / "out"
    assert main(["bench", "vision", "--quick", "--data", str(tmp_path / "toy"), "--frames", "16", "--out", str(out)]) == 0
    speed = json.loads((out / "vision.json").read_text())["sequences"]["toy"]["speed"]
    assert speed["clock"] == "process_time" and speed["goals_ms"] == {"full frame": 4.0, "tracked": 1.0}
    ms = speed["cpu_ms_per_pair"]
    n = speed["frames"]["full frame, all frames"]  # the frames after the background frames
    assert n >= 5 and ms["full frame, all frames"] > 0
    assert "tracking on: tracked" in ms and sum(v for k, v in speed["frames"].items() if k.startswith("tracking on")) == n
