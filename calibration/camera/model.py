"""The camera sun sensor's ray model: OpenCV's pinhole with Brown–Conrady distortion (seed 001 §2.1 A7–A8).

The thesis (seed 001 eq. 4) uses a bare pinhole, V = (−x_s, −y_s, −z_c), with the principal point assumed at
the image centre and no distortion, and flags the missing calibration of principal point, aspect ratio and
lens distortion (digest §2.1 A7, §7 item 4). This module is that calibration's model: OpenCV's camera
matrix (fx, fy, cx, cy) and distortion (k1, k2, p1, p2, k3), plus the camera's rotation against the sensor
body frame on the bench, so that a pixel gives a sun direction in the body frame directly.

Frames
------
- Camera frame: OpenCV's, x right, y down, z forward along the optical axis.
- Body frame: +z is the boresight; the sun direction is n = (sin θ cos φ, sin θ sin φ, cos θ)
  (:mod:`calibration.geometry`). ``rotation_deg`` is a Rodrigues vector [°] whose rotation R maps
  body-frame vectors into the camera frame, X_cam = R · n; with (0, 0, 0) the frames coincide.
- Pixels: x to the right (columns), y down (rows), origin at the centre of pixel (0, 0) (project-wide; it
  is also OpenCV's convention for cx, cy).

Projection (OpenCV's ``projectPoints`` with tvec = 0, a direction taken as a point at unit distance):

.. math:: x' = X/Z,\\; y' = Y/Z,\\; r^2 = x'^2 + y'^2,\\; g = 1 + k_1 r^2 + k_2 r^4 + k_3 r^6

.. math:: x'' = x' g + 2 p_1 x' y' + p_2 (r^2 + 2 x'^2),\\; y'' = y' g + p_1 (r^2 + 2 y'^2) + 2 p_2 x' y'

.. math:: u = f_x x'' + c_x,\\; v = f_y y'' + c_y
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

import cv2
import numpy as np

from ..errors import CalibrationFormatError
from ..geometry import zenith_azimuth_from_vector

__all__ = ["CameraModel", "camera_from_document", "design_camera", "project", "ray_directions", "rotation_matrix",
           "zenith_azimuth"]

KIND = "camera"
"""Value of the ``"kind"`` marker in a serialised :class:`CameraModel`."""
FAMILY = "camera"
"""Value of the ``"family"`` tag of a camera calibration document."""
DOCUMENT_FORMAT = "sunbench.calibration"
"""Value of the ``"format"`` tag of a calibration document (every family's)."""
DOCUMENT_VERSION = 1
"""Version of the camera calibration document; bumped when the meaning of a field changes."""

_FLOATS = ("fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2", "k3")
_INTS = ("width_px", "height_px")


@dataclass(frozen=True)
class CameraModel:
    """OpenCV pinhole + Brown–Conrady camera and its rotation against the sensor body frame.

    Attributes
    ----------
    fx_px, fy_px : float
        Focal lengths along x and y [px].
    cx_px, cy_px : float
        Principal point [px].
    k1, k2, k3 : float
        Radial distortion coefficients [unitless].
    p1, p2 : float
        Tangential (decentring) distortion coefficients [unitless].
    width_px, height_px : int
        Frame size [px].
    rotation_deg : tuple of 3 float
        Rodrigues vector [°] of the rotation body → camera frame.
    """

    fx_px: float
    fy_px: float
    cx_px: float
    cy_px: float
    k1: float = 0.0
    k2: float = 0.0
    p1: float = 0.0
    p2: float = 0.0
    k3: float = 0.0
    width_px: int = 640
    height_px: int = 480
    rotation_deg: tuple[float, float, float] = (0.0, 0.0, 0.0)

    def __post_init__(self) -> None:
        for name in _FLOATS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
                raise TypeError(f"`{name}` must be a number, got {type(value).__name__}")
            if not math.isfinite(value):
                raise ValueError(f"`{name}` must be finite, got {value}")
        if not (self.fx_px > 0 and self.fy_px > 0):
            raise ValueError(f"`fx_px` and `fy_px` must be positive, got {self.fx_px} and {self.fy_px}")
        for name in _INTS:
            value = getattr(self, name)
            if isinstance(value, bool) or not isinstance(value, (int, np.integer)) or value <= 0:
                raise ValueError(f"`{name}` must be a positive integer, got {value!r}")
        rot = tuple(float(v) for v in np.asarray(self.rotation_deg, dtype=float).reshape(-1))
        if len(rot) != 3 or not all(math.isfinite(v) for v in rot):
            raise ValueError(f"`rotation_deg` must be 3 finite numbers, got {self.rotation_deg!r}")
        object.__setattr__(self, "rotation_deg", rot)
        for name in _FLOATS:
            object.__setattr__(self, name, float(getattr(self, name)))
        for name in _INTS:
            object.__setattr__(self, name, int(getattr(self, name)))

    # -- OpenCV's arrays -----------------------------------------------------------------------------------
    @property
    def camera_matrix(self) -> np.ndarray:
        """K = [[fx, 0, cx], [0, fy, cy], [0, 0, 1]]."""
        return np.array([[self.fx_px, 0.0, self.cx_px], [0.0, self.fy_px, self.cy_px], [0.0, 0.0, 1.0]])

    @property
    def dist_coeffs(self) -> np.ndarray:
        """OpenCV's (k1, k2, p1, p2, k3)."""
        return np.array([self.k1, self.k2, self.p1, self.p2, self.k3])

    @property
    def rvec(self) -> np.ndarray:
        """Rodrigues vector of the body → camera rotation [rad], shape (3,)."""
        return np.radians(np.array(self.rotation_deg))

    # -- JSON ----------------------------------------------------------------------------------------------
    def to_dict(self) -> dict:
        """Plain JSON-able document with the ``"kind": "camera"`` marker."""
        out: dict = {"kind": KIND}
        for f in fields(self):
            value = getattr(self, f.name)
            out[f.name] = list(value) if f.name == "rotation_deg" else value
        return out

    @classmethod
    def from_dict(cls, document: dict) -> CameraModel:
        """Rebuild from :meth:`to_dict`.

        Raises
        ------
        CalibrationFormatError
            Not a mapping, another kind, or a missing / non-numeric / invalid field (the message names it).
        """
        if not isinstance(document, dict):
            raise CalibrationFormatError(f"camera model: expected a JSON object, got {type(document).__name__}")
        if document.get("kind") != KIND:
            raise CalibrationFormatError(f"camera model: field `kind` must be {KIND!r}, got {document.get('kind')!r}")
        values: dict = {}
        for f in fields(cls):
            if f.name not in document:
                raise CalibrationFormatError(f"camera model: missing field `{f.name}`")
            value = document[f.name]
            if f.name == "rotation_deg":
                ok = (isinstance(value, (list, tuple)) and len(value) == 3
                      and all(_is_number(v) and math.isfinite(v) for v in value))
                if not ok:
                    raise CalibrationFormatError(f"camera model: field `rotation_deg` must be 3 finite numbers, "
                                                 f"got {value!r}")
                values[f.name] = tuple(float(v) for v in value)
            elif f.name in _INTS:
                if isinstance(value, bool) or not isinstance(value, int) or value <= 0:
                    raise CalibrationFormatError(f"camera model: field `{f.name}` must be a positive integer, "
                                                 f"got {value!r}")
                values[f.name] = value
            else:
                if not _is_number(value) or not math.isfinite(value):
                    raise CalibrationFormatError(f"camera model: field `{f.name}` must be a finite number, "
                                                 f"got {value!r}")
                values[f.name] = float(value)
        unknown = sorted(set(document) - {f.name for f in fields(cls)} - {"kind"})
        if unknown:
            raise CalibrationFormatError(f"camera model: unknown fields {unknown}")
        try:
            return cls(**values)
        except (TypeError, ValueError) as exc:
            raise CalibrationFormatError(f"camera model: invalid values ({exc})") from exc


def camera_from_document(document) -> CameraModel:
    """The camera model of a camera calibration document (``sunbench fit camera``, or a camera run's fit).

    The document is ``{"format": "sunbench.calibration", "version": 1, "family": "camera", "kind": "camera",
    "model": {CameraModel.to_dict()}, ...}``; a bare :meth:`CameraModel.to_dict` is taken as well.

    Raises
    ------
    CalibrationFormatError
        Not a mapping, another format, version or family, no model, or a bad model field (the message names it).
    """
    if not isinstance(document, dict):
        raise CalibrationFormatError(f"camera calibration: expected a JSON object, got {type(document).__name__}")
    if "model" not in document:
        if document.get("kind") == KIND and "fx_px" in document:
            return CameraModel.from_dict(document)  # a bare model
        raise CalibrationFormatError("camera calibration: missing field `model` (the camera model)")
    if document.get("format") is not None and document.get("format") != DOCUMENT_FORMAT:
        raise CalibrationFormatError(f"camera calibration: field `format` must be {DOCUMENT_FORMAT!r}, got "
                                     f"{document.get('format')!r}")
    version = document.get("version")
    if version is not None and version != DOCUMENT_VERSION:
        raise CalibrationFormatError(f"camera calibration: version {version!r} is not supported (this sunbench "
                                     f"reads version {DOCUMENT_VERSION})")
    family = document.get("family")
    if family is not None and family != FAMILY:
        raise CalibrationFormatError(f"camera calibration: field `family` must be {FAMILY!r}, got {family!r}")
    return CameraModel.from_dict(document["model"])


def _is_number(value) -> bool:
    return not isinstance(value, bool) and isinstance(value, (int, float))


def design_camera(width_px: int = 640, height_px: int = 480, *, horizontal_fov_deg: float | None = None,
                  focal_px: float | None = None) -> CameraModel:
    """The design's camera: fx = fy from the field of view, centre of the frame, no distortion, no rotation.

    Parameters
    ----------
    width_px, height_px : int
        Frame size [px].
    horizontal_fov_deg : float, optional
        Full horizontal field of view [°]; f = (width/2) / tan(FOV/2).
    focal_px : float, optional
        Focal length [px] (instead of the field of view). One of the two must be given.

    References
    ----------
    seed 001 eq. 4 (pinhole, principal point at the image centre, digest §2.1 A7).
    """
    if (horizontal_fov_deg is None) == (focal_px is None):
        raise ValueError("give exactly one of `horizontal_fov_deg` and `focal_px`")
    if focal_px is None:
        if not 0 < horizontal_fov_deg < 180:
            raise ValueError(f"`horizontal_fov_deg` must lie in (0, 180), got {horizontal_fov_deg}")
        focal_px = (width_px / 2) / math.tan(math.radians(horizontal_fov_deg) / 2)
    return CameraModel(fx_px=float(focal_px), fy_px=float(focal_px), cx_px=(width_px - 1) / 2,
                       cy_px=(height_px - 1) / 2, width_px=int(width_px), height_px=int(height_px))


def rotation_matrix(model: CameraModel) -> np.ndarray:
    """R (3×3) of the Rodrigues vector ``model.rotation_deg``: X_cam = R · n_body."""
    return cv2.Rodrigues(model.rvec.reshape(3, 1))[0]


def project(model: CameraModel, directions_body) -> np.ndarray:
    """Pixels of sun directions (OpenCV's ``projectPoints`` with tvec = 0).

    Parameters
    ----------
    model : CameraModel
    directions_body : array_like, shape (N, 3) or (3,)
        Direction vectors in the body frame (any length; taken as points at that distance).

    Returns
    -------
    pixels : ndarray, shape (N, 2) (or (2,))
        (x, y) [px]; NaN for directions behind the camera (camera-frame z ≤ 0).

    References
    ----------
    seed 001 eq. 4 (the pinhole, with the distortion and principal point the thesis leaves out); OpenCV's
    camera model (see the module docstring).
    """
    d = np.asarray(directions_body, dtype=float)
    single = d.ndim == 1
    d = np.atleast_2d(d)
    if d.shape[-1] != 3:
        raise ValueError(f"`directions_body` must have shape (N, 3), got {np.shape(directions_body)}")
    out = np.full((len(d), 2), np.nan)
    if len(d):
        z = d @ rotation_matrix(model)[2]
        front = np.isfinite(z) & (z > 0)
        if front.any():
            pts, _ = cv2.projectPoints(d[front].reshape(-1, 1, 3), model.rvec, np.zeros(3), model.camera_matrix,
                                       model.dist_coeffs)
            out[front] = pts.reshape(-1, 2)
    return out[0] if single else out


def _distort(xn: np.ndarray, yn: np.ndarray, k: np.ndarray):
    """Distorted normalised coordinates and the 2×2 Jacobian d(x'', y'')/d(x', y') (OpenCV's model)."""
    k1, k2, p1, p2, k3 = k
    r2 = xn * xn + yn * yn
    g = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    dg = k1 + r2 * (2 * k2 + 3 * k3 * r2)  # dg/d(r²)
    xd = xn * g + 2 * p1 * xn * yn + p2 * (r2 + 2 * xn * xn)
    yd = yn * g + p1 * (r2 + 2 * yn * yn) + 2 * p2 * xn * yn
    j11 = g + 2 * xn * xn * dg + 2 * p1 * yn + 6 * p2 * xn
    j12 = 2 * xn * yn * dg + 2 * p1 * xn + 2 * p2 * yn
    j21 = 2 * xn * yn * dg + 2 * p1 * xn + 2 * p2 * yn
    j22 = g + 2 * yn * yn * dg + 6 * p1 * yn + 2 * p2 * xn
    return xd, yd, (j11, j12, j21, j22)


def _undistort_points(points, camera_matrix, dist_coeffs, criteria) -> np.ndarray:
    """OpenCV's iterative undistortion: ``undistortPointsIter`` (OpenCV 4) or ``undistortPoints`` with a
    termination criterion (OpenCV 5, where the two were merged)."""
    if hasattr(cv2, "undistortPointsIter"):
        return cv2.undistortPointsIter(points, camera_matrix, dist_coeffs, None, None, criteria)
    return cv2.undistortPoints(points, camera_matrix, dist_coeffs, None, None, criteria=criteria)


def ray_directions(model: CameraModel, pixels) -> np.ndarray:
    """Unit sun directions in the body frame seen by pixels (inverse of :func:`project`).

    OpenCV's iterative ``undistortPoints`` (run to 50 iterations / 1e-12; with its default criterion it
    stops at ~1e-5 px for a few per cent of distortion) gives the undistorted normalised coordinates, and
    three Newton steps on the distortion polynomial (its analytic Jacobian) polish them: the round trip
    :func:`project` ∘ :func:`ray_directions` is exact to ~1e-12 px over a 640×480 frame.

    Parameters
    ----------
    model : CameraModel
    pixels : array_like, shape (N, 2) or (2,)
        (x, y) [px].

    Returns
    -------
    directions : ndarray, shape (N, 3) (or (3,))
        Unit vectors in the body frame (+z boresight) [unitless].

    References
    ----------
    seed 001 eq. 4 (V = A − B, the ray through the lens centre), inverted with OpenCV's distortion model.
    """
    p = np.asarray(pixels, dtype=float)
    single = p.ndim == 1
    p = np.atleast_2d(p)
    if p.shape[-1] != 2:
        raise ValueError(f"`pixels` must have shape (N, 2), got {np.shape(pixels)}")
    if not len(p):
        return np.zeros((0, 3))
    k = model.dist_coeffs
    xd = (p[:, 0] - model.cx_px) / model.fx_px
    yd = (p[:, 1] - model.cy_px) / model.fy_px
    finite = np.isfinite(xd) & np.isfinite(yd)
    xn, yn = xd.copy(), yd.copy()
    if np.any(k != 0) and finite.any():
        criteria = (cv2.TERM_CRITERIA_COUNT | cv2.TERM_CRITERIA_EPS, 50, 1e-12)
        und = _undistort_points(p[finite].reshape(-1, 1, 2), model.camera_matrix, k, criteria)
        xn[finite], yn[finite] = und[:, 0, 0], und[:, 0, 1]
        for _ in range(3):  # Newton on (x'', y'')(x', y') = (xd, yd)
            fx, fy, (a, b, c, d) = _distort(xn, yn, k)
            ex, ey = fx - xd, fy - yd
            det = a * d - b * c
            xn = xn - (d * ex - b * ey) / det
            yn = yn - (a * ey - c * ex) / det
    cam = np.stack([xn, yn, np.ones_like(xn)], axis=-1)
    cam /= np.linalg.norm(cam, axis=-1, keepdims=True)
    body = cam @ rotation_matrix(model)  # Rᵀ · cam, as rows
    return body[0] if single else body


def zenith_azimuth(model: CameraModel, pixels) -> tuple[np.ndarray, np.ndarray]:
    """Sun zenith and azimuth in the body frame for pixels [°].

    Parameters
    ----------
    model : CameraModel
    pixels : array_like, shape (N, 2) or (2,)
        (x, y) [px].

    Returns
    -------
    zenith_deg, azimuth_deg : ndarray
        θ from the boresight [°] and φ in [0, 360) [°], n = (sin θ cos φ, sin θ sin φ, cos θ).

    References
    ----------
    seed 001 eqs. 5–7 (relative azimuth and zenith; atan2 instead of arccos, digest §2.1 A8), in the
    project's convention of seed 003 eq. 12.
    """
    return zenith_azimuth_from_vector(ray_directions(model, pixels))
