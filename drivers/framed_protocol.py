"""The framing sunbench's framed binary modules share (the CMOS pinhole and the quadrant-photodiode sun sensors):
the codec, the host's request/reply exchange and the simulated module's frame loop — written once here.

Each module's own protocol module (:mod:`drivers.cmos_protocol`, :mod:`drivers.qd_protocol`) documents its byte
table and builds its :class:`FrameFormat` from three things that differ: the sync word, the width of the length
field and the largest payload. Everything else is common. A frame, both directions, little-endian::

    sync        len(sync) bytes (two for both modules), a module's own, so a driver pointed at the wrong
                module reports "no sync" instead of misreading a reply
    code        u8, command (host → module) or reply (module → host) code: reply = command | REPLY
    sequence    u8, chosen by the host, echoed in the reply
    length N    the format's length field (u16 or u32): payload length [bytes], at most the format's maximum
    payload     N bytes
    CRC-32      u32, zlib.crc32 of code … end of payload

An error frame (code ERROR) carries an error code u8 and an ASCII message; the codes are common too:
1 unknown command, 2 bad length, 3 bad CRC (the command arrived corrupted; its sequence byte is echoed as
received), 4 value out of range, 5 not ready.

Three parts: :class:`FrameFormat` (encode, decode), :class:`FramedModule` (a driver's exchange with retries and
typed errors) and :class:`FramedResponder` (a simulator's frame loop and replies).
"""

from __future__ import annotations

import struct
import time
import zlib
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, ClassVar

from .errors import ChecksumError, DeviceError, DeviceTimeout, ProtocolError
from .transport import Port, ask_again

CRC = struct.Struct("<I")
REPLY = 0x80  # reply code = command | REPLY
ERROR = 0xFF

UNKNOWN_COMMAND, BAD_LENGTH, BAD_CRC, OUT_OF_RANGE, NOT_READY = 1, 2, 3, 4, 5
ERROR_MESSAGES = {1: "unknown command", 2: "bad length", 3: "bad CRC", 4: "value out of range", 5: "not ready"}


# -- the codec ------------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Frame:
    code: int
    sequence: int
    payload: bytes


class FrameError(ValueError):
    """A frame that cannot be decoded; `consumed` bytes of the buffer belong to it (or to garbage)."""

    def __init__(self, message: str, consumed: int):
        super().__init__(message)
        self.consumed = consumed


class CrcMismatch(FrameError):
    """A whole frame whose CRC-32 does not match: it arrived, corrupted (line noise)."""


@dataclass(frozen=True)
class FrameFormat:
    """One module's framing: its sync word, its length field and its largest payload.

    Attributes
    ----------
    sync : bytes
        The sync word that starts every frame.
    length : struct.Struct
        The length field (``struct.Struct("<H")`` or ``struct.Struct("<I")``).
    max_payload : int
        Largest payload [bytes]; longer ones are refused by :meth:`encode` and by :meth:`decode`.
    header : struct.Struct
        Sync, code, sequence and length (derived).
    """

    sync: bytes
    length: struct.Struct
    max_payload: int
    header: struct.Struct = field(init=False)

    def __post_init__(self):
        object.__setattr__(self, "header", struct.Struct(f"<{len(self.sync)}sBB{self.length.format.lstrip('<')}"))

    def encode(self, code: int, sequence: int, payload: bytes = b"") -> bytes:
        """One frame: sync, header, payload, CRC-32."""
        if len(payload) > self.max_payload:
            raise ValueError(f"payload of {len(payload)} bytes exceeds {self.max_payload}")
        body = bytes([code, sequence & 0xFF]) + self.length.pack(len(payload)) + payload
        return self.sync + body + CRC.pack(zlib.crc32(body))

    def decode(self, buffer) -> tuple[Frame | None, int]:
        """Take one frame from the start of `buffer`.

        Returns
        -------
        frame : Frame or None
            None when the buffer does not hold a whole frame yet.
        consumed : int
            Bytes of the buffer the frame used (0 when incomplete).

        Raises
        ------
        FrameError
            Garbage before a sync, a length over the maximum or a CRC mismatch (:class:`CrcMismatch`);
            `consumed` says how many bytes to drop to resynchronise.
        """
        sync, header = self.sync, self.header
        if len(buffer) >= len(sync) and bytes(buffer[:len(sync)]) != sync:
            at = bytes(buffer).find(sync, 1)
            # keep a trailing first byte of the sync: it may be the first half of the next one
            raise FrameError("no sync at the start of the frame",
                             at if at > 0 else len(buffer) - (buffer[-1] == sync[0]))
        if len(buffer) < header.size:
            return None, 0
        _, code, sequence, length = header.unpack_from(buffer)
        if length > self.max_payload:
            raise FrameError(f"payload length {length} exceeds {self.max_payload}", len(sync))
        total = header.size + length + CRC.size
        if len(buffer) < total:
            return None, 0
        body = bytes(buffer[len(sync): header.size + length])
        (crc,) = CRC.unpack_from(buffer, header.size + length)
        if zlib.crc32(body) != crc:
            raise CrcMismatch("CRC mismatch", total)
        return Frame(code, sequence, body[header.size - len(sync):]), total

    def frame_length(self, header: bytes) -> int:
        """Whole length of the frame whose first `self.header.size` bytes are `header` [bytes]."""
        return self.header.size + self.header.unpack_from(header)[-1] + CRC.size


