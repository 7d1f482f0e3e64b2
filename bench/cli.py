"""`sunbench fit | apply | header | demo | sim`: calibrations from files, and the simulated bench's devices.

Every command ends bad input with one line on stderr naming the file, row and column, and exit code 2,
never a traceback (`cli_common.user_errors`). The app itself is built by the `cli/` package.
"""

from __future__ import annotations

from importlib import metadata
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from calibration.design import DEFAULT_SENSOR, SensorDesign
from calibration.errors import CalibrationError
from calibration.evaluation import CalibrationOutcome, StageFrames, calibrate
from calibration.models import METHODS, Calibration
from calibration.models.physical import PhysicalCalibration
from calibration.pinhole import PinholeBuild
from calibration.qd.evaluation import METHODS as QD_METHODS
from calibration.stage_geometry import GeometryPrior
from calibration.synthetic import EXAMPLE_BUILD, synthetic_bench_data

from .benchfile import BenchFile, BenchFileError, load_bench_file
from .camera_datafile import (
    camera_calibration_document,
    camera_header_from_document,
    is_camera_document,
    read_camera_calibration,
    read_camera_frames,
)
from .cli_common import (
    err,
    fmt,
    horizon_accuracy_table,
    horizon_parameters_table,
    metrics_table,
    out,
    qd_metrics_table,
    user_errors,
)
from .css_datafile import css_header_from_document, is_css_document, read_css_calibration
from .datafile import (
    DataFileError,
    calibration_document,
    header_from_document,
    load_calibration_json,
    read_bench_frames,
    read_calibration,
    read_spots_csv,
    write_applied_csv,
    write_bench_csv,
    write_calibration,
)
from .horizon_datafile import horizon_header_from_document, is_horizon_document, read_horizon_calibration
from .qd_datafile import (
    QdFrames,
    angular_errors_deg,
    is_qd_document,
    qd_calibration_file,
    qd_header_from_document,
    read_qd_calibration,
    read_qd_frames,
    read_qd_readings,
    write_qd_applied_csv,
)

#: `fit`, `apply`, `header`, `demo`, `sim`; `register` adds them to the `sunbench` app (cli/main.py).
commands = typer.Typer()
fit_app = typer.Typer(help="Fit a calibration to bench data.", no_args_is_help=True)


def register(app: typer.Typer) -> None:
    """Add this module's commands to `app`."""
    app.registered_commands.extend(commands.registered_commands)
    app.add_typer(fit_app, name="fit")


def _version() -> str:
    try:
        return metadata.version("sunbench")
    except metadata.PackageNotFoundError:
        return "unknown"


def physical_table(cal: PhysicalCalibration, truth: PinholeBuild | None = None) -> Table:
    table = Table(title=f"Physical model: fitted build ({cal.method})", title_justify="left")
    for name in ("parameter", "fitted", "± 1σ") + (("truth",) if truth else ()):
        table.add_column(name, justify="left" if name == "parameter" else "right")
    for name in cal.fitted:
        if not hasattr(cal, name):
            continue  # a bench-geometry parameter: in the geometry table
        row = [name, f"{getattr(cal, name):.5f}", f"{cal.uncertainties[name]:.5f}"]
        if truth:
            row.append(f"{getattr(truth, name):.5f}")
        table.add_row(*row)
    return table


def geometry_table(geometry: dict) -> Table:
    table = Table(title="Bench geometry (from the stage angles)", title_justify="left")
    for name in ("quantity", "value", "± 1σ", "from"):
        table.add_column(name, justify="left" if name in ("quantity", "from") else "right")
    for name, entry in geometry.items():
        value, sd = entry["value"], entry["sd"]
        table.add_row(name, "—" if value is None else f"{value:.6g}", "—" if sd is None else f"{sd:.3g}",
                      entry["source"])
    return table


