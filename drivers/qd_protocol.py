"""Wire format of the quadrant-photodiode (QD) sun-sensor module — sunbench's own, documented here.

Seed 002's Sputnix module talks to the on-board computer "by a set of commands over a communication
protocol" and says no more (digest §3.4), so the project defines one, shaped like the CMOS module's
(:mod:`drivers.cmos_protocol`) with its own sync word, so a driver pointed at the wrong module reports
"no sync" instead of misreading a reply. The framing code is :mod:`drivers.framed_protocol`'s, shared with the
CMOS module; this module gives it the sync word, the u16 length field and the largest payload of the table below.

Frame, both directions, little-endian::

    offset  size  field
    0       2     sync        0xA5 0x51  ("Q")
    2       1     code        command (host → module) or reply (module → host) code
    3       1     sequence    chosen by the host, echoed in the reply
    4       2     length N    payload length [bytes], at most MAX_PAYLOAD (255)
    6       N     payload
    6 + N   4     CRC-32      zlib.crc32 of bytes 2 … 6 + N − 1 (code to end of payload)

===============  ==============  ===============================  ===========================================
command          code  reply     payload sent                     reply payload
===============  ==============  ===============================  ===========================================
IDENTIFY         0x01  0x81      —                                model 16s, serial 16s, firmware 8s (ASCII,
                                                                  NUL-padded), ADC bits u8, pedestal u16
                                                                  [counts], amperes per count f32 × 4 (Q1 …
                                                                  Q4) [A], detector side f32 [µm], dead gap
                                                                  f32 [µm], integration per sample u32 [µs],
                                                                  largest averaging count u16
READ             0x02  0x82      — (one sample) or                samples N u16, flags u8, sums u32 × 4 (Q1 …
                                 averaging count N u16            Q4, the N samples' ADC counts added)
                                                                  [counts], die temperature i16 [0.01 °C]
                                                                  (mean over the read), sample counter u32
SET_TEMPERATURE  0x03  0x83      TEC mode u8 (0 off, 1 on),       TEC status (below)
                                 setpoint i16 [0.01 °C]
GET_TEMPERATURE  0x04  0x84      —                                TEC status: mode u8, setpoint i16
                                                                  [0.01 °C], die temperature i16 [0.01 °C],
                                                                  settled u8 (1 when within the module's
                                                                  tolerance of the setpoint)
(error)                0xFF                                       error code u8, message (ASCII)
===============  ==============  ===============================  ===========================================

Quadrants are numbered as seed 002's eq. 2.1 implies (digest §2.2): Q1 at (−x, −y), Q2 at (+x, +y), Q3 at
(+x, −y), Q4 at (−x, +y) in the detector frame; every per-quadrant field is in the order Q1, Q2, Q3, Q4.

READ: each of the N samples integrates the four photocurrents for the integration time, then converts them
(one transimpedance channel and ADC per quadrant). A channel reads ``pedestal + I / (amperes per count)``
counts, clipped to [0, 2^bits − 1]; the host takes ``I = (sum / N − pedestal) × amperes per count``. Flags:
bit k (k = 0 … 3) is set when any sample of quadrant k + 1 was at full scale (2^bits − 1: saturated), bit
k + 4 when any was at 0 (under range). The sample counter counts the samples taken since power-up,
including this read's. A READ takes N × integration time plus a fixed conversion overhead; while it runs the
module answers every command with error 5 (not ready).

SET_TEMPERATURE drives the module's thermo-electric cooler (TEC): mode 1 regulates the die at the setpoint
(used on the bench to sweep the dark current over temperature with the shutter closed); mode 0 switches the
TEC off and the die drifts to ambient (the setpoint field is then ignored and echoed as sent). The reply is
the TEC status after the change.

Error codes: 1 unknown command, 2 bad length, 3 bad CRC (the command arrived corrupted; its sequence byte is
echoed as received), 4 value out of range (averaging count 0 or above the largest, a setpoint outside the
TEC's range, a TEC mode other than 0 or 1), 5 not ready (a READ is in progress).
"""

from __future__ import annotations

import struct

from .framed_protocol import (  # noqa: F401 - re-exported
    BAD_CRC,
    BAD_LENGTH,
    ERROR,
    NOT_READY,
    OUT_OF_RANGE,
    REPLY,
    UNKNOWN_COMMAND,
    Frame,
    FrameFormat,
    centi,
    pad,
    unpad,
)

# re-exported: the names of the shared framing (drivers/framed_protocol.py) that the driver, the simulator and the
# tests take from here
from .tec_protocol import (  # noqa: F401 - re-exported: the temperature commands both modules share
    GET_TEMPERATURE,
    SET_TEMPERATURE,
    TEC_OFF,
    TEC_ON,
    TEC_REQUEST,
    TEC_STATUS,
)

FORMAT = FrameFormat(sync=b"\xa5\x51", length=struct.Struct("<H"), max_payload=255)
MAX_PAYLOAD = FORMAT.max_payload
encode_frame = FORMAT.encode  # (code, sequence, payload=b"") -> one frame: sync, header, payload, CRC-32
decode_frame = FORMAT.decode  # (buffer) -> (Frame or None while incomplete, bytes consumed); raises FrameError

IDENTIFY, READ = 0x01, 0x02  # SET_TEMPERATURE, GET_TEMPERATURE: drivers/tec_protocol.py

IDENTITY = struct.Struct("<16s16s8sBH4fffIH")
READ_REQUEST = struct.Struct("<H")
READ_REPLY = struct.Struct("<HB4IhI")
