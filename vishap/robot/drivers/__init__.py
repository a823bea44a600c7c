"""Device drivers found by name: ``open_device(spec, **kwargs) -> Device`` (docs/devices.md).

A spec is one of

* ``sim`` — the MuJoCo plant :class:`vishap.robot.plant.MujocoPlant` (keyword arguments such as
  ``passive_object``, ``sensor`` or ``q0`` are passed through; its stiffness limit comes from the
  gains file unless given, :mod:`vishap.robot.drivers.sim`);
* a name registered by any installed package in the Python entry-point group ``vishap.devices``
  (``[project.entry-points."vishap.devices"] NAME = "module:Class"``); vishap registers
  ``openhaptics`` (:class:`vishap.robot.drivers.openhaptics.OpenHapticsDevice`) there;
* ``module:Class`` (or ``module:factory``) — any importable driver, inside the package or not.

The target is called with the keyword arguments and must return a :class:`~vishap.robot.device.Device`.
Every failure to find or build one is a single :class:`~vishap._core.errors.ConfigError` naming the
spec (unknown names list the known ones; a module that cannot be imported is named with the reason);
a driver that cannot reach its hardware raises :class:`~vishap._core.errors.DeviceError` itself.
"""
from __future__ import annotations

import importlib
from importlib import metadata

from vishap._core.errors import ConfigError, DeviceError
from vishap.robot.device import Device

__all__ = ["ENTRY_POINT_GROUP", "BUILTIN", "registered", "resolve", "open_device", "describe_all"]

ENTRY_POINT_GROUP = "vishap.devices"
#: Drivers every installation has, whatever its package metadata says.
BUILTIN = {"sim": "vishap.robot.drivers.sim:sim_device"}


def registered() -> dict[str, str]:
    """Name → ``module:attr`` of every known driver: the built-in ones, then the entry points."""
    out = dict(BUILTIN)
    for ep in metadata.entry_points(group=ENTRY_POINT_GROUP):
        out.setdefault(ep.name, ep.value)
    return out


def _load(target: str, spec: str):
    module_name, _, attr = target.partition(":")
    if not module_name or not attr:
        raise ConfigError(f"expected NAME or module:Class, got {spec!r}", field="device")
    try:
        module = importlib.import_module(module_name)
    except ImportError as exc:
        raise ConfigError(f"driver {spec!r}: cannot import module {module_name!r} ({exc})", field="device") from None
    obj = module
    for part in attr.split("."):
        try:
            obj = getattr(obj, part)
        except AttributeError:
            raise ConfigError(f"driver {spec!r}: module {module_name!r} has no {attr!r}", field="device") from None
    if not callable(obj):
        raise ConfigError(f"driver {spec!r}: {target} is not a class or factory", field="device")
    return obj


def resolve(spec: str):
    """The driver class (or factory) a spec names, without opening a device."""
    spec = str(spec).strip()
    if ":" in spec:
        return _load(spec, spec)
    known = registered()
    if spec not in known:
        raise ConfigError(f"unknown device {spec!r} (known: {', '.join(sorted(known))}; or give module:Class)",
                          field="device")
    return _load(known[spec], spec)


def open_device(spec: str, **kwargs) -> Device:
    """Open the device ``spec`` names (see the module docstring), passing ``kwargs`` to its driver."""
    factory = resolve(spec)
    try:
        device = factory(**kwargs)
    except TypeError as exc:
        raise ConfigError(f"driver {spec!r}: bad arguments {sorted(kwargs)} ({exc})", field="device") from None
    if not isinstance(device, Device):
        close = getattr(device, "close", None)
        if callable(close):
            close()
        raise ConfigError(f"driver {spec!r} returned {type(device).__name__}, not a vishap.robot.device.Device "
                          f"(implement read, command_torque, step and time)", field="device")
    return device


def describe_all(**kwargs) -> dict[str, dict]:
    """Every registered driver: its target and, where it opens here, :meth:`Device.describe`;
    otherwise why not (``vishap devices``)."""
    out = {}
    for name, target in registered().items():
        row: dict = {"target": target}
        try:
            dev = open_device(name, **kwargs)
        except (ConfigError, DeviceError) as exc:
            row["unavailable"] = str(exc)
        else:
            try:
                row.update(dev.describe())
            finally:
                dev.close()
        out[name] = row
    return out

