"""Accuracy of a calibration in the columns of seed 003 Table 4.1, at the fitted points and held out.

Held out is scored two ways, and a method is judged by the worse:

* leave-one-azimuth-out: every bench azimuth in turn is removed, the model is fitted to the rest, and the
  removed points are predicted — how the calibration does between the measured azimuths;
* leave-one-zenith-ring-out: the same with every interior zenith ring (the innermost and outermost rings
  stay in: leaving them out would score extrapolation, which a flight sensor inside the calibrated field
  never needs) — how it does between the rings, where a 6th-order θ(r) oscillates.

Each fit also reports its residual against the repeat scatter (χ²/dof, in angle through the calibration's
own Jacobian, so every method is judged alike), and :func:`calibrate` puts it all together: repeats combined
robustly, the physical model's robust fit rejecting what disagrees with it, the bench geometry fitted from
stage angles, every method scored, the best chosen, and warnings in words when something is wrong.
"""

from __future__ import annotations

import dataclasses
from dataclasses import asdict, dataclass

import numpy as np

from .data import BenchData
from .design import DEFAULT_SENSOR, SensorDesign
from .errors import CalibrationError, InsufficientDataError
from .geometry import angular_error_deg, wrap_deg, zenith_azimuth_from_vector
from .models import METHODS, Calibration
from .models.physical import OUTLIER_SIGMAS, fit_physical
from .repeats import CombinedRepeats, RejectedFrame, combine_repeats
from .stage_geometry import GeometryPrior, StageGeometry, StageGeometryError, split_arm_ratio

#: χ²/dof above this (a residual 3× the repeat scatter) says the model does not describe the data.
CHI2_WARNING = 9.0
#: A share of rejected frames above this is worth a word.
REJECTED_WARNING = 0.02


@dataclass(frozen=True)
class AccuracyMetrics:
    """Accuracy of predicted directions against the true ones (seed 003 Table 4.1 columns and more).

    Attributes
    ----------
    n_points : int
        Points evaluated.
    rms_zenith_deg : float
        RMS of the zenith error [°].
    rms_azimuth_deg : float
        RMS of the azimuth error, wrapped to ±180°, over the off-normal points (the azimuth is undefined at
        normal incidence) [°].
    rms_vector_deg : float
        RMS of the angle between the true and the measured direction (eq. 13) [°].
    bound95_deg : float
        The 95 % bound as the thesis quotes it, 2 × `rms_vector_deg` [°].
    p95_vector_deg : float
        Empirical 95th percentile of the vector error [°].
    max_vector_deg : float
        Largest vector error [°].
    rms_vector_below40_deg : float
        RMS vector error of the points with zenith below 40° (seed 003 §4.3 quotes this range too) [°].
    """

    n_points: int
    rms_zenith_deg: float
    rms_azimuth_deg: float
    rms_vector_deg: float
    bound95_deg: float
    p95_vector_deg: float
    max_vector_deg: float
    rms_vector_below40_deg: float

    def to_dict(self) -> dict:
        return asdict(self)


def _rms(values) -> float:
    values = np.asarray(values, dtype=float)
    return float(np.sqrt(np.mean(values**2))) if values.size else float("nan")


def accuracy_metrics(data: BenchData, zenith_deg, azimuth_deg) -> AccuracyMetrics:
    """Compare predicted directions with the true ones of `data`.

    References
    ----------
    seed 003, eqs. 12–13 and Table 4.1 (RMS zenith, RMS azimuth, RMS vector; 95 % = 2 × RMS).
    """
    zenith_deg = np.asarray(zenith_deg, dtype=float)
    azimuth_deg = np.asarray(azimuth_deg, dtype=float)
    vector = angular_error_deg(data.zenith_deg, data.azimuth_deg, zenith_deg, azimuth_deg)  # eq. 13
    off = ~data.normal_incidence
    low = data.zenith_deg < 40.0
    rms_vector = _rms(vector)
    return AccuracyMetrics(
        n_points=len(data),
        rms_zenith_deg=_rms(zenith_deg - data.zenith_deg),
        rms_azimuth_deg=_rms(wrap_deg(azimuth_deg[off] - data.azimuth_deg[off])),
        rms_vector_deg=rms_vector,
        bound95_deg=2.0 * rms_vector,
        p95_vector_deg=float(np.percentile(vector, 95)) if vector.size else float("nan"),
        max_vector_deg=float(vector.max()) if vector.size else float("nan"),
        rms_vector_below40_deg=_rms(vector[low]),
    )


