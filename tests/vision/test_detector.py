"""The detector registry and the default detector (vishap.vision.detector)."""
import pytest

from vishap._core.errors import ConfigError
from vishap.vision import detector as D


def test_unknown_names_list_the_known_ones():
    with pytest.raises(ConfigError, match="known: .*geometric"):
        D.make_detector("no-such-detector")


def test_the_default_falls_back_to_the_next_detector_and_says_why(monkeypatch):
    def unavailable(**_):
        raise ConfigError("runtime missing: pip install -e .[learned]")

    monkeypatch.setitem(D._REGISTRY, "hybrid", (unavailable, "test stand-in"))
    det, note = D.make_default_detector()
    assert det.name == "geometric"
    assert "hybrid" in note and "runtime missing" in note


def test_the_default_is_the_first_that_builds(monkeypatch):
    class Stub:
        name = "hybrid"

        def process(self, image, t):  # pragma: no cover - not called
            raise AssertionError

        def reset(self):  # pragma: no cover
            pass

    monkeypatch.setitem(D._REGISTRY, "hybrid", (lambda **_: Stub(), "test stand-in"))
    det, note = D.make_default_detector()
    assert isinstance(det, Stub) and note == ""


def test_nothing_buildable_is_one_clear_error(monkeypatch):
    def unavailable(**_):
        raise ConfigError("broken")

    for name in D.DEFAULT_DETECTORS:
        monkeypatch.setitem(D._REGISTRY, name, (unavailable, "test stand-in"))
    with pytest.raises(ConfigError, match="no default detector"):
        D.make_default_detector()
