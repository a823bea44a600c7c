"""Servo gains from ``gains.yaml``, refused outside the measured stable region (VisHap §2.3, Eq. 4–5).

``gains.yaml`` (beside this module) holds the default gains, the largest virtual stiffness the
device may render, and the stable region measured by ``vishap bench stability``: the Kp × Kv grid
(1 = stable with both the ideal sensor and the encoder model) and the range of the Eq. 5 filter
constant ``a``. :func:`check_gains` accepts ``(Kp, Kv)`` only when every measured grid node around
it is stable, and ``a`` only inside the measured range; anything else is a :class:`ConfigError`
naming the file and field.
"""
from __future__ import annotations

import bisect
import math
import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from pydantic import Field, model_validator

from vishap._core.config import Schema, load_config
from vishap._core.errors import ConfigError

__all__ = ["GAINS_FILE", "Gains", "GainsFile", "load_gains", "check_gains", "max_renderable_stiffness"]

GAINS_FILE = Path(__file__).with_name("gains.yaml")


class _GainsSection(Schema):
    kp: float = Field(ge=0, description="N/m")
    kv: float = Field(ge=0, description="N·s/m")
    a: float = Field(gt=0, description="rad/s")
    ramp_s: float = Field(ge=0, description="s")
    velocity_hz: float = Field(default=0.0, ge=0, description="Hz, Kalman velocity estimator bandwidth; 0: the device's rates")
    vision_hz: float = Field(default=0.0, ge=0, description="Hz, X_d sample rate the target is averaged over; 0: off")


class _Region(Schema):
    measured_by: str
    kp: list[float] = Field(min_length=2)
    kv: list[float] = Field(min_length=2)
    stable: list[list[int]]
    a_min: float = Field(gt=0)
    a_max: float = Field(gt=0)
    #: the smallest stable a at each Kp of the filter sweep (``{kp: a_min}``); where given, ``a`` is
    #: checked against the larger of the two bracketing Kp's values instead of the global ``a_min``
    a_min_by_kp: dict[float, float] | None = None

    @model_validator(mode="after")
    def _shape(self):
        if len(self.stable) != len(self.kp) or any(len(row) != len(self.kv) for row in self.stable):
            raise ValueError(f"stable must be {len(self.kp)} rows of {len(self.kv)} (kp × kv)")
        if sorted(self.kp) != self.kp or sorted(self.kv) != self.kv:
            raise ValueError("kp and kv must be increasing")
        return self


class _Renderable(Schema):
    measured_by: str
    damping_n_s_m: list[float] = Field(min_length=1)
    max_stiffness_n_m: list[float] = Field(min_length=1)

    @model_validator(mode="after")
    def _shape(self):
        if len(self.damping_n_s_m) != len(self.max_stiffness_n_m):
            raise ValueError("damping_n_s_m and max_stiffness_n_m must have the same length")
        if sorted(self.damping_n_s_m) != self.damping_n_s_m:
            raise ValueError("damping_n_s_m must be increasing")
        return self


class GainsFile(Schema):
    gains: _GainsSection
    max_stiffness_n_m: float = Field(gt=0)
    stable_region: _Region
    renderable_stiffness: _Renderable | None = None


#: the shipped file's gains: the one home of their values (``Gains()`` is them; a field given overrides it)
_SHIPPED = load_config(GAINS_FILE, GainsFile).gains


@dataclass(frozen=True)
class Gains:
    """Controller gains: ``kp`` (N/m), ``kv`` (N·s/m), Eq. 5 filter constant ``a`` (rad/s), ramp-up (s).
    Fields not given are the shipped ``gains.yaml``'s (unchecked here: :func:`load_gains` checks a file's
    gains against its measured stable region)."""

    kp: float = _SHIPPED.kp
    kv: float = _SHIPPED.kv
    a: float = _SHIPPED.a
    ramp_s: float = _SHIPPED.ramp_s
    #: bandwidth (Hz) of the per-joint Kalman velocity estimator on the joint angles; 0 uses the
    #: device's own rates (the driver's backward difference)
    velocity_hz: float = _SHIPPED.velocity_hz
    #: rate (Hz) at which X_d arrives; > 0 averages the target over one sample interval (a boxcar
    #: whose zeros fall on the sample rate and its harmonics); 0 leaves the target as it comes
    vision_hz: float = _SHIPPED.vision_hz

    def __post_init__(self):
        for name, lo, strict in (("kp", 0.0, False), ("kv", 0.0, False), ("a", 0.0, True), ("ramp_s", 0.0, False),
                                 ("velocity_hz", 0.0, False), ("vision_hz", 0.0, False)):
            v = getattr(self, name)
            if not isinstance(v, (int, float)) or isinstance(v, bool) or not math.isfinite(v):
                raise ConfigError(f"expected a finite number, got {v!r}", field=f"gains.{name}")
            if v < lo or (strict and v == lo):
                raise ConfigError(f"expected {'>' if strict else '≥'} {lo}, got {v!r}", field=f"gains.{name}")


