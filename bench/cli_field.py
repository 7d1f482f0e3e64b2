"""`sunbench field sunpos | record | simulate | compare | locate`: the real Sun as reference (seed 003 §5, seed 001).

`sunpos` prints SPA's apparent position; `record` reads a real sensor outdoors, `simulate` a simulated field day of
a sensor, both through its driver (:mod:`bench.field_run`, :mod:`drivers.sim.field`); `compare` sets a field CSV's
readings against SPA; `locate` finds the site and the heading from the Sun's track. Bad input ends in one stderr
line and exit code 2 (`cli_common.user_errors`).
"""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Optional

import numpy as np
import typer
from rich.markup import escape
from rich.table import Table

from calibration.errors import FieldDataError
from calibration.field.sky import Atmosphere, Site, sun_position, utc_seconds

from .cli_common import out, user_errors

field_app = typer.Typer(help="The real Sun as the reference: solar position, field runs, comparison, position.",
                        no_args_is_help=True)

#: Seed 003's field day (§5): the roof of an NSU building in Novosibirsk, 29 September 2019, 10:58:17 to
#: 16:24:45 local time (UTC+7; the thesis does not give the zone, Novosibirsk has kept UTC+7 since 2016).
SEED003_SITE = Site(54.8437, 83.0930, 160.0)
SEED003_START = "2019-09-29T03:58:17Z"
SEED003_HOURS = 5.4411  # to 16:24:45
#: TT − UT of the simulated sky [s] (the measured value around 2013–2019), written in the file's header
SIMULATED_DELTA_T_S = 69.0


def register(app: typer.Typer) -> None:
    """Add `field` and its commands to `app`."""
    app.add_typer(field_app, name="field")


@field_app.command("sunpos")
@user_errors
def sunpos(
    time: str = typer.Option(..., "--time", help="ISO 8601 time; no zone means UTC (2003-10-17T12:30:30-07:00)."),
    lat: float = typer.Option(..., "--lat", help="Latitude, north positive [°]."),
    lon: float = typer.Option(..., "--lon", help="Longitude, east positive [°]."),
    alt: float = typer.Option(0.0, "--alt", help="Height above sea level [m]."),
    pressure: float = typer.Option(1013.25, "--pressure", help="Station pressure [hPa] (refraction)."),
    temperature: float = typer.Option(12.0, "--temperature", help="Air temperature [°C] (refraction)."),
    delta_t: Optional[float] = typer.Option(None, "--delta-t", help="TT − UT [s] (default: pvlib's estimate)."),
) -> None:
    """The Sun's apparent zenith and azimuth (east of north) by NREL SPA, in degrees."""
    site = Site(lat, lon, alt)
    atmosphere = Atmosphere(pressure, temperature, delta_t)
    position = sun_position([time], site, atmosphere)
    out.print(f"apparent zenith {position.apparent_zenith_deg[0]:.5f}°  azimuth {position.azimuth_deg[0]:.5f}°  "
              f"(geometric zenith {position.zenith_deg[0]:.5f}°; SPA, {escape(time)} at {lat:.6f}, {lon:.6f}, "
              f"{alt:g} m, {pressure:g} hPa, {temperature:g} °C)", highlight=False)