def holdout_predictions(method: str, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *,
                        by: str = "azimuth", **fit_options):
    """Held-out predictions: leave one bench azimuth (or one interior zenith ring) out at a time.

    `fit_options` go to the method's ``fit`` (for example ``glass_index`` for ``physical``).

    Returns
    -------
    evaluated : BenchData
        The points left out in turn, in their original order.
    zenith_deg, azimuth_deg : ndarray
        What a model fitted without the point's azimuth (ring) says [°].

    References
    ----------
    seed 003, Table 4.1 (its columns, here held out rather than at the nodes).
    """
    groups = data.azimuth_groups() if by == "azimuth" else data.zenith_rings()
    if by != "azimuth":
        fit_options = {**METHODS[method].ring_out_options, **fit_options}
    labels = sorted(set(groups[groups >= 0].tolist()))
    if by != "azimuth":
        if not labels:
            raise CalibrationError("leave-one-ring-out needs at least 3 zenith rings off normal incidence")
    elif len(labels) < 3:
        raise CalibrationError(f"held-out evaluation needs at least 3 bench azimuths, the data have {len(labels)}")
    zenith = np.full(len(data), np.nan)
    azimuth = np.full(len(data), np.nan)
    for label in labels:
        out = groups == label
        calibration = METHODS[method].fit(data.subset(~out), design, **fit_options)
        zenith[out], azimuth[out] = calibration.apply(data.x_px[out], data.y_px[out])
    keep = groups >= 0
    return data.subset(keep), zenith[keep], azimuth[keep]


@dataclass(frozen=True)
class MethodReport:
    """One method fitted to one data set.

    Attributes
    ----------
    method : str
    calibration : Calibration or None
        Fitted to all the data; None when the method could not be fitted.
    fitted : AccuracyMetrics or None
        At the fitted points.
    heldout : AccuracyMetrics or None
        The worse (by vector RMS) of the two held-out schemes: what the method is judged by.
    error : str or None
        Why the method could not be fitted or evaluated.
    heldout_azimuth, heldout_ring : AccuracyMetrics or None
        Leave-one-azimuth-out and leave-one-zenith-ring-out.
    chi2_dof : float or None
        Residual at the nodes against the repeat scatter, Σ Δ² / σ² per degree of freedom (None without
        repeats).
    """

    method: str
    calibration: Calibration | None
    fitted: AccuracyMetrics | None
    heldout: AccuracyMetrics | None
    error: str | None = None
    heldout_azimuth: AccuracyMetrics | None = None
    heldout_ring: AccuracyMetrics | None = None
    chi2_dof: float | None = None

    @property
    def heldout_scheme(self) -> str | None:
        """Which held-out scheme `heldout` is: "azimuth" or "ring"."""
        if self.heldout is None:
            return None
        return "ring" if self.heldout is self.heldout_ring else "azimuth"

    def to_dict(self) -> dict:
        plain = lambda m: m.to_dict() if m else None  # noqa: E731
        return {"method": self.method, "error": self.error, "fitted": plain(self.fitted),
                "heldout": plain(self.heldout), "heldout_scheme": self.heldout_scheme,
                "heldout_azimuth": plain(self.heldout_azimuth), "heldout_ring": plain(self.heldout_ring),
                "chi2_dof": self.chi2_dof}


def parameter_count(calibration: Calibration) -> int:
    """Free parameters of a fitted calibration (for the degrees of freedom of χ²)."""
    fitted = getattr(calibration, "fitted", None)
    if fitted:
        return len(fitted)

    def numbers(value) -> int:
        if isinstance(value, bool) or value is None:
            return 0
        if isinstance(value, (int, float)):
            return 1
        if isinstance(value, (list, tuple)):
            return sum(numbers(v) for v in value)
        return 0

    return max(sum(numbers(v) for v in calibration.parameters().values()), 1)


