"""The versioned JSON document of a QD calibration, and applying it to readings from the document alone.

A document is a plain ``dict`` of JSON types (the caller writes it to a file):

.. code-block:: text

    {"format": "sunbench.calibration", "family": "qd", "version": 1, "method": "geometric" | "polynomial" | "physical",
     "sensor_id": str | null,
     "design": {... QdDesign, with "eq21_length_m" and "layout"},
     "dark": {"model": "none" | "constant" | "linear" | "exponential", "t_ref_c": float,
              "quadrants": [{name: {"value": float, "sd": float | null}}, × 4], ...},
     "parameters": {name: {"value": float or [float], "sd": float or [float] or null}},
     "model": {... what the method needs besides its parameters},
     "correlation": {"names": [str], "matrix": [[float]]} | null,
     "metrics": {...} | null,
     "notes": [str]}

``parameters`` by method: geometric x0_m, y0_m, alpha0_deg, beta0_deg, phi0_deg, d_m (eq. 2.2);
polynomial coef_alpha, coef_beta (eq. 2.3, on normalised eq. 2.1 ratios; ``model`` holds terms, centre and
scale); physical x0_m … gain4 (``model`` holds radius_m, offsets and layout).

:func:`apply_document` turns raw currents and temperatures into (α, β, zenith, azimuth) with nothing but the
document: dark current (§2.1), eq. 2.1, then the method.

References
----------
seed 002, §2.1, eqs. 2.1–2.3, §5.2–5.3 (the parameters each model needs); DESIGN.md (every calibration is a
versioned JSON document).
"""

from __future__ import annotations

import numpy as np

from ..errors import CalibrationFormatError
from ..models.base import FORMAT
from ..plain import plain
from .angles import zenith_azimuth_from_projection
from .dark import DarkModel, subtract_dark
from .design import quadrant_layout
from .geometric import GEOMETRIC_PARAMETERS, GeometricParameters, angles_from_spot
from .physical import PHYSICAL_PARAMETERS, PhysicalParameters, invert_physical
from .polynomial import PolynomialModel
from .spot import spot_position, spot_ratios

#: Version of the QD document; bumped when the meaning of a field changes.
QD_FORMAT_VERSION = 1
#: The family tag.
FAMILY = "qd"
#: Methods a document can hold.
QD_METHODS = ("geometric", "polynomial", "physical")


def _entry(value, sd=None) -> dict:
    return {"value": plain(value), "sd": None if sd is None else plain(sd)}


def geometric_parts(params: GeometricParameters, sd: dict | None, length_m: float, layout) -> tuple[dict, dict]:
    """The ``parameters`` and ``model`` of a geometric document (seed 002 eq. 2.2)."""
    sd = sd or {}
    return ({n: _entry(getattr(params, n), sd.get(n)) for n in GEOMETRIC_PARAMETERS},
            {"length_m": float(length_m), "layout": quadrant_layout(layout).astype(int).tolist(),
             "input": "eq. 2.1 spot centre [m] with length_m"})


def polynomial_parts(model: PolynomialModel, layout) -> tuple[dict, dict]:
    """The ``parameters`` and ``model`` of a polynomial document (seed 002 eq. 2.3)."""
    return ({"coef_alpha": _entry(model.coef_alpha, model.sd_alpha),
             "coef_beta": _entry(model.coef_beta, model.sd_beta)},
            {"kind": model.kind, "degree": plain(model.degree), "terms": [list(t) for t in model.terms],
             "center": list(model.center), "scale": list(model.scale),
             "condition_number": plain(model.condition_number),
             "layout": quadrant_layout(layout).astype(int).tolist(),
             "input": "eq. 2.1 ratios u = 2 x_c / L, v = 2 y_c / L, normalised (u − center) / scale"})


def physical_parts(params: PhysicalParameters, sd: dict | None) -> tuple[dict, dict]:
    """The ``parameters`` and ``model`` of a physical document (seed 002 eqs. 2.1–2.2 past the thesis:
    :mod:`calibration.qd.physical`)."""
    sd = sd or {}
    return ({n: _entry(getattr(params, n), sd.get(n)) for n in PHYSICAL_PARAMETERS},
            {"radius_m": params.radius_m, "offsets": params.offsets, "layout": [list(r) for r in params.layout]})


