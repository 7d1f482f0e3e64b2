"""A field file against the Sun: its readings made directions, compared with SPA, the clouds flagged, the site
located — what `sunbench field compare | locate` print and the dashboard's field page draws.

The science is in :mod:`calibration.field`; this module turns a field CSV and a calibration into its inputs
(the sensor's direction from the spot by the calibration of its family; the site, the air and the mount from
the file's header or the caller's options) and its results into tables and JSON.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from calibration.design import DEFAULT_SENSOR
from calibration.errors import CalibrationFormatError, FieldDataError
from calibration.field.clouds import BrightnessFlags, brightness_cloud_flags
from calibration.field.compare import FieldComparison, compare_with_sun
from calibration.field.locate import SiteFix, distance_km, locate
from calibration.field.sky import Atmosphere, Mount, Site

from .camera_datafile import is_camera_document
from .datafile import DataFileError
from .field_datafile import FieldData, iso_utc, read_field_csv

MODES = ("file", "fit")
#: The dark level under a spot's peak, by the calibration's family, for the brightness flag [DN]: the CMOS
#: module's bias and dark signal, a webcam's black level (the simulated ones'; a real sensor's is within a few DN
#: of them, which the flag's 15 % margin absorbs at the peaks the exposure control keeps, 25–90 % of full scale).
DARK_DN = {"cmos": 18.0, "camera": 12.0}


@dataclass(frozen=True)
class FieldSetup:
    """What a field run was, from the file's header and the caller's options."""

    site: Site | None
    atmosphere: Atmosphere
    mount: Mount
    heading_known: bool
    altitude_m: float
    fov_half_deg: float
    notes: tuple[str, ...] = ()


@dataclass(frozen=True)
class FieldAnalysis:
    """The results of :func:`analyse_field`."""

    data: FieldData
    setup: FieldSetup
    zenith_deg: np.ndarray  # the sensor's direction in its own frame [°]
    azimuth_deg: np.ndarray
    cloudy: np.ndarray
    brightness: BrightnessFlags | None
    comparison: FieldComparison | None
    fix: SiteFix | None
    notes: tuple[str, ...] = field(default=())


def sensor_directions(data: FieldData, calibration: dict | None) -> tuple[np.ndarray, np.ndarray]:
    """The sensor's own zenith and azimuth [°] of every row: its spot through `calibration` (a calibration document
    of its family), or the file's calibrated columns."""
    if data.has_spots and calibration is not None:
        return _apply(calibration, data.x_px, data.y_px, data.path)
    if data.zenith_deg is not None:
        return data.zenith_deg, data.azimuth_deg
    raise DataFileError(data.path, "holds the sensor's spot (x_px, y_px): give its calibration (--cal CAL.json) to "
                                   "turn spots into directions")


def _apply(document: dict, x_px, y_px, path: str) -> tuple[np.ndarray, np.ndarray]:
    """Spots through a calibration document (the CMOS methods, or a camera model)."""
    if not isinstance(document, dict):
        raise CalibrationFormatError("a calibration file holds a JSON object")
    if is_camera_document(document):
        from calibration.camera import camera_from_document, zenith_azimuth
        model = camera_from_document(document)
        return zenith_azimuth(model, np.column_stack([x_px, y_px]))
    if document.get("family") == "qd":
        raise CalibrationFormatError("a QD calibration turns currents into directions, not spots: apply it first "
                                     "(sunbench apply) and give the field file zenith_deg, azimuth_deg")
    from calibration.models import calibration_from_dict
    zenith, azimuth = calibration_from_dict(document).apply(np.asarray(x_px), np.asarray(y_px))
    return np.asarray(zenith, dtype=float), np.asarray(azimuth, dtype=float)


