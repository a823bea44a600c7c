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


def test_bench_vision_runs_the_chosen_stages_and_variants_with_the_working_range_figure(tmp_path, capsys):
    """--stages and --variants keep a long run affordable: only the named stages and refinement
    variants run; each variant reports the 3-D RMS over the goal's working range (0.4–0.8 m), and
    the summary pools it over the sequences. The speed stage measures the cap fits alone beside the
    shipped pipeline in the same run."""
    import pytest

    write_sequence(tmp_path / "toy", seed=3, frames=16, learn=4)
    out = tmp_path / "out"
    assert main(["bench", "vision", "--data", str(tmp_path / "toy"), "--frames", "16", "--out", str(out),
                 "--stages", "refinement,speed", "--variants", "shipped", "(before)", "--rounds", "1"]) == 0
    rec = json.loads((out / "vision.json").read_text())
    seq = rec["sequences"]["toy"]
    assert set(seq) == {"frames", "skin_model", "refinement", "speed"}
    assert set(seq["refinement"]) == {"cap fits + side-edge axis levelled on them + disparity filter (shipped)",
                                      "cap fits + side-edge axis, fixed mean + disparity filter (before)"}
    for r in seq["refinement"].values():
        assert r["working_range_frames"] > 0 and r["tip3d_rms_mm_working_range"] > 0
    summary = rec["refinement_summary"]["cap fits + side-edge axis levelled on them + disparity filter (shipped)"]
    assert summary["sequences"] == 1 and summary["goal_mm"] == 1.5
    assert summary["working_range_pooled_mm"] == pytest.approx(
        seq["refinement"]["cap fits + side-edge axis levelled on them + disparity filter (shipped)"]["tip3d_rms_mm_working_range"])
    assert any(k.startswith("cap fits only (no side-edge axis): ") for k in seq["speed"]["cpu_ms_per_pair"])
    assert not (out / "vision_speed_accuracy.png").exists() and (out / "vision_stereo_refinement.png").is_file()
    capsys.readouterr()
    assert main(["bench", "vision", "--data", str(tmp_path / "toy"), "--out", str(tmp_path / "o2"), "--stages", "speedy"]) != 0
    assert "unknown stage(s) speedy" in capsys.readouterr().err
    assert not (tmp_path / "o2" / "vision.json").exists()


def test_working_range_rms_pools_the_depth_bins_inside_the_range():
    from vishap.bench.vision import working_range_rms

    bd = {"0.3-0.4": {"frames": 10, "gross": 0, "tip3d_rms_mm_without_gross": 9.0},
          "0.4-0.5": {"frames": 12, "gross": 2, "tip3d_rms_mm_without_gross": 1.0},
          "0.5-0.6": {"frames": 30, "gross": 0, "tip3d_rms_mm_without_gross": 2.0},
          "0.8-1.0": {"frames": 5, "gross": 0, "tip3d_rms_mm_without_gross": 7.0}}
    rms, n = working_range_rms(bd)
    assert n == 40 and abs(rms - ((10 * 1.0 + 30 * 4.0) / 40) ** 0.5) < 1e-12
    assert working_range_rms({}) == (None, 0)
