"""A data-set spec for mixed builds (``vishap dataset build SPEC.yaml --out DIR``, issue 18 item 2).

::

    defaults:                      # any sequence option, for every group (optional)
      frames: 60
      resolution: 320x240
    groups:
      - name: wall-light           # sequences go to DIR/wall-light/seed-NNNNNN
        scene: wall
        seeds: "0:20"              # seeds 0 … 19
        skin_tone: [light, medium] # a list is cycled over the group's seeds (seed A gets the first)
        background: auto
        lighting: [constant, step]
      - name: fabric-dark
        scene: fabric
        trajectory: fabric
        seeds: "100:110"
        skin_tone: dark
        background: mixed
        effects: false             # camera effects off: exact pixels

Sequence options (each a value or a list): ``trajectory``, ``frames``, ``resolution`` (WxH),
``fps``, ``hand_free``, ``start_s``, ``lighting``, ``skin_tone``, ``background``, ``occlusion``,
``effects`` (camera effects: noise, defocus, motion blur, auto-exposure), ``exposure_s`` (the
cameras' exposure time, s; default the camera model's 12 ms), ``msaa``, ``store``
(``png`` or ``video``: lossless FFV1, :mod:`vishap.scale.store`). The spec is
checked on load, every sequence included: the first problem is one :class:`ConfigError` naming the
file and the field (``groups.1.skin_tone``).
"""
from __future__ import annotations

import os
import re
from pathlib import Path
from typing import Any

from pydantic import Field, field_validator, model_validator

from vishap._core.config import Schema, load_config
from vishap._core.errors import ConfigError

__all__ = ["SequenceOptions", "Group", "DatasetSpec", "load_dataset_spec", "dataset_jobs"]

_NAME = re.compile(r"^[A-Za-z0-9][A-Za-z0-9_.-]*$")
Scalar = str | float | int | bool | None


class SequenceOptions(Schema):
    """Options of a sequence; each may be one value or a list cycled over the seeds."""

    trajectory: Scalar | list[Scalar] = None
    frames: int | list[int] | None = None
    resolution: str | list[str] | None = None
    fps: float | list[float] | None = None
    hand_free: int | list[int] | None = None
    start_s: float | list[float] | None = None
    lighting: str | list[str] | None = None
    skin_tone: Scalar | list[Scalar] = None
    background: str | list[str] | None = None
    occlusion: bool | list[bool] | None = None
    effects: bool | list[bool] | None = None
    exposure_s: float | list[float] | None = None
    msaa: int | list[int] | None = None
    store: str | list[str] | None = None

    @field_validator("*")
    @classmethod
    def _non_empty_list(cls, v):
        if isinstance(v, list) and not v:
            raise ValueError("an empty list; give a value or a non-empty list")
        return v


class Group(SequenceOptions):
    name: str
    scene: str
    seeds: str

    @field_validator("name")
    @classmethod
    def _folder_name(cls, v: str) -> str:
        if not _NAME.match(v):
            raise ValueError("must be a folder name: letters, digits, '_', '.', '-'")
        return v

    @field_validator("seeds")
    @classmethod
    def _seed_range(cls, v: str) -> str:
        from vishap.scale.cli import seed_range

        try:
            seed_range(v)
        except Exception as exc:
            raise ValueError(str(exc)) from None
        return v


class DatasetSpec(Schema):
    defaults: SequenceOptions = Field(default_factory=SequenceOptions)
    groups: list[Group] = Field(min_length=1)

    @model_validator(mode="after")
    def _unique_names(self):
        names = [g.name for g in self.groups]
        dup = sorted({n for n in names if names.count(n) > 1})
        if dup:
            raise ValueError(f"group names must be unique; repeated: {dup}")
        return self


_SPEC_FIELDS = {"trajectory": "trajectory", "frames": "frames", "fps": "fps", "hand_free": "hand_free_frames",
                "start_s": "start_s", "lighting": "lighting", "skin_tone": "skin_tone", "background": "background",
                "occlusion": "occlusion", "effects": "effects", "exposure_s": "exposure_s", "msaa": "msaa",
                "store": "store"}

_SPEC_KEYS = {v: k for k, v in _SPEC_FIELDS.items()}


def _pick(value: Any, k: int) -> Any:
    return value[k % len(value)] if isinstance(value, list) else value


def _resolution(text: str) -> tuple[int, int]:
    m = re.fullmatch(r"\s*(\d+)\s*[xX]\s*(\d+)\s*", str(text))
    if not m:
        raise ConfigError(f"expected WIDTHxHEIGHT such as 640x480, got {text!r}", field="resolution")
    return int(m.group(1)), int(m.group(2))


def _sequence_spec(group: Group, options: dict, seed: int, k: int):
    from vishap.sim.sequence import SequenceSpec

    kw = {"scene": group.scene, "seed": seed}
    for key, value in options.items():
        v = _pick(value, k)
        if v is None:
            continue
        if key == "resolution":
            kw["width"], kw["height"] = _resolution(v)
        else:
            kw[_SPEC_FIELDS[key]] = v
    return SequenceSpec(**kw)


def dataset_jobs(spec: DatasetSpec, *, file: str | os.PathLike | None = None) -> list:
    """One :class:`~vishap.scale.sequences.Job` per (group, seed), every sequence checked; a problem
    becomes a :class:`ConfigError` naming ``file`` and ``groups.<i>.<field>``."""
    from vishap.scale.cli import seed_range
    from vishap.scale.sequences import Job, check_spec, seed_folder, spec_parameters

    defaults = spec.defaults.model_dump(exclude_unset=True)
    jobs = []
    for i, group in enumerate(spec.groups):
        options = defaults | group.model_dump(exclude_unset=True, exclude={"name", "scene", "seeds"})
        for k, seed in enumerate(seed_range(group.seeds)):
            try:
                one = _sequence_spec(group, options, seed, k)
                check_spec(one)
            except ConfigError as exc:
                where = _SPEC_KEYS.get(exc.field, exc.field) if exc.file is None else f"{exc.field} of {exc.file}"
                raise ConfigError(f"{exc.reason} (group {group.name!r}, seed {seed})", file=file,
                                  field=f"groups.{i}.{where}") from None
            jobs.append(Job(f"{group.name}/{seed_folder(seed)}", one, spec_parameters(one)))
    return jobs


def load_dataset_spec(path: str | os.PathLike) -> tuple[DatasetSpec, list]:
    """Read and check a spec file; returns the spec and its jobs."""
    spec = load_config(path, DatasetSpec)
    return spec, dataset_jobs(spec, file=Path(path))
