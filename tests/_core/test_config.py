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


# ---- the one validated reader: nothing but a ConfigError escapes, non-finite values are refused
from vishap._core.config import check_tree, read_mapping, read_yaml_text  # noqa: E402

_BOMB = "a: &a [1,1,1,1,1,1,1,1,1,1]\n" + "".join(
    f"{n}: &{n} [{', '.join([f'*{p}'] * 10)}]\n" for p, n in zip("abcdef", "bcdefg"))


@pytest.mark.parametrize(
    "text, what",
    [
        ("name: !!timestamp 2024-13-45\n", "timestamp"),
        ("name: " + "[" * 3000 + "]" * 3000 + "\n", "nesting"),
        ("name: " + "{a: " * 200 + "1" + "}" * 200 + "\n", "nesting"),
        ("name: &a [*a]\n", "nesting"),
        ("name: !!python/object:os.system x\n", "not allowed"),
        ("name: !!binary AAA\n", "not allowed"),
        ("name: !custom x\n", "not allowed"),
        ("name: a\nstiffness_n_m: .inf\n", "stiffness_n_m"),
        ("name: a\nstiffness_n_m: .nan\n", "stiffness_n_m"),
        ("name: a\nstiffness_n_m: 1" + "0" * 400 + "\n", "stiffness_n_m"),
        ("name: a\nstiffness_n_m: 1e400\n", "stiffness_n_m"),
        ("name: a\nwalls:\n  - {normal: [0, .nan, 1], offset_m: 0.1}\n", "walls.0.normal.1"),
        ("\x00\x01\x02", "YAML"),
        (_BOMB, "values"),
    ],
)
def test_hostile_yaml_gives_one_config_error(tmp_path, text, what):
    p = tmp_path / "scene.yaml"
    p.write_text(text)
    with pytest.raises(ConfigError) as exc:
        load_config(p, Scene)
    assert "scene.yaml" in str(exc.value) and what in str(exc.value)


@pytest.mark.parametrize("suffix, text", [(".toml", "name = 'a'\nstiffness_n_m = nan\n"),
                                          (".json", '{"name": "a", "stiffness_n_m": Infinity}'),
                                          (".toml", "x = " + "[" * 3000 + "]" * 3000),
                                          (".json", "[" * 5000 + "]" * 5000)])
def test_toml_and_json_are_checked_alike(tmp_path, suffix, text):
    p = tmp_path / f"s{suffix}"
    p.write_text(text)
    with pytest.raises(ConfigError, match=f"s\\{suffix}"):
        load_config(p, Scene)


def test_yaml_12_exponents_are_numbers_and_dates_stay_text():
    assert read_yaml_text("a: 1e5\nb: -2.5E-3\nc: 2024-01-01\nd: e5\n") == {
        "a": 1e5, "b": -2.5e-3, "c": "2024-01-01", "d": "e5"}


def test_schema_refuses_non_finite_floats_set_in_code():
    s = Scene(name="a", stiffness_n_m=1.0)
    with pytest.raises(Exception):
        s.stiffness_n_m = float("inf")
    with pytest.raises(ConfigError, match="finite"):
        from vishap._core.config import validate

        validate(Scene, {"name": "a", "stiffness_n_m": float("nan")})


def test_check_tree_refuses_objects():
    with pytest.raises(ConfigError, match="object"):
        check_tree({"a": object()})


def test_reader_on_folder_and_binary(tmp_path):
    with pytest.raises(ConfigError, match="not a file"):
        read_mapping(tmp_path)
    p = tmp_path / "b.yaml"
    p.write_bytes(b"\xff\xfe\x00junk")
    with pytest.raises(ConfigError, match="b.yaml"):
        read_mapping(p)


def test_reading_turns_slips_into_config_errors(tmp_path):
    from vishap._core.config import reading

    with pytest.raises(ConfigError, match="f.yaml.*TypeError"):
        with reading(tmp_path / "f.yaml"):
            float([1, 2])


def test_write_atomic_is_group_readable(tmp_path):
    import os
    import stat

    old = os.umask(0o022)
    try:
        p = write_atomic(tmp_path / "calib.yaml", "x: 1\n")
    finally:
        os.umask(old)
    assert stat.S_IMODE(p.stat().st_mode) == 0o644