def field_setup(data: FieldData, *, site: Site | None = None, altitude_m: float | None = None,
                heading_deg: float | None = None,
                roll_deg: float | None = None, pitch_deg: float | None = None, pressure_hpa: float | None = None,
                temperature_c: float | None = None, delta_t_s: float | None = None,
                fov_half_deg: float | None = None, calibration: dict | None = None) -> FieldSetup:
    """The site, the air and the mount: the options first, then the file's header comments."""
    meta = data.metadata
    notes = []
    altitude = altitude_m if altitude_m is not None else meta.get("altitude_m", 0.0)
    if site is None and "latitude_deg" in meta and "longitude_deg" in meta:
        site = Site(meta["latitude_deg"], meta["longitude_deg"], altitude)

    def pick(option, key, default=None):
        return option if option is not None else meta.get(key, default)

    pressure = pick(pressure_hpa, "pressure_hpa")
    temperature = pick(temperature_c, "temperature_c")
    if "pressure_hpa" in data.numbers and np.isfinite(data.numbers["pressure_hpa"]).any() and pressure_hpa is None:
        pressure = float(np.nanmedian(data.numbers["pressure_hpa"]))
        notes.append(f"the air's pressure is the median of the file's column, {pressure:.1f} hPa")
    if "temperature_c" in data.numbers and np.isfinite(data.numbers["temperature_c"]).any() and temperature_c is None:
        temperature = float(np.nanmedian(data.numbers["temperature_c"]))
    if pressure is None or temperature is None:
        notes.append("no pressure or temperature given: refraction for 1013.25 hPa and 12 °C")
    atmosphere = Atmosphere(1013.25 if pressure is None else pressure, 12.0 if temperature is None else temperature,
                            pick(delta_t_s, "delta_t_s"))
    heading = pick(heading_deg, "heading_deg")
    roll, pitch = pick(roll_deg, "roll_deg"), pick(pitch_deg, "pitch_deg")
    if roll is None or pitch is None:
        missing = " and ".join(n for n, v in (("roll", roll), ("pitch", pitch)) if v is None)
        notes.append(f"no {missing} given: taken as 0 (level)")
    fov = pick(fov_half_deg, "fov_half_deg")
    if fov is None and isinstance(calibration, dict) and isinstance(calibration.get("design"), dict):
        fov = calibration["design"].get("fov_half_deg")
    fov = float(fov if fov is not None else DEFAULT_SENSOR.fov_half_deg)
    mount = Mount(heading_deg=0.0 if heading is None else heading, roll_deg=roll or 0.0, pitch_deg=pitch or 0.0)
    return FieldSetup(site=site, atmosphere=atmosphere, mount=mount, heading_known=heading is not None,
                      altitude_m=site.altitude_m if site is not None else altitude, fov_half_deg=fov,
                      notes=tuple(notes))