def centi(value_c: float) -> int:
    """A temperature as the wire's i16 in 0.01 °C (clamped to the i16 range)."""
    return max(min(int(round(value_c * 100.0)), 32767), -32768)


def pad(text: str, size: int) -> bytes:
    return text.encode("ascii", "replace")[:size].ljust(size, b"\0")


def unpad(raw: bytes) -> str:
    return raw.split(b"\0", 1)[0].decode("ascii", "replace")


# -- the host side: a driver's exchange -----------------------------------------------------------------------
class ModuleError(DeviceError):
    """The module answered with an error frame; `code` is its error code."""

    def __init__(self, device: str, code: int, message: str):
        self.code = code
        super().__init__(device, f"module error {code} ({ERROR_MESSAGES.get(code, 'unknown')}): {message}")


class FramedModule:
    """What a driver of a framed module does on every command (a base of the driver class).

    Every reply is checked — sync, CRC, the echoed sequence number, the reply code, the payload length. Bytes
    before a sync are skipped, and so is a whole reply to another sequence number (a late reply to an earlier
    request). A bad exchange raises a typed error carrying the bytes, after the port's input is drained so the
    next exchange starts clean: :class:`~drivers.errors.DeviceTimeout` (silence, or a reply cut short),
    :class:`~drivers.errors.ChecksumError` (a CRC mismatch, either way: the module reports error 3 when our
    command reached it corrupted) or :class:`~drivers.errors.ProtocolError` (anything else malformed); each is
    asked again, up to ``retries`` times. An error frame from the module raises :attr:`module_error`, not
    retried.

    The driver class sets :attr:`frame_format` and :attr:`module_error`, and its constructor (which takes the
    port) calls :meth:`_attach`.
    """

    frame_format: ClassVar[FrameFormat]
    module_error: ClassVar[type[ModuleError]] = ModuleError

    port: Port
    name: str
    retries: int
    retry_count: int  # commands sent again so far: how noisy the link is
    _sequence: int

    def _attach(self, port: Port, *, retries: int, name: str | None) -> None:
        self.port = port
        self.name = name or port.name
        self.retries = int(retries)
        self.retry_count = 0
        self._sequence = 0

    def _exchange(self, command: int, payload: bytes = b"", *, timeout_s: float | None = None) -> bytes:
        """Send `command`, return its reply's payload; asked again after a garbled, cut or missing reply.

        Only for modules whose every command is safe to repeat. Each attempt carries a new sequence number, so a
        late reply to an earlier one is recognised and skipped.
        """
        return ask_again(self.name, lambda: self._exchange_once(command, payload, timeout_s), self.retries,
                         on_retry=self._count_retry)

    def _count_retry(self, exc: Exception) -> None:
        self.retry_count += 1

    def _exchange_once(self, command: int, payload: bytes, timeout_s: float | None) -> bytes:
        fmt = self.frame_format
        with self.port.transaction():
            self.port.discard_input()
            self._sequence = (self._sequence + 1) & 0xFF
            self.port.write(fmt.encode(command, self._sequence, payload))
            frame = self._read_reply(self._sequence, timeout_s)
            if frame.code == ERROR:
                code, message = 0, ""
                if frame.payload:
                    code, message = frame.payload[0], frame.payload[1:].decode("ascii", "replace")
                if code == BAD_CRC:  # the module got our command corrupted: the link, not the module
                    raise ChecksumError(self.name, f"module error 3 (bad CRC): our command reached it corrupted "
                                                   f"({message})")
                raise self.module_error(self.name, code, message)
            if frame.code != command | REPLY:
                self._fail(f"reply code 0x{frame.code:02X} to command 0x{command:02X}",
                           fmt.encode(frame.code, frame.sequence, frame.payload)[:64])
            return frame.payload

    def _read_reply(self, sequence: int, timeout_s: float | None) -> Frame:
        """The reply frame with `sequence`: garbage before a sync and replies to other sequences are skipped."""
        fmt = self.frame_format
        deadline = time.monotonic() + (self.port.timeout_s if timeout_s is None else timeout_s)
        buf = bytearray()
        problem: tuple[str, bytes] | None = None  # the last thing skipped, for the error if nothing else comes
        final = False
        while True:
            try:
                frame, used = fmt.decode(buf)
            except CrcMismatch as exc:
                self.port.discard_input()
                raise ChecksumError(self.name, str(exc), received=bytes(buf[:min(exc.consumed, 64)])) from None
            except FrameError as exc:
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
                if buf:  # a frame began and stopped (cut inside its header: it needed an empty frame's length)
                    total = fmt.frame_length(buf) if len(buf) >= fmt.header.size else fmt.header.size + CRC.size
                    raise DeviceTimeout(self.name, f"reply cut short after {len(buf)} of {total} bytes",
                                        received=bytes(buf[:64]))
                if problem:
                    raise ProtocolError(self.name, problem[0], received=problem[1])
                raise DeviceTimeout(self.name, "no reply within the timeout")
            missing = fmt.header.size - len(buf)
            if missing <= 0:  # a header is in: the rest of the frame
                missing = fmt.frame_length(buf) - len(buf)
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


