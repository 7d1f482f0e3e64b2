"""Which field readings a cloud spoiled, from the spot's brightness (seed 003 §5: "clouds spoil it").

A cloud in front of the Sun dims the spot and, when only its edge covers the disc, moves the spot's centroid
towards the uncovered side (seed 003 §5 blames the spot's shape under partial shading). The sensor cannot see
the cloud; it sees the spot's signal per unit exposure fall below what the clear Sun gives at that angle. The
clear Sun's signal is a smooth function of the angle on the sensor — the aperture's projected area, the pixels'
angular response and, towards the edge of the field, the mask's vignetting — so the clear law is the sensor's
own, fitted on the run: log s(θ) a cubic in θ. Clouds only take light away, so the clear law is the run's upper
envelope: fitted by least squares, the readings far below it dropped, and fitted again (a few rounds), which
holds while at least a third of the run, over the angles it covers, saw a clear Sun.

An image sensor that sees the disc itself (a camera) has a better flag from the blob's shape
(:func:`calibration.camera.spots.cloud_flag`); this one needs only the peak and the exposure every image
family records.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import FieldDataError

#: A reading whose signal falls this fraction below the clear law is flagged (haze of up to ~10 % is not).
DEFAULT_DROP = 0.15


@dataclass(frozen=True)
class BrightnessFlags:
    """The clear-Sun law fitted on a run and the readings below it.

    Attributes
    ----------
    cloudy : ndarray of bool
        Readings whose signal per ms fell more than `drop` below the clear law, or to the dark level (NaN readings
        are not flagged).
    ratio : ndarray
        Each reading's signal over the clear law's [unitless] (1: clear).
    law : ndarray
        The clear law's coefficients: log s = Σ c_i u^i, u = θ − `centre_deg` in radians, i = 0…3.
    centre_deg : float
    drop : float
    """

    cloudy: np.ndarray
    ratio: np.ndarray
    law: np.ndarray
    centre_deg: float
    drop: float


def brightness_cloud_flags(peak_dn, exposure_ms, sensor_zenith_deg, *, background_dn: float = 0.0,
                           drop: float = DEFAULT_DROP, rounds: int = 6) -> BrightnessFlags:
    """Flag the readings a cloud dimmed (see the module docstring).

    Parameters
    ----------
    peak_dn : array_like
        The spot's peak [DN] (NaN where there was no spot).
    exposure_ms : array_like
        The exposure of each reading [ms].
    sensor_zenith_deg : array_like
        The Sun's zenith on the sensor [°] (the calibrated direction).
    background_dn : float
        Dark level under the peak [DN].
    drop : float
        Fraction below the clear law that counts as cloud.

    Returns
    -------
    BrightnessFlags
    """
    peak = np.asarray(peak_dn, dtype=float)
    exposure = np.asarray(exposure_ms, dtype=float)
    theta = np.radians(np.asarray(sensor_zenith_deg, dtype=float))
    signal = (peak - background_dn) / exposure
    usable = np.isfinite(signal) & (signal > 0) & np.isfinite(theta) & (np.cos(theta) > 0.05)
    if usable.sum() < 5:
        raise FieldDataError(f"{int(usable.sum())} readings with a spot: too few to tell a clear Sun from cloud")
    log_s = np.log(signal[usable])
    centre = float(np.median(theta[usable]))
    u = theta[usable] - centre
    degree = int(min(3, max(0, np.unique(np.round(u, 3)).size - 1)))
    design = np.vander(u, degree + 1, increasing=True)
    keep = np.ones(log_s.size, dtype=bool)
    coef = np.zeros(degree + 1)
    for _ in range(rounds):
        if keep.sum() <= degree:
            break
        coef = np.linalg.lstsq(design[keep], log_s[keep], rcond=None)[0]
        new_keep = log_s - design @ coef > np.log(1 - drop)
        if np.array_equal(new_keep, keep):
            break
        keep = new_keep
    ratio = np.full(signal.shape, np.nan)
    ratio[usable] = np.exp(log_s - design @ coef)
    cloudy = np.zeros(signal.shape, dtype=bool)
    cloudy[usable] = ratio[usable] < 1 - drop
    dark = np.isfinite(signal) & (signal <= 0)  # a spot no brighter than the dark: the Sun all but gone
    ratio[dark], cloudy[dark] = 0.0, True
    return BrightnessFlags(cloudy=cloudy, ratio=ratio, law=np.pad(coef, (0, 3 - degree)),
                           centre_deg=float(np.degrees(centre)), drop=drop)
