"""Calibration models, by method name.

===================  =====================================================================
method               what it is
===================  =====================================================================
``seed003``          centre + 6th-order θ(r) + linear azimuth (seed 003 eqs. 7–11)
``seed003-tilt``     plus the detector tilt θ*(φ) (seed 003 eqs. 14–16)
``seed003-sector``   one θ(r) per 45° sector (seed 003 §4.5)
``physical``         joint physical model: offset, gap, cover glass, tilt, rotation
``physical-mask``    the same with the cover glass bonded under the mask (tilted against the die)
===================  =====================================================================
"""

from __future__ import annotations

from ..data import BenchData
from ..design import DEFAULT_SENSOR, SensorDesign
from ..errors import CalibrationFormatError
from .base import FORMAT, FORMAT_VERSION, Calibration
from .physical import PhysicalCalibration, PhysicalMaskCalibration
from .seed003 import Seed003Calibration, Seed003SectorCalibration, Seed003TiltCalibration

METHODS: dict[str, type[Calibration]] = {
    cls.method: cls
    for cls in (Seed003Calibration, Seed003TiltCalibration, Seed003SectorCalibration, PhysicalCalibration,
                PhysicalMaskCalibration)
}


def fit_calibration(data: BenchData, method: str, design: SensorDesign = DEFAULT_SENSOR) -> Calibration:
    """Fit the calibration model named `method` to bench data."""
    if method not in METHODS:
        raise ValueError(f"`method` must be one of {', '.join(METHODS)}, got {method!r}")
    return METHODS[method].fit(data, design)


def calibration_from_dict(document: dict) -> Calibration:
    """Rebuild a calibration from its JSON document; refuses other formats and versions."""
    if not isinstance(document, dict) or document.get("format") != FORMAT:
        raise CalibrationFormatError(f"not a sunbench calibration (expected \"format\": \"{FORMAT}\")")
    version = document.get("version")
    if version != FORMAT_VERSION:
        raise CalibrationFormatError(
            f"calibration format version {version!r} is not supported (this sunbench reads version "
            f"{FORMAT_VERSION})")
    method = document.get("method")
    if method not in METHODS:
        raise CalibrationFormatError(f"unknown calibration method {method!r}")
    parameters = document.get("parameters")
    if not isinstance(parameters, dict):
        raise CalibrationFormatError("calibration has no \"parameters\" object")
    return METHODS[method].from_parameters(parameters)


__all__ = ["METHODS", "Calibration", "fit_calibration", "calibration_from_dict", "FORMAT", "FORMAT_VERSION"]
