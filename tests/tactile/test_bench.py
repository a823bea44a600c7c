import json

from vishap.cli import main


def test_bench_tactile_writes_record_and_charts(tmp_path, capsys):
    out = tmp_path / "b"
    assert main(["bench", "tactile", "--out", str(out), "--seconds", "0.6", "--per-class", "1",
                 "--noise", "150", "--repeats", "1", "--quick", "--json"]) == 0
    rec = json.loads(capsys.readouterr().out)
    for key in ("realtime_factor", "classifier_accuracy", "feedforward_onset_gain_ms", "jnd_updates_saved_fraction"):
        assert isinstance(rec[key], float) and rec[key] > 0, key
    assert rec["worked_examples"]["all_correct"]
    assert rec["feedforward"]["near_misses"] == 4 and rec["feedforward"]["approaches"] == 2
    assert json.loads((out / "tactile.json").read_text())["classifier_accuracy"] == rec["classifier_accuracy"]
    for name in rec["charts"]:
        assert (out / name).stat().st_size > 1000, name