def chi2_per_dof(calibration: Calibration, data: BenchData, noise_px, n_parameters: int) -> float:
    """Residual at the nodes against the centroid noise, as χ²/dof in angle.

    Each point's noise σ [px per axis] is carried into angle through the calibration's own Jacobian J (numerical,
    ±0.01 px), so E[Δ²] = σ² ‖J‖²_F for a calibration that fits; χ² = Σ 2 Δ² / (σ² ‖J‖²_F) over 2N − p degrees
    of freedom. About 1 when the residual is the noise, large when the model misses.

    References
    ----------
    seed 003, eq. 13 (Δ); first-order propagation of the centroid noise.
    """
    x, y = data.x_px, data.y_px
    zen, az = calibration.apply(x, y)
    err = angular_error_deg(data.zenith_deg, data.azimuth_deg, zen, az)
    h = 0.01
    jac2 = np.zeros_like(x)
    for dx, dy in ((h, 0.0), (0.0, h)):
        z2, a2 = calibration.apply(x + dx, y + dy)
        jac2 += (angular_error_deg(zen, az, z2, a2) / h) ** 2
    sigma2 = np.asarray(noise_px, dtype=float) ** 2 * jac2
    dof = max(2 * len(data) - n_parameters, 1)
    with np.errstate(divide="ignore", invalid="ignore"):
        terms = np.where(sigma2 > 0, 2.0 * err**2 / sigma2, 0.0)
    return float(np.sum(terms) / dof)


def evaluate_method(method: str, data: BenchData, design: SensorDesign = DEFAULT_SENSOR, *, noise_px=None,
                    **fit_options) -> MethodReport:
    """Fit one method to all the data and evaluate it at the nodes and held out (both schemes).

    The repeats of each bench direction are averaged first (:meth:`BenchData.direction_means`), as seed 003
    §4.3 does before fitting and before its Table 4.1 (:func:`calibrate` combines them robustly instead and
    passes one point per direction, with its centroid noise `noise_px`).
    """
    data = data.direction_means()
    if noise_px is not None and method.startswith("physical"):
        fit_options = {**fit_options, "noise_px": noise_px}
    try:
        calibration = METHODS[method].fit(data, design, **fit_options)
    except CalibrationError as exc:
        return MethodReport(method, None, None, None, str(exc))
    fitted = accuracy_metrics(data, *calibration.apply(data.x_px, data.y_px))
    chi2 = None if noise_px is None else chi2_per_dof(calibration, data, noise_px, parameter_count(calibration))
    schemes, problems = {}, []
    for by in ("azimuth", "ring"):
        try:
            options = {k: v for k, v in fit_options.items() if k != "noise_px"}
            evaluated, zenith, azimuth = holdout_predictions(method, data, design, by=by, **options)
            schemes[by] = accuracy_metrics(evaluated, zenith, azimuth)
        except CalibrationError as exc:
            problems.append(str(exc))
    if not schemes:
        return MethodReport(method, calibration, fitted, None, f"no held-out figure: {'; '.join(problems)}",
                            chi2_dof=chi2)
    worse = max(schemes.values(), key=lambda m: m.rms_vector_deg)
    note = None
    if "ring" not in schemes:
        note = f"held out between azimuths only; between zenith rings it cannot be scored ({problems[-1]})"
    return MethodReport(method, calibration, fitted, worse, note, schemes.get("azimuth"), schemes.get("ring"), chi2)


def compare_methods(data: BenchData, methods=None, design: SensorDesign = DEFAULT_SENSOR,
                    fit_options: dict[str, dict] | None = None) -> list[MethodReport]:
    """Evaluate every method (default: all of :data:`calibration.models.METHODS`) on the same data.

    `fit_options` maps a method name to keyword arguments of its ``fit``, e.g.
    ``{"physical": {"glass_index": 1.77, "fit_index": True}}``.

    Data that no method could fit (one azimuth, fewer bench directions than the least any method needs) are
    refused up front with one :class:`~calibration.errors.InsufficientDataError`.
    """
    means = data.direction_means()
    need = min(m.min_points for m in METHODS.values())
    if len(means) < need:
        raise InsufficientDataError(f"too few bench directions, {len(means)} (from {len(data)} frames); "
                                    f"a calibration needs at least {need}")
    means.require_spread(min_points=need, method="calibration")
    fit_options = fit_options or {}
    return [evaluate_method(m, data, design, **_options_for(m, fit_options)) for m in (methods or list(METHODS))]


def _options_for(method: str, fit_options: dict) -> dict:
    """The fit options of a method; the physical variants share the ``physical`` entry."""
    if method in fit_options:
        return dict(fit_options[method])
    return dict(fit_options.get("physical", {})) if method.startswith("physical") else {}