def _bracket(values: list[float], x: float) -> list[int] | None:
    """Indices of the grid nodes bracketing ``x`` (one index on a node); None outside the grid."""
    if x < values[0] or x > values[-1]:
        return None
    i = bisect.bisect_left(values, x)
    if values[i] == x:
        return [i]
    return [i - 1, i]


def check_gains(gains: Gains, region: _Region, *, file: str | os.PathLike | None = None) -> Gains:
    """Return ``gains`` if they lie inside the measured stable ``region``, else raise :class:`ConfigError`."""
    ik = _bracket(region.kp, gains.kp)
    jk = _bracket(region.kv, gains.kv)
    if ik is None:
        raise ConfigError(
            f"kp {gains.kp} N/m is outside the measured range {region.kp[0]}…{region.kp[-1]}", file=file, field="gains.kp"
        )
    if jk is None:
        raise ConfigError(
            f"kv {gains.kv} N·s/m is outside the measured range {region.kv[0]}…{region.kv[-1]}", file=file, field="gains.kv"
        )
    bad = [(region.kp[i], region.kv[j]) for i in ik for j in jk if not region.stable[i][j]]
    if bad:
        raise ConfigError(
            f"(kp {gains.kp}, kv {gains.kv}) is outside the measured stable region: the run(s) at (kp, kv) = "
            f"{bad} oscillated or diverged ({region.measured_by})",
            file=file,
            field="gains",
        )
    a_min = region.a_min
    if region.a_min_by_kp:
        kps = sorted(region.a_min_by_kp)
        idx = _bracket(kps, gains.kp)
        if idx is not None:
            a_min = max(region.a_min_by_kp[kps[i]] for i in idx)
    if not a_min <= gains.a <= region.a_max:
        raise ConfigError(
            f"a {gains.a} rad/s is outside the measured stable range {a_min}…{region.a_max} at kp {gains.kp}",
            file=file, field="gains.a"
        )
    return gains


def load_gains(path: str | os.PathLike | None = None, *, override: dict | None = None) -> tuple[Gains, GainsFile]:
    """Read ``path`` (default: the shipped ``gains.yaml``), apply ``override`` (e.g. ``{"kp": 600}``)
    to its gains, and return the checked :class:`Gains` with the whole file.

    Gains outside the file's measured stable region are refused with a :class:`ConfigError`.
    """
    path = GAINS_FILE if path is None else Path(path)
    cfg = load_config(path, GainsFile)
    values = cfg.gains.model_dump()
    for k, v in (override or {}).items():
        if k not in values:
            raise ConfigError(f"unknown gain {k!r} (expected one of {sorted(values)})", file=path, field=f"gains.{k}")
        values[k] = v
    try:
        gains = Gains(**values)
    except ConfigError as exc:
        raise ConfigError(exc.reason, file=path, field=exc.field) from None
    return check_gains(gains, cfg.stable_region, file=path), cfg


@lru_cache(maxsize=4)
def _renderable(path: str) -> tuple[tuple[float, ...], tuple[float, ...]]:
    cfg = load_config(path, GainsFile)
    r = cfg.renderable_stiffness
    if r is None:
        return (0.0,), (float(cfg.max_stiffness_n_m),)
    return tuple(r.damping_n_s_m), tuple(r.max_stiffness_n_m)


def max_renderable_stiffness(damping_n_s_m: float, path: str | os.PathLike | None = None) -> float:
    """The stiffest law (N/m) the device renders stably with normal damping ``damping_n_s_m`` (N·s/m).

    From the file's ``renderable_stiffness`` table (``vishap bench stability``, contact sweep: every
    mode in its own contact set-up): the entry at the largest measured damping not above the law's
    (more damping than measured earns nothing), never above the data sheet's stiffness
    (``PhantomParams.datasheet_stiffness_n_m``). 0 below the smallest measured damping.
    """
    from vishap.robot.params import DEFAULT

    bs, ks = _renderable(str(GAINS_FILE if path is None else path))
    i = bisect.bisect_right(bs, float(damping_n_s_m)) - 1
    if i < 0:
        return 0.0
    return min(float(ks[i]), DEFAULT.datasheet_stiffness_n_m)
