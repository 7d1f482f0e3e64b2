"""Driver of the CMOS pinhole sun-sensor module (seed 003), over the framed protocol of
:mod:`drivers.cmos_protocol`.

Every reply is checked — sync, CRC, the echoed sequence number, the reply code, the payload length. Bytes
before a sync are skipped, and so is a whole reply to another sequence number (a late reply to an earlier
request). A bad exchange raises a typed error carrying the bytes, after the port's input is drained so the
next exchange starts clean: :class:`~drivers.errors.DeviceTimeout` (silence, or a reply cut short),
:class:`~drivers.errors.ChecksumError` (a CRC mismatch, either way: the module reports error 3 when our
command reached it corrupted) or :class:`~drivers.errors.ProtocolError` (anything else malformed). Each is
asked again, up to ``retries`` times (3 by default), since every command of the module is safe to repeat.
"""

from __future__ import annotations

import struct
import time
from dataclasses import dataclass

import numpy as np

from . import cmos_protocol as wire
from .errors import ChecksumError, DeviceError, DeviceTimeout, LimitError, ProtocolError
from .interfaces import ImageSensor, SensorIdentity
from .transport import DEFAULT_RETRIES, Port, ask_again


class SensorError(DeviceError):
    """The module answered with an error frame; `code` is its error code."""

    def __init__(self, device: str, code: int, message: str):
        self.code = code
        super().__init__(device, f"module error {code} ({wire.ERROR_MESSAGES.get(code, 'unknown')}): {message}")


@dataclass(frozen=True)
class OnboardCentroid:
    """The module's own centroid (its firmware runs seed 003 §3.3).

    Attributes
    ----------
    x_px, y_px : float
        Spot centre [px]; NaN unless `status` is "ok".
    peak_dn : int
    n_pixels : int
    status : str
        "ok", "no spot", "saturated spot" or "several spots".
    exposure_ms : float
    """

    x_px: float
    y_px: float
    peak_dn: int
    n_pixels: int
    status: str
    exposure_ms: float


