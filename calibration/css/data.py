"""Bench data of a coarse-sun-sensor head: one row per reading of its channels, the Sun's direction known.

The bench turns the head in front of the sun simulator; each row holds the Sun's direction in the head's body
frame (from the table's angles through :mod:`calibration.mount`; zenith up to 180°, since a cube is lit from every
side), one reading of each channel present, and the head's temperature. Dark rows (the light off) give the
offsets; check rows are never fitted, only scored. A channel's reading may be missing (NaN) in a row; the other
channels of that row are still used.

References
----------
seed 000, §3.1 (a triplet of detectors on each face), ch. 5.3.1 (faces and frame), digest §8.2 item 6 and §8.3
item 7 (angular sweeps at fixed irradiance, per detector and per temperature); DESIGN.md (units in names, row
and column named in errors).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BenchDataError
from . import head


@dataclass(frozen=True)
class CssBenchData:
    """Readings of a CSS head on the bench.

    Attributes
    ----------
    zenith_deg, azimuth_deg : ndarray, shape (N,)
        Sun direction in the head's body frame at each reading [°], zenith in [0, 180]; ignored (may be NaN) on
        dark rows.
    signals : ndarray, shape (N, K)
        Raw readings, column k = channel ``channels[k]``: photodiode currents [A], thermopile voltages [V]. NaN
        is a missing reading of that channel.
    temperature_c : ndarray, shape (N,)
        Head temperature [°C].
    channels : tuple of str
        The channels of `signals`' columns, a subset of :data:`calibration.css.head.CHANNELS` in that order.
        Default: all 18 (then `signals` must have 18 columns).
    repeat : ndarray of int, shape (N,)
        Pass number (repeats of a direction share its zenith and azimuth). Default 0.
    sensor_id : str or None
    dark : ndarray of bool, shape (N,)
        True for readings with the light off.
    check : ndarray of bool, shape (N,)
        True for check points, never fitted, only scored.
    row_id : ndarray of int, shape (N,)
        Names of the rows in messages (data-file rows or catalogue ids). Default 1…N.
    """

    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    signals: np.ndarray
    temperature_c: np.ndarray
    channels: tuple | None = None
    repeat: np.ndarray | None = None
    sensor_id: str | None = None
    dark: np.ndarray | None = None
    check: np.ndarray | None = None
    row_id: np.ndarray | None = None

    def __post_init__(self) -> None:
        signals = np.asarray(self.signals, dtype=float)
        if signals.ndim != 2:
            raise BenchDataError(f"`signals` must have shape (N, channels), got {signals.shape}", column="signals")
        channels = head.CHANNELS if self.channels is None else tuple(str(c) for c in self.channels)
        unknown = [c for c in channels if c not in head.CHANNELS]
        if unknown:
            raise BenchDataError(f"unknown channel(s) {', '.join(unknown)} (channels are px_uv, px_vis, px_ir … "
                                 "mz_ir)", column=unknown[0])
        order = [head.CHANNELS.index(c) for c in channels]
        if len(set(order)) != len(order) or order != sorted(order):
            raise BenchDataError("`channels` must be distinct and in the head's order (px_uv, px_vis, px_ir, py_uv "
                                 f"…), got {', '.join(channels)}", column="channels")
        if signals.shape[1] != len(channels):
            raise BenchDataError(f"`signals` has {signals.shape[1]} columns for {len(channels)} channels",
                                 column="signals")
        n = signals.shape[0]
        object.__setattr__(self, "channels", channels)
        object.__setattr__(self, "signals", signals)
        for name in ("zenith_deg", "azimuth_deg", "temperature_c"):
            value = np.asarray(getattr(self, name), dtype=float).ravel()
            if value.size != n:
                raise BenchDataError(f"`{name}` has {value.size} values for {n} readings", column=name)
            object.__setattr__(self, name, value)
        defaults = {"repeat": np.zeros(n, int), "dark": np.zeros(n, bool), "check": np.zeros(n, bool),
                    "row_id": np.arange(1, n + 1)}
        for name, default in defaults.items():
            value = getattr(self, name)
            value = default if value is None else np.asarray(value).ravel().astype(default.dtype)
            if value.size != n:
                raise BenchDataError(f"`{name}` has {value.size} values for {n} readings", column=name)
            object.__setattr__(self, name, value)
        both = self.dark & self.check
        if both.any():
            row = int(np.flatnonzero(both)[0])
            raise BenchDataError(f"row {self.row_id[row]} is marked both dark and check", row=row, column="check")
        infinite = np.isinf(signals)
        if infinite.any():
            row, col = (int(v) for v in np.argwhere(infinite)[0])
            raise BenchDataError(f"row {self.row_id[row]} has an infinite {head.column(channels[col])} reading",
                                 row=row, column=head.column(channels[col]))
        empty = np.all(np.isnan(signals), axis=1) if signals.shape[1] else np.ones(n, bool)
        if empty.any():
            row = int(np.flatnonzero(empty)[0])
            raise BenchDataError(f"row {self.row_id[row]} has no reading of any channel", row=row, column="signals")
        bad = ~np.isfinite(self.temperature_c)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise BenchDataError(f"row {self.row_id[row]} has no temperature", row=row, column="temperature_c")
        light = ~self.dark
        bad = light & ~(np.isfinite(self.zenith_deg) & (self.zenith_deg >= 0) & (self.zenith_deg <= 180))
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise BenchDataError(f"row {self.row_id[row]} (light on) has zenith {self.zenith_deg[row]!r}°: it must "
                                 "lie in 0…180°", row=row, column="zenith_deg")
        bad = light & ~np.isfinite(self.azimuth_deg)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise BenchDataError(f"row {self.row_id[row]} (light on) has no azimuth", row=row, column="azimuth_deg")

    @classmethod
    def from_columns(cls, columns: dict, zenith_deg, azimuth_deg, temperature_c, **kwargs) -> CssBenchData:
        """Build from CSV-style columns ``px_uv_a`` … ``mz_ir_v`` (those present, any others ignored).

        References
        ----------
        seed 000 §3.1 (18 detectors); :mod:`calibration.css.head` (column names with units).
        """
        present = [c for c, col in zip(head.CHANNELS, head.COLUMNS) if col in columns]
        if not present:
            raise BenchDataError("no channel column (px_uv_a … mz_ir_v) in the data", column="signals")
        signals = np.column_stack([np.asarray(columns[head.column(c)], float) for c in present])
        return cls(zenith_deg, azimuth_deg, signals, temperature_c, channels=tuple(present), **kwargs)

    def __len__(self) -> int:
        return self.signals.shape[0]

    @property
    def columns(self) -> tuple[str, ...]:
        """CSV column names of the channels (``px_uv_a`` …)."""
        return tuple(head.column(c) for c in self.channels)

    @property
    def sun_vectors(self) -> np.ndarray:
        """Unit sun vectors in the body frame (N, 3), NaN on dark rows (seed 000 digest §5.3; DESIGN.md)."""
        v = head.sun_vectors(np.where(self.dark, 0.0, self.zenith_deg), np.where(self.dark, 0.0, self.azimuth_deg))
        return np.where(self.dark[:, None], np.nan, v)

    def signal(self, channel: str) -> np.ndarray:
        """The readings of one channel (N,) [A or V]."""
        if channel not in self.channels:
            raise KeyError(f"no channel {channel!r} in the data (it has {', '.join(self.channels)})")
        return self.signals[:, self.channels.index(channel)]

    @property
    def temperature_span_c(self) -> float:
        """max − min of the temperatures [°C]."""
        return float(np.ptp(self.temperature_c)) if len(self) else 0.0

    def subset(self, mask) -> CssBenchData:
        """The rows where `mask` is True (or the rows at the given indices)."""
        return CssBenchData(self.zenith_deg[mask], self.azimuth_deg[mask], self.signals[mask],
                            self.temperature_c[mask], self.channels, self.repeat[mask], self.sensor_id,
                            self.dark[mask], self.check[mask], self.row_id[mask])

    def select_channels(self, channels) -> CssBenchData:
        """The same rows with only `channels` (rows then without any reading are dropped)."""
        channels = tuple(c for c in self.channels if c in set(channels))
        idx = [self.channels.index(c) for c in channels]
        sig = self.signals[:, idx]
        keep = ~np.all(np.isnan(sig), axis=1)
        return CssBenchData(self.zenith_deg[keep], self.azimuth_deg[keep], sig[keep], self.temperature_c[keep],
                            channels, self.repeat[keep], self.sensor_id, self.dark[keep], self.check[keep],
                            self.row_id[keep])
