"""Bench data of a QD sun sensor: one row per reading, the light's direction known (or the light off).

References
----------
seed 002, §3.1 and §4 (readings at known table angles; dark currents against temperature); digest §8 (the
data model: raw currents, temperature, repeats, sensor serial number).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import BenchDataError
from .angles import projection_angles, zenith_azimuth_from_projection


@dataclass(frozen=True)
class QdBenchData:
    """Readings of a QD sensor on the bench.

    Attributes
    ----------
    zenith_deg, azimuth_deg : ndarray, shape (N,)
        True Sun direction in the body frame at each reading [°] (from the table through
        :mod:`calibration.mount`); ignored (may be NaN) on dark rows. Zenith below 90°.
    currents_a : ndarray, shape (N, 4)
        Raw quadrant currents, column k−1 = quadrant k [A] (dark current not subtracted).
    temperature_c : ndarray, shape (N,)
        Sensor temperature [°C].
    repeat : ndarray of int, shape (N,)
        Pass number of the reading (repeats of a direction share its zenith and azimuth). Default 0.
    sensor_id : str or None
    dark : ndarray of bool, shape (N,)
        True for readings with the light off (the dark-current fit uses these only).
    check : ndarray of bool, shape (N,)
        True for off-node check points, never fitted, only scored.
    row_id : ndarray of int, shape (N,)
        Names of the rows in messages (data-file rows or catalogue ids). Default 1…N.
    """

    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    currents_a: np.ndarray
    temperature_c: np.ndarray
    repeat: np.ndarray | None = None
    sensor_id: str | None = None
    dark: np.ndarray | None = None
    check: np.ndarray | None = None
    row_id: np.ndarray | None = None

    def __post_init__(self) -> None:
        currents = np.asarray(self.currents_a, dtype=float)
        if currents.ndim != 2 or currents.shape[1] != 4:
            raise BenchDataError(f"`currents_a` must have shape (N, 4), got {currents.shape}", column="currents_a")
        n = currents.shape[0]
        fields = {"zenith_deg": float, "azimuth_deg": float, "temperature_c": float}
        for name, kind in fields.items():
            value = np.asarray(getattr(self, name), dtype=kind).ravel()
            if value.size != n:
                raise BenchDataError(f"`{name}` has {value.size} values for {n} readings", column=name)
            object.__setattr__(self, name, value)
        object.__setattr__(self, "currents_a", currents)
        defaults = {"repeat": np.zeros(n, int), "dark": np.zeros(n, bool), "check": np.zeros(n, bool),
                    "row_id": np.arange(1, n + 1)}
        for name, default in defaults.items():
            value = getattr(self, name)
            value = default if value is None else np.asarray(value).ravel().astype(default.dtype)
            if value.size != n:
                raise BenchDataError(f"`{name}` has {value.size} values for {n} readings", column=name)
            object.__setattr__(self, name, value)
        if np.any(self.dark & self.check):
            row = int(np.flatnonzero(self.dark & self.check)[0])
            raise BenchDataError(f"row {self.row_id[row]} is marked both dark and check", row=row, column="check")
        bad = ~np.all(np.isfinite(currents), axis=1)
        bad |= ~np.isfinite(self.temperature_c)
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise BenchDataError(f"row {self.row_id[row]} has a non-finite current or temperature", row=row)
        light = ~self.dark
        bad = light & ~(np.isfinite(self.zenith_deg) & np.isfinite(self.azimuth_deg)
                        & (self.zenith_deg >= 0) & (self.zenith_deg < 90))
        if bad.any():
            row = int(np.flatnonzero(bad)[0])
            raise BenchDataError(f"row {self.row_id[row]} (light on) has no direction in front of the sensor "
                                 f"(zenith {self.zenith_deg[row]!r}°)", row=row, column="zenith_deg")

    @classmethod
    def from_projection(cls, alpha_deg, beta_deg, currents_a, temperature_c, **kwargs) -> QdBenchData:
        """Build from the Sun's projection angles (α, β) instead of zenith and azimuth (NaN on dark rows).

        References
        ----------
        seed 002, eq. 2.2 (digest §2.3: tan α = s_x/s_z, tan β = s_y/s_z).
        """
        zen, az = zenith_azimuth_from_projection(alpha_deg, beta_deg)
        return cls(zen, az, currents_a, temperature_c, **kwargs)

    def __len__(self) -> int:
        return self.currents_a.shape[0]

    @property
    def projection_deg(self) -> tuple[np.ndarray, np.ndarray]:
        """(α, β) of each reading [°] (NaN on dark rows), computed together (seed 002 eq. 2.2)."""
        a, b = projection_angles(np.where(self.dark, 0.0, self.zenith_deg), self.azimuth_deg)
        return np.where(self.dark, np.nan, a), np.where(self.dark, np.nan, b)

    @property
    def alpha_deg(self) -> np.ndarray:
        """α of each reading [°] (NaN on dark rows); both angles at once: :attr:`projection_deg`."""
        return self.projection_deg[0]

    @property
    def beta_deg(self) -> np.ndarray:
        """β of each reading [°] (NaN on dark rows); both angles at once: :attr:`projection_deg`."""
        return self.projection_deg[1]

    def subset(self, mask) -> QdBenchData:
        """The rows where `mask` is True (or the rows at the given indices)."""
        return QdBenchData(self.zenith_deg[mask], self.azimuth_deg[mask], self.currents_a[mask],
                           self.temperature_c[mask], self.repeat[mask], self.sensor_id, self.dark[mask],
                           self.check[mask], self.row_id[mask])