def analyse_field(data: FieldData, calibration: dict | None = None, *, heading: str = "file", level: str = "file",
                  do_compare: bool = True, do_locate: bool = False, setup: FieldSetup | None = None,
                  sigma_deg: float | None = None, level_sd_deg: float | None = None,
                  fit_until_s: float | None = None) -> FieldAnalysis:
    """Directions, cloud flags, the comparison with the Sun and (with `do_locate`) the site from the track.

    `heading`, `level`: ``"file"`` takes them from the header (or the options in `setup`), ``"fit"`` fits them
    (an unknown heading makes the azimuth error relative; seed 003 §5 removed a constant offset). Without a
    heading the comparison fits it.
    `fit_until_s` (Unix s): fit them over the clear readings before that time only (seed 003 §5 removed the
    offset over the clear interval before 12:00).
    """
    if heading not in MODES or level not in MODES:
        raise FieldDataError(f"heading and level are one of {MODES}, got {heading!r}, {level!r}")
    setup = setup or field_setup(data, calibration=calibration)
    zenith, azimuth = sensor_directions(data, calibration)
    valid = data.ok & np.isfinite(zenith) & np.isfinite(azimuth)
    notes = list(setup.notes)
    cloudy = np.zeros(len(data), dtype=bool) if data.cloud is None else data.cloud.copy()
    if data.spot_cloud is not None:  # the sensor's own flag (the camera's: its spot's shape), beside the operator's
        shape = data.spot_cloud & valid
        cloudy |= shape
        notes.append(f"{int(shape.sum())} readings flagged as cloud by the sensor itself (spot_cloud: the spot's shape "
                     "was not the clear disc's)")
    brightness = None
    if "peak_dn" in data.numbers and "exposure_ms" in data.numbers:
        try:
            family = "camera" if is_camera_document(calibration) else "cmos"
            brightness = brightness_cloud_flags(np.where(valid, data.numbers["peak_dn"], np.nan),
                                                data.numbers["exposure_ms"], zenith, background_dn=DARK_DN[family])
            cloudy |= brightness.cloudy
            notes.append(f"{int(brightness.cloudy.sum())} readings flagged as cloud: their spot was more than "
                         f"{brightness.drop:.0%} dimmer than the clear Sun at that angle")
        except FieldDataError as exc:
            notes.append(f"no cloud flag from the spot's brightness: {exc}")
    comparison = None
    if do_compare:
        if setup.site is None:
            raise FieldDataError("the site is unknown: give --lat and --lon, or the file's latitude_deg and "
                                 "longitude_deg header comments")
        fit_heading = heading == "fit" or not setup.heading_known
        if not setup.heading_known and heading == "file":
            notes.append("the file gives no heading: it is fitted")
        fit_mask = None
        if fit_until_s is not None:
            fit_mask = (data.t_s <= fit_until_s) & ~cloudy & (zenith <= setup.fov_half_deg)
            notes.append(f"heading and level fitted over the {int((fit_mask & valid).sum())} clear readings before "
                         f"{iso_utc(fit_until_s)}")
        try:
            comparison = compare_with_sun(data.t_s, zenith, azimuth, setup.site, setup.mount, setup.atmosphere,
                                          heading="fit" if fit_heading else "given",
                                          level="fit" if level == "fit" else "given", cloudy=cloudy, invalid=~valid,
                                          fov_half_deg=setup.fov_half_deg, fit_mask=fit_mask)
        except FieldDataError as exc:
            if not do_locate:
                raise
            notes.append(f"no comparison with the Sun at the file's site: {exc}")  # the site may be what is wrong
    fix = None
    if do_locate:
        # the readings of a clear Sun inside the sensor's field, by the sensor's own angle: the file's site (which
        # may be wrong: that is why one locates) chooses nothing
        use = valid & ~cloudy & (zenith <= setup.fov_half_deg)
        fix = locate(data.t_s[use], zenith[use], azimuth[use], altitude_m=setup.altitude_m, atmosphere=setup.atmosphere,
                     mount=setup.mount, level="fit" if level == "fit" else "given", sigma_deg=sigma_deg,
                     level_sd_deg=level_sd_deg)
    return FieldAnalysis(data=data, setup=setup, zenith_deg=zenith, azimuth_deg=azimuth, cloudy=cloudy,
                         brightness=brightness, comparison=comparison, fix=fix, notes=tuple(notes))


# -- JSON for the dashboard ------------------------------------------------------------------------------------

def _list(values) -> list:
    return [None if not math.isfinite(float(v)) else round(float(v), 6) for v in np.asarray(values, dtype=float)]


def _stats(summary) -> dict:
    return {"n": summary.count, "rms_zenith_deg": _num(summary.zenith.rms),
            "rms_azimuth_deg": _num(summary.azimuth.rms), "rms_vector_deg": _num(summary.vector.rms),
            "std_vector_deg": _num(summary.vector.std), "max_vector_deg": _num(summary.vector.max_abs)}


def _num(value) -> float | None:
    return None if value is None or not math.isfinite(float(value)) else float(value)


def summary_of(comparison: FieldComparison, mask) -> dict:
    """Error statistics of the samples in `mask` (of those with a reading)."""
    from calibration.field.compare import ErrorStats, FieldSummary

    m = np.asarray(mask, dtype=bool) & comparison.valid
    return _stats(FieldSummary(count=int(m.sum()), zenith=ErrorStats.of(comparison.zenith_error_deg[m]),
                               azimuth=ErrorStats.of(comparison.azimuth_error_deg[m]),
                               azimuth_arc=ErrorStats.of(comparison.azimuth_arc_error_deg[m]),
                               vector=ErrorStats.of(comparison.vector_error_deg[m])))