def qd_document(method: str, parameters: dict, model: dict, *, dark, design=None, sensor_id: str | None = None,
                correlation: tuple | None = None, metrics: dict | None = None, notes=()) -> dict:
    """Assemble a QD calibration document (module docstring).

    Parameters
    ----------
    method : {"geometric", "polynomial", "physical"}
    parameters, model : dict
        From :func:`geometric_parts`, :func:`polynomial_parts` or :func:`physical_parts`.
    dark : DarkFit or DarkModel
    design : QdDesign, optional
    correlation : (names, matrix), optional
    metrics : dict, optional
    notes : sequence of str

    References
    ----------
    DESIGN.md ("every calibration is a versioned JSON document"); seed 002 §2.1 and eqs. 2.1–2.3.
    """
    if method not in QD_METHODS:
        raise ValueError(f"`method` must be one of {QD_METHODS}, got {method!r}")
    doc = {"format": FORMAT, "family": FAMILY, "version": QD_FORMAT_VERSION, "method": method,
           "sensor_id": sensor_id, "design": None if design is None else plain(design.to_dict()),
           "dark": plain(dark.to_dict()), "parameters": plain(parameters), "model": plain(model),
           "correlation": None if correlation is None else {"names": list(correlation[0]),
                                                             "matrix": plain(np.asarray(correlation[1]))},
           "metrics": plain(metrics) if metrics is not None else None, "notes": [str(n) for n in notes]}
    validate_document(doc)
    return doc


def _value(doc: dict, name: str):
    try:
        return doc["parameters"][name]["value"]
    except (KeyError, TypeError) as exc:
        raise CalibrationFormatError(f"qd {doc.get('method')} calibration: parameter `{name}` missing") from exc


def _finite_numbers(value, what: str):
    arr = np.asarray(value, dtype=float) if value is not None else np.array(np.nan)
    if not np.all(np.isfinite(arr)):
        raise CalibrationFormatError(f"{what} must be finite numbers, got {value!r}")
    return arr


def validate_document(doc) -> None:
    """Raise :class:`~calibration.errors.CalibrationFormatError` unless `doc` is a QD calibration this version reads.

    References
    ----------
    DESIGN.md (versioned calibration documents).
    """
    if not isinstance(doc, dict) or doc.get("format") != FORMAT:
        raise CalibrationFormatError(f"not a sunbench calibration (expected \"format\": \"{FORMAT}\")")
    if doc.get("family") != FAMILY:
        raise CalibrationFormatError(f"not a QD calibration (family {doc.get('family')!r})")
    if doc.get("version") != QD_FORMAT_VERSION:
        raise CalibrationFormatError(f"QD calibration version {doc.get('version')!r} is not supported (this sunbench "
                                     f"reads version {QD_FORMAT_VERSION})")
    method = doc.get("method")
    if method not in QD_METHODS:
        raise CalibrationFormatError(f"unknown QD calibration method {method!r}")
    if not isinstance(doc.get("parameters"), dict) or not isinstance(doc.get("model"), dict):
        raise CalibrationFormatError("QD calibration without \"parameters\" or \"model\" objects")
    if not isinstance(doc.get("dark"), dict):
        raise CalibrationFormatError("QD calibration without its \"dark\" model")
    DarkModel.from_dict(doc["dark"])
    names = {"geometric": GEOMETRIC_PARAMETERS, "polynomial": ("coef_alpha", "coef_beta"),
             "physical": PHYSICAL_PARAMETERS}[method]
    for name in names:
        _finite_numbers(_value(doc, name), f"parameter `{name}`")
    model = doc["model"]
    try:
        quadrant_layout(model["layout"])
        if method == "geometric":
            _finite_numbers(model["length_m"], "model `length_m`")
        elif method == "polynomial":
            terms = model["terms"]
            if len(terms) != len(_value(doc, "coef_alpha")) or len(terms) != len(_value(doc, "coef_beta")):
                raise CalibrationFormatError("the polynomial's terms and coefficients differ in number")
            _finite_numbers(model["center"], "model `center`")
            if np.any(_finite_numbers(model["scale"], "model `scale`") == 0):
                raise CalibrationFormatError("the polynomial's scale holds a zero")
        else:
            _finite_numbers(model["radius_m"], "model `radius_m`")
            if model["offsets"] not in ("rotation", "additive"):
                raise CalibrationFormatError(f"unknown offsets model {model['offsets']!r}")
    except (KeyError, TypeError, ValueError) as exc:
        if isinstance(exc, CalibrationFormatError):
            raise
        raise CalibrationFormatError(f"QD {method} calibration: malformed \"model\" ({exc!r})") from exc


