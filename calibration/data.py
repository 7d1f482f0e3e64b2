"""Bench data: the points a calibration is fitted to and judged on.

A point is one spot centre (x_px, y_px) measured while the true sun direction in the sensor body frame was
(zenith_deg, azimuth_deg). Repeats of one bench direction are separate points.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .errors import BenchDataError, InsufficientDataError

#: Zenith below which a point counts as normal incidence (the centre stage of seed 003 §4.2) [°].
NORMAL_INCIDENCE_DEG = 0.05


@dataclass(frozen=True)
class BenchData:
    """Spot centres measured at known sun directions.

    Attributes
    ----------
    zenith_deg : ndarray, shape (n,)
        True zenith θ of the sun in the body frame [°], in [0, 90).
    azimuth_deg : ndarray, shape (n,)
        True azimuth φ [°]; stored wrapped to [0, 360).
    x_px, y_px : ndarray, shape (n,)
        Spot centre [px] (x right, y down, origin at the centre of pixel 0, 0).
    repeat : ndarray of int, shape (n,), optional
        Repeat index of the point at its bench direction.
    sensor_id : str, optional
        Serial of the sensor the data belong to.
    exposure_ms : ndarray, optional
        Exposure of each frame [ms].
    frame_id : ndarray of int, optional
        Where each point came from (the data row of a CSV file, 1-based; a reading's id in the catalogue), so
        a rejected frame can be named.
    """

    zenith_deg: np.ndarray
    azimuth_deg: np.ndarray
    x_px: np.ndarray
    y_px: np.ndarray
    repeat: np.ndarray | None = None
    sensor_id: str | None = None
    exposure_ms: np.ndarray | None = field(default=None, compare=False)
    frame_id: np.ndarray | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        arrays = {}
        for name in ("zenith_deg", "azimuth_deg", "x_px", "y_px"):
            a = np.asarray(getattr(self, name), dtype=float).reshape(-1)
            arrays[name] = a
        n = arrays["zenith_deg"].size
        for name, a in arrays.items():
            if a.size != n:
                raise BenchDataError(f"`{name}` has {a.size} values, `zenith_deg` has {n}", column=name)
            bad = np.flatnonzero(~np.isfinite(a))
            if bad.size:
                raise BenchDataError(f"`{name}` is not a finite number at point {bad[0]}", row=int(bad[0]), column=name)
        bad = np.flatnonzero((arrays["zenith_deg"] < 0) | (arrays["zenith_deg"] >= 90))
        if bad.size:
            raise BenchDataError(
                f"`zenith_deg` must lie in [0, 90), got {arrays['zenith_deg'][bad[0]]} at point {bad[0]}",
                row=int(bad[0]), column="zenith_deg")
        arrays["azimuth_deg"] = np.mod(arrays["azimuth_deg"], 360.0)
        for name, a in arrays.items():
            a.setflags(write=False)
            object.__setattr__(self, name, a)
        for name in ("repeat", "exposure_ms", "frame_id"):
            v = getattr(self, name)
            if v is not None:
                v = np.asarray(v).reshape(-1)
                if v.size != n:
                    raise BenchDataError(f"`{name}` has {v.size} values, expected {n}", column=name)
                object.__setattr__(self, name, v)

    def __len__(self) -> int:
        return int(self.zenith_deg.size)

    def subset(self, mask) -> BenchData:
        """The points selected by a boolean mask or an index array."""
        pick = lambda a: None if a is None else a[mask]  # noqa: E731
        return BenchData(self.zenith_deg[mask], self.azimuth_deg[mask], self.x_px[mask], self.y_px[mask],
                         pick(self.repeat), self.sensor_id, pick(self.exposure_ms), pick(self.frame_id))

    def direction_labels(self, tolerance_deg: float = 1e-3) -> np.ndarray:
        """Label of each point's bench direction, numbered in order of first appearance.

        Directions are told apart by (zenith, azimuth) rounded to `tolerance_deg`; normal-incidence frames
        stay apart by bench azimuth, as the centre stage records them.
        """
        key = np.round(np.column_stack([self.zenith_deg, self.azimuth_deg]) / tolerance_deg)
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        rank = np.empty(first.size, dtype=int)
        rank[np.argsort(first)] = np.arange(first.size)
        return rank[inverse.reshape(-1)]

    def direction_means(self, tolerance_deg: float = 1e-3) -> BenchData:
        """One point per bench direction: the mean spot of its repeats.

        Seed 003 §4.3 averages the frames taken at each direction (4 in the reported run) before fitting
        and before computing Table 4.1, so a point is a direction, not a frame. Directions are told apart by
        (zenith, azimuth) rounded to `tolerance_deg`; normal-incidence frames stay apart by bench azimuth, as
        the centre stage records them. Points come out in order of first appearance.
        """
        key = np.round(np.column_stack([self.zenith_deg, self.azimuth_deg]) / tolerance_deg)
        _, first, inverse, counts = np.unique(key, axis=0, return_index=True, return_inverse=True,
                                              return_counts=True)
        inverse = inverse.reshape(-1)
        if counts.max() == 1:
            return self
        order = np.argsort(first)
        mean = lambda a: (np.bincount(inverse, weights=a) / counts)[order]  # noqa: E731
        return BenchData(self.zenith_deg[first][order], self.azimuth_deg[first][order],
                         mean(self.x_px), mean(self.y_px), sensor_id=self.sensor_id)

    @property
    def normal_incidence(self) -> np.ndarray:
        """Boolean mask of the normal-incidence (centre-stage) points."""
        return self.zenith_deg <= NORMAL_INCIDENCE_DEG

    def azimuth_groups(self, tolerance_deg: float = 0.5) -> np.ndarray:
        """Label of the bench azimuth of each off-normal point (−1 at normal incidence).

        Points whose azimuths lie within `tolerance_deg` of each other share a label; labels are in order of
        azimuth. Used for leave-one-azimuth-out evaluation and per-sector fits.
        """
        labels = np.full(len(self), -1, dtype=int)
        off = np.flatnonzero(~self.normal_incidence)
        if off.size == 0:
            return labels
        az = self.azimuth_deg[off]
        order, group = chained_groups(az, tolerance_deg)
        # the circle closes: a group just below 360° is the same direction as the one at 0°
        if group[-1] > 0 and az[order][0] + 360.0 - az[order][-1] <= tolerance_deg:
            group[group == group[-1]] = 0
        labels[off[order]] = group
        return labels

    def zenith_rings(self, tolerance_deg: float = 0.5) -> np.ndarray:
        """Label of the interior zenith ring of each point (−1 for normal incidence and the first and last
        rings, whose leaving out would score extrapolation); labels are in order of zenith.

        References
        ----------
        seed 003, §4.2 (the grid's zenith rings, 10° apart).
        """
        labels = np.full(len(self), -1, dtype=int)
        off = np.flatnonzero(~self.normal_incidence)
        if off.size == 0:
            return labels
        order, ring = chained_groups(self.zenith_deg[off], tolerance_deg)
        interior = (ring > 0) & (ring < ring[-1])
        labels[off[order][interior]] = ring[interior]
        return labels

    def require_spread(self, *, min_points: int, method: str) -> None:
        """Raise :class:`InsufficientDataError` unless there is enough data for `method`.

        Checks that the off-normal points span at least two azimuths, then that there are `min_points`
        points.
        """
        groups = self.azimuth_groups()
        azimuths = sorted({float(self.azimuth_deg[groups == g][0]) for g in set(groups[groups >= 0].tolist())})
        if len(azimuths) == 1:
            raise InsufficientDataError(
                f"{method}: all off-normal points are at one azimuth ({azimuths[0]:g}°); a calibration needs "
                "bench directions at two azimuths or more", column="azimuth_deg")
        if len(self) < min_points:
            raise InsufficientDataError(f"{method}: too few points, {len(self)}; needs at least {min_points}")


def chained_groups(values: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray]:
    """Sort `values` and number the groups whose neighbours lie within `tolerance`: (order, group of each
    sorted value), groups numbered in increasing value.

    References
    ----------
    seed 003, §4.2 (a grid's azimuths and zenith rings, read back with a stage's jitter).
    """
    values = np.asarray(values, dtype=float)
    order = np.argsort(values)
    return order, np.concatenate([[0], np.cumsum(np.diff(values[order]) > tolerance)])