def analysis_document(analysis: FieldAnalysis, *, name: str) -> dict:
    """The analysis as JSON (the dashboard's field page; README "Field data CSV")."""
    site = analysis.setup.site
    document: dict = {"name": name, "n": len(analysis.data), "notes": list(analysis.notes),
                      "site": None if site is None else {"latitude_deg": site.latitude_deg,
                                                         "longitude_deg": site.longitude_deg,
                                                         "altitude_m": site.altitude_m},
                      "comparison": None, "location": None}
    c = analysis.comparison
    if c is not None:
        fit = c.mount_fit
        heading_fitted = fit is not None and "heading" in fit.parameters
        document["comparison"] = {
            "time_utc": analysis.data.time_utc, "sun_zenith_deg": _list(c.sun_zenith_deg),
            "sun_azimuth_deg": _list(c.sun_azimuth_deg), "measured_zenith_deg": _list(c.measured_zenith_deg),
            "measured_azimuth_deg": _list(c.measured_azimuth_deg), "zenith_error_deg": _list(c.zenith_error_deg),
            "azimuth_error_deg": _list(c.azimuth_error_deg), "vector_error_deg": _list(c.vector_error_deg),
            "clear": (c.valid & ~c.cloudy).tolist(), "in_fov": c.in_fov.tolist(), "cloud": c.cloudy.tolist(),
            "heading": {"deg": c.mount.heading_deg, "sd_deg": _num(fit.heading_sigma_deg) if heading_fitted else None,
                        "fitted": heading_fitted},
            "level": {"roll_deg": c.mount.roll_deg, "pitch_deg": c.mount.pitch_deg,
                      "fitted": fit is not None and "roll" in fit.parameters},
            "stats": {"clear": _stats(c.summary), "all": summary_of(c, c.in_fov)},
            "notes": list(c.notes), "warnings": list(c.warnings)}
    fix = analysis.fix
    if fix is not None:
        lat, lon = fix.ellipse.outline(scale=math.sqrt(5.991))  # 95 % of a 2-D Gaussian
        document["location"] = {
            "latitude_deg": fix.latitude_deg, "longitude_deg": fix.longitude_deg, "heading_deg": fix.heading_deg,
            "sd_latitude_km": fix.north_sigma_km, "sd_longitude_km": fix.east_sigma_km,
            "sd_heading_deg": _num(fix.sigma_deg.get("heading")),
            "ellipse": {"latitude_deg": _list(lat), "longitude_deg": _list(lon)}, "ellipse_level": "95 %",
            "semi_axes_km": [fix.ellipse.semi_major_km, fix.ellipse.semi_minor_km],
            "error_km": None if site is None else float(distance_km(site.latitude_deg, site.longitude_deg,
                                                                    fix.latitude_deg, fix.longitude_deg)),
            "n": fix.n_points, "residual_rms_deg": fix.residual_rms_deg, "warnings": list(fix.warnings)}
    return document


def analyse_field_csv(text: str, *, calibration: dict | None = None, heading: str = "file", level: str = "file",
                      locate: bool = True, fov_half_deg: float | None = None, level_sd_deg: float | None = None,
                      name: str = "upload.csv") -> dict:
    """A field CSV's content analysed (:func:`analyse_field`) as JSON (:func:`analysis_document`); bad input
    raises :class:`~bench.datafile.DataFileError` or a :class:`~calibration.errors.CalibrationError`."""
    data = read_field_csv(name, text=text)
    setup = field_setup(data, fov_half_deg=fov_half_deg, calibration=calibration)
    analysis = analyse_field(data, calibration, heading=heading, level=level, do_compare=setup.site is not None,
                             do_locate=locate, setup=setup, level_sd_deg=level_sd_deg)
    return analysis_document(analysis, name=name)
