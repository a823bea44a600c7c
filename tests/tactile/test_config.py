import copy

import pytest
import yaml

from vishap._core.errors import ConfigError
from vishap.tactile.config import DEFAULT_CONFIG_PATH, load_tactile_config, tactile_config_from_dict


@pytest.fixture
def raw():
    return yaml.safe_load(DEFAULT_CONFIG_PATH.read_text())


def test_default_config_loads_paper_values():
    cfg = load_tactile_config()
    assert [(b.low_hz, b.high_hz) for b in cfg.bands] == [(0, 20), (20, 200), (200, 400)]
    c = cfg.presets["concentrated"]
    assert [r.beta_hz for r in c] == [320, 160, 260] and [r.gamma for r in c] == [1.8, 0.7, 0.4]
    assert cfg.classifier.slip_speed_m_s == 0.15 and cfg.classifier.slip_pulse_max_s == 0.1
    assert cfg.classifier.stable_time_s == 0.25
    assert cfg.pins.rows * cfg.pins.cols == 24 and cfg.pins.update_hz == 40 and cfg.pins.f_high_hz == 320


@pytest.mark.parametrize(
    "path, value, field",
    [
        (("regions", 0, "beta_hz"), 520.0, "regions.0.beta_hz"),
        (("presets", "slip", 2, "beta_hz"), 10.0, "presets.slip.2.beta_hz"),
        (("regions", 1, "alpha"), 0.1, "regions.1.alpha"),
        (("regions", 2, "alpha"), 1.2, "regions.2.alpha"),
        (("regions", 2, "lambda_per_cm"), -3.0, "regions.2.lambda_per_cm"),
        (("control", "distributed_beta2_hz"), 450.0, "control.distributed_beta2_hz"),
        (("pins", "f_high_hz"), 800.0, "pins.f_high_hz"),
        (("bands", 1, "high_hz"), 900.0, "bands.1.high_hz"),
    ],
)
def test_bad_values_name_the_field(raw, path, value, field):
    data = copy.deepcopy(raw)
    node = data
    for p in path[:-1]:
        node = node[p]
    node[path[-1]] = value
    with pytest.raises(ConfigError) as e:
        tactile_config_from_dict(data, file="tactile.yaml")
    assert e.value.field == field
    assert field in str(e.value) and "tactile.yaml" in str(e.value)


def test_structural_errors(raw, tmp_path):
    data = copy.deepcopy(raw)
    data["bands"][1]["low_hz"] = 30.0
    with pytest.raises(ConfigError, match="contiguous"):
        tactile_config_from_dict(data)
    data = copy.deepcopy(raw)
    data["allocation"]["glove_band_hz"] = [0.0, 50.0]
    with pytest.raises(ConfigError, match="allocation"):
        tactile_config_from_dict(data)
    data = copy.deepcopy(raw)
    data["regions"].pop()
    with pytest.raises(ConfigError, match="regions"):
        tactile_config_from_dict(data)
    bad = tmp_path / "t.yaml"
    data = copy.deepcopy(raw)
    data["sensor"]["pitch_m"] = -1
    bad.write_text(yaml.safe_dump(data))
    with pytest.raises(ConfigError, match=r"t\.yaml.*sensor\.pitch_m"):
        load_tactile_config(bad)
