"""``vishap dataset build``: a mixed spec, its sequences equal ``vishap synth`` runs, and bad specs."""
from __future__ import annotations

import hashlib
import json
from pathlib import Path

import pytest

from vishap._core.errors import ConfigError
from vishap.cli import main
from vishap.scale.dataset_spec import load_dataset_spec

SPEC = """
defaults: {frames: 2, resolution: 160x120, hand_free: 1}
groups:
  - {name: wall-mixed, scene: wall, seeds: "0:3", skin_tone: [light, dark], lighting: [constant, step]}
  - {name: fabric-exact, scene: fabric, seeds: "7:8", background: wood, effects: false, resolution: 192x144}
"""


def _digest(folder: Path) -> dict[str, str]:
    return {p.relative_to(folder).as_posix(): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.render
def test_build_a_mixed_spec_equals_synth_runs_and_resumes(tmp_path, capsys):
    spec = tmp_path / "spec.yaml"
    spec.write_text(SPEC)
    out = tmp_path / "set"
    assert main(["dataset", "build", str(spec), "--out", str(out), "--workers", "1", "--quiet"]) == 0
    m = json.loads((out / "manifest.json").read_text())
    assert sorted(m["sequences"]) == ["fabric-exact/seed-000007", "wall-mixed/seed-000000",
                                      "wall-mixed/seed-000001", "wall-mixed/seed-000002"]
    p = {k: v["parameters"] for k, v in m["sequences"].items()}
    assert [p[f"wall-mixed/seed-00000{s}"]["skin_tone"] for s in range(3)] == ["light", "dark", "light"]
    assert [p[f"wall-mixed/seed-00000{s}"]["lighting"] for s in range(3)] == ["constant", "step", "constant"]
    fab = p["fabric-exact/seed-000007"]
    assert (fab["scene"], fab["width"], fab["height"], fab["effects"], fab["background"]) == ("fabric", 192, 144, False, "wood")

    single = tmp_path / "single"
    assert main(["synth", "--scene", "wall", "--frames", "2", "--resolution", "160x120", "--hand-free", "1", "--seed", "1",
                 "--skin-tone", "dark", "--lighting", "step", "--quiet", "--out", str(single)]) == 0
    assert _digest(out / "wall-mixed" / "seed-000001") == _digest(single)

    capsys.readouterr()
    assert main(["dataset", "build", str(spec), "--out", str(out), "--workers", "1", "--quiet", "--json"]) == 0
    again = json.loads(capsys.readouterr().out.strip().splitlines()[-1])
    assert (again["built"], again["skipped"]) == (0, 4)


@pytest.mark.parametrize("text, field, match", [
    ('groups:\n  - {name: a, scene: wall, seeds: "0:2", skin_tone: [light, purple]}', "groups.0.skin_tone", "purple"),
    ('groups:\n  - {name: a, scene: wall, seeds: "5:2"}', "groups.0.seeds", "A < B"),
    ('groups:\n  - {name: a, scene: moon, seeds: "0:2"}', "groups.0.scene", "unknown scene"),
    ('groups:\n  - {name: a, scene: wall, seeds: "0:2", lighting: [constant, disco]}', "groups.0.lighting", "disco"),
    ('groups:\n  - {name: a, scene: wall, seeds: "0:2", resolution: big}', "groups.0.resolution", "WIDTHxHEIGHT"),
    ('groups:\n  - {name: a, scene: wall, seeds: "0:2", hand_free: -1}', "groups.0.hand_free", ">= 0"),
    ('groups:\n  - {name: a, scene: wall, seeds: "0:2", colour: red}', "groups.0.colour", "Extra inputs"),
    ('groups:\n  - {name: a, scene: wall, seeds: "0:2"}\n  - {name: a, scene: fabric, seeds: "0:2"}', "<top level>",
     "unique"),
    ('defaults: {frames: 0}\ngroups:\n  - {name: a, scene: wall, seeds: "0:1"}', "groups.0.frames", "positive"),
    ('groups:\n  - {name: "../up", scene: wall, seeds: "0:1"}', "groups.0.name", "folder name"),
    ("groups: []", "groups", "at least 1"),
    ('groups:\n  - {name: a, scene: wall, seeds: "0:2", exposure_s: [0.004, 0.05]}', "groups.0.exposure_s",
     "longer than a frame"),
])
def test_bad_spec_names_the_field(tmp_path, capsys, text, field, match):
    spec = tmp_path / "spec.yaml"
    spec.write_text(text)
    with pytest.raises(ConfigError, match=match) as e:
        load_dataset_spec(spec)
    assert e.value.field == field and e.value.file == str(spec)
    out = tmp_path / "set"
    assert main(["dataset", "build", str(spec), "--out", str(out), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"field '{field}'" in err and err.count("\n") == 1
    assert not out.exists()


def test_the_exposure_is_a_sequence_option_recorded_only_when_set(tmp_path):
    from vishap.scale.sequences import spec_parameters

    spec = tmp_path / "spec.yaml"
    spec.write_text('groups:\n  - {name: a, scene: wall, seeds: "0:1", frames: 2, exposure_s: 0.004}\n'
                    '  - {name: b, scene: wall, seeds: "0:1", frames: 2}')
    _, jobs = load_dataset_spec(spec)
    assert [j.spec.exposure_s for j in jobs] == [0.004, None]
    # the default leaves the manifest's parameters as they were before the option existed
    assert jobs[0].parameters["exposure_s"] == 0.004 and "exposure_s" not in jobs[1].parameters
    assert "exposure_s" not in spec_parameters(jobs[1].spec)
