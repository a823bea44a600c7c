"""Database of interaction modes (VisHap §2.2, "Scene Configuration").

"A button allows a click, and a hard wall only allows a sliding along the surface. For each object
we only need specify the index into a database that describes its interaction property."  The
database is ``modes.yaml`` beside this file; a scene object refers to a mode by name. Each mode
names the object kinds it fits, what the finger may do, how the device target behaves in contact
(``follow`` the finger's projection, or stay at the object's ``centre``) and the force law with
its parameters (Fig. 5; HAPTEX §II-B for fabric).
"""
from __future__ import annotations

import os
from functools import lru_cache
from pathlib import Path
from typing import Annotated, Literal, Union

from pydantic import Field

from vishap._core.config import Schema
from vishap._core.errors import ConfigError

__all__ = [
    "WallSpringLaw",
    "ButtonClickLaw",
    "FabricFrictionLaw",
    "Mode",
    "ModeDatabase",
    "DEFAULT_MODES",
    "load_modes",
    "default_modes",
    "check_stiffness",
    "law_stiffnesses",
]

DEFAULT_MODES = Path(__file__).with_name("modes.yaml")

Positive = Annotated[float, Field(gt=0)]
NonNegative = Annotated[float, Field(ge=0)]


class WallSpringLaw(Schema):
    """Fig. 5 left: a linear spring in the depth below the plane (N/m), plus normal damping."""

    kind: Literal["wall_spring"]
    stiffness_n_m: Positive
    damping_n_s_m: NonNegative = 0.0


class ButtonClickLaw(Schema):
    """Fig. 5 right: resistance spring to the trigger depth, low stiffness after the click, hard bottom."""

    kind: Literal["button_click"]
    k_resist_n_m: Positive
    k_click_n_m: Positive
    k_bottom_n_m: Positive
    transition_m: Annotated[float, Field(gt=0, le=0.002)] = 0.0002
    damping_n_s_m: NonNegative = 0.0


class FabricFrictionLaw(Schema):
    """HAPTEX §II-B: penalty force on penetration and stick/slip friction (μ from the scene's surface)."""

    kind: Literal["fabric_friction"]
    k_penalty_n_m: Positive
    damping_n_s_m: NonNegative = 0.0
    k_tangential_n_m: Positive
    damping_tangential_n_s_m: NonNegative = 0.0


Law = Annotated[Union[WallSpringLaw, ButtonClickLaw, FabricFrictionLaw], Field(discriminator="kind")]

_LAW_KINDS = {"wall_spring": {"wall"}, "button_click": {"button"}, "fabric_friction": {"fabric"}}


class Mode(Schema):
    """One entry of the database."""

    description: str = ""
    kinds: list[Literal["wall", "button", "fabric"]] = Field(min_length=1)
    allows: list[Literal["slide", "press", "click", "stroke", "texture"]] = Field(min_length=1)
    target: Literal["follow", "centre"]
    #: ᴼΛ = diag(λx, λy, λz) for the position servo while the law renders contact (Eq. 8–9): λ_z = 0
    #: because the law gives the normal force; λx = λy = 0 lets the finger drag the device (sliding),
    #: 1 holds it laterally (a key in its guide)
    contact_gain: tuple[
        Annotated[float, Field(ge=0, le=1)], Annotated[float, Field(ge=0, le=1)], Annotated[float, Field(ge=0, le=1)]
    ] = (0.0, 0.0, 0.0)
    law: Law


class ModeDatabase(Schema):
    modes: dict[str, Mode] = Field(min_length=1)

    def get(self, name: str, *, kind: str | None = None, file=None, field: str | None = None) -> Mode:
        """The mode called ``name``; a :class:`ConfigError` naming ``file``/``field`` if it is unknown
        or does not fit an object of ``kind``."""
        if name not in self.modes:
            raise ConfigError(
                f"unknown interaction mode {name!r}; expected one of {sorted(self.modes)}", file=file, field=field
            )
        mode = self.modes[name]
        if kind is not None and kind not in mode.kinds:
            raise ConfigError(
                f"mode {name!r} is for {mode.kinds} objects, not a {kind!r}", file=file, field=field
            )
        return mode


def load_modes(path: str | os.PathLike = DEFAULT_MODES) -> ModeDatabase:
    """Read and validate a mode database file (YAML or TOML: a mapping name -> mode)."""
    from vishap._core.config import read_mapping, validate

    try:
        db = validate(ModeDatabase, {"modes": read_mapping(path)}, file=path)
    except ConfigError as exc:
        if exc.field is None or not exc.field.startswith("modes."):
            raise
        from vishap.world.scene import _without_tags

        stripped = ConfigError(exc.reason, file=path, field=exc.field[len("modes."):])
        raise _without_tags(stripped, tuple(_LAW_KINDS)) from None
    for name, mode in db.modes.items():
        bad = set(mode.kinds) - _LAW_KINDS[mode.law.kind]
        if bad:
            raise ConfigError(
                f"law {mode.law.kind!r} cannot render {sorted(bad)} objects", file=path, field=f"{name}.kinds"
            )
        check_stiffness(law_stiffnesses(mode.law), file=path, prefix=f"{name}.law.")
    return db


def law_stiffnesses(law) -> list[tuple[str, float, float]]:
    """``(field, stiffness N/m, damping N·s/m)`` of every spring a law renders (the button's bottom
    board included; a fabric's tangential spring with its tangential damping)."""
    if law.kind == "wall_spring":
        return [("stiffness_n_m", law.stiffness_n_m, law.damping_n_s_m)]
    if law.kind == "button_click":
        return [(f, getattr(law, f), law.damping_n_s_m) for f in ("k_resist_n_m", "k_click_n_m", "k_bottom_n_m")]
    return [("k_penalty_n_m", law.k_penalty_n_m, law.damping_n_s_m),
            ("k_tangential_n_m", law.k_tangential_n_m, law.damping_tangential_n_s_m)]


def check_stiffness(items, *, file=None, prefix: str = "") -> None:
    """Refuse (:class:`ConfigError` naming ``prefix + field``) any ``(field, K, B)`` stiffer than the
    device renders stably at damping B (:func:`vishap.robot.gains.max_renderable_stiffness`)."""
    from vishap.robot.gains import max_renderable_stiffness

    for field, k, b in items:
        k_max = max_renderable_stiffness(b)
        if k > k_max:
            raise ConfigError(
                f"{k:g} N/m is stiffer than the device renders stably with {b:g} N·s/m of damping "
                f"(at most {k_max:g} N/m: `vishap bench stability`, contact sweep, capped at the data sheet's "
                f"3.5 N/mm); lower it or add damping", file=file, field=f"{prefix}{field}")


@lru_cache(maxsize=1)
def default_modes() -> ModeDatabase:
    """The database shipped with vishap (``vishap/world/modes.yaml``)."""
    return load_modes(DEFAULT_MODES)
