"""Repeated frames at one bench direction, combined robustly, with every rejected frame named.

Seed 003 §4.3 averages the frames taken at each bench direction before fitting. A plain mean lets one glint
(a reflection that moves the spot by pixels) spoil its direction, and nothing notices. Here the frames of a
direction are combined by the largest group that agrees within the repeat scatter:

1. The repeat scatter σ_rep [px, per axis] is estimated over many directions at once: the median distance of
   the frames from their direction's median spot, which a few glints cannot move, divided by the median of a
   2-D Gaussian's radius (√(2 ln 2) σ) and corrected for the few frames per direction. The scatter grows
   with incidence (a fainter, longer spot), so it is pooled per zenith ring (all azimuths at one zenith),
   and over the whole data set for the overall figure.
2. In each direction the frame with the most neighbours within k σ_rep seeds the agreeing group (so two good
   frames outvote two glints that disagree with each other as well); the group is every frame within k σ_rep
   of the seed group's median. The others are rejected, each named with how far off it was.
3. The direction's point is the mean of its agreeing frames, with σ_rep / √n as its centroid noise.

A direction whose frames all disagree (two frames, one a glint) cannot be decided from its repeats; it is
kept as the median of its frames and left to the robust fit (:mod:`calibration.models.physical`), which
rejects a direction that disagrees with the model.

References
----------
seed 003, §4.3 (frames averaged per direction); research note anchors-sunsensors §6 (robust fits and outlier
rejection against the measured noise).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from .data import BenchData

#: Frames farther than this many repeat-scatter sigmas from their direction's agreeing group are rejected.
REJECT_SIGMAS = 6.0
#: Distances below this never reject a frame, whatever the scatter [px] (a scatter of exact synthetic data is 0).
REJECT_FLOOR_PX = 0.01
#: Median of the radius of a 2-D Gaussian of unit sigma per axis: √(2 ln 2).
RAYLEIGH_MEDIAN = float(np.sqrt(2.0 * np.log(2.0)))


@dataclass(frozen=True)
class RejectedFrame:
    """A frame left out of a calibration, and why.

    Attributes
    ----------
    frame_id : int or None
        Where it came from (CSV data row, 1-based, or the catalogue's reading id).
    zenith_deg, azimuth_deg : float
        Its bench direction [°].
    x_px, y_px : float
        Its spot centre [px].
    offset_px : float
        How far it lay from what the rest says: its direction's agreeing frames, or the model [px].
    reason : str
        In words.
    """

    frame_id: int | None
    zenith_deg: float
    azimuth_deg: float
    x_px: float
    y_px: float
    offset_px: float
    reason: str

    def to_dict(self) -> dict:
        return {"row": self.frame_id, "zenith_deg": self.zenith_deg, "azimuth_deg": self.azimuth_deg,
                "x_px": self.x_px, "y_px": self.y_px, "offset_px": self.offset_px, "reason": self.reason}

    def describe(self) -> str:
        where = f"row {self.frame_id}" if self.frame_id is not None else "a frame"
        return (f"{where} (zenith {self.zenith_deg:.3f}°, azimuth {self.azimuth_deg:.3f}°): {self.offset_px:.2f} px "
                f"off; {self.reason}")


@dataclass(frozen=True)
class CombinedRepeats:
    """Bench data with one point per direction.

    Attributes
    ----------
    data : BenchData
        One point per bench direction: the mean of its agreeing frames.
    n_frames : ndarray of int
        Frames averaged into each point.
    repeat_scatter_px : float or None
        σ_rep, the centroid scatter of one frame per axis over all directions [px]; None when no direction has
        two frames.
    point_scatter_px : ndarray or None
        σ_rep of each point's zenith ring [px].
    rejected : list of RejectedFrame
    first_index : ndarray of int
        Index in the frames of each point's first frame (to look up what else is known of it).
    members : tuple of ndarray
        Indices in the frames of each point's averaged frames.
    """

    data: BenchData
    n_frames: np.ndarray
    repeat_scatter_px: float | None
    rejected: list[RejectedFrame] = field(default_factory=list)
    first_index: np.ndarray | None = None
    point_scatter_px: np.ndarray | None = None
    members: tuple = ()

    @property
    def noise_px(self) -> np.ndarray | None:
        """Centroid noise of each combined point, per axis [px] (σ_rep / √n), or None."""
        if self.repeat_scatter_px is None:
            return None
        scatter = self.repeat_scatter_px if self.point_scatter_px is None else self.point_scatter_px
        return scatter / np.sqrt(self.n_frames)


def _agreeing(xy: np.ndarray, limit: float) -> np.ndarray:
    """Mask of the largest group of frames that agree within `limit` [px] (module docstring, step 2)."""
    dist = np.hypot(*(xy[:, None, :] - xy[None, :, :]).transpose(2, 0, 1))
    neighbours = (dist <= limit).sum(axis=1)
    seed = dist[int(np.argmax(neighbours))] <= limit
    centre = np.median(xy[seed], axis=0)
    return np.hypot(*(xy - centre).T) <= limit


#: Median-unbiasing factor of the scaled distance for n frames at a direction (Monte Carlo, 200 000 Gaussian
#: draws per n: the median of n points is not their mean, so √(n/(n−1)) alone leaves 0–14 % of bias).
_SMALL_N_FACTOR = {2: 1.0023, 3: 1.1393, 4: 1.0932, 5: 1.0445, 6: 1.0504, 7: 1.0251, 8: 1.0302}

#: Frames a zenith ring needs for its own scatter; a ring with fewer uses the overall figure.
RING_MIN_FRAMES = 12


def _scaled_distances(data: BenchData, labels: np.ndarray):
    """Each repeated frame's distance from its direction's median, scaled to a per-axis sigma's units, and the
    direction it belongs to."""
    counts = np.bincount(labels)
    dist, owner = [], []
    for label in np.flatnonzero(counts >= 2):
        pick = np.flatnonzero(labels == label)
        xy = np.column_stack([data.x_px[pick], data.y_px[pick]])
        d = np.hypot(*(xy - np.median(xy, axis=0)).T)
        # the distance to a centre fitted from the same n frames shrinks by √((n − 1)/n)
        factor = _SMALL_N_FACTOR.get(pick.size, 1.0)
        dist.append(d * factor * np.sqrt(pick.size / (pick.size - 1.0)) / RAYLEIGH_MEDIAN)
        owner.append(np.full(pick.size, label))
    if not dist:
        return np.empty(0), np.empty(0, dtype=int)
    return np.concatenate(dist), np.concatenate(owner)


def repeat_scatter_px(data: BenchData, labels: np.ndarray | None = None) -> float | None:
    """Robust per-axis centroid scatter of repeated frames, σ_rep [px] (module docstring, step 1).

    Returns None when no bench direction has two frames or more.

    References
    ----------
    seed 003, §4.3 (repeats per direction); the Rayleigh median √(2 ln 2) σ of a 2-D Gaussian's radius.
    """
    labels = data.direction_labels() if labels is None else labels
    dist, _ = _scaled_distances(data, labels)
    return float(np.median(dist)) if dist.size else None


def ring_scatter_px(data: BenchData, labels: np.ndarray, overall: float) -> np.ndarray:
    """σ_rep of each direction's zenith ring (directions within 0.5° of zenith pooled) [px], per direction.

    References
    ----------
    seed 003, §4.2 (the grid's rings); module docstring, step 1.
    """
    dist, owner = _scaled_distances(data, labels)
    n_dir = int(labels.max()) + 1
    zenith = np.empty(n_dir)
    zenith[labels] = data.zenith_deg
    out = np.full(n_dir, overall)
    ring = np.round(zenith / 0.5)
    for value in np.unique(ring):
        members = np.flatnonzero(ring == value)
        d = dist[np.isin(owner, members)]
        if d.size >= RING_MIN_FRAMES:
            out[members] = max(float(np.median(d)), 1e-12)
    return out


def combine_repeats(data: BenchData, *, reject_sigmas: float = REJECT_SIGMAS) -> CombinedRepeats:
    """One point per bench direction from its repeated frames, glints rejected (module docstring).

    Parameters
    ----------
    data : BenchData
        Frames; repeats share (zenith_deg, azimuth_deg).
    reject_sigmas : float
        k: a frame farther than k σ_rep from its direction's agreeing frames is rejected.

    Returns
    -------
    CombinedRepeats
        Points in order of their direction's first frame.

    References
    ----------
    seed 003, §4.3 (frames averaged per direction before fitting).
    """
    labels = data.direction_labels()
    n_dir = int(labels.max()) + 1 if labels.size else 0
    sigma = repeat_scatter_px(data, labels)
    ring = ring_scatter_px(data, labels, sigma) if sigma is not None else None
    first = np.full(n_dir, -1)
    x = np.empty(n_dir)
    y = np.empty(n_dir)
    n = np.zeros(n_dir, dtype=int)
    rejected: list[RejectedFrame] = []
    members = []
    for label in range(n_dir):
        idx = np.flatnonzero(labels == label)
        first[label] = idx[0]
        xy = np.column_stack([data.x_px[idx], data.y_px[idx]])
        local = ring[label] if ring is not None else 0.0
        limit = max(reject_sigmas * local, REJECT_FLOOR_PX)
        keep = _agreeing(xy, limit) if idx.size >= 2 else np.ones(1, dtype=bool)
        if keep.sum() < 2 and idx.size >= 2:
            # no two frames agree: the repeats cannot say which is right; the robust fit decides
            x[label], y[label] = np.median(xy, axis=0)
            n[label] = idx.size
            members.append(idx)
            continue
        centre = xy[keep].mean(axis=0)
        x[label], y[label] = centre
        n[label] = int(keep.sum())
        members.append(idx[keep])
        for i in np.flatnonzero(~keep):
            j = idx[i]
            rejected.append(RejectedFrame(
                None if data.frame_id is None else int(data.frame_id[j]), float(data.zenith_deg[j]),
                float(data.azimuth_deg[j]), float(data.x_px[j]), float(data.y_px[j]),
                float(np.hypot(*(xy[i] - centre))),
                f"disagrees with the other {int(keep.sum())} frames of its direction "
                f"(> {reject_sigmas:g} × the repeat scatter {local:.3f} px at this zenith)"))
    combined = BenchData(data.zenith_deg[first], data.azimuth_deg[first], x, y, sensor_id=data.sensor_id,
                         frame_id=None if data.frame_id is None else data.frame_id[first])
    return CombinedRepeats(combined, n, sigma, rejected, first, ring, tuple(members))