class CmosSunSensor(ImageSensor):
    """The CMOS pinhole sun-sensor module.

    Parameters
    ----------
    port : Port
        Opened with ``open_port(url, baudrate=921600)`` (RS-485 adapter, or a simulator URL).
    exposure_range_ms : (float, float)
        Exposures the module accepts [ms]; requests outside are refused before sending.
    packing : int
        Pixel packing requested for frames (:data:`~drivers.cmos_protocol.PACKED10` halves the transfer).
    frame_timeout_s : float
        Timeout of a capture reply [s]; it must cover the exposure and the transfer.
    retries : int
        How many times a command is sent again after a garbled, cut or missing reply (default 3,
        :data:`~drivers.transport.DEFAULT_RETRIES`); a dead module is reported after ``retries + 1`` timeouts.

    Attributes
    ----------
    retry_count : int
        Commands sent again so far: how noisy the link is.
    """

    reports_serial = True  # IDENTIFY answers the module's own serial

    def __init__(self, port: Port, *, exposure_range_ms=(0.01, 1000.0), packing: int = wire.PACKED10,
                 frame_timeout_s: float = 5.0, retries: int = DEFAULT_RETRIES, name: str | None = None):
        self.port = port
        self.name = name or port.name
        self.exposure_range_ms = exposure_range_ms
        self.packing = packing
        self.frame_timeout_s = frame_timeout_s
        self.retries = int(retries)
        self.retry_count = 0
        self._sequence = 0
        self._identity: SensorIdentity | None = None
        self._shape: tuple[int, int] | None = None

    # -- one exchange ---------------------------------------------------------------------------------
    def _exchange(self, command: int, payload: bytes = b"", *, timeout_s: float | None = None) -> bytes:
        """Send `command`, return its reply's payload; asked again after a garbled, cut or missing reply.

        Every command is safe to repeat: the queries, SET_EXPOSURE (an absolute value, not a step), and
        CAPTURE / CENTROID (a fresh exposure; the frame whose reply was lost is never used). Each attempt
        carries a new sequence number, so a late reply to an earlier one is recognised and skipped.
        """
        return ask_again(self.name, lambda: self._exchange_once(command, payload, timeout_s), self.retries,
                         on_retry=self._count_retry)

    def _count_retry(self, exc: Exception) -> None:
        self.retry_count += 1

    def _exchange_once(self, command: int, payload: bytes, timeout_s: float | None) -> bytes:
        with self.port.transaction():
            self.port.discard_input()
            self._sequence = (self._sequence + 1) & 0xFF
            self.port.write(wire.encode_frame(command, self._sequence, payload))
            frame = self._read_reply(self._sequence, timeout_s)
            if frame.code == wire.ERROR:
                code_, message = ((frame.payload[0], frame.payload[1:].decode("ascii", "replace")) if frame.payload
                                  else (0, ""))
                if code_ == 3:  # the module got our command with a bad CRC: the link, not the module
                    raise ChecksumError(self.name, f"module error 3 (bad CRC): our command reached it corrupted "
                                                   f"({message})")
                raise SensorError(self.name, code_, message)
            if frame.code != command | wire.REPLY:
                self._fail(f"reply code 0x{frame.code:02X} to command 0x{command:02X}",
                           wire.encode_frame(frame.code, frame.sequence, frame.payload)[:64])
            return frame.payload

    def _read_reply(self, sequence: int, timeout_s: float | None) -> wire.Frame:
        """The reply frame with `sequence`: garbage before a sync and replies to other sequences are skipped."""
        deadline = time.monotonic() + (self.port.timeout_s if timeout_s is None else timeout_s)
        buf = bytearray()
        problem: tuple[str, bytes] | None = None  # the last thing skipped, for the error if nothing else comes
        final = False
        while True:
            try:
                frame, used = wire.decode_frame(buf)
            except wire.CrcMismatch as exc:
                self.port.discard_input()
                raise ChecksumError(self.name, str(exc), received=bytes(buf[:min(exc.consumed, 64)])) from None
            except wire.FrameError as exc:
                used = max(exc.consumed, 1)
                problem = (str(exc), bytes(buf[:min(used, 64)]))
                del buf[:used]
                continue
            if frame is not None:
                raw = bytes(buf[:min(used, 64)])
                del buf[:used]
                if frame.sequence == sequence:
                    return frame
                problem = (f"reply to sequence {frame.sequence}, expected {sequence}", raw)  # a late reply
                continue
            if final:
                if buf:  # a frame began and stopped
                    length = wire.HEADER.unpack_from(buf)[3] if len(buf) >= wire.HEADER.size else 0
                    total = wire.HEADER.size + length + wire.CRC.size
                    raise DeviceTimeout(self.name, f"reply cut short after {len(buf)} of {total} bytes",
                                        received=bytes(buf[:64]))
                if problem:
                    raise ProtocolError(self.name, problem[0], received=problem[1])
                raise DeviceTimeout(self.name, "no reply within the timeout")
            missing = wire.HEADER.size - len(buf)
            if missing <= 0:  # a header is in: the rest of the frame
                missing = wire.HEADER.size + wire.HEADER.unpack_from(buf)[3] + wire.CRC.size - len(buf)
            try:
                buf += self.port.read_exact(missing, timeout_s=max(deadline - time.monotonic(), 1e-3))
            except DeviceTimeout as exc:
                buf += exc.received
                final = True  # nothing more will come: decode what did, then say what went wrong

    def _fail(self, message: str, received: bytes):
        self.port.discard_input()
        raise ProtocolError(self.name, message, received=received)

    def _unpack(self, layout: struct.Struct, payload: bytes, what: str):
        if len(payload) != layout.size:
            self._fail(f"{what} reply has {len(payload)} payload bytes, expected {layout.size}", payload[:64])
        return layout.unpack(payload)

    # -- the interface ----------------------------------------------------------------------------------
    def identify(self) -> SensorIdentity:
        model, serial, firmware, width, height, bits = self._unpack(wire.IDENTITY, self._exchange(wire.IDENTIFY),
                                                                    "IDENTIFY")
        self._identity = SensorIdentity(wire.unpad(model), wire.unpad(serial), wire.unpad(firmware))
        self._shape = (height, width)
        self.bit_depth = bits
        return self._identity

    def set_exposure_ms(self, exposure_ms: float) -> float:
        """Set the exposure [ms]; returns what the module set (it rounds to its line time)."""
        low, high = self.exposure_range_ms
        if not low <= exposure_ms <= high:
            raise LimitError(self.name, f"exposure {exposure_ms} ms is outside [{low}, {high}] ms")
        (us,) = self._unpack(wire.EXPOSURE,
                             self._exchange(wire.SET_EXPOSURE, wire.EXPOSURE.pack(round(exposure_ms * 1000))),
                             "SET_EXPOSURE")
        return us / 1000.0

    def exposure_ms(self) -> float:
        (us,) = self._unpack(wire.EXPOSURE, self._exchange(wire.GET_EXPOSURE), "GET_EXPOSURE")
        return us / 1000.0

    def capture(self) -> np.ndarray:
        """Expose and transfer one frame: 2-D uint16 [DN]."""
        frame, _ = self.capture_with_metadata()
        return frame

    def capture_with_metadata(self) -> tuple[np.ndarray, dict]:
        payload = self._exchange(wire.CAPTURE, bytes([self.packing]), timeout_s=self.frame_timeout_s)
        if len(payload) < wire.FRAME_HEADER.size:
            self._fail("CAPTURE reply too short", payload[:64])
        width, height, bits, packing, exposure_us, counter = wire.FRAME_HEADER.unpack_from(payload)
        pixels = payload[wire.FRAME_HEADER.size:]
        count = width * height
        expected = count * 2 if packing == wire.RAW16 else count * 5 // 4
        if packing not in (wire.RAW16, wire.PACKED10) or len(pixels) != expected:
            self._fail(f"frame of {width}×{height} with packing {packing} has {len(pixels)} pixel bytes", payload[:64])
        if packing == wire.RAW16:
            image = np.frombuffer(pixels, dtype="<u2").astype(np.uint16).reshape(height, width)
        else:
            image = wire.unpack10(pixels, count).reshape(height, width)
        return image, {"exposure_ms": exposure_us / 1000.0, "frame_counter": counter, "bit_depth": bits}

    def onboard_centroid(self) -> OnboardCentroid:
        x, y, peak, n, status, exposure_us = self._unpack(wire.CENTROID_REPLY, self._exchange(
            wire.CENTROID, timeout_s=self.frame_timeout_s), "CENTROID")
        return OnboardCentroid(float(x), float(y), int(peak), int(n),
                               wire.CENTROID_STATUS.get(status, f"status {status}"), exposure_us / 1000.0)

    def temperature_c(self) -> float:
        (centi,) = self._unpack(wire.TEMPERATURE_REPLY, self._exchange(wire.TEMPERATURE), "TEMPERATURE")
        return centi / 100.0