@field_app.command("simulate")
@user_errors
def simulate(
    output: Path = typer.Option(..., "-o", "--output", help="Field CSV to write."),
    bench: Optional[Path] = typer.Option(None, "--bench", "-b", help="Simulated bench file whose sensor goes "
                                                                     "outdoors (default: the built-in one)."),
    serial: Optional[str] = typer.Option(None, "--serial", help="Which sensor of a simulated fleet."),
    start: str = typer.Option(SEED003_START, "--start", help="UTC start (default: seed 003's field day)."),
    hours: float = typer.Option(SEED003_HOURS, "--hours", min=0.01, max=24.0, help="Duration [h]."),
    interval: float = typer.Option(30.0, "--interval", min=0.1, max=3600.0, help="Between readings [s]."),
    lat: float = typer.Option(SEED003_SITE.latitude_deg, "--lat", help="Site latitude [°]."),
    lon: float = typer.Option(SEED003_SITE.longitude_deg, "--lon", help="Site longitude [°]."),
    alt: float = typer.Option(SEED003_SITE.altitude_m, "--alt", help="Site height [m]."),
    heading: float = typer.Option(12.0, "--heading", help="True heading of the sensor's +x axis [°]."),
    roll: float = typer.Option(0.02, "--roll", help="True roll of the mount [°]."),
    pitch: float = typer.Option(-0.03, "--pitch", help="True pitch of the mount [°]."),
    compass_error: float = typer.Option(3.0, "--compass-error", min=0.0,
                                        help="1σ of the heading written in the file (a household compass) [°]."),
    clouds: str = typer.Option("seed003", "--clouds", help="'seed003' (clear, then clouds after local noon), "
                                                          "'none', or banks per hour (a number)."),
    pressure: float = typer.Option(1000.0, "--pressure", help="Station pressure [hPa]."),
    temperature: float = typer.Option(12.0, "--temperature", help="Air temperature [°C]."),
    seed: int = typer.Option(3, "--seed", help="Seed of the clouds, the compass and the sensor's noise."),
    truth: Optional[Path] = typer.Option(None, "--truth", help="Also write what the field really was (JSON)."),
) -> None:
    """Record a simulated field day of a simulated sensor (the bench's CMOS module through its driver, or its camera);
    the header says what an operator would know: the site, the mount's level by an inclinometer (to 0.1°) and a
    compass heading."""
    from drivers.sim.field import field_world
    from drivers.sim.sky import SimulatedMount, SimulatedSky

    from .field_run import record_field
    from .field_sim import cloud_banks, field_sensor, sensor_world

    site = Site(lat, lon, alt)
    atmosphere = Atmosphere(pressure, temperature, SIMULATED_DELTA_T_S)  # refuse impossible air before anything runs
    start_s = float(utc_seconds([start])[0])
    rng = np.random.default_rng(seed)
    banks, haze = cloud_banks(clouds, start_s, start_s + hours * 3600.0, rng)
    sky = SimulatedSky(site.latitude_deg, site.longitude_deg, site.altitude_m, pressure_hpa=atmosphere.pressure_hpa,
                       temperature_c=atmosphere.temperature_c, delta_t_s=SIMULATED_DELTA_T_S, haze=haze, clouds=banks)
    mount = SimulatedMount(heading, roll, pitch)
    base, family, sensor_truth = sensor_world(bench, serial)
    world = field_world(sky, mount, start_s, base=base)
    offsets = np.arange(0.0, hours * 3600.0 + 1e-9, interval)
    with field_sensor(family, world, sensor_truth) as (sensor, read, full_scale):
        with out.status("recording the simulated field") as status:
            record = record_field(sensor, read, offsets_s=offsets, start_utc_s=start_s,
                                  wait_until=world.clock.advance_to, full_scale_dn=full_scale,
                                  progress=lambda i, n: status.update(f"reading {i}/{n}"))
    compass = round(heading + rng.normal(0.0, compass_error)) if compass_error > 0 else heading
    # the level as an inclinometer on the sensor reads it, to 0.1° (a level mount reads 0; a bracket tilted toward
    # the Sun, as seed 001's camera sat, reads its tilt)
    inclinometer = {"roll_deg": round(roll, 1) + 0.0, "pitch_deg": round(pitch, 1) + 0.0}
    from .field_datafile import write_field_csv
    write_field_csv(output, record.columns, metadata={
        "latitude_deg": site.latitude_deg, "longitude_deg": site.longitude_deg, "altitude_m": site.altitude_m,
        "heading_deg": compass, **inclinometer, "pressure_hpa": pressure, "temperature_c": temperature,
        "delta_t_s": SIMULATED_DELTA_T_S})
    ok = sum(s == "ok" for s in record.columns["status"])
    level = ("is level" if not any(inclinometer.values()) else
             f"is tilted roll {inclinometer['roll_deg']:g}°, pitch {inclinometer['pitch_deg']:g}° (an inclinometer)")
    out.print(f"{len(record)} readings ({ok} with a spot) written to {escape(str(output))}; the header says the "
              f"mount {level} and heads {compass:g}° (a compass), the truth is {heading:g}°, roll {roll:g}°, "
              f"pitch {pitch:g}°", highlight=False)
    if truth is not None:
        truth.parent.mkdir(parents=True, exist_ok=True)
        truth.write_text(json.dumps({
            "site": {"latitude_deg": lat, "longitude_deg": lon, "altitude_m": alt},
            "mount": {"heading_deg": heading, "roll_deg": roll, "pitch_deg": pitch},
            "sensor": {"family": family, "serial": (sensor_truth or world.sensor).serial},
            # per reading: the fraction of the disc behind a cloud, and the haze's and the cloud's transmission
            "clouds": [[round(c.covered_fraction(), 4), c.transmission, c.cloud_transmission]
                       for c in (world.sky.cloud_state(t) for t in start_s + offsets)],
        }, indent=1) + "\n")


