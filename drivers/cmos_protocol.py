"""Wire format of the CMOS pinhole sun-sensor module — sunbench's own, documented here.

Seed 003's module (an STM32 driving a 640×480 10-bit LUPA300 over RS-485) has no published protocol, so the
project defines one (research note anchors-protocols §6.3: "project-defined … document it as ours"). The framing
code is :mod:`drivers.framed_protocol`'s, shared with the QD module; this module gives it the sync word, the u32
length field and the largest payload of the table below.

Frame, both directions, little-endian::

    offset  size  field
    0       2     sync        0xA5 0x5A
    2       1     code        command (host → module) or reply (module → host) code
    3       1     sequence    chosen by the host, echoed in the reply
    4       4     length N    payload length [bytes], at most MAX_PAYLOAD
    8       N     payload
    8 + N   4     CRC-32      zlib.crc32 of bytes 2 … 8 + N − 1 (code to end of payload)

=========  ==============  ===========================  ===========================================
command    code  reply     payload sent                 reply payload
=========  ==============  ===========================  ===========================================
IDENTIFY   0x01  0x81      —                            model 16s, serial 16s, firmware 8s (ASCII,
                                                        NUL-padded), width u16, height u16, bits u8
SET_EXP    0x02  0x82      exposure u32 [µs]            exposure actually set u32 [µs]
GET_EXP    0x03  0x83      —                            exposure u32 [µs]
CAPTURE    0x04  0x84      packing u8 (0 raw16, 1 10b)  width u16, height u16, bits u8, packing u8,
                                                        exposure u32 [µs], frame counter u32, pixels
CENTROID   0x05  0x85      —                            x f32 [px], y f32 [px], peak u16 [DN],
                                                        pixels u16, status u8, exposure u32 [µs]
TEMP       0x06  0x86      —                            temperature i16 [0.01 °C]
(error)          0xFF                                   error code u8, message (ASCII)
=========  ==============  ===========================  ===========================================

Pixels: ``raw16`` is one u16 per pixel, row-major; ``packed10`` puts 4 pixels in 5 bytes — the 8 high bits of
each, then one byte holding the 2 low bits of pixel k in bits 2k…2k+1 (the MIPI RAW10 layout). Centroid
status: 0 ok, 1 no spot, 2 saturated spot, 3 several spots. Error codes: 1 unknown command, 2 bad length,
3 bad CRC, 4 value out of range, 5 not ready.
"""

from __future__ import annotations

import struct

import numpy as np

# re-exported: the names of the shared framing (drivers/framed_protocol.py) that the driver, the simulator and the
# tests take from here
from .framed_protocol import (  # noqa: F401 - re-exported
    BAD_LENGTH,
    ERROR,
    OUT_OF_RANGE,
    Frame,
    FrameFormat,
    centi,
    pad,
    unpad,
)

FORMAT = FrameFormat(sync=b"\xa5\x5a", length=struct.Struct("<I"), max_payload=2 * 1024 * 1024)
MAX_PAYLOAD = FORMAT.max_payload
encode_frame = FORMAT.encode  # (code, sequence, payload=b"") -> one frame: sync, header, payload, CRC-32
decode_frame = FORMAT.decode  # (buffer) -> (Frame or None while incomplete, bytes consumed); raises FrameError

IDENTIFY, SET_EXPOSURE, GET_EXPOSURE, CAPTURE, CENTROID, TEMPERATURE = 0x01, 0x02, 0x03, 0x04, 0x05, 0x06

RAW16, PACKED10 = 0, 1

IDENTITY = struct.Struct("<16s16s8sHHB")
EXPOSURE = struct.Struct("<I")
FRAME_HEADER = struct.Struct("<HHBBII")
CENTROID_REPLY = struct.Struct("<ffHHBI")
TEMPERATURE_REPLY = struct.Struct("<h")

CENTROID_STATUS = {0: "ok", 1: "no spot", 2: "saturated spot", 3: "several spots"}


def pack10(pixels: np.ndarray) -> bytes:
    """Pack 10-bit pixels (any shape, size divisible by 4) into 5 bytes per 4 pixels (MIPI RAW10 layout)."""
    p = np.ascontiguousarray(pixels, dtype=np.uint16).reshape(-1, 4)
    out = np.empty((p.shape[0], 5), dtype=np.uint8)
    out[:, :4] = (p >> 2).astype(np.uint8)
    low = p & 3
    out[:, 4] = (low[:, 0] | (low[:, 1] << 2) | (low[:, 2] << 4) | (low[:, 3] << 6)).astype(np.uint8)
    return out.tobytes()


def unpack10(data: bytes, count: int) -> np.ndarray:
    """Inverse of :func:`pack10`: `count` pixels as uint16."""
    b = np.frombuffer(data, dtype=np.uint8).reshape(-1, 5)
    if b.shape[0] * 4 != count:
        raise ValueError(f"{len(data)} bytes do not hold {count} packed 10-bit pixels")
    high = b[:, :4].astype(np.uint16) << 2
    low = b[:, 4:5]
    high |= (low >> np.array([0, 2, 4, 6], dtype=np.uint8)) & 3
    return high.reshape(-1)