def best_method(reports: list[MethodReport]) -> MethodReport:
    """The report with the lowest held-out vector RMS — the worse of its two schemes — (the fitted one when
    none could be held out)."""
    usable = [r for r in reports if r.calibration is not None]
    if not usable:
        raise CalibrationError("no method could be fitted: " + "; ".join(str(r.error) for r in reports))
    both = [r for r in usable if r.heldout_azimuth and r.heldout_ring]
    if both:  # a method scored only between azimuths may hide its error between rings: never prefer it
        return min(both, key=lambda r: r.heldout.rms_vector_deg)
    if any(r.heldout for r in usable):
        return min((r for r in usable if r.heldout), key=lambda r: r.heldout.rms_vector_deg)
    return min(usable, key=lambda r: r.fitted.rms_vector_deg)


@dataclass(frozen=True)
class CalibrationOutcome:
    """Everything :func:`calibrate` found.

    Attributes
    ----------
    reports : list of MethodReport
    chosen : MethodReport
    data : BenchData
        The points every method was fitted to: one per bench direction, outliers removed, true directions
        (from the fitted bench geometry for stage angles).
    noise_px : ndarray or None
        Centroid noise of each of those points per axis [px].
    repeats : CombinedRepeats
    rejected : list of RejectedFrame
        Frames the repeats rejected, then directions the robust physical fit rejected.
    geometry : dict or None
        The bench geometry of stage-angle data: each quantity with its value, 1σ and where it came from.
    warnings : list of str
        What is wrong, in words, with the likely causes.
    """

    reports: list[MethodReport]
    chosen: MethodReport
    data: BenchData
    noise_px: np.ndarray | None
    repeats: CombinedRepeats
    rejected: list[RejectedFrame]
    geometry: dict | None
    warnings: list[str]

    def quality(self) -> dict:
        """The chosen calibration's residual against the repeat scatter, and the warnings (JSON-able)."""
        cal = self.chosen.calibration
        return {"chi2_dof": self.chosen.chi2_dof, "repeat_scatter_px": self.repeats.repeat_scatter_px,
                "residual_rms_px": getattr(cal, "residual_rms_px", None),
                "frames": int(self.repeats.n_frames.sum()), "directions": len(self.data),
                "warnings": list(self.warnings)}


@dataclass(frozen=True)
class StageFrames:
    """The table's stage angles of each frame, for data recorded as stage angles.

    Attributes
    ----------
    azimuth_deg, zenith_deg : ndarray
        Azimuth stage φ_s and zenith stage Ω [°], one per frame.
    prior : GeometryPrior
        What is known of the bench's lengths (and the sensor's tilt on its fixture).
    """

    azimuth_deg: np.ndarray
    zenith_deg: np.ndarray
    prior: GeometryPrior