def print_outcome(outcome: CalibrationOutcome, chosen: str) -> None:
    """The rejected frames, the bench geometry and the warnings of a calibration, for the terminal."""
    if outcome.geometry is not None:
        out.print(geometry_table(outcome.geometry))
    quality = outcome.quality()
    scatter = quality["repeat_scatter_px"]
    chi2 = next(r.chi2_dof for r in outcome.reports if r.method == chosen)
    out.print(f"{quality['frames']} frames at {quality['directions']} directions; repeat scatter "
              + (f"{scatter:.4f} px per frame; {chosen}: χ²/dof = {fmt(chi2 if chi2 is not None else float('nan'), 2)}"
                 if scatter is not None else "unknown (no repeats)"), highlight=False)
    if outcome.rejected:
        out.print(f"[bold]{len(outcome.rejected)} rejected frame(s)[/] (left out of every fit):", highlight=False)
        for r in outcome.rejected:
            out.print("  " + escape(r.describe()), highlight=False)
    for w in outcome.warnings:
        out.print(f"[bold yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)


def _fit_and_report(data, method: Optional[str], fit_options=None, *, design: SensorDesign = DEFAULT_SENSOR,
                    stage: StageFrames | None = None) -> tuple[Calibration, CalibrationOutcome]:
    with err.status("fitting and cross-validating every method…"):
        outcome = calibrate(data, fit_options=fit_options, design=design, stage=stage)
    chosen = outcome.chosen.method if method is None else method
    report = next(r for r in outcome.reports if r.method == chosen)
    if report.calibration is None:
        raise CalibrationError(f"method {chosen} could not be fitted: {report.error}")
    out.print(metrics_table(outcome.reports, chosen))
    return report.calibration, outcome


def _option_or(metadata: dict, name: str, option):
    """An option wins over the CSV's header comment; None when neither gives it."""
    return option if option is not None else metadata.get(name)


@fit_app.command("cmos")
@user_errors
def fit_cmos(
    data_csv: Path = typer.Argument(..., help="Bench data CSV (see the README)."),
    method: Optional[str] = typer.Option(None, "--method", "-m",
                                         help=f"One of {', '.join(METHODS)}; default: the most accurate held out."),
    output: Optional[Path] = typer.Option(None, "--output", "-o", help="Write the calibration JSON here."),
    header: Optional[Path] = typer.Option(None, "--header", help="Also write a C header for the sensor's MCU."),
    sensor: Optional[str] = typer.Option(None, "--sensor", help="Fit this sensor_id of a multi-sensor file."),
    lever_arm_mm: Optional[float] = typer.Option(None, help="Stage angles: axis-to-sensor distance d of seed 003 "
                                                            "eq. 8 [mm], as measured (fitted with it)."),
    lever_arm_sd_mm: Optional[float] = typer.Option(None, help="1σ of --lever-arm-mm [mm] (default 0.5 %)."),
    source_distance_mm: Optional[float] = typer.Option(None, help="Stage angles: sensor-to-simulator distance L "
                                                                  "[mm], as measured (fitted with it)."),
    source_distance_sd_mm: Optional[float] = typer.Option(None, help="1σ of --source-distance-mm [mm] "
                                                                     "(default 0.5 %)."),
    mount_tilt_x_deg: Optional[float] = typer.Option(None, help="Stage angles: the sensor's tilt on its fixture "
                                                                "toward azimuth 0° [°], if measured (default 0)."),
    mount_tilt_y_deg: Optional[float] = typer.Option(None, help="The same toward azimuth 90° [°]."),
    pixel_pitch_mm: Optional[float] = typer.Option(None, help="Detector pixel pitch [mm] (default: the CSV's "
                                                              "header comment, else seed 003's 0.0099)."),
    width_px: Optional[int] = typer.Option(None, help="Detector width [px] (default 640)."),
    height_px: Optional[int] = typer.Option(None, help="Detector height [px] (default 480)."),
    pinhole_height_mm: Optional[float] = typer.Option(None, help="Nominal pinhole height L [mm] (the fit's start)."),
    glass_index: Optional[float] = typer.Option(None, help="physical: refractive index of the glass between pinhole "
                                                           "and pixels (BK7/D263 1.52, sapphire 1.77, "
                                                           "fused silica 1.46)."),
    fit_index: bool = typer.Option(False, "--fit-index", help="physical: fit the glass index too (it is "
                                                              "strongly correlated with the thickness)."),
) -> None:
    """Fit a CMOS pinhole sensor's calibration; print the accuracy of every method side by side."""
    if method is not None and method not in METHODS:
        raise CalibrationError(f"--method must be one of {', '.join(METHODS)}, got {method!r}")
    frames = read_bench_frames(data_csv, sensor_id=sensor)
    meta = frames.metadata
    glass_index = _option_or(meta, "glass_index", glass_index) or 1.52
    if not 1.0 <= glass_index <= 3.0:
        raise CalibrationError(f"--glass-index must lie in [1, 3], got {glass_index}")
    given = {name: _option_or(meta, name, value) for name, value in (
        ("pixel_pitch_mm", pixel_pitch_mm), ("width_px", width_px), ("height_px", height_px),
        ("pinhole_height_mm", pinhole_height_mm))}
    try:
        design = SensorDesign(**{**DEFAULT_SENSOR.to_dict(), **{k: (int(v) if k.endswith("_px") else v)
                                                                  for k, v in given.items() if v is not None}})
    except ValueError as exc:
        raise CalibrationError(str(exc)) from None
    prior = GeometryPrior(  # validated even when the file has true angles: a bad option is an error
        lever_arm_mm=_option_or(meta, "lever_arm_mm", lever_arm_mm),
        lever_arm_sd_mm=_option_or(meta, "lever_arm_sd_mm", lever_arm_sd_mm),
        source_distance_mm=_option_or(meta, "source_distance_mm", source_distance_mm),
        source_distance_sd_mm=_option_or(meta, "source_distance_sd_mm", source_distance_sd_mm),
        mount_tilt_x_deg=_option_or(meta, "mount_tilt_x_deg", mount_tilt_x_deg) or 0.0,
        mount_tilt_y_deg=_option_or(meta, "mount_tilt_y_deg", mount_tilt_y_deg) or 0.0)
    stage = None if frames.stage is None else StageFrames(frames.stage[0], frames.stage[1], prior)
    data = frames.data
    try:
        calibration, outcome = _fit_and_report(
            data, method, {"physical": {"glass_index": glass_index, "fit_index": fit_index}}, design=design,
            stage=stage)
    except CalibrationError as exc:
        raise DataFileError(data_csv, str(exc), column=getattr(exc, "column", None)) from None
    if isinstance(calibration, PhysicalCalibration):
        out.print(physical_table(calibration))
    print_outcome(outcome, calibration.method)
    if given["pixel_pitch_mm"] is None:
        out.print(f"[yellow]note:[/] pixel pitch not given (--pixel-pitch-mm or '# pixel_pitch_mm: …' in the CSV); "
                  f"assumed seed 003's {DEFAULT_SENSOR.pixel_pitch_mm * 1000:g} µm — the gap and the glass scale "
                  "with it, the angles do not", highlight=False)
    out.print(f"{len(data)} frames from {escape(str(data_csv))}; method [bold]{calibration.method}[/]")
    document = calibration_document(calibration, sensor_id=data.sensor_id, source=str(data_csv),
                                    reports=outcome.reports, software=f"sunbench {_version()}", outcome=outcome,
                                    design=design)
    if output:
        write_calibration(output, document)
        out.print(f"calibration written to {escape(str(output))}")
    if header:
        _write_text(header, header_from_document(document, calibration))
        out.print(f"C header written to {escape(str(header))}")


#: Column heads of the dark-current parameters (calibration.qd.dark.DARK_PARAMETERS).
_DARK_HEADS = {"id0_a": "offset I_d0 [A]", "kd_a_per_c": "slope k_d [A/°C]", "a_a": "offset a [A]",
               "c_a": "scale c [A]", "b_per_c": "rate b [1/°C]"}


def qd_dark_table(dark) -> Table | None:
    """The dark-current fit per quadrant (seed 002 §2.1): each parameter ± 1σ and the residual."""
    from calibration.qd.dark import DARK_PARAMETERS

    names = DARK_PARAMETERS[dark.kind]
    if not names:
        return None
    lo, hi = dark.temperature_range_c
    model = {"linear": "I_d = I_d0 + k_d·t", "constant": "I_d = I_d0",
             "exponential": f"I_d = a + c·exp(b·(t − {dark.model.t_ref_c:g} °C))"}[dark.kind]
    table = Table(title=f"Dark current per quadrant (seed 002 §2.1): {dark.kind}, {model}; {dark.n_points} dark "
                        f"readings over {lo:.2f}…{hi:.2f} °C", title_justify="left")
    table.add_column("quadrant")
    for name in names:
        table.add_column(_DARK_HEADS.get(name, name), justify="right")
    table.add_column("residual SD [A]", justify="right")
    sd = dark.model.sd
    for k in range(4):
        cells = []
        for j in range(len(names)):
            value, sigma = dark.model.parameters[k, j], sd[k, j]
            cells.append(f"{value:.4e} ± {sigma:.2e}" if np.isfinite(sigma) else f"{value:.4e} ± —")
        resid = dark.model.residual_sd_a[k]
        table.add_row(f"Q{k + 1}", *cells, f"{resid:.2e}" if np.isfinite(resid) else "—")
    if dark.note:
        table.caption = escape(dark.note)
        table.caption_justify = "left"
    return table


def print_qd_outcome(outcome, frames: QdFrames, method: str) -> None:
    """The dark fit, the geometric model's correlations, the rejected rows (by CSV row) and the warnings."""
    from calibration.qd.geometric import CORRELATION_LIMIT

    data = frames.data
    dark_table = qd_dark_table(outcome.dark)
    if dark_table is not None:
        out.print(dark_table)
    else:
        out.print(f"dark current: {escape(outcome.dark.note)}", highlight=False)
    try:
        geometric = outcome.report("geometric")
    except KeyError:
        geometric = None
    if geometric is not None and geometric.model is not None:
        statements = geometric.details.get("statements") or []
        out.print("[bold]Geometric model (eq. 2.2), strong correlations:[/]" if statements else
                  f"Geometric model (eq. 2.2): no two parameters correlated beyond ±{CORRELATION_LIMIT:g}",
                  highlight=False)
        for statement in statements:
            out.print("  " + escape(statement), highlight=False, soft_wrap=True)
    scatter = outcome.repeat_scatter_share
    chi2 = outcome.report(method).chi2_dof
    out.print(f"{len(data)} readings ({int(data.dark.sum())} dark, {int(data.check.sum())} check) at "
              f"{len(outcome.directions)} directions; repeat scatter of a quadrant share "
              + (f"{scatter:.2e}" if scatter is not None else "unknown (no repeats)")
              + f"; {method}: χ²/dof = " + (fmt(chi2, 2) if chi2 is not None else "—"), highlight=False)
    if outcome.rejected:
        out.print(f"[bold]{len(outcome.rejected)} rejected row(s)[/] (left out of every fit):", highlight=False)
        for r in outcome.rejected:
            where = "" if np.isnan(r.alpha_deg) else f" (α {r.alpha_deg:.3f}°, β {r.beta_deg:.3f}°)"
            out.print(f"  {frames.where(r.row_id)}{where}: {escape(r.reason)}", highlight=False, soft_wrap=True)
    for w in outcome.warnings:
        out.print(f"[bold yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)


@fit_app.command("qd")
@user_errors
def fit_qd(
    data_csv: Path = typer.Argument(..., help="QD bench data CSV (see the README)."),
    method: Optional[str] = typer.Option(None, "--method", "-m", help=f"One of {', '.join(QD_METHODS)}; default: "
                                                                      "the fewest held-out points without a direction, "
                                                                      "then the smallest held-out max error."),
    output: Optional[Path] = typer.Option(None, "--output", "-o", help="Write the calibration JSON here."),
    header: Optional[Path] = typer.Option(None, "--header", help="Also write a C header for the sensor's MCU."),
    sensor: Optional[str] = typer.Option(None, "--sensor", help="Fit this sensor_id of a multi-sensor file."),
) -> None:
    """Fit a quadrant-photodiode (QD) sensor's calibration (seed 002): the dark current, then every method held
    out between the grid's nodes."""
    from calibration.qd.evaluation import calibrate_qd

    if method is not None and method not in QD_METHODS:
        raise CalibrationError(f"--method must be one of {', '.join(QD_METHODS)}, got {method!r}")
    frames = read_qd_frames(data_csv, sensor_id=sensor)
    data = frames.data
    try:
        with err.status("fitting the dark current and cross-validating every method…"):
            outcome = calibrate_qd(data, design=frames.design)
    except CalibrationError as exc:
        raise DataFileError(data_csv, str(exc), column=getattr(exc, "column", None)) from None
    chosen = outcome.chosen.method if method is None else method
    report = outcome.report(chosen)
    out.print(qd_metrics_table(outcome.reports, chosen))
    if report.document is None:
        raise DataFileError(data_csv, f"method {chosen} could not be fitted: {report.error}")
    print_qd_outcome(outcome, frames, chosen)
    out.print(f"{len(data)} readings from {escape(str(data_csv))}"
              + (f" (sensor {escape(data.sensor_id)})" if data.sensor_id else "") + f"; method [bold]{chosen}[/]"
              + ("" if method is None else f" (asked for; the best held out is {outcome.chosen.method})"),
              highlight=False)
    document = qd_calibration_file(report.document, source=str(data_csv), software=f"sunbench {_version()}",
                                   rejected=outcome.rejected, warnings=outcome.warnings)
    text = qd_header_from_document(document) if header else None  # a header that cannot be written: no file at all
    if output:
        write_calibration(output, document)
        out.print(f"calibration written to {escape(str(output))}")
    if header:
        _write_text(header, text)
        out.print(f"C header written to {escape(str(header))}")


def camera_accuracy_table(calibration) -> Table:
    """A camera calibration's figures: held out by whole zenith rings and by whole azimuths (each left out, the
    model refitted without it and its spots predicted), and the fit's at the nodes."""
    table = Table(title="Accuracy [°]: held out (whole zenith rings, whole azimuths left out) and at the nodes",
                  title_justify="left")
    for name in ("scheme", "groups", "spots", "RMS", "max"):
        table.add_column(name, justify="left" if name == "scheme" else "right")
    held = calibration.held_out
    if held is not None:
        for scheme in (held.rings, held.azimuths):
            worst = " *" if scheme is held.worst else ""
            table.add_row(f"{scheme.name} out{worst}", str(len(scheme.groups)), str(len(scheme.errors_deg)),
                          fmt(scheme.rms_deg, 4), fmt(scheme.max_deg, 4))
    fit = calibration.fit
    table.add_row("fit (at the nodes)", "—", str(len(fit.residual_deg)), fmt(fit.rms_deg, 4), fmt(fit.max_deg, 4))
    table.caption = "* = the worse held-out scheme (the calibration's held-out figure)"
    table.caption_justify = "left"
    return table


def camera_model_table(calibration) -> Table:
    """The fitted camera model (OpenCV's intrinsics, distortion and the rotation body → camera), each ± 1σ."""
    table = Table(title="Camera model (OpenCV): fitted parameters", title_justify="left")
    for name in ("parameter", "fitted", "± 1σ"):
        table.add_column(name, justify="left" if name == "parameter" else "right")
    model, sigma = calibration.model, calibration.fit.sigma
    values = {**{k: getattr(model, k) for k in ("fx_px", "fy_px", "cx_px", "cy_px", "k1", "k2", "p1", "p2", "k3")},
              **dict(zip(("rot_x_deg", "rot_y_deg", "rot_z_deg"), model.rotation_deg))}
    for name, value in values.items():
        sd = sigma.get(name)
        table.add_row(name, f"{value:.6g}", "fixed" if sd is None else f"{sd:.3g}")
    return table


@fit_app.command("camera")
@user_errors
def fit_camera(
    data_csv: Path = typer.Argument(..., help="Camera bench data CSV (see the README)."),
    output: Optional[Path] = typer.Option(None, "--output", "-o", help="Write the calibration JSON here."),
    header: Optional[Path] = typer.Option(None, "--header", help="Also write a C header for the sensor's processor."),
    sensor: Optional[str] = typer.Option(None, "--sensor", help="Fit this sensor_id of a multi-sensor file."),
    width_px: Optional[int] = typer.Option(None, help="Frame width [px] (default: the CSV's '# width_px:' comment, "
                                                      "else 640)."),
    height_px: Optional[int] = typer.Option(None, help="Frame height [px] (default: '# height_px:', else 480)."),
) -> None:
    """Fit a camera sun sensor's calibration (seed 001): OpenCV's camera model and its rotation against the body
    frame, scored held out by whole zenith rings and by whole azimuths."""
    from calibration.camera import calibrate_camera

    frames = read_camera_frames(data_csv, sensor_id=sensor, width_px=width_px, height_px=height_px)
    data = frames.data
    try:
        with err.status("fitting the camera model and leaving rings and azimuths out…"):
            calibration = calibrate_camera(data)
    except CalibrationError as exc:
        raise DataFileError(data_csv, str(exc), column=getattr(exc, "column", None)) from None
    out.print(camera_accuracy_table(calibration))
    out.print(camera_model_table(calibration))
    scatter, dof = data.repeat_scatter_px()
    fit = calibration.fit
    out.print(f"{len(data)} spots at {len(np.unique(np.round(np.c_[data.zenith_deg, data.azimuth_deg], 6), axis=0))}"
              f" directions; repeat scatter " + (f"{scatter:.4f} px per axis" if dof else "unknown (no repeats)")
              + f"; fit residual {fit.rms_px:.4f} px; χ²/dof = {fmt(fit.reduced_chi2, 2)}", highlight=False)
    for w in calibration.warnings:
        out.print(f"[bold yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)
    held = calibration.held_out
    out.print(f"{len(data)} spots from {escape(str(data_csv))}" + (f" (sensor {escape(data.sensor_id)})"
                                                                  if data.sensor_id else "")
              + f", frame {data.width_px}×{data.height_px} px"
              + ("" if held is None else f"; held out RMS {held.rms_deg:.4f}° ({held.worst.name} left out), max "
                                         f"{held.max_deg:.4f}°"), highlight=False)
    document = camera_calibration_document(calibration, source=str(data_csv), software=f"sunbench {_version()}")
    text = camera_header_from_document(document) if header else None  # a header that cannot be written: no file
    if output:
        write_calibration(output, document)
        out.print(f"calibration written to {escape(str(output))}")
    if header:
        _write_text(header, text)
        out.print(f"C header written to {escape(str(header))}")


def _sd(value, sd, digits: int = 4) -> str:
    """`value ± sd` in compact notation (a fixed parameter: `value (fixed)`)."""
    if value is None:
        return "—"
    text = f"{value:.{digits}g}"
    return text + (" (fixed)" if sd is None else f" ± {sd:.2g}" if np.isfinite(sd) else " ± —")


def css_diodes_table(document: dict) -> Table:
    """A CSS calibration's detectors: each fitted parameter ± 1σ (seed 000 eq. 3.1 with a response law), the normal
    as a body zenith and azimuth with its 1σ, the residual's χ²/dof against the noise; a faulty channel by its
    fault."""
    from calibration.css.diode import SHAPE_NAME

    law = document["response"]
    spline = law not in SHAPE_NAME
    shape = "spline" if spline else SHAPE_NAME[law]
    table = Table(title=f"Detectors ({law} law): m = S·(1 + c_T·ΔT)·R(n·s)·E(θ) + b + b_T·ΔT, ΔT = T − 25 °C; each "
                        "fitted parameter ± 1σ" + ("; R a cubic spline in cos θ on fixed knots, 0 beyond its last "
                                                  "(the field's edge)" if spline else ""), title_justify="left")
    heads = ("channel", "S [A|V]", "b [A|V]", "normal θ, φ [°]", "± [°]", "spline knots" if spline else shape,
             "field's edge [°]" if spline else "FOV θ_c [°]", "c_T [1/°C]", "b_T [A|V/°C]", "χ²/dof")
    for name in heads:
        table.add_column(name, justify="left" if name == "channel" else "right")
    for channel, entry in document["diodes"].items():
        if not entry["valid"]:
            table.add_row(channel, f"[red]left out: {escape(str(entry.get('fault')))}[/]", *[""] * (len(heads) - 2))
            continue
        p = entry["parameters"]
        cell = {name: _sd(v["value"], v["sd"] if v.get("fitted") else None, 4 if name in ("scale", "fov_half_deg")
                          else 3 if name in ("bias", shape) else 2) for name, v in p.items()}
        normal = entry["normal"]
        knots = entry.get("spline_knots_deg") or []
        table.add_row(channel, cell["scale"], cell["bias"], f"{normal['zenith_deg']:.3f}, {normal['azimuth_deg']:.3f}",
                      fmt(float("nan") if normal.get("sd_deg") is None else normal["sd_deg"], 3),
                      str(len(knots)) if spline else cell[shape],
                      f"{knots[-1]:g}" if spline and knots else
                      "none" if p["fov_half_deg"]["value"] is None else cell["fov_half_deg"],
                      cell["temp_coeff_per_c"], cell["bias_temp_coeff_per_c"],
                      fmt(float("nan") if entry["fit"]["chi2_dof"] is None else entry["fit"]["chi2_dof"], 1))
    return table


def css_accuracy_table(metrics: dict) -> Table:
    """The Sun's direction from a CSS calibration [°]: held out (interleaved folds of directions left out and
    refitted), at the check directions (never fitted) and at the fitted directions."""
    table = Table(title="The Sun's direction [°]: weighted least squares over the calibrated detectors",
                  title_justify="left")
    for name in ("scored", "readings", "degenerate", "RMS", "p95", "max", "RMS / stated 1σ"):
        table.add_column(name, justify="left" if name == "scored" else "right")
    for label, key in (("held out *", "held_out"), ("check directions", "check"), ("fitted directions", "at_nodes")):
        m = metrics.get(key)
        if not m:
            table.add_row(label, *["—"] * 6)
            continue
        num = lambda v, d=4: fmt(float("nan") if v is None else v, d)  # noqa: E731
        table.add_row(label, str(m["n_points"]), str(m["n_degenerate"]), num(m["rms_deg"]), num(m["p95_deg"]),
                      num(m["max_deg"]), num(m["normalised_rms"], 1))
    table.caption = ("* = the calibration's held-out figure; degenerate: fewer than two non-coplanar faces lit (the "
                     "direction is not determined, not scored)")
    table.caption_justify = "left"
    return table


@fit_app.command("css")
@user_errors
def fit_css_command(
    data_csv: Path = typer.Argument(..., help="CSS bench data CSV (see the README)."),
    output: Optional[Path] = typer.Option(None, "--output", "-o", help="Write the calibration JSON here."),
    response: Optional[str] = typer.Option(None, "--response", "-r", metavar="kelly|power|spline",
                                           help="Every detector's angular response law: kelly (Basilisk's cos·(1 − "
                                                "e^(−cos²/κ))), power (cos^p) or spline (a cubic spline in cos θ on "
                                                "fixed knots, its end the field's cut-off). Default: kelly and spline "
                                                "both fitted, the better held out kept."),
    header: Optional[Path] = typer.Option(None, "--header", help="Also write a C header for the head's MCU."),
    sensor: Optional[str] = typer.Option(None, "--sensor", "--sensor-id",
                                         help="Fit this sensor_id of a multi-sensor file."),
    json_out: Optional[Path] = typer.Option(None, "--json", help="Also write the fit's figures as JSON here."),
) -> None:
    """Fit a coarse-sun-sensor head's calibration (seed 000): every detector's scale, offset, normal, response and
    temperature coefficients, and the Sun's direction scored held out. Without --response the Kelly law and the
    spline are both fitted and the one with the smaller held-out error of the Sun's direction is written."""
    import json

    from calibration.css.diode import RESPONSES

    from .css_datafile import (
        DEFAULT_CSS_LAWS,
        css_calibration_file,
        css_metrics,
        fit_css_laws,
        rank_css_fits,
        read_css_frames,
    )

    if response is not None and response not in RESPONSES:
        raise CalibrationError(f"--response must be {', '.join(RESPONSES[:-1])} or {RESPONSES[-1]}, got {response!r}")
    frames = read_css_frames(data_csv, sensor_id=sensor)
    data = frames.data
    laws = DEFAULT_CSS_LAWS if response is None else (response,)
    try:
        with err.status("fitting every detector and leaving directions out…"):
            outcomes = fit_css_laws(data, laws)
    except CalibrationError as exc:
        raise DataFileError(data_csv, str(exc), column=getattr(exc, "column", None)) from None
    outcome = rank_css_fits(outcomes)[0]
    response = outcome.response
    document = css_calibration_file(outcome, source=str(data_csv), software=f"sunbench {_version()}")
    metrics = css_metrics(outcome)
    out.print(css_diodes_table(document))
    out.print(css_accuracy_table(metrics))
    if outcome.rejected:
        out.print(f"[bold]{len(outcome.rejected)} rejected reading(s)[/] (left out of the fit and the scores):",
                  highlight=False)
        for r in outcome.rejected:
            where = "" if not np.isfinite(r.zenith_deg) else (f" (zenith {r.zenith_deg:.2f}°, azimuth "
                                                               f"{r.azimuth_deg:.2f}°)")
            out.print(f"  {frames.where(r.row_id)}{where}: {escape((r.channel or 'every channel') + ' ' + r.reason)}",
                      highlight=False, soft_wrap=True)
    for w in outcome.warnings:
        out.print(f"[bold yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)
    out.print(f"{len(data)} readings ({int(data.dark.sum())} dark, {int(data.check.sum())} check) of "
              f"{len(data.channels)} detector(s) from {escape(str(data_csv))}"
              + (f" (sensor {escape(data.sensor_id)})" if data.sensor_id else "")
              + f"; {len(outcome.valid_channels)} calibrated, {response} law", highlight=False)
    if len(outcomes) > 1:
        held = lambda o: "—" if o.sun_heldout is None else f"{o.sun_heldout.rms_deg:.4f}°"  # noqa: E731
        out.print("response laws fitted: " + ", ".join(f"{o.response} (held-out RMS {held(o)})" for o in outcomes)
                  + f"; the {response} law kept (the smaller held-out error of the Sun's direction, a near tie going "
                    "to the law with fewer parameters)", highlight=False)
    text = css_header_from_document(document) if header else None  # a header that cannot be written: no file at all
    if output:
        write_calibration(output, document)
        out.print(f"calibration written to {escape(str(output))}")
    if header:
        _write_text(header, text)
        out.print(f"C header written to {escape(str(header))}")
    if json_out:
        figures = {"source": str(data_csv), "sensor_id": data.sensor_id, "metrics": metrics,
                   "diodes": document["diodes"], "warnings": document["warnings"], "rejected": document["rejected"]}
        _write_text(json_out, json.dumps(figures, indent=2) + "\n")
        out.print(f"figures written to {escape(str(json_out))}")


@fit_app.command("horizon")
@user_errors
def fit_horizon_command(
    data_csv: Path = typer.Argument(..., help="Horizon bench data CSV (see the README)."),
    output: Optional[Path] = typer.Option(None, "--output", "-o", help="Write the calibration JSON here."),
    header: Optional[Path] = typer.Option(None, "--header", help="Also write a C header for the sensor's MCU."),
    sensor: Optional[str] = typer.Option(None, "--sensor", "--sensor-id",
                                         help="Fit this sensor_id of a multi-sensor file."),
) -> None:
    """Fit a scanning horizon sensor's own errors (seed 004): each cone's half-angle and phase offset, the threshold
    bias of the disc radius and the mount's roll and yaw on the table, ± 1σ, with roll and pitch scored at the check
    points and with each disc radius left out."""
    from .horizon_datafile import fit_horizon, horizon_calibration_file, read_horizon_frames

    frames = read_horizon_frames(data_csv, sensor_id=sensor)
    data = frames.data
    try:
        with err.status("fitting the crossing model and leaving disc radii out…"):
            fit = fit_horizon(data)
    except CalibrationError as exc:
        raise DataFileError(data_csv, str(exc), column=getattr(exc, "column", None)) from None
    document = horizon_calibration_file(fit, source=str(data_csv), software=f"sunbench {_version()}")
    out.print(horizon_parameters_table(document))
    out.print(f"χ²/dof {fit.chi2_dof:.2f} against the repeat scatter ({fit.noise.source}); condition number "
              f"{fit.condition_number:.3g}; phase residual RMS {fit.rms_deg:.4f}° over {fit.n_edges} edges",
              highlight=False)
    out.print(horizon_accuracy_table(fit.heldout))
    if fit.rejected:
        out.print(f"[bold]{len(fit.rejected)} rejected edge(s)[/] (left out of the fit):", highlight=False)
        for r in fit.rejected:
            out.print(f"  {frames.where(r.row_id)}: {escape(r.describe())}", highlight=False, soft_wrap=True)
    for w in fit.warnings:
        out.print(f"[bold yellow]warning:[/] {escape(w)}", highlight=False, soft_wrap=True)
    out.print(f"{fit.n_scans} scans ({len(data)} rows, {int(data.check.sum())} check rows) at disc radii "
              f"{', '.join(f'{r:.3f}°' for r in fit.radii_deg)} from {escape(str(data_csv))}"
              + (f" (sensor {escape(data.sensor_id)})" if data.sensor_id else ""), highlight=False)
    text = horizon_header_from_document(document) if header else None
    if output:
        write_calibration(output, document)
        out.print(f"calibration written to {escape(str(output))}")
    if header:
        _write_text(header, text)
        out.print(f"C header written to {escape(str(header))}")


def _write_text(path: Path, text: str) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)


@commands.command("apply")
@user_errors
def apply_calibration(
    calibration_json: Path = typer.Argument(..., help="Calibration JSON written by `sunbench fit`."),
    spots_csv: Path = typer.Argument(..., help="CSV with x_px, y_px columns (a CMOS or camera calibration; a QD "
                                               "calibration: i1_a … i4_a, temperature_c; a CSS calibration: its "
                                               "detector columns px_uv_a … mz_ir_v, temperature_c)."),
    output: Path = typer.Option(..., "--output", "-o", help="Output CSV: the input columns + zenith_deg, azimuth_deg "
                                                            "(QD: alpha_deg, beta_deg first, error_deg last; CSS: "
                                                            "sigma_deg, faces_lit, error_deg after them)."),
) -> None:
    """Turn spot centres (or a QD sensor's currents, a CSS head's readings) into sun directions with a fitted
    calibration."""
    document = load_calibration_json(calibration_json)
    if is_qd_document(document):
        _apply_qd(calibration_json, spots_csv, output)
        return
    if is_css_document(document):
        _apply_css(calibration_json, spots_csv, output)
        return
    if is_horizon_document(document):
        _apply_horizon(calibration_json, spots_csv, output)
        return
    if is_camera_document(document):
        _apply_camera(calibration_json, spots_csv, output)
        return
    calibration, _ = read_calibration(calibration_json)
    table, x, y = read_spots_csv(spots_csv)
    zenith, azimuth = calibration.apply(x, y)
    write_applied_csv(output, table, zenith, azimuth)
    out.print(f"{len(x)} directions written to {escape(str(output))} (method {calibration.method})")


def _apply_camera(calibration_json: Path, spots_csv: Path, output: Path) -> None:
    """`apply` with a camera calibration: each row's spot through OpenCV's model to its zenith and azimuth in the
    body frame (seed 001 eqs. 4–7 with the calibrated camera)."""
    from calibration.camera import zenith_azimuth

    model, document = read_camera_calibration(calibration_json)
    table, x, y = read_spots_csv(spots_csv)
    zenith, azimuth = zenith_azimuth(model, np.column_stack([x, y]))
    write_applied_csv(output, table, zenith, azimuth)
    out.print(f"{len(x)} directions written to {escape(str(output))} (camera model of "
              f"{escape(str(document.get('sensor_id') or 'an unnamed sensor'))})", highlight=False)


def _apply_qd(calibration_json: Path, readings_csv: Path, output: Path) -> None:
    """`apply` with a QD calibration: α, β, zenith, azimuth per row, and the angular error where the file has the
    true direction (seed 002 §2.1, eqs. 2.1–2.3, through the document alone)."""
    from calibration.qd.document import apply_document

    document = read_qd_calibration(calibration_json)
    readings = read_qd_readings(readings_csv)
    alpha, beta, zenith, azimuth = apply_document(document, readings.currents_a, readings.temperature_c)
    alpha, beta, zenith, azimuth = (np.where(readings.dark, np.nan, v) for v in (alpha, beta, zenith, azimuth))
    error = angular_errors_deg(readings, alpha, beta) if readings.has_truth else None
    write_qd_applied_csv(output, readings, alpha, beta, zenith, azimuth, error)
    found = np.isfinite(alpha) & np.isfinite(beta)
    none = int((~found & ~readings.dark).sum())
    out.print(f"{int(found.sum())} directions written to {escape(str(output))} (QD method {document['method']})"
              + (f"; {int(readings.dark.sum())} dark row(s) left without one" if readings.dark.any() else "")
              + (f"; no direction for {none} lit row(s) (no light, or the spot off the QD's centre)" if none else ""),
              highlight=False)
    if error is not None and np.isfinite(error).any():
        e = error[np.isfinite(error)]
        out.print(f"angular error against the file's directions: max {e.max():.4f}°, RMS {np.sqrt(np.mean(e**2)):.4f}° "
                  f"over {e.size} row(s)", highlight=False)
    sensor = document.get("sensor_id")
    if sensor and readings.sensor_ids and readings.sensor_ids != [sensor]:
        out.print(f"[yellow]note:[/] the calibration is of sensor {escape(sensor)}, the readings of "
                  f"{escape(', '.join(readings.sensor_ids))}", highlight=False)


def _apply_css(calibration_json: Path, readings_csv: Path, output: Path) -> None:
    """`apply` with a CSS calibration: each row's Sun direction from its detectors' readings and temperature, its 1σ
    and the faces lit, and the angle to the file's true direction where it has one (the document alone)."""
    from .css_datafile import apply_css, read_css_calibration, read_css_readings, write_css_applied_csv

    document = read_css_calibration(calibration_json)
    readings = read_css_readings(readings_csv)
    applied = apply_css(document, readings)
    write_css_applied_csv(output, readings, applied)
    lit = ~readings.dark
    none = int((lit & ~applied.determined).sum())
    out.print(f"{int(applied.determined.sum())} directions written to {escape(str(output))} (CSS head, "
              f"{document['response']} law)"
              + (f"; {int(readings.dark.sum())} dark row(s) left without one" if readings.dark.any() else "")
              + (f"; no direction for {none} lit row(s) (fewer than two non-coplanar faces lit)" if none else ""),
              highlight=False, soft_wrap=True)
    if applied.determined.any():
        sigma = applied.sigma_deg[applied.determined]
        out.print(f"stated 1σ: median {np.median(sigma):.4f}°, max {np.max(sigma):.4f}°", highlight=False)
    error = applied.error_deg
    if error is not None and np.isfinite(error).any():
        e = error[np.isfinite(error)]
        out.print(f"angular error against the file's directions: RMS {np.sqrt(np.mean(e**2)):.4f}°, p95 "
                  f"{np.percentile(e, 95):.4f}°, max {e.max():.4f}° over {e.size} row(s)", highlight=False)
    sensor = document.get("sensor_id")
    if sensor and readings.sensor_ids and readings.sensor_ids != [sensor]:
        out.print(f"[yellow]note:[/] the calibration is of sensor {escape(sensor)}, the readings of "
                  f"{escape(', '.join(readings.sensor_ids))}", highlight=False)


def _apply_horizon(calibration_json: Path, readings_csv: Path, output: Path) -> None:
    """`apply` with a horizon calibration: each scan's roll and pitch in the sensor's own frame from its crossings
    (seed 004 eq. 2.7 with the calibrated γ_k, o_k and Δρ) and, where the file gives the table's angles, the error
    against them through the calibrated mount."""
    from .horizon_datafile import apply_horizon, read_horizon_frames, write_horizon_applied_csv

    document = read_horizon_calibration(calibration_json)
    frames = read_horizon_frames(readings_csv)
    roll, pitch, error = apply_horizon(document, frames)
    write_horizon_applied_csv(output, readings_csv, roll, pitch, error)
    solved = np.isfinite(roll)
    out.print(f"{int(np.unique(frames.data.scan[solved]).size)} scans' roll and pitch written to {escape(str(output))}"
              + (f"; {int(np.unique(frames.data.scan[~solved]).size)} scan(s) without a solution (fewer than two "
                 "edges)" if (~solved).any() else ""), highlight=False)
    e = error[np.isfinite(error[:, 0])]
    if e.size:
        out.print(f"against the table: roll RMS {np.sqrt(np.mean(e[:, 0] ** 2)):.4f}°, pitch RMS "
                  f"{np.sqrt(np.mean(e[:, 1] ** 2)):.4f}°", highlight=False)


@commands.command("header")
@user_errors
def export_header(
    calibration_json: Path = typer.Argument(..., help="Calibration JSON written by `sunbench fit`."),
    output: Path = typer.Option(..., "--output", "-o", help="C header to write."),
) -> None:
    """Export a calibration as a C header with `sunbench_sun_direction()` (QD: `sunbench_qd_sun_direction()`)
    for the sensor's MCU."""
    document = load_calibration_json(calibration_json)
    if is_qd_document(document):
        text = qd_header_from_document(read_qd_calibration(calibration_json))
    elif is_css_document(document):
        text = css_header_from_document(read_css_calibration(calibration_json))
    elif is_horizon_document(document):
        text = horizon_header_from_document(read_horizon_calibration(calibration_json))
    elif is_camera_document(document):
        text = camera_header_from_document(read_camera_calibration(calibration_json)[1])
    else:
        calibration, document = read_calibration(calibration_json)
        text = header_from_document(document, calibration)
    _write_text(output, text)
    out.print(f"C header written to {escape(str(output))}")


@commands.command("demo")
@user_errors
def demo(
    seed: int = typer.Option(1, help="Seed of the simulated centroid noise."),
    noise_px: float = typer.Option(0.02, help="Centroid noise, one sigma per axis [px]."),
    output_dir: Optional[Path] = typer.Option(None, "--out", help="Also save the bench data CSV, the "
                                                                 "calibration JSON and the C header here."),
) -> None:
    """Simulate a seed 003 calibration run of a sensor with known build errors and fit it."""
    truth = EXAMPLE_BUILD
    data = synthetic_bench_data(truth, noise_px=noise_px, seed=seed)
    out.print(f"Simulated sensor {data.sensor_id}: pinhole at ({truth.x0_px}, {truth.y0_px}) px, air gap "
              f"{truth.gap_mm} mm over {truth.glass_mm} mm of glass (n = {truth.glass_index}), detector tilt "
              f"α = {truth.tilt_x_deg}°, β = {truth.tilt_y_deg}°, rotation {truth.rotation_deg}°; "
              f"seed 003 grid, {len(data)} frames, centroid noise {noise_px} px.")
    calibration, outcome = _fit_and_report(data, None)
    if isinstance(calibration, PhysicalCalibration):
        out.print(physical_table(calibration, truth))
    print_outcome(outcome, calibration.method)
    if output_dir:
        write_bench_csv(output_dir / "bench-data.csv", data)
        document = calibration_document(calibration, sensor_id=data.sensor_id, source="sunbench demo",
                                        reports=outcome.reports, software=f"sunbench {_version()}",
                                        outcome=outcome, design=DEFAULT_SENSOR)
        write_calibration(output_dir / "calibration.json", document)
        _write_text(output_dir / "calibration.h", header_from_document(document, calibration))
        out.print(f"bench data, calibration and C header written to {escape(str(output_dir))}/")


#: How other people's software reaches each kind of simulated device (research/peer-clients.md, the peer tests
#: in tests/peers/): kind → (client, how). "{url}", "{host}", "{port}" are the device's TCP address; "{pty}" is
#: a pseudo-terminal, for a client that opens a serial port by path (`sunbench sim --pty`).
CLIENT_HINTS: dict[str, tuple[tuple[str, str], ...]] = {
    "apt": (("pylablib", 'Thorlabs.KinesisMotor(("serial", "{url}"), scale="K10CR1")'),
            ("QMI", 'qmi.make_instrument("k10cr1", Thorlabs_K10CR1, "serial:{pty}")'),  # a serial transport only
            ("thorlabs-apt-device", 'APTDevice_Motor(serial_port="{pty}", controller=EndPoint.USB, '
                                    'bays=(EndPoint.USB,), channels=(1,))')),
    "smc100": (("QMI", 'qmi.make_instrument("smc", Newport_SMC100CC, "tcp:{host}:{port}", "SIM", '
                       '{{1: LinearActuator(...)}})'),
               ("pystages", 'SMC100("{pty}", [1])')),
    "lx200": (("INDI", "indi_lx200autostar, CONNECTION_MODE TCP, DEVICE_ADDRESS {host}:{port}"),),
    "lamp": (("lantz-drivers", "Newport69907 on the serial port {pty}"),),
    "shutter": (("InstrumentKit", 'ik.thorlabs.SC10.open_tcpip("{host}", {port}), prompt "> "'),),
    "led": (("PyVISA", 'TCPIP0::{host}::{port}::SOCKET, read and write termination "\\n"'),),
    "earth": (("PyVISA", 'TCPIP0::{host}::{port}::SOCKET, read and write termination "\\n" (SCPI-style: *IDN?, '
                         'IRIS 66.5, HEAT ON, COV OPEN, STAT?)'),
              ("sunbench", 'EarthSimulatorSource(open_port("{url}"))'),),
    "sensor-cmos": (("sunbench", 'CmosSunSensor(open_port("{url}"))'),),
    "sensor-qd": (("sunbench", 'QdSunSensor(open_port("{url}"))'),),
    "sensor-css": (("sunbench", 'CssHead(open_port("{url}"))'),),
    "sensor-horizon": (("sunbench", 'HorizonSensorModule(open_port("{url}"))'),),
}


def client_hints(kind: str, url: str, pty: str | None) -> list[str]:
    """`client: how` for each known client of a device of `kind` served at `url` (and on `pty`, if any)."""
    host, port = url.removeprefix("socket://").rsplit(":", 1)
    lines = []
    for client, how in CLIENT_HINTS.get(kind, ()):
        text = how.format(url=url, host=host, port=port, pty=pty or "PTY")
        if "{pty}" in how and pty is None:
            text += "  (a serial port by path: add --pty)"
        lines.append(f"{client}: {text}")
    return lines


def _stop_on_signals() -> None:
    """Ctrl-C stops the servers, whatever this process inherited: a shell starts a background job with SIGINT
    ignored, and Python then never raises KeyboardInterrupt (a CI runner's `cmd &` did); a SIGTERM stops them too."""
    import signal

    def stop(signum, frame):
        raise KeyboardInterrupt

    signal.signal(signal.SIGINT, signal.default_int_handler)
    signal.signal(signal.SIGTERM, stop)


@commands.command("sim")
@user_errors
def serve_simulators(
    config: Optional[Path] = typer.Option(None, "--config", "-c", help="Bench YAML file (its `simulation:` "
                                                                     "section); default: the simulated bench of "
                                                                     "examples/bench-sim.yaml."),
    table: Optional[str] = typer.Option(None, "--table", metavar="apt|smc100|lx200",
                                        help="The simulated table (overrides the bench file's)."),
    source: Optional[str] = typer.Option(None, "--source", metavar="xenon|led|earth",
                                         help="The simulated sun simulator (overrides the bench file's)."),
    axis_order: Optional[str] = typer.Option(None, "--axis-order", metavar="azimuth-on-zenith|zenith-on-azimuth",
                                             help="Which stage rides on which (overrides the bench file's)."),
    host: str = typer.Option("127.0.0.1", help="Interface to listen on."),
    port: int = typer.Option(0, help="First TCP port (devices get consecutive ports); 0 = any free ports."),
    time_scale: Optional[float] = typer.Option(None, "--time-scale", min=0.0, max=1000.0,
                                               help="Override the simulated clock (0 = instant)."),
    pty: bool = typer.Option(False, "--pty", help="Also serve every device on a pseudo-terminal, for clients "
                                                  "that open a serial port by path (use one link at a time)."),
    indi_compatible: bool = typer.Option(False, "--indi-compatible",
                                         help="The LX200 answers :MA#, :Sa and :h?# as INDI expects, not as the Meade "
                                              "manual says (the bench file's simulation.lx200.indi_compatible)."),
) -> None:
    """Serve every simulated device of the bench on a TCP port; print each one's URL and how known clients
    connect to it."""
    import time
    import typing

    from pydantic import ValidationError

    from drivers.sim.bench import SimBench, SimBenchConfig

    bench_file = load_bench_file(config) if config else BenchFile()
    sim = bench_file.simulation
    if sim is None:
        raise BenchFileError(f"{config}: no simulation: section to serve")
    overrides = {"table": table, "source": source, "axis_order": axis_order}
    for field, value in overrides.items():
        allowed = typing.get_args(SimBenchConfig.model_fields[field].annotation)
        if value is not None and value not in allowed:
            raise BenchFileError(f"--{field.replace('_', '-')} must be one of {', '.join(allowed)}, got {value!r}")
    try:
        sim = SimBenchConfig.model_validate({**sim.model_dump(), **{k: v for k, v in overrides.items() if v}})
    except ValidationError as exc:  # an override that does not fit the rest of the bench
        problems = "; ".join(e["msg"].removeprefix("Value error, ") for e in exc.errors())
        raise BenchFileError(f"{config or 'the default bench'} with the overrides: {problems}") from None
    if indi_compatible:
        if sim.table != "lx200":
            raise BenchFileError(f"--indi-compatible applies to the lx200 table, not {sim.table} (--table lx200)")
        sim = sim.model_copy(update={"lx200": sim.lx200.model_copy(update={"indi_compatible": True})})
    bench = SimBench(sim, time_scale=time_scale)
    _stop_on_signals()
    server = bench.serve(host=host, base_port=port)
    bridges = {}
    try:
        if pty:
            from drivers.sim.pty_bridge import PtyBridge
            bridges = {role: PtyBridge(device).start() for role, device in bench.devices.items()}
        serial = {"qd": sim.qd.serial, "camera": sim.camera.serial, "css": sim.css.serial,
                  "horizon": sim.horizon.serial}.get(sim.family, sim.sensor.serial)
        out.print(f"simulated bench: {sim.table} table, {sim.source} source, {sim.axis_order}, {sim.family} sensor "
                  f"{serial}, time scale {bench.time_scale:g}", highlight=False)
        for role, url in server.urls.items():
            print(f"{role:14s} {url}", flush=True)  # `role url`: what scripts parse
            path = bridges[role].path if role in bridges else None
            if path:
                print(f"{'':15s}pty: {path}", flush=True)
            kind = sim.table if role.startswith("table") else f"sensor-{sim.family}" if role == "sensor" else role
            for line in client_hints(kind, url, path):
                print(f"{'':15s}{line}", flush=True)
        if bench.camera is not None:
            print("(the simulated camera is in-process only, served on no port: a USB camera's wire is UVC, which the "
                  "kernel and OpenCV own; `sunbench run` and `serve` with this bench file use it)", flush=True)
        print("serving; Ctrl-C to stop", flush=True)
        while True:
            time.sleep(0.5)
    except KeyboardInterrupt:
        pass
    finally:
        for bridge in bridges.values():
            bridge.close()
        server.stop()
