"""Field runs: an image sensor's readings against the real Sun, one every `interval_s`, stamped in UTC.

The same family code reads the sensor as on the bench (:attr:`bench.families.Family.read`), through the same
driver; outdoors there is no table and no lamp, only time. The exposure follows the Sun: a saturated spot halves
it and a dim one raises it, the reading taken again (a few tries), as an operator would (seed 003 §5 set
3.92 ms beforehand; the Sun's brightness changes with its zenith on the sensor and with haze).

A simulated field (:mod:`drivers.sim.field`) runs on its own clock: `wait_until` advances it. Outdoors,
`wait_until` sleeps.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

#: The columns every field run records (a sensor that flags cloud itself adds ``spot_cloud``).
COLUMNS = ("time_utc", "x_px", "y_px", "peak_dn", "exposure_ms", "status")
#: The spot's peak the exposure aims at, as a fraction of the full scale, and the band it tolerates.
TARGET_PEAK = 0.6
PEAK_BAND = (0.25, 0.9)
EXPOSURE_TRIES = 5


@dataclass
class FieldRecord:
    """What a field run recorded, by column (a field CSV's columns, :mod:`bench.field_datafile`). A sensor whose
    readings carry their own cloud flag (the camera's ``cloud``: the spot's shape) adds a ``spot_cloud`` column."""

    columns: dict = field(default_factory=lambda: {name: [] for name in COLUMNS})
    on_row: Callable[[dict], None] | None = None  # each row as it is added (a file written as the run goes)

    def add(self, t_utc_s: float, reading, exposure_ms: float) -> None:
        c = self.columns
        c["time_utc"].append(t_utc_s)
        c["x_px"].append(float(reading.value("x_px", math.nan)))
        c["y_px"].append(float(reading.value("y_px", math.nan)))
        c["peak_dn"].append(float(reading.value("peak_dn", math.nan)))
        c["exposure_ms"].append(exposure_ms)
        c["status"].append(reading.status)
        if "cloud" in reading.values and "spot_cloud" not in c:
            c["spot_cloud"] = [None] * (len(c["time_utc"]) - 1)  # the rows before said nothing
        if "spot_cloud" in c:
            flag = reading.values.get("cloud")
            c["spot_cloud"].append(None if flag is None or not reading.ok else bool(flag))
        if self.on_row is not None:
            self.on_row({name: values[-1] for name, values in c.items()})

    def __len__(self) -> int:
        return len(self.columns["time_utc"])


def _better_exposure(reading, exposure_ms: float, full_scale_dn: float, limits_ms: tuple[float, float]) -> float | None:
    """The exposure to try next, or None when this reading's is good (or no better one can be told)."""
    peak = float(reading.value("peak_dn", math.nan))
    if reading.status == "SaturatedSpotError" or (math.isfinite(peak) and peak > PEAK_BAND[1] * full_scale_dn):
        new = exposure_ms * 0.4
    elif reading.ok and math.isfinite(peak) and peak < PEAK_BAND[0] * full_scale_dn:
        new = exposure_ms * min(4.0, TARGET_PEAK * full_scale_dn / max(peak, 1.0))
    else:
        return None
    new = min(max(new, limits_ms[0]), limits_ms[1])
    return None if math.isclose(new, exposure_ms) else new


def record_field(sensor, read: Callable, *, offsets_s, start_utc_s: float, wait_until: Callable[[float], None],
                 full_scale_dn: float, exposure_ms: float = 1.0, exposure_limits_ms=(0.01, 1000.0),
                 clock: Callable[[], float] | None = None, progress: Callable[[int, int], None] | None = None,
                 into: FieldRecord | None = None) -> FieldRecord:
    """Read the sensor at `start_utc_s + offsets_s` (UTC seconds), adjusting the exposure to the Sun.

    Parameters
    ----------
    sensor : ImageSensor
        The family's driver.
    read : callable
        The family's ``read(sensor, repeat, clock) -> Reading``.
    offsets_s : sequence of float
        When to read, from the run's start [s], increasing.
    wait_until : callable
        ``wait_until(offset_s)``: returns at that offset (advances a simulated clock, or sleeps).
    full_scale_dn : float
        The sensor's full scale (saturation) [DN].
    clock : callable, optional
        Seconds since the run's start, for the reading's own time stamp (default: the offset asked).
    into : FieldRecord, optional
        Where to record (so a caller keeps what was read if the run is cut short).
    """
    record = into if into is not None else FieldRecord()
    exposure = float(sensor.set_exposure_ms(exposure_ms) or exposure_ms)
    offsets = np.asarray(offsets_s, dtype=float)
    now = clock or (lambda: float(offsets[i]))
    for i, offset in enumerate(offsets):
        wait_until(float(offset))
        for _ in range(EXPOSURE_TRIES):
            reading = read(sensor, 0, now)
            better = _better_exposure(reading, exposure, full_scale_dn, exposure_limits_ms)
            if better is None:
                break
            exposure = float(sensor.set_exposure_ms(better) or better)
        record.add(start_utc_s + float(reading.t_s), reading, exposure)
        if progress is not None:
            progress(i + 1, len(offsets))
    return record
