"""The camera sun sensor of seed 001: its ray model, its spot detection and its bench calibration.

- :mod:`.model` — OpenCV's pinhole + Brown–Conrady camera rotated against the sensor body frame: pixels ↔
  sun directions (seed 001 eq. 4, with what the thesis leaves out);
- :mod:`.spots` — the detection pipeline A1–A6 (luminance, threshold eq. 1, labelling, largest object,
  middle-pixel and weighted centroids, validity test eqs. 2–3) and a cloud flag;
- :mod:`.fit` — the bench grid, the robust fit with its covariance, held-out errors and warnings.
"""

from .fit import (
    PARAMETERS,
    CameraBenchData,
    CameraCalibration,
    CameraFit,
    HeldOut,
    HeldOutScheme,
    calibrate_camera,
    camera_grid,
    fit_camera,
    held_out,
    initial_camera,
)
from .model import (
    CameraModel,
    camera_from_document,
    design_camera,
    project,
    ray_directions,
    rotation_matrix,
    zenith_azimuth,
)
from .spots import CLOUD_THRESHOLDS, CameraSpot, CloudThresholds, cloud_flag, detect_spot, luminance

__all__ = [
    "CLOUD_THRESHOLDS",
    "PARAMETERS",
    "CameraBenchData",
    "CameraCalibration",
    "CameraFit",
    "CameraModel",
    "CameraSpot",
    "CloudThresholds",
    "HeldOut",
    "HeldOutScheme",
    "calibrate_camera",
    "camera_from_document",
    "camera_grid",
    "cloud_flag",
    "design_camera",
    "detect_spot",
    "fit_camera",
    "held_out",
    "initial_camera",
    "luminance",
    "project",
    "ray_directions",
    "rotation_matrix",
    "zenith_azimuth",
]