def _fit_stage_geometry(points: BenchData, stage: tuple, prior: GeometryPrior, design: SensorDesign,
                        noise, options: dict, warnings: list[str]):
    """Joint fit of sensor and bench geometry from stage angles (:mod:`calibration.stage_geometry`)."""
    azimuths = np.unique(np.round(np.mod(stage[0], 360.0), 1)).size
    fit_names = ("arm_ratio",) + (("zenith_zero_deg", "source_elevation_deg") if azimuths >= 3 else ())
    base = dict(mount_tilt_x_deg=prior.mount_tilt_x_deg, mount_tilt_y_deg=prior.mount_tilt_y_deg)
    given = prior.ratio
    starts = [given[0]] if given else [0.02, 0.1, 0.25]
    best = None
    for q0 in starts:  # the ratio's start matters little, but a bad one can settle in a side minimum
        try:
            fit = fit_physical(points, design, noise_px=noise, stage=stage, geometry=StageGeometry(q0, **base),
                               fit_geometry=fit_names, **options)
        except CalibrationError:
            continue
        cost = float(np.sum(fit.offsets_px[~fit.outliers] ** 2))
        if best is None or cost < best[0]:
            best = (cost, fit)
    if best is None:
        raise StageGeometryError("the sensor and the bench geometry could not be fitted jointly from these "
                                 "stage angles; give the geometry (--lever-arm-mm and --source-distance-mm)")
    fit = best[1]
    q, sd_q = fit.geometry.arm_ratio, fit.geometry_sd["arm_ratio"]
    if not np.isfinite(sd_q) or sd_q > 0.25 * max(q, 1e-3):
        raise StageGeometryError(
            f"the spots do not determine the bench geometry (lever arm / (source distance + lever arm) = "
            f"{q:.4f} ± {sd_q:.4f}); measure and give both --lever-arm-mm and --source-distance-mm (with "
            "--lever-arm-sd-mm and --source-distance-sd-mm), or add zeniths up to 60°")
    if given:
        z = abs(q - given[0]) / np.hypot(sd_q, given[1])
        if z > 3.0:
            warnings.append(
                f"the given bench geometry (lever arm {prior.lever_arm_mm:g} mm, source distance "
                f"{prior.source_distance_mm:g} mm: d/(L+d) = {given[0]:.5f} ± {given[1]:.5f}) disagrees with what "
                f"the spots say ({q:.5f} ± {sd_q:.5f}, {z:.1f} σ apart); the spots' value is used. Check the lever "
                "arm and the source distance.")
        else:  # consistent: the measurement sharpens the fit
            fit = fit_physical(points, design, noise_px=noise, stage=stage, geometry=fit.geometry,
                               fit_geometry=fit_names, ratio_prior=given, **options)
            q, sd_q = fit.geometry.arm_ratio, fit.geometry_sd["arm_ratio"]
    lengths = split_arm_ratio(q, sd_q, prior)
    geometry = {"arm_ratio": {"value": q, "sd": sd_q, "source": "fitted"}}
    for name in ("lever_arm_mm", "source_distance_mm"):
        given_value = getattr(prior, name)
        if lengths[name] is None:
            geometry[name] = {"value": given_value, "sd": None, "source": "unknown (only the ratio is seen)"}
        else:
            geometry[name] = {"value": lengths[name][0], "sd": lengths[name][1],
                              "source": "fitted with the given value" if given_value is not None
                              else "from the fitted ratio and the other length"}
    for name in fit_names[1:]:
        geometry[name] = {"value": getattr(fit.geometry, name), "sd": fit.geometry_sd[name], "source": "fitted"}
    for name in ("mount_tilt_x_deg", "mount_tilt_y_deg"):
        geometry[name] = {"value": getattr(prior, name), "sd": None,
                          "source": "given (not separable from the detector's tilt without an outside reference)"}
    geometry["azimuth_zero_deg"] = {"value": 0.0, "sd": None,
                                    "source": "defines the azimuth origin (not separable from the detector's rotation)"}
    return fit, geometry


