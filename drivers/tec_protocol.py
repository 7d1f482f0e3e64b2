"""The temperature control that the framed sensor modules share: the QD module's TEC (drivers/qd_protocol.py) and the
CSS head's thermal plate (drivers/css_protocol.py) speak the same two commands over their own framing.

===============  ==============  ===============================  ===========================================
command          code  reply     payload sent                     reply payload
===============  ==============  ===============================  ===========================================
SET_TEMPERATURE  0x03  0x83      mode u8 (0 off, 1 on),           status (below)
                                 setpoint i16 [0.01 °C]
GET_TEMPERATURE  0x04  0x84      —                                status: mode u8, setpoint i16 [0.01 °C],
                                                                  temperature i16 [0.01 °C], settled u8 (1
                                                                  when within the module's tolerance)
===============  ==============  ===============================  ===========================================

:class:`TemperatureClient` is the drivers' half (on a :class:`~drivers.framed_protocol.FramedModule`),
:class:`drivers.sim.temperature.TemperatureResponder` the simulators'.
"""

from __future__ import annotations

import struct
import time

from .errors import DeviceTimeout, LimitError
from .framed_protocol import centi
from .interfaces import TecStatus

SET_TEMPERATURE, GET_TEMPERATURE = 0x03, 0x04
TEC_OFF, TEC_ON = 0, 1
TEC_REQUEST = struct.Struct("<Bh")
TEC_STATUS = struct.Struct("<BhhB")


class TemperatureClient:
    """SET_TEMPERATURE and GET_TEMPERATURE of a framed module, mixed into its driver after
    :class:`~drivers.framed_protocol.FramedModule` (whose `_exchange`, `_unpack` and `_fail` it uses), which sets
    `setpoint_range_c`. `controller` names the device in messages ("TEC", "plate"), `regulated` what it holds at
    the setpoint ("die", "head")."""

    controller = "TEC"
    regulated = "die"
    settle_timeout_s = 900.0
    setpoint_range_c: tuple[float, float]
    name: str

    def _temperature_status(self, payload: bytes, command: int, what: str) -> TecStatus:
        mode, setpoint, temperature, settled = self._unpack(TEC_STATUS, self._exchange(command, payload), what)
        if mode not in (TEC_OFF, TEC_ON):
            self._fail(f"{what} reply has {self.controller} mode {mode}",
                       TEC_STATUS.pack(mode, setpoint, temperature, settled))
        return TecStatus(mode == TEC_ON, setpoint / 100.0 if mode == TEC_ON else None, temperature / 100.0,
                         bool(settled))

    def set_temperature_setpoint_c(self, setpoint_c: float | None) -> TecStatus:
        """Regulate at `setpoint_c` [°C] (resolution 0.01 °C); None switches the control off. A setpoint outside
        `setpoint_range_c` raises :class:`~drivers.errors.LimitError`, unsent."""
        if setpoint_c is None:
            return self._temperature_status(TEC_REQUEST.pack(TEC_OFF, 0), SET_TEMPERATURE, "SET_TEMPERATURE")
        low, high = self.setpoint_range_c
        if not low <= setpoint_c <= high:  # NaN fails too
            raise LimitError(self.name, f"setpoint {setpoint_c} °C is outside [{low}, {high}] °C")
        return self._temperature_status(TEC_REQUEST.pack(TEC_ON, centi(setpoint_c)), SET_TEMPERATURE,
                                        "SET_TEMPERATURE")

    def temperature_status(self) -> TecStatus:
        return self._temperature_status(b"", GET_TEMPERATURE, "GET_TEMPERATURE")

    def wait_until_settled(self, *, timeout_s: float | None = None, poll_s: float = 1.0,
                           pause=time.sleep) -> TecStatus:
        """Poll until the module has settled; :class:`DeviceTimeout` if it has not within `timeout_s` (default
        `settle_timeout_s`). `pause(poll_s)` waits between polls (a caller that must be able to cancel passes one
        that raises)."""
        timeout_s = self.settle_timeout_s if timeout_s is None else timeout_s
        deadline = time.monotonic() + timeout_s
        while True:
            status = self.temperature_status()
            if status.settled:
                return status
            if time.monotonic() > deadline:
                raise DeviceTimeout(self.name, f"{self.controller} not settled after {timeout_s} s ({self.regulated} "
                                               f"at {status.temperature_c:.2f} °C, setpoint {status.setpoint_c} °C)")
            pause(poll_s)