@field_app.command("record")
@user_errors
def record(
    output: Path = typer.Option(..., "-o", "--output", help="Field CSV to write."),
    kind: str = typer.Option(..., "--kind", help="The sensor: cmos (a CMOS module on a serial port) or camera "
                                                 "(a camera OpenCV opens)."),
    port: str = typer.Option(..., "--port", help="cmos: the port URL (/dev/ttyUSB0, socket://host:port, sim://NAME); "
                                                 "camera: the OpenCV source (0, /dev/video0, a file)."),
    hours: float = typer.Option(2.0, "--hours", min=1e-4, max=24.0, help="Duration [h]."),
    interval: float = typer.Option(10.0, "--interval", min=0.05, max=3600.0, help="Between readings [s]."),
    exposure: float = typer.Option(1.0, "--exposure", min=0.01, max=1000.0, help="First exposure [ms]."),
    lat: Optional[float] = typer.Option(None, "--lat", help="Site latitude [°] (written in the header)."),
    lon: Optional[float] = typer.Option(None, "--lon", help="Site longitude [°]."),
    alt: Optional[float] = typer.Option(None, "--alt", help="Site height [m]."),
    heading: Optional[float] = typer.Option(None, "--heading", help="Heading of the sensor's +x axis [°], if known."),
    roll: Optional[float] = typer.Option(None, "--roll", help="Mount roll from an inclinometer [°]."),
    pitch: Optional[float] = typer.Option(None, "--pitch", help="Mount pitch from an inclinometer [°]."),
    pressure: Optional[float] = typer.Option(None, "--pressure", help="Station pressure [hPa]."),
    temperature: Optional[float] = typer.Option(None, "--temperature", help="Air temperature [°C]."),
) -> None:
    """Record a field run of a real sensor: a reading every --interval seconds, stamped in UTC by this computer's
    clock (keep it synchronised: 1 s of clock error is 0.004° of the Sun's motion), the exposure following the
    Sun. The rows are written as they come, so a run cut short keeps what it read."""
    import time as _time

    from .field_datafile import FieldCsvAppender
    from .field_run import COLUMNS, FieldRecord, record_field

    if kind not in ("cmos", "camera"):
        raise FieldDataError(f"--kind must be cmos or camera, got {kind!r}")
    if (lat is None) != (lon is None):
        raise FieldDataError("give both --lat and --lon, or neither")
    if lat is not None:
        Site(lat, lon, alt or 0.0)  # refuse a site out of range before anything runs
    if pressure is not None or temperature is not None:
        Atmosphere(1013.25 if pressure is None else pressure, 12.0 if temperature is None else temperature)
    sensor, read, full_scale, close = _open_sensor(kind, port)
    start = _time.time()
    metadata = {"latitude_deg": lat, "longitude_deg": lon, "altitude_m": alt, "heading_deg": heading,
                "roll_deg": roll, "pitch_deg": pitch, "pressure_hpa": pressure, "temperature_c": temperature}

    def wait_until(offset_s: float) -> None:
        delay = start + offset_s - _time.time()
        if delay > 0:
            _time.sleep(delay)

    offsets = np.arange(0.0, hours * 3600.0 + 1e-9, interval)
    names = COLUMNS + (("spot_cloud",) if kind == "camera" else ())  # the camera flags cloud itself
    try:
        # every row goes to the file as it is read: a run cut short, or killed, keeps what it read
        with FieldCsvAppender(output, names, metadata=metadata) as sink, out.status("recording") as status:
            recorder = FieldRecord(on_row=sink.append)
            if kind == "camera":
                recorder.columns["spot_cloud"] = []
            record_field(sensor, read, offsets_s=offsets, start_utc_s=start, wait_until=wait_until,
                         full_scale_dn=full_scale, exposure_ms=exposure, clock=lambda: _time.time() - start,
                         progress=lambda i, n: status.update(f"reading {i}/{n}"), into=recorder)
    finally:
        close()
    ok = sum(s == "ok" for s in recorder.columns["status"])
    out.print(f"{len(recorder)} readings ({ok} with a spot) written to {escape(str(output))}", highlight=False)