def geometric_from_document(doc: dict) -> GeometricParameters:
    """The eq. 2.2 parameters of a geometric document (seed 002 eq. 2.2)."""
    return GeometricParameters(**{n: float(_value(doc, n)) for n in GEOMETRIC_PARAMETERS})


def polynomial_from_document(doc: dict) -> PolynomialModel:
    """The eq. 2.3 model of a polynomial document (seed 002 eq. 2.3)."""
    m = doc["model"]
    return PolynomialModel(tuple(tuple(int(v) for v in t) for t in m["terms"]), m["kind"], m["degree"],
                           tuple(float(v) for v in m["center"]), tuple(float(v) for v in m["scale"]),
                           np.asarray(_value(doc, "coef_alpha"), float), np.asarray(_value(doc, "coef_beta"), float))


def physical_from_document(doc: dict) -> PhysicalParameters:
    """The physical model's parameters of a physical document (seed 002 eqs. 2.1–2.2,
    :mod:`calibration.qd.physical`)."""
    m = doc["model"]
    return PhysicalParameters(**{n: float(_value(doc, n)) for n in PHYSICAL_PARAMETERS}, radius_m=float(m["radius_m"]),
                              offsets=m["offsets"], layout=tuple(tuple(r) for r in m["layout"]))


def angles_from_photocurrents(doc: dict, photocurrents_a) -> tuple[np.ndarray, np.ndarray]:
    """(α, β) [°] of dark-corrected currents through the document's method (NaN where it has no answer).

    References
    ----------
    seed 002, eqs. 2.1–2.3.
    """
    method = doc["method"]
    layout = doc["model"]["layout"]
    currents = np.asarray(photocurrents_a, dtype=float)
    if method == "geometric":
        xc, yc = spot_position(currents, float(doc["model"]["length_m"]), layout, invalid="nan")  # eq. 2.1
        return angles_from_spot(xc, yc, geometric_from_document(doc))  # eq. 2.2
    if method == "polynomial":
        u, v = spot_ratios(currents, layout, invalid="nan")  # eq. 2.1
        return polynomial_from_document(doc).evaluate(u, v)  # eq. 2.3
    alpha, beta, _ = invert_physical(currents, physical_from_document(doc))
    return alpha, beta


def apply_document(doc: dict, currents_a, temperature_c) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Sun direction from raw quadrant currents and the sensor's temperature, with the document alone.

    Parameters
    ----------
    doc : dict
        A QD calibration document.
    currents_a : array_like, shape (..., 4)
        Raw currents of quadrants 1–4 [A].
    temperature_c : numeric
        Sensor temperature [°C], broadcast against the readings.

    Returns
    -------
    alpha_deg, beta_deg, zenith_deg, azimuth_deg : ndarray
        [°]; NaN for readings the calibration cannot turn into a direction (no light, spot off the centre).

    References
    ----------
    seed 002, §2.1 (dark current), eqs. 2.1–2.3; seed 003, eq. 12 (zenith and azimuth).
    """
    validate_document(doc)
    dark = DarkModel.from_dict(doc["dark"])
    photo = subtract_dark(currents_a, temperature_c, dark)  # seed 002 §2.1
    alpha, beta = angles_from_photocurrents(doc, photo)
    alpha, beta = np.asarray(alpha, float), np.asarray(beta, float)
    ok = np.isfinite(alpha) & np.isfinite(beta)
    zen, az = zenith_azimuth_from_projection(np.where(ok, alpha, 0.0), np.where(ok, beta, 0.0))
    return alpha, beta, np.where(ok, zen, np.nan), np.where(ok, az, np.nan)
