import pytest
from pydantic import Field

from vishap._core.config import Schema, load_config, write_atomic
from vishap._core.errors import ConfigError, VishapError


class Wall(Schema):
    normal: tuple[float, float, float]
    offset_m: float


class Scene(Schema):
    name: str
    walls: list[Wall] = Field(default_factory=list)
    stiffness_n_m: float = Field(gt=0)


def test_valid_yaml_and_toml(tmp_path):
    y = tmp_path / "s.yaml"
    y.write_text("name: a\nstiffness_n_m: 500\nwalls:\n  - {normal: [0, 0, 1], offset_m: 0.1}\n")
    s = load_config(y, Scene)
    assert s.walls[0].normal == (0.0, 0.0, 1.0)
    t = tmp_path / "s.toml"
    t.write_text('name = "a"\nstiffness_n_m = 500\n[[walls]]\nnormal = [0, 0, 1]\noffset_m = 0.1\n')
    assert load_config(t, Scene) == s


@pytest.mark.parametrize(
    "text, field",
    [
        ("name: a\nstiffness_n_m: -1\n", "stiffness_n_m"),
        ("name: a\n", "stiffness_n_m"),
        ("name: a\nstiffness_n_m: 5\nwalls:\n  - {normal: [0, 1], offset_m: 0.1}\n", "walls.0.normal"),
        ("name: a\nstiffness_n_m: 5\ncolour: red\n", "colour"),
    ],
)
def test_errors_name_file_and_field(tmp_path, text, field):
    p = tmp_path / "scene.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_config(p, Scene)
    assert exc.value.field.startswith(field)
    assert "scene.yaml" in str(exc.value) and field in str(exc.value)
    assert isinstance(exc.value, VishapError)


@pytest.mark.parametrize("text", ["", "- 1\n- 2\n", "name: [unclosed\n"])
def test_unreadable_files(tmp_path, text):
    p = tmp_path / "scene.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError, match="scene.yaml"):
        load_config(p, Scene)


def test_missing_file(tmp_path):
    with pytest.raises(ConfigError, match="not found"):
        load_config(tmp_path / "nope.yaml", Scene)


def test_write_atomic(tmp_path):
    p = write_atomic(tmp_path / "sub" / "f.txt", "hello")
    assert p.read_text() == "hello"
    assert [x.name for x in p.parent.iterdir()] == ["f.txt"]
