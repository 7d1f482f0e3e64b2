"""The simulators' half of the temperature commands the framed modules share (drivers/tec_protocol.py): the QD
module's TEC and the CSS head's thermal plate, each a :class:`~drivers.sim.qd_optics.TecModel` on the simulated
clock. Mixed into a :class:`~drivers.framed_protocol.FramedResponder` simulator that has `tec` (the TecModel),
`_noise` (its random stream), `world` and `temperature_settings` (its `tec_range_c` and `thermometer_noise_c`)."""

from __future__ import annotations

from .. import tec_protocol as tec
from ..framed_protocol import BAD_LENGTH, OUT_OF_RANGE, centi


class TemperatureResponder:
    """SET_TEMPERATURE and GET_TEMPERATURE answered from the simulator's TecModel; `controller` names it in error
    messages ("TEC", "plate")."""

    controller = "TEC"

    def _temperature_commands(self) -> dict:
        return {tec.SET_TEMPERATURE: self._set_temperature, tec.GET_TEMPERATURE: self._get_temperature}

    def _status(self, frame) -> bytes:
        noise = self.temperature_settings.thermometer_noise_c * self._noise.standard_normal()
        payload = tec.TEC_STATUS.pack(int(self.tec.enabled), centi(self.tec.setpoint_c),
                                      centi(self.tec.measured_c() + noise), int(self.tec.settled()))
        return self._reply(frame.code, frame.sequence, payload)

    def _set_temperature(self, frame):
        if len(frame.payload) != tec.TEC_REQUEST.size:
            return self._error(frame.sequence, BAD_LENGTH, "SET_TEMPERATURE takes mode u8, setpoint i16")
        mode, setpoint_centi = tec.TEC_REQUEST.unpack(frame.payload)
        setpoint = setpoint_centi / 100.0
        low, high = self.temperature_settings.tec_range_c
        if mode not in (tec.TEC_OFF, tec.TEC_ON):
            return self._error(frame.sequence, OUT_OF_RANGE, f"{self.controller} mode {mode}")
        if mode == tec.TEC_ON and not low <= setpoint <= high:
            return self._error(frame.sequence, OUT_OF_RANGE, f"setpoint {setpoint} C outside [{low}, {high}] C")
        self.tec.set(mode == tec.TEC_ON, setpoint)
        return self._status(frame)

    def _get_temperature(self, frame):
        if frame.payload:
            return self._error(frame.sequence, BAD_LENGTH, "GET_TEMPERATURE takes no payload")
        if self.world.clock.instant:  # at time scale 0 the query a bench polls completes the settling
            self.world.clock.advance_to(self.tec.settle_time_s())
        return self._status(frame)