def _open_sensor(kind: str, port: str):
    """The sensor's driver, its family's reading function, its full scale and how to close it."""
    from .families import family

    if kind == "cmos":
        from drivers.cmos_sensor import CmosSunSensor
        from drivers.transport import open_port

        from .families.cmos import FULL_SCALE_DN

        link = open_port(port)
        sensor = CmosSunSensor(link)
        sensor.identify()
        return sensor, family("cmos").read, float(FULL_SCALE_DN), link.close
    from drivers.usb_camera import UsbCamera

    camera = UsbCamera(int(port) if port.isdigit() else port)
    return camera, family("camera").read, 255.0, camera.close


def _stats_table(title: str, rows: list[tuple[str, dict]]) -> Table:
    table = Table(title=title)
    for column in ("samples", "n", "zenith RMS [°]", "azimuth RMS [°]", "vector RMS [°]", "vector σ [°]",
                   "vector max [°]"):
        table.add_column(column, justify="right" if column != "samples" else "left")
    for name, s in rows:
        table.add_row(name, str(s.get("n", 0)), *(_f(s.get(k)) for k in (
            "rms_zenith_deg", "rms_azimuth_deg", "rms_vector_deg", "std_vector_deg", "max_vector_deg")))
    return table


def _f(value, digits: int = 4) -> str:
    return "—" if value is None or (isinstance(value, float) and not math.isfinite(value)) else f"{value:.{digits}f}"


def _analysis(data_csv: Path, cal: Optional[Path], *, lat, lon, alt, heading, roll, pitch, pressure, temperature,
              delta_t, fov, heading_mode: str, level_mode: str, do_locate: bool, sigma=None, level_sd=None,
              fit_until=None):
    from .datafile import load_calibration_json
    from .field_analysis import analyse_field, field_setup
    from .field_datafile import read_field_csv

    data = read_field_csv(data_csv)
    calibration = load_calibration_json(cal) if cal is not None else None
    site = None
    if lat is not None or lon is not None:
        if lat is None or lon is None:
            raise FieldDataError("give both --lat and --lon")
        site = Site(lat, lon, alt or 0.0)
    setup = field_setup(data, site=site, altitude_m=alt, heading_deg=heading, roll_deg=roll, pitch_deg=pitch,
                        pressure_hpa=pressure,
                        temperature_c=temperature, delta_t_s=delta_t, fov_half_deg=fov, calibration=calibration)
    return analyse_field(data, calibration, heading=heading_mode, level=level_mode,
                         do_compare=not do_locate or setup.site is not None, do_locate=do_locate, setup=setup,
                         sigma_deg=sigma, level_sd_deg=level_sd,
                         fit_until_s=None if fit_until is None else float(utc_seconds([fit_until])[0]))


def _print_lines(title: str, lines) -> None:
    for line in lines:
        out.print(f"{title}: {escape(line)}", highlight=False, soft_wrap=True)


