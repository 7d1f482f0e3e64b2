"""The one typed home of the QD sun sensor's nominal design (seed 002 §1.3, §2.1).

Every other module of :mod:`calibration.qd` takes these as arguments. The thesis gives the diaphragm
(about 20 µm optimal, up to 100 µm acceptable) and the ±40° field, but neither the pinhole height, nor the
QD's dead gap, nor the L of eq. 2.1; the defaults of those are the project's (the bench's simulated sensor
uses the same nominal numbers, so a calibration starts near its truth).

References
----------
seed 002, §1.3 (diaphragm 20–100 µm, ADC, thermometer), eq. 2.1 (L), §5.2–5.4 (±40° field of view).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

#: Quadrant signs (sign of x, sign of y) of Q1..Q4 that eq. 2.1 implies (digest §2.2, §7 item 2):
#: Q1 (−x, −y), Q2 (+x, +y), Q3 (+x, −y), Q4 (−x, +y). Row k−1 is quadrant k.
THESIS_LAYOUT = ((-1, -1), (1, 1), (1, -1), (-1, 1))
#: The usual counter-clockwise numbering, Q1 (+,+), Q2 (−,+), Q3 (−,−), Q4 (+,−) (digest §7 item 2).
CYCLIC_LAYOUT = ((1, 1), (-1, 1), (-1, -1), (1, -1))
#: Layouts by name.
LAYOUTS = {"thesis": THESIS_LAYOUT, "cyclic": CYCLIC_LAYOUT}

#: Angular diameter of the Sun seen from the Earth's orbit [°].
SUN_DIAMETER_DEG = 0.53


def quadrant_layout(layout) -> np.ndarray:
    """A quadrant layout as a (4, 2) array of signs, checked.

    Parameters
    ----------
    layout : str or array_like, shape (4, 2)
        ``"thesis"`` (eq. 2.1's), ``"cyclic"``, or the sign (±1) of x and y of each quadrant, row k−1 for
        quadrant k. The four rows must be the four quadrants, each once.

    Returns
    -------
    signs : ndarray of float, shape (4, 2)

    References
    ----------
    seed 002, eq. 2.1; digest §7 item 2 (make the channel-to-quadrant mapping configurable).
    """
    if isinstance(layout, str):
        if layout not in LAYOUTS:
            raise ValueError(f"`layout` must be one of {sorted(LAYOUTS)} or a (4, 2) array of signs, got {layout!r}")
        layout = LAYOUTS[layout]
    signs = np.asarray(layout, dtype=float)
    if signs.shape != (4, 2) or not np.all(np.abs(signs) == 1.0):
        raise ValueError(f"`layout` must be a (4, 2) array of ±1, got {np.asarray(layout).tolist()}")
    if len({tuple(row) for row in signs.tolist()}) != 4:
        raise ValueError(f"`layout` must name each quadrant once, got {signs.astype(int).tolist()}")
    return signs


@dataclass(frozen=True)
class QdDesign:
    """Nominal design of a QD pinhole sun sensor.

    Attributes
    ----------
    diaphragm_diameter_m : float
        Pinhole diameter [m]. 100 µm, the largest the thesis accepts (its optimum is about 20 µm).
    pinhole_height_m : float
        Nominal distance d from the diaphragm to the QD surface [m]. 30 µm: with the 100 µm hole the spot
        (a circle of the hole's size, moved by d·tan) still covers the QD's centre at (40°, 40°).
    gap_m : float
        Nominal width of the QD's cross-shaped dead gap [m]. 5 µm.
    length_m : float or None
        The L of eq. 2.1 [m]; None means π/4 × the diaphragm diameter, the L for which eq. 2.1 returns the
        true spot centre near the QD centre for a uniform round spot (the ratio's slope there is
        4 / (π r) per metre for a spot of radius r).
    layout : str or tuple
        Channel-to-quadrant layout (:func:`quadrant_layout`). ``"thesis"`` by default.
    fov_half_deg : float
        Half field of view per projection angle [°]: the thesis' ±40° (80°).
    sun_diameter_deg : float
        Angular diameter of the (simulated) Sun [°].
    full_scale_a : float or None
        The ADC's full scale [A]: a reading at or above it is saturated (None: not known; a channel's maximum
        repeated exactly in several readings is then taken as the clip level).
    """

    diaphragm_diameter_m: float = 100e-6
    pinhole_height_m: float = 30e-6
    gap_m: float = 5e-6
    length_m: float | None = None
    layout: str | tuple = "thesis"
    fov_half_deg: float = 40.0
    sun_diameter_deg: float = SUN_DIAMETER_DEG
    full_scale_a: float | None = None

    def __post_init__(self) -> None:
        for name in ("diaphragm_diameter_m", "pinhole_height_m"):
            if not getattr(self, name) > 0:
                raise ValueError(f"`{name}` must be positive, got {getattr(self, name)}")
        if not 0 <= self.gap_m < self.diaphragm_diameter_m:
            raise ValueError(f"`gap_m` must lie in [0, diaphragm diameter), got {self.gap_m}")
        if self.length_m is not None and not self.length_m > 0:
            raise ValueError(f"`length_m` must be positive, got {self.length_m}")
        if self.full_scale_a is not None and not self.full_scale_a > 0:
            raise ValueError(f"`full_scale_a` must be positive, got {self.full_scale_a}")
        if not 0 < self.fov_half_deg < 90:
            raise ValueError(f"`fov_half_deg` must lie in (0, 90), got {self.fov_half_deg}")
        quadrant_layout(self.layout)

    @property
    def radius_m(self) -> float:
        """Diaphragm radius [m]."""
        return 0.5 * self.diaphragm_diameter_m

    @property
    def eq21_length_m(self) -> float:
        """The L used in eq. 2.1 [m] (see `length_m`)."""
        return self.length_m if self.length_m is not None else math.pi / 4.0 * self.diaphragm_diameter_m

    @property
    def layout_signs(self) -> np.ndarray:
        """The layout as a (4, 2) array of signs."""
        return quadrant_layout(self.layout)

    def to_dict(self) -> dict:
        out = asdict(self)
        out["layout"] = self.layout if isinstance(self.layout, str) else [list(r) for r in self.layout]
        out["eq21_length_m"] = self.eq21_length_m
        return out


DEFAULT_QD = QdDesign()
