"""Names under which in-process simulators answer ``sim://NAME`` URLs."""

from __future__ import annotations

import threading

_lock = threading.Lock()
_devices: dict = {}


def register(name: str, device) -> str:
    """Serve `device` (a :class:`~drivers.sim.device.SimDevice`) at ``sim://name``; returns the URL."""
    with _lock:
        if name in _devices and _devices[name] is not device:
            raise ValueError(f"sim://{name} is already taken")
        _devices[name] = device
    return f"sim://{name}"


def unregister(name: str) -> None:
    with _lock:
        _devices.pop(name, None)


def lookup(name: str):
    with _lock:
        try:
            return _devices[name]
        except KeyError:
            raise KeyError(f"no simulator registered as sim://{name} "
                           f"(registered: {', '.join(sorted(_devices)) or 'none'})") from None