_COMMON = {
    "cal": typer.Option(None, "--cal", help="Calibration JSON of the sensor (turns spots into directions)."),
    "lat": typer.Option(None, "--lat", help="Site latitude [°] (default: the file's header)."),
    "lon": typer.Option(None, "--lon", help="Site longitude [°] (default: the file's header)."),
    "alt": typer.Option(None, "--alt", help="Site height [m]."),
    "heading": typer.Option(None, "--heading", help="Heading of the sensor's +x axis, east of north [°]."),
    "roll": typer.Option(None, "--roll", help="Mount roll from an inclinometer [°]."),
    "pitch": typer.Option(None, "--pitch", help="Mount pitch from an inclinometer [°]."),
    "pressure": typer.Option(None, "--pressure", help="Station pressure [hPa]."),
    "temperature": typer.Option(None, "--temperature", help="Air temperature [°C]."),
    "delta_t": typer.Option(None, "--delta-t", help="TT − UT [s]."),
    "fov": typer.Option(None, "--fov", help="The sensor's half field of view [°]."),
    "level_fit": typer.Option(False, "--level-fit", help="Fit the mount's roll and pitch too."),
    "plots": typer.Option(None, "--plots", help="Write the figures (HTML) into this folder."),
    "json_out": typer.Option(None, "--json", help="Write the results as JSON."),
}


@field_app.command("compare")
@user_errors
def compare(
    data_csv: Path = typer.Argument(..., help="Field CSV (README, \"Field data CSV\")."),
    cal: Optional[Path] = _COMMON["cal"], lat: Optional[float] = _COMMON["lat"],
    lon: Optional[float] = _COMMON["lon"], alt: Optional[float] = _COMMON["alt"],
    heading: Optional[float] = _COMMON["heading"],
    heading_fit: bool = typer.Option(False, "--heading-fit", help="The heading is unknown (a compass): fit it; the "
                                                                   "azimuth error becomes relative."),
    roll: Optional[float] = _COMMON["roll"], pitch: Optional[float] = _COMMON["pitch"],
    level_fit: bool = _COMMON["level_fit"],
    fit_until: Optional[str] = typer.Option(None, "--fit-until", help="Fit the heading (and level) over the clear "
                                                                     "readings before this UTC time only (seed 003: "
                                                                     "the clear morning, before 12:00)."),
    pressure: Optional[float] = _COMMON["pressure"], temperature: Optional[float] = _COMMON["temperature"],
    delta_t: Optional[float] = _COMMON["delta_t"], fov: Optional[float] = _COMMON["fov"],
    plots: Optional[Path] = _COMMON["plots"], json_out: Optional[Path] = _COMMON["json_out"],
) -> None:
    """Compare a field file's readings with the Sun by SPA (seed 003 §5): zenith, azimuth and vector errors."""
    from .field_analysis import analysis_document, summary_of

    analysis = _analysis(data_csv, cal, lat=lat, lon=lon, alt=alt, heading=heading, roll=roll, pitch=pitch,
                         pressure=pressure, temperature=temperature, delta_t=delta_t, fov=fov,
                         heading_mode="fit" if heading_fit else "file", level_mode="fit" if level_fit else "file",
                         do_locate=False, fit_until=fit_until)
    c = analysis.comparison
    document = analysis_document(analysis, name=data_csv.name)
    stats = document["comparison"]["stats"]
    out.print(_stats_table(f"{escape(data_csv.name)} against SPA ({len(analysis.data)} readings, the Sun within "
                           f"{c.fov_half_deg:g}° of the boresight)",
                           [("clear", stats["clear"]), ("all in the FOV", summary_of(c, c.in_fov))]))
    m = c.mount
    fitted = c.mount_fit.parameters if c.mount_fit is not None else ()
    out.print(f"mount: heading {m.heading_deg:.4f}°{' (fitted)' if 'heading' in fitted else ''}, roll "
              f"{m.roll_deg:.4f}°, pitch {m.pitch_deg:.4f}°{' (fitted)' if 'roll' in fitted else ''}", highlight=False)
    _print_lines("note", analysis.notes + c.notes)
    _print_lines("warning", c.warnings)
    _outputs(document, plots, json_out, data_csv.stem)


