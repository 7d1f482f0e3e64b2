"""Wire format of the coarse-sun-sensor (CSS) head — sunbench's own, documented here.

Seed 000's PilsenCUBE head (digest §3.1, §3.6) is a cube with a triplet of detectors at the centre of each of its six
faces — an EPD-365 UV photodiode (``uv``), a BPW 21 visible photodiode (``vis``) and a TPS 230 thermopile (``ir``) —
each behind its own preamplifier and a 16-sample-averaging ADC (ADuC842); the thesis defines no host protocol. The
bench's head is a module shaped like the QD module (:mod:`drivers.qd_protocol`) with its own sync word, so a driver
pointed at the wrong module reports "no sync" instead of misreading a reply. The framing code is
:mod:`drivers.framed_protocol`'s; this module gives it the sync word, the u16 length field and the largest payload.

Frame, both directions, little-endian::

    offset  size  field
    0       2     sync        0xA5 0x43  ("C")
    2       1     code        command (host → module) or reply (module → host) code
    3       1     sequence    chosen by the host, echoed in the reply
    4       2     length N    payload length [bytes], at most MAX_PAYLOAD (512; the largest reply, IDENTIFY's, is 336)
    6       N     payload
    6 + N   4     CRC-32      zlib.crc32 of bytes 2 … 6 + N − 1 (code to end of payload)

===============  ==============  ===============================  ===========================================
command          code  reply     payload sent                     reply payload
===============  ==============  ===============================  ===========================================
IDENTIFY         0x01  0x81      —                                model 16s, serial 16s, firmware 8s (ASCII,
                                                                  NUL-padded), ADC bits u8, channel count u8
                                                                  (18), largest averaging count u16, sample
                                                                  time u32 [µs]; then per channel, in the
                                                                  channel order below: name 8s (ASCII,
                                                                  NUL-padded), pedestal u32 [counts], units
                                                                  per count f32 [A/count or V/count] — 336
                                                                  bytes
READ             0x02  0x82      — (one sample) or                samples N u16, flags u8, saturated mask u32,
                                 averaging count N u16            under-range mask u32, sums u32 × 18 (the N
                                                                  samples' ADC codes added, channel order)
                                                                  [counts], head temperature i16 [0.01 °C]
                                                                  (mean over the read), sample counter u32 —
                                                                  89 bytes
SET_TEMPERATURE  0x03  0x83      plate mode u8 (0 off, 1 on),     plate status (below)
                                 setpoint i16 [0.01 °C]
GET_TEMPERATURE  0x04  0x84      —                                plate status: mode u8, setpoint i16
                                                                  [0.01 °C], head temperature i16 [0.01 °C],
                                                                  settled u8 (1 when within the module's
                                                                  tolerance of the setpoint)
(error)                0xFF                                       error code u8, message (ASCII)
===============  ==============  ===============================  ===========================================

Channels. 18, named ``<face>_<type>`` and always in this fixed order, face-major (:data:`CHANNELS`): faces px, py,
mx, my, pz, mz (outward normals +X, +Y, −X, −Y, +Z, −Z of the head's body frame; the thesis' faces 1 … 6), types
uv, vis, ir within each face — channel i is bit i of the masks and the i-th sum. IDENTIFY names them, so a host
can check the module's wiring against this order. A channel's signal is a current [A] for the photodiodes (uv,
vis) and a voltage [V] for the thermopile (ir).

READ: each of the N samples converts all 18 channels once (the sample time, multiplexed). A channel reads
``pedestal + signal / (units per count)`` counts, clipped to [0, 2^bits − 1]; codes are unsigned on every
channel: the photodiodes' ranges start just above zero (a small pedestal keeps the offset's noise inside the
range), the thermopile's voltage has either sign and its range is offset binary around a mid-scale pedestal, so
its sum too is a u32. The host takes ``signal = (sum / N − pedestal) × units per count``. Saturated mask: bit i
is set when any sample of channel i was at full scale (2^bits − 1: its signal is then a lower bound); under-range
mask: bit i when any was at 0. Flags: bit 0 the thermal plate regulates (mode 1), bit 1 it has settled; bits 2–7
are 0. The sample counter counts the samples taken since power-up, including this read's. A READ takes N × sample
time plus a fixed overhead; while it runs the module answers every command with error 5 (not ready). The
thesis' ADC averages 16 conversions per reading (digest §3.6): a READ of N = 16 is that reading. N is at most
the largest averaging count, which keeps N × (2^bits − 1) within a u32.

SET_TEMPERATURE drives the head's thermal plate (a heater/TEC under the head, as the QD module's TEC): mode 1
regulates the head at the setpoint (the bench sweeps offsets and responsivities over temperature with it); mode
0 switches it off and the head drifts to ambient (the setpoint field is then ignored and echoed as sent). The
reply is the plate status after the change.

Error codes: 1 unknown command, 2 bad length, 3 bad CRC (the command arrived corrupted; its sequence byte is
echoed as received), 4 value out of range (averaging count 0 or above the largest, a setpoint outside the plate's
range, a plate mode other than 0 or 1), 5 not ready (a READ is in progress).
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

FORMAT = FrameFormat(sync=b"\xa5\x43", length=struct.Struct("<H"), max_payload=512)
MAX_PAYLOAD = FORMAT.max_payload
encode_frame = FORMAT.encode  # (code, sequence, payload=b"") -> one frame: sync, header, payload, CRC-32
decode_frame = FORMAT.decode  # (buffer) -> (Frame or None while incomplete, bytes consumed); raises FrameError

IDENTIFY, READ = 0x01, 0x02  # SET_TEMPERATURE, GET_TEMPERATURE: drivers/tec_protocol.py

PLATE_OFF, PLATE_ON = TEC_OFF, TEC_ON
FLAG_PLATE_ON, FLAG_SETTLED = 0x01, 0x02

FACES = ("px", "py", "mx", "my", "pz", "mz")
TYPES = ("uv", "vis", "ir")
#: The head's channels in wire order, face-major (module docstring)
CHANNELS = tuple(f"{face}_{kind}" for face in FACES for kind in TYPES)
N_CHANNELS = len(CHANNELS)
#: The unit of each detector type's signal: amperes (photodiodes) or volts (thermopile)
UNITS = {"uv": "A", "vis": "A", "ir": "V"}

IDENTITY_HEAD = struct.Struct("<16s16s8sBBHI")  # model, serial, firmware, bits, channels, max average, sample [µs]
IDENTITY_CHANNEL = struct.Struct("<8sIf")  # name, pedestal [counts], units per count [A or V per count]
IDENTITY = struct.Struct(IDENTITY_HEAD.format + IDENTITY_CHANNEL.format.lstrip("<") * N_CHANNELS)
READ_REQUEST = struct.Struct("<H")
READ_REPLY = struct.Struct(f"<HBII{N_CHANNELS}IhI")

assert IDENTITY.size <= MAX_PAYLOAD and READ_REPLY.size <= MAX_PAYLOAD
