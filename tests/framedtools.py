"""What the tests of the two framed modules (the CMOS and the QD sun sensors, drivers/framed_protocol.py) share:
a garbled frame for the scripted driver tests, and the link faults their simulators are given."""

from __future__ import annotations


def garbled(raw: bytes) -> bytes:
    """`raw` with its last payload byte flipped: the frame arrives whole, its CRC-32 (the last 4 bytes) does not
    match."""
    bad = bytearray(raw)
    bad[-5] ^= 0xFF
    return bytes(bad)


def inject(sim, fault: str, count: int) -> None:
    """Give the simulated module `sim` a link fault through its back door: ``no_reply``, ``corrupt_crc`` (the
    next `count` replies carry a wrong CRC) or a :class:`~drivers.sim.device.WireFaults` counter (``garble``,
    ``truncate``: the next `count` replies)."""
    if fault == "no_reply":
        sim.faults.no_reply = True
    elif fault == "corrupt_crc":
        sim.corrupt_crc = count
    else:
        setattr(sim.faults, fault, count)