@field_app.command("locate")
@user_errors
def locate_site(
    data_csv: Path = typer.Argument(..., help="Field CSV (README, \"Field data CSV\")."),
    cal: Optional[Path] = _COMMON["cal"], alt: Optional[float] = _COMMON["alt"],
    roll: Optional[float] = _COMMON["roll"], pitch: Optional[float] = _COMMON["pitch"],
    level_fit: bool = _COMMON["level_fit"],
    pressure: Optional[float] = _COMMON["pressure"], temperature: Optional[float] = _COMMON["temperature"],
    delta_t: Optional[float] = _COMMON["delta_t"], fov: Optional[float] = _COMMON["fov"],
    noise: Optional[float] = typer.Option(None, "--noise", min=0.0, help="The direction noise per component [°] "
                                                                         "(default: from the residuals)."),
    level_sd: Optional[float] = typer.Option(None, "--level-sd", min=0.0, help="1σ of the given roll and pitch [°] "
                                             "(the inclinometer's or level's accuracy): the site's uncertainty then "
                                             "includes the level's."),
    plots: Optional[Path] = _COMMON["plots"], json_out: Optional[Path] = _COMMON["json_out"],
) -> None:
    """Where the sensor stood and where it looked: latitude, longitude and heading from the Sun's track (seed 001),
    by least squares with their uncertainty. A site in the file's header is used only to report the error."""
    from .field_analysis import analysis_document

    analysis = _analysis(data_csv, cal, lat=None, lon=None, alt=alt, heading=None, roll=roll, pitch=pitch,
                         pressure=pressure, temperature=temperature, delta_t=delta_t, fov=fov, heading_mode="fit",
                         level_mode="fit" if level_fit else "file", do_locate=True, sigma=noise, level_sd=level_sd)
    fix = analysis.fix
    document = analysis_document(analysis, name=data_csv.name)
    table = Table(title=f"{escape(data_csv.name)}: the site from the Sun's track ({fix.n_points} readings)")
    for column in ("", "value", "1σ"):
        table.add_column(column, justify="right" if column else "left")
    table.add_row("latitude", f"{fix.latitude_deg:.5f}°", f"{fix.north_sigma_km:.3f} km")
    table.add_row("longitude", f"{fix.longitude_deg:.5f}°", f"{fix.east_sigma_km:.3f} km")
    table.add_row("heading", f"{fix.heading_deg:.4f}°", f"{fix.sigma_deg.get('heading', math.nan):.4f}°")
    if "roll" in fix.parameters:
        table.add_row("roll", f"{fix.roll_deg:.4f}°", f"{fix.sigma_deg['roll']:.4f}°")
        table.add_row("pitch", f"{fix.pitch_deg:.4f}°", f"{fix.sigma_deg['pitch']:.4f}°")
    out.print(table)
    loc = document["location"]
    out.print(f"uncertainty ellipse (1σ): {fix.ellipse.semi_major_km:.3f} × {fix.ellipse.semi_minor_km:.3f} km, "
              f"major axis {fix.ellipse.orientation_deg:.1f}° east of north; residual RMS "
              f"{fix.residual_rms_deg:.4f}° per component", highlight=False)
    if loc["error_km"] is not None:
        out.print(f"the file's site is {loc['error_km']:.3f} km away", highlight=False)
    _print_lines("note", analysis.notes)
    _print_lines("warning", fix.warnings)
    _outputs(document, plots, json_out, data_csv.stem)


def _outputs(document: dict, plots: Optional[Path], json_out: Optional[Path], stem: str) -> None:
    from .field_plots import write_comparison_plots, write_location_plot

    if plots is not None:
        written = []
        if document["comparison"] is not None:
            written.append(write_comparison_plots(document, plots / f"{stem}-errors.html"))
        if document["location"] is not None:
            written.append(write_location_plot(document, plots / f"{stem}-site.html"))
        out.print("plots: " + ", ".join(escape(str(p)) for p in written), highlight=False)
    if json_out is not None:
        json_out.parent.mkdir(parents=True, exist_ok=True)
        json_out.write_text(json.dumps(document) + "\n")
