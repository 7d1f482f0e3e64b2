"""Wire format of the scanning Earth-horizon sensor module (seed 004's dual-cone scanner) — sunbench's own,
documented here.

Seed 004's sensor (digest §2.1–2.3) turns one mirror on one motor at 1 rev/s; with two fixed mirrors one revolution
sweeps the bolometer's 2° IFOV around two scan cones of half-angle γ = 70° about ±Y_s (the package's conventions,
calibration/horizon/__init__.py), and an index mark on the rotor gives the scan's phase reference (δ = 0). The
module samples each cone's detector signal at a fixed number of samples per revolution, runs the normalised
constant-threshold locator on board (seed 004 eq. 2.1, C1 = 0.5 by default, linear interpolation between samples)
and reports, per revolution, the crossing times from the index mark. The thesis defines no host protocol: this is
the bench's, a framed module like the CSS head's (:mod:`drivers.css_protocol`) with its own sync word, so a driver
pointed at the wrong module reports "no sync" instead of misreading a reply. The framing code is
:mod:`drivers.framed_protocol`'s.

Frame, both directions, little-endian::

    offset  size  field
    0       2     sync        0xA5 0x48  ("H")
    2       1     code        command (host → module) or reply (module → host) code
    3       1     sequence    chosen by the host, echoed in the reply
    4       2     length N    payload length [bytes], at most MAX_PAYLOAD (4096)
    6       N     payload
    6 + N   4     CRC-32      zlib.crc32 of bytes 2 … 6 + N − 1 (code to end of payload)

=============  ==============  ========================  ==========================================================
command        code  reply     payload sent              reply payload
=============  ==============  ========================  ==========================================================
IDENTIFY       0x01  0x81      —                         model 16s, serial 16s, firmware 8s (ASCII, NUL-padded),
                                                         cones u8 (2), ADC bits u8, samples per revolution u16,
                                                         nominal period u32 [µs], nominal γ f32 [°], IFOV half-
                                                         angle f32 [°], threshold C1 f32 [fraction], largest
                                                         READ_SCANS count u8 — 61 bytes
READ_SCANS     0x02  0x82      revolutions n u8          count u8 (= n), then per revolution (36 bytes):
                                                         revolution counter u32, period u32 [µs]; per cone 1, 2:
                                                         t_out u32 [µs], t_in u32 [µs], edge flags u8, space level
                                                         u16 [counts], Earth level u16 [counts]; head temperature
                                                         i16 [0.01 °C]
GET_PULSE      0x03  0x83      —                         period u32 [µs], decimation d u16, N u16, threshold u16 ×
                                                         2 [counts, cone 1, 2], then N samples u16 of cone 1 and
                                                         N of cone 2 [counts] — 12 + 4 N bytes
SET_THRESHOLD  0x04  0x84      threshold C1 f32          threshold C1 f32 (as now set)
GET_STATUS     0x05  0x85      —                         threshold C1 f32, head temperature i16 [0.01 °C], motor
                                                         u8 (1 turning), revolution counter u32, last period u32
                                                         [µs] — 15 bytes
(error)              0xFF                                error code u8, message (ASCII)
=============  ==============  ========================  ==========================================================

READ_SCANS. The module waits for the next index mark, then reports the `n` (1 … the largest count) complete
revolutions that follow, so a READ_SCANS takes about n + 1 periods and while it runs the module answers every
command with error 5 (not ready). A revolution's period is the module's count from index mark to index mark (its
µs timer); the times are counted from the revolution's index mark. Edge flags, per cone: bit 0 the falling edge
(Earth → space, ``t_out``) was found, bit 1 the rising edge (space → Earth, ``t_in``), bit 2 a sample of the pulse
was at the ADC's full scale (saturated: something far hotter than the Earth was in view); bits 3–7 are 0. A time
whose flag is clear is 0 and means nothing. The revolution counter counts the revolutions since power-up: a gap
between two reads is the revolutions that were not reported.

The locator, per cone and revolution, in two passes: a first threshold from rough levels (the means of the samples
in the lowest and the highest quarter of the pulse's range) finds the Earth (the longest run above it) and its two
edges; then the Earth level is the median of the Earth's samples more than two IFOV diameters of phase (2 · 2α /
sin γ) from either edge, the space level the median of the space's samples as far from them — the plateaus, so a
short chord, whose top is narrow, does not lower its Earth level (a plateau too short for that keeps the rough
level) —, the threshold is ``space + C1 × (Earth − space)`` and an edge is where the pulse crosses it (with a
hysteresis of 5 % of the range against noise), its time interpolated linearly between the two samples either side.
The levels a READ_SCANS reports are the plateaus'. A pulse whose range is below the module's minimum contrast (the
detector sees no Earth, or is dead) has no edges.

GET_PULSE returns the last reported revolution's pulse of both cones, every d-th sample (d the smallest that keeps
N = samples per revolution / d within MAX_PULSE_SAMPLES): sample j lies at ``j × d × period / samples per
revolution`` after the index mark. Before the first READ_SCANS it is error 5.

SET_THRESHOLD sets C1 for the following revolutions (the range is [0.1, 0.9]).

Error codes: 1 unknown command, 2 bad length, 3 bad CRC (the command arrived corrupted; its sequence byte is echoed
as received), 4 value out of range (a count of 0 or above the largest, a threshold outside [0.1, 0.9]), 5 not ready
(a READ_SCANS is in progress; no revolution reported yet), 6 no index mark (the motor does not turn: no revolution
completes within two nominal periods).
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

# re-exported above: the names of the shared framing (drivers/framed_protocol.py) that the driver, the simulator
# and the tests take from here
FORMAT = FrameFormat(sync=b"\xa5\x48", length=struct.Struct("<H"), max_payload=4096)
MAX_PAYLOAD = FORMAT.max_payload
encode_frame = FORMAT.encode  # (code, sequence, payload=b"") -> one frame: sync, header, payload, CRC-32
decode_frame = FORMAT.decode  # (buffer) -> (Frame or None while incomplete, bytes consumed); raises FrameError

IDENTIFY, READ_SCANS, GET_PULSE, SET_THRESHOLD, GET_STATUS = 0x01, 0x02, 0x03, 0x04, 0x05
NO_INDEX = 6  # error code: the motor does not turn
ERROR_MESSAGES = {NO_INDEX: "no index mark"}

N_CONES = 2
#: Edge flags of one cone in a READ_SCANS revolution
EDGE_OUT, EDGE_IN, EDGE_SATURATED = 0x01, 0x02, 0x04
#: The threshold fractions SET_THRESHOLD accepts
THRESHOLD_RANGE = (0.1, 0.9)
#: The most samples per cone GET_PULSE returns
MAX_PULSE_SAMPLES = 1000

IDENTITY = struct.Struct("<16s16s8sBBHIfffB")
READ_REQUEST = struct.Struct("<B")
READ_HEAD = struct.Struct("<B")
CONE = "IIBHH"  # t_out [µs], t_in [µs], edge flags, space level, Earth level
SCAN = struct.Struct("<II" + CONE * N_CONES + "h")  # revolution, period [µs], the cones, temperature [0.01 °C]
PULSE_HEAD = struct.Struct("<IHHHH")  # period [µs], decimation, N, threshold per cone [counts]
THRESHOLD = struct.Struct("<f")
STATUS = struct.Struct("<fhBII")  # threshold, temperature [0.01 °C], motor turning, revolution, last period [µs]

assert IDENTITY.size == 61 and SCAN.size == 36 and STATUS.size == 15
assert PULSE_HEAD.size + 2 * N_CONES * MAX_PULSE_SAMPLES <= MAX_PAYLOAD


def pulse_decimation(samples_per_revolution: int) -> int:
    """The smallest d that keeps samples per revolution / d within :data:`MAX_PULSE_SAMPLES`."""
    return max(1, -(-int(samples_per_revolution) // MAX_PULSE_SAMPLES))


def max_scans_per_read() -> int:
    """The most revolutions one READ_SCANS reply holds within :data:`MAX_PAYLOAD` (capped at 255 by its u8)."""
    return min(255, (MAX_PAYLOAD - READ_HEAD.size) // SCAN.size)