# -- the device side: a simulator's frame loop ----------------------------------------------------------------
class FramedResponder:
    """The protocol front of a simulated framed module: put it before :class:`drivers.sim.device.SimDevice`
    among the simulator's bases.

    :meth:`handle` takes whole frames off the input: a command frame goes to :meth:`_dispatch` (the handler
    :meth:`_commands` names for its code, or error 1), a frame with a bad CRC is answered with error 3 echoing
    its sequence byte as received, and garbage is dropped. Replies that take simulated time are held back by
    :meth:`_hold_until` and come out of :meth:`unsolicited` when it has passed.

    The simulator sets :attr:`frame_format` and has a `world` with a `clock`. Back door: :attr:`corrupt_crc`, the
    number of next replies that carry a wrong CRC.
    """

    frame_format: ClassVar[FrameFormat]
    world: Any

    def __init__(self) -> None:
        super().__init__()  # SimDevice's, next in the simulator's bases
        self.corrupt_crc = 0
        self._held: list[tuple[float, bytes]] = []  # (ready time, reply) of the commands in progress

    def _commands(self) -> dict[int, Callable[[Frame], bytes]]:  # pragma: no cover - abstract
        """The handler of each command code."""
        raise NotImplementedError

    def handle(self, inbuf: bytearray) -> bytes:
        out = bytearray()
        while inbuf:
            try:
                frame, used = self.frame_format.decode(inbuf)
            except CrcMismatch as exc:
                sequence = inbuf[3]
                del inbuf[: max(exc.consumed, 1)]
                out += self._error(sequence, BAD_CRC, "CRC mismatch")
                continue
            except FrameError as exc:
                del inbuf[: max(exc.consumed, 1)]
                continue
            if frame is None:
                break
            del inbuf[:used]
            out += self._dispatch(frame)
        return bytes(out)

    def _dispatch(self, frame: Frame) -> bytes:
        handler = self._commands().get(frame.code)
        if handler is None:
            return self._error(frame.sequence, UNKNOWN_COMMAND, f"unknown command 0x{frame.code:02X}")
        return handler(frame)

    def _reply(self, command: int, sequence: int, payload: bytes) -> bytes:
        raw = self.frame_format.encode(command | REPLY, sequence, payload)
        if self.corrupt_crc > 0:
            self.corrupt_crc -= 1
            raw = raw[:-1] + bytes([raw[-1] ^ 0xFF])
        return raw

    def _error(self, sequence: int, code: int, message: str) -> bytes:
        return self.frame_format.encode(ERROR, sequence, bytes([code]) + message.encode("ascii", "replace"))

    def _hold_until(self, ready: float, reply: bytes) -> bytes:
        """`reply`, once the simulated clock reaches `ready` [s]: at time scale 0 the clock jumps there at once,
        otherwise it is held back for :meth:`unsolicited`."""
        if self.world.clock.instant:
            self.world.clock.advance_to(ready)
            return reply
        self._held.append((ready, reply))
        return b""

    def unsolicited(self) -> bytes:
        if not self._held:
            return b""
        now = self.world.clock.now()
        ready = [r for t, r in self._held if t <= now]
        self._held = [(t, r) for t, r in self._held if t > now]
        return b"".join(ready)

    def reset_link(self) -> None:
        super().reset_link()  # SimDevice's, next in the simulator's bases
        self._held.clear()