def calibrate(frames: BenchData, *, methods=None, design: SensorDesign = DEFAULT_SENSOR,
              fit_options: dict[str, dict] | None = None, stage: StageFrames | None = None) -> CalibrationOutcome:
    """Calibrate a sensor from its frames, robustly and honestly (module docstring).

    1. Repeats are combined by their agreeing frames (:func:`~calibration.repeats.combine_repeats`).
    2. The physical model is fitted robustly with the centroid noise as its scale; directions it rejects are
       left out for every method. From stage angles it fits the bench geometry jointly.
    3. Every method is fitted and scored held out (the worse of two schemes) and against the repeat scatter.
    4. The best held-out method is chosen; warnings say what looks wrong.

    Parameters
    ----------
    frames : BenchData
        One point per frame (for stage angles, the directions only group the repeats).
    methods : list of str, optional
        Default: every method of :data:`calibration.models.METHODS`.
    design : SensorDesign
    fit_options : dict
        Per-method fit options (``{"physical": {"glass_index": 1.77}}``; the physical variants share them).
    stage : StageFrames, optional
        The stage angles of the frames and what is known of the bench's geometry.

    References
    ----------
    seed 003, §4.3 and Table 4.1; research note anchors-sunsensors §6.
    """
    fit_options = fit_options or {}
    methods = list(methods or METHODS)
    warnings: list[str] = []
    repeats = combine_repeats(frames)
    points, noise = repeats.data, repeats.noise_px
    rejected = list(repeats.rejected)
    physical_options = {k: v for k, v in _options_for("physical", fit_options).items() if k != "noise_px"}
    need = min(METHODS[m].min_points for m in methods)
    if len(points) < need:
        raise InsufficientDataError(f"too few bench directions, {len(points)} (from {len(frames)} frames); "
                                    f"a calibration needs at least {need}")
    geometry = None
    if stage is not None:
        first = repeats.first_index
        fit, geometry = _fit_stage_geometry(points, (stage.azimuth_deg[first], stage.zenith_deg[first]), stage.prior,
                                            design, noise, physical_options, warnings)
        zen, az = zenith_azimuth_from_vector(fit.vectors)
        points = BenchData(zen, az, points.x_px, points.y_px, sensor_id=points.sensor_id, frame_id=points.frame_id)
    else:
        points.require_spread(min_points=need, method="calibration")
        try:
            fit = fit_physical(points, design, noise_px=noise, **physical_options)
        except CalibrationError:
            fit = None  # the physical report will say why
    if fit is not None and fit.outliers.any():
        for i in np.flatnonzero(fit.outliers):
            scale = f"its centroid noise {fit.noise_px[i]:.3f} px" if noise is not None else "the residuals' scatter"
            for j in repeats.members[i]:  # every frame of the direction, each with its own distance
                rejected.append(RejectedFrame(
                    None if frames.frame_id is None else int(frames.frame_id[j]), float(points.zenith_deg[i]),
                    float(points.azimuth_deg[i]), float(frames.x_px[j]), float(frames.y_px[j]),
                    float(np.hypot(*(fit.model_px[i] - (frames.x_px[j], frames.y_px[j])))),
                    f"its direction ({len(repeats.members[i])} frame(s), no two agreeing or all off) disagrees "
                    f"with the physical model by {fit.offsets_px[i]:.2f} px, more than {OUTLIER_SIGMAS:g} × {scale}"))
        keep = ~fit.outliers
        points = points.subset(keep)
        noise = None if noise is None else noise[keep]
    reports = [evaluate_method(m, points, design, noise_px=noise, **_options_for(m, fit_options)) for m in methods]
    if stage is not None:  # the joint fit's covariance carries the bench geometry's uncertainty into the sensor's
        joint = fit.calibration if not fit.outliers.any() else None
        reports = [dataclasses.replace(r, calibration=joint) if r.method == "physical" and r.calibration is not None
                   and joint is not None else r for r in reports]
    chosen = best_method(reports)
    warnings += _quality_warnings(chosen, reports, repeats, rejected, stage is not None)
    return CalibrationOutcome(reports, chosen, points, noise, repeats, rejected, geometry, warnings)


def _quality_warnings(chosen: MethodReport, reports: list[MethodReport], repeats: CombinedRepeats,
                      rejected: list[RejectedFrame], from_stage: bool) -> list[str]:
    """What looks wrong with a calibration, in words, with the likely causes."""
    out = []
    if repeats.repeat_scatter_px is None:
        out.append("no bench direction has repeated frames, so the residual cannot be compared with the centroid "
                   "noise; repeat each direction (seed 003 takes 4 frames) to let the calibration check itself")
    elif chosen.chi2_dof is not None and chosen.chi2_dof > CHI2_WARNING:
        causes = ["the bench geometry (lever arm, source distance, stage zeros" +
                  (", fitted here from the stage angles" if from_stage else "; give stage angles to fit it") + ")",
                  "outliers the repeats could not catch (glints, stray light)",
                  "a sensor the models do not describe (e.g. glass bonded under the mask: `physical-mask`)"]
        out.append(f"the residual of {chosen.method} is {np.sqrt(chosen.chi2_dof):.1f}× the repeat scatter "
                   f"(χ²/dof = {chosen.chi2_dof:.1f}, scatter {repeats.repeat_scatter_px:.3f} px per frame): the "
                   "calibration does not describe these data to their noise. Likely causes: " + "; ".join(causes))
    n_frames = int(repeats.n_frames.sum()) + len(repeats.rejected)
    if rejected and len(rejected) > REJECTED_WARNING * max(n_frames, 1):
        out.append(f"{len(rejected)} of {n_frames} frames were rejected as outliers "
                   f"({100 * len(rejected) / n_frames:.1f} %): "
                   "look for glints, reflections or stray light on the bench")
    if (chosen.heldout and chosen.fitted
            and chosen.heldout.rms_vector_deg > 3 * max(chosen.fitted.rms_vector_deg, 1e-4)
            and chosen.heldout.rms_vector_deg > 0.02):
        out.append(f"{chosen.method} does {chosen.heldout.rms_vector_deg / chosen.fitted.rms_vector_deg:.0f}× worse "
                   f"between the measured directions ({chosen.heldout.rms_vector_deg:.3f}°) "
                   "than at them: add directions")
    return out
