"""`sunbench study …`: method studies on simulated sensors.

`css-attitude` calibrates a simulated coarse-sun-sensor head on the simulated bench, flies it on a tumbling orbit and
compares seed 000's LUT algorithm with the least-squares estimator (:mod:`bench.css_study`). `horizon-errors` and
`cmos-plan` are Monte Carlo studies on Dask (:mod:`bench.study_engine`): the horizon sensor's error budget
(:mod:`bench.study_horizon`) and plan density against CMOS accuracy (:mod:`bench.study_cmos`). Bad input ends in one
stderr line and exit code 2 (`cli_common.user_errors`).
"""

from __future__ import annotations

import functools
import json
from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape
from rich.table import Table

from .cli_common import err, out, user_errors

study_app = typer.Typer(help="Method studies on simulated sensors.", no_args_is_help=True)


def register(app: typer.Typer) -> None:
    """Add `study` and its commands to `app`."""
    app.add_typer(study_app, name="study")


def _cell(value) -> str:
    return "—" if value is None else f"{value:.2f}"


@study_app.command("css-attitude")
@user_errors
def css_attitude(
    orbits: float = typer.Option(1.0, "--orbits", min=0.01, help="Orbits flown."),
    samples_per_orbit: int = typer.Option(180, "--samples-per-orbit", min=1, max=100_000,
                                          help="Readings per orbit (the head tumbles: each an independent attitude)."),
    altitude_km: float = typer.Option(660.0, "--altitude-km", min=100.0, max=40_000.0,
                                      help="Orbit altitude (the Earth's angular radius: 65° at 660 km)."),
    beta_deg: float = typer.Option(30.0, "--beta-deg", min=-90.0, max=90.0, help="The Sun's angle out of the orbit."),
    seed: int = typer.Option(0, "--seed", help="Random seed of the head's build, the attitudes and the noise."),
    response: str = typer.Option("fresnel", "--response",
                                 help="The simulated head's angular response: fresnel | kelly | power | thesis."),
    calibration: Optional[Path] = typer.Option(None, "--cal", exists=True, dir_okay=False,
                                               help="The head's bench calibration (default: calibrated here)."),
    plots: Optional[Path] = typer.Option(None, "--plots", help="Write the comparison's plots (HTML) to this file."),
    as_json: bool = typer.Option(False, "--json", help="Print the whole result as JSON."),
) -> None:
    """Seed 000's LUT algorithm against the least-squares estimator on a tumbling head in orbit, with the Earth's
    albedo and without: RMS and percentile angular errors, and errors by the Sun–Earth angle."""
    from drivers.sim.css_optics import css_truth
    from drivers.sim.css_orbit import orbit_samples

    from .css_datafile import read_css_calibration
    from .css_study import compare_attitude, write_attitude_plots

    if response not in ("fresnel", "kelly", "power", "thesis"):
        raise typer.BadParameter(f"no response law {response!r} (fresnel, kelly, power, thesis)")
    truth = css_truth(f"CSS-STUDY-{seed}", seed=seed + 1000, response=response)
    document = read_css_calibration(calibration) if calibration is not None else None
    samples = orbit_samples(orbits, samples_per_orbit, altitude_km=altitude_km, beta_deg=beta_deg, seed=seed)
    with out.status("calibrating the head on the simulated bench, then flying it …"):
        result = compare_attitude(truth, samples, document=document, seed=seed)
    if plots is not None:
        write_attitude_plots(result, plots)
    if as_json:
        out.print_json(json.dumps(result))
        return
    out.print(f"{result['sunlit']} sunlit readings of {result['samples']} on {orbits:g} orbit(s) at "
              f"{altitude_km:g} km, β = {beta_deg:g}°; the head's response: {response}", highlight=False)
    for scene, block in result["scenes"].items():
        table = Table(title=f"{scene}: angular error of the Sun [°]")
        for column in ("method", "n", "none", "flagged", "RMS", "50 %", "95 %", "99 %", "max", "RMS unflagged"):
            table.add_column(column, justify="left" if column == "method" else "right")
        for name, f in block["figures"].items():
            table.add_row(name, str(f["n"]), str(f["missing"]), str(f["flagged"]), _cell(f["rms_deg"]),
                          _cell(f["p50_deg"]), _cell(f["p95_deg"]), _cell(f["p99_deg"]), _cell(f["max_deg"]),
                          _cell(f["rms_determined_deg"]))
        table.caption = ("flagged: the least-squares estimate says itself that the direction is undetermined (fewer "
                         "than two non-coplanar lit faces); it is scored all the same")
        out.print(table)
        bins = block["by_sun_earth_angle"]
        by_angle = Table(title=f"{scene}: RMS error [°] by the Sun–Earth angle")
        by_angle.add_column("method")
        for lo, hi in bins["bins"]:
            by_angle.add_column(f"{lo:g}–{hi:g}°", justify="right")
        for name in block["figures"]:
            by_angle.add_row(name, *[_cell(cell["rms_deg"]) for cell in bins[name]])
        out.print(by_angle)
    if plots is not None:
        out.print(f"plots: {plots}", highlight=False)


# -- Monte Carlo studies on Dask ----------------------------------------------------------------------------------
def _study_errors(command):
    """A study's own typed errors (:class:`bench.study_engine.StudyError`: a bad spec, a factor whose model is
    missing, an unreachable scheduler) as one stderr line and exit code 2, like every other bad input; Ctrl-C says
    what was kept."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        from .study_engine import StudyError

        try:
            return command(*args, **kwargs)
        except StudyError as exc:
            err.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        except KeyboardInterrupt:
            err.print("interrupted: the chunks finished so far are kept; the same command resumes the study",
                      highlight=False)
            raise typer.Exit(130) from None

    return wrapper


def _numbers(text: str, option: str, kind=float, lo: float | None = None, hi: float | None = None) -> list:
    """A comma-separated list of numbers (`400,500,700`) for a swept option; a typed error naming the bad one."""
    values = []
    for part in [p.strip() for p in str(text).split(",")]:
        try:
            value = kind(part)
        except ValueError:
            raise typer.BadParameter(f"{option}: {part!r} is not a {'whole ' if kind is int else ''}number") from None
        if value != value or (lo is not None and value < lo) or (hi is not None and value > hi):
            raise typer.BadParameter(f"{option}: {part} lies outside [{lo}, {hi}]")
        values.append(value)
    if len(set(values)) != len(values):
        raise typer.BadParameter(f"{option}: a value is repeated in {text!r}")
    return values


SchedulerOption = typer.Option(None, "--scheduler", metavar="tcp://HOST:PORT",
                               help="An existing Dask cluster's scheduler (its workers need sunbench installed); "
                                    "default: a local cluster on every core.")
WorkersOption = typer.Option(None, "--workers", min=1, max=1024, help="Worker processes of the local cluster "
                                                                       "(default: one per core).")
DrawsHelp = "Random draws per setting (the same draws at every setting)."


def _run(spec, out_path: Path, scheduler, workers, plot, plots: bool, as_json: bool):
    """Run the study; its account goes to stdout, or to stderr when stdout carries JSON."""
    from .study_engine import run_study

    say = err if as_json else out

    result = run_study(spec, out_path, scheduler=scheduler, workers=workers, console=err, progress=True,
                       plot=plot if plots else (lambda table, summary, path: None))
    say.print(f"{spec.name}: {len(result.table)} of {len(spec)} simulations ({result.computed} run now"
              + (f" at {result.simulations_per_s:.1f}/s on {result.workers} worker(s)" if result.computed else "")
              + f", {result.reused} kept from an earlier run); spec {spec.digest}", highlight=False)
    failed = int((result.table["error"] != "").sum()) if len(result.table) and "error" in result.table else 0
    if failed:
        first = result.table.loc[result.table["error"] != "", "error"].iloc[0]
        say.print(f"{failed} simulation(s) ended in an error (the `error` column), e.g.: {escape(first)}",
                  highlight=False)
    return result


def _finish(result, as_json: bool = False) -> None:
    (err if as_json else out).print(f"table: {result.table_path}\nsummary: {result.summary_path}"
              + (f"\nplots: {result.plot_path}" if result.plot_path else ""), highlight=False)
    if result.failed_chunks:
        for k, why in sorted(result.failed_chunks.items()):
            err.print(f"[bold red]chunk {k} failed twice:[/] {escape(why)}", highlight=False, soft_wrap=True)
        err.print(f"{len(result.failed_chunks)} chunk(s) failed; run the same command again to retry them",
                  highlight=False)
        raise typer.Exit(1)


def _cell4(value) -> str:
    return "—" if value is None or value != value else f"{value:.4f}"


def _words(text: str, option: str, allowed) -> list[str]:
    """A comma-separated list of words (`peak-threshold,two-level`) for a swept option, each one of `allowed`."""
    values = [p.strip() for p in str(text).split(",") if p.strip()]
    for value in values:
        if value not in allowed:
            raise typer.BadParameter(f"{option}: no {value!r} ({', '.join(allowed)})")
    if not values:
        raise typer.BadParameter(f"{option}: give at least one of {', '.join(allowed)}")
    if len(set(values)) != len(values):
        raise typer.BadParameter(f"{option}: a value is repeated in {text!r}")
    return values


@study_app.command("horizon-errors")
@_study_errors
@user_errors
def horizon_errors(
    altitude_km: str = typer.Option("400,500,700,1000", "--altitude-km", help="Altitudes \\[km], comma-separated."),
    factors: str = typer.Option("altitude,cone,noise,mount,ifov,oblate,atmosphere,all", "--factors",
                                help="Budget rows: each error source alone, or `all` together (altitude, cone, "
                                     "noise, mount, ifov, oblate, atmosphere, all)."),
    altitude_error_km: str = typer.Option("10", "--altitude-error-km",
                                          help="σ of the altitude the spacecraft believes \\[km] (ref [16]: 10)."),
    cone_error_deg: str = typer.Option("0.02", "--cone-error-deg", help="σ of each cone's half-angle [°]."),
    noise_s: str = typer.Option("2e-5", "--noise-s", help="σ of each crossing's time \\[s]."),
    mount_error_deg: str = typer.Option("0.2", "--mount-error-deg",
                                        help="σ of the mounting misalignment about each axis [°] (ref [16]: 0.2)."),
    ifov_deg: str = typer.Option("2", "--ifov-deg", help="IFOV half-angle [°] with the 50 % locator (thesis: 2)."),
    gamma_deg: str = typer.Option("70", "--gamma-deg", help="Scan half-cone γ [°] (thesis: 70)."),
    scan_rate_hz: str = typer.Option("1", "--scan-rate-hz", help="Scan rate \\[rev/s] (thesis: 1)."),
    roll_range_deg: float = typer.Option(10.0, "--roll-range-deg", min=0.0, max=33.0,
                                         help="True roll drawn in ±this [°] (the sensor's range: 33)."),
    pitch_range_deg: float = typer.Option(10.0, "--pitch-range-deg", min=0.0, max=17.0,
                                          help="True pitch drawn in ±this [°] (the sensor's range: 17)."),
    solver: str = typer.Option("least-squares", "--solver",
                               help="least-squares | steepest-descent (ρ from the altitude) | free-rho | closed-form "
                                    "(ρ solved from the crossings); not for the atmosphere, solved on WGS84."),
    locator: str = typer.Option("peak-threshold", "--locator",
                                help="The atmosphere's edge locator(s): peak-threshold (the thesis' eq. 2.1), "
                                     "local-threshold, local-integrated, inflection, two-level."),
    atmosphere_correction: str = typer.Option("none", "--atmosphere-correction",
                                              help="none (h* = 0, the thesis' case D) | climatology (each crossing's "
                                                   "h* predicted from the day's climatology)."),
    weather: str = typer.Option("ordinary", "--weather",
                                help="The truth's weather at each crossing: ordinary | cold-pool | none (the "
                                     "climatology itself)."),
    band_error: str = typer.Option("0.05", "--band-error",
                                   help="σ of the truth band's strength (log-normal; the truth's band is the "
                                        "7-sub-band model, the correction's the 5-sub-band one)."),
    day_of_year: str = typer.Option("103", "--day-of-year", help="Day of the year (thesis: 103, 12 April)."),
    sample_s: str = typer.Option("1e-3", "--sample-s",
                                 help="The pulse's sample interval \\[s] (thesis' case D: 1e-3)."),
    draws: int = typer.Option(200, "--draws", min=1, max=10_000_000, help=DrawsHelp),
    seed: int = typer.Option(0, "--seed", help="Seed of the study."),
    chunk_size: int = typer.Option(100, "--chunk-size", min=1, max=1_000_000, help="Simulations per Dask task."),
    out_path: Path = typer.Option(Path("horizon-errors.csv"), "--out", help="Results table (.csv, or .parquet with "
                                                                            "pyarrow); chunks in <out>.chunks/."),
    scheduler: Optional[str] = SchedulerOption,
    workers: Optional[int] = WorkersOption,
    plots: bool = typer.Option(True, "--plots/--no-plots", help="Write <stem>.html beside the table."),
    as_json: bool = typer.Option(False, "--json", help="Print the summary as JSON."),
) -> None:
    """The scanning horizon sensor's error budget (seed 004): roll and pitch errors against altitude for each error
    source alone and all together, by Monte Carlo on Dask; any option takes a comma-separated list to sweep it."""
    from .study_horizon import (
        ATMOSPHERE_CORRECTIONS,
        ATMOSPHERE_OPTIONS,
        LOCATORS,
        SOLVERS,
        WEATHERS,
        horizon_spec,
        write_horizon_plot,
    )

    if solver not in SOLVERS:
        raise typer.BadParameter(f"no solver {solver!r} ({', '.join(SOLVERS)})")
    names = [f.strip() for f in factors.split(",") if f.strip()]
    spec = horizon_spec(
        altitudes_km=_numbers(altitude_km, "--altitude-km", lo=100.0, hi=40_000.0), factors=names, draws=draws,
        seed=seed, chunk_size=chunk_size,
        altitude_error_km=_numbers(altitude_error_km, "--altitude-error-km", lo=0.0, hi=1000.0),
        cone_error_deg=_numbers(cone_error_deg, "--cone-error-deg", lo=0.0, hi=5.0),
        noise_s=_numbers(noise_s, "--noise-s", lo=0.0, hi=0.1),
        mount_error_deg=_numbers(mount_error_deg, "--mount-error-deg", lo=0.0, hi=10.0),
        ifov_deg=_numbers(ifov_deg, "--ifov-deg", lo=0.0, hi=10.0),
        gamma_deg=_numbers(gamma_deg, "--gamma-deg", lo=1.0, hi=89.0),
        scan_rate_hz=_numbers(scan_rate_hz, "--scan-rate-hz", lo=0.01, hi=100.0),
        roll_range_deg=roll_range_deg, pitch_range_deg=pitch_range_deg, solver=solver,
        locator=_words(locator, "--locator", LOCATORS),
        atmosphere_correction=_words(atmosphere_correction, "--atmosphere-correction", ATMOSPHERE_CORRECTIONS),
        weather=_words(weather, "--weather", WEATHERS),
        band_error=_numbers(band_error, "--band-error", lo=0.0, hi=1.0),
        day_of_year=_numbers(day_of_year, "--day-of-year", lo=1.0, hi=366.0),
        sample_s=_numbers(sample_s, "--sample-s", lo=1e-6, hi=0.01))
    result = _run(spec, out_path, scheduler, workers, write_horizon_plot, plots, as_json)
    summary = result.summary
    if as_json:
        out.print_json(summary.to_json(orient="records"))
        _finish(result, as_json=True)
        return
    others = [c for c in spec.sweep if c not in ("altitude_km", "factor")]
    table = Table(title="Roll and pitch error [°] (solved − true): mean |error|, RMS, 95 % of |error|",
                  title_justify="left")
    label = {"atmosphere_correction": "correction"}
    for column in ("altitude [km]", "factor", *[label.get(o, o) for o in others], "n", "errors", "roll mean",
                   "roll RMS", "roll 95 %", "pitch mean", "pitch RMS", "pitch 95 %", "nadir RMS"):
        table.add_column(column, justify="left" if column == "factor" else "right")
    shown = set()
    for _, group in summary.groupby(list(spec.sweep), sort=False):
        cell = {row["output"]: row for _, row in group.iterrows()}
        roll, pitch, nadir = (cell.get(k) for k in ("roll_error_deg", "pitch_error_deg", "nadir_error_deg"))
        first = group.iloc[0]
        # a row without the atmosphere ignores its options: shown once, with "—" for them
        blind = first["factor"] not in ("atmosphere", "all")
        values = ["—" if blind and o in ATMOSPHERE_OPTIONS else str(first[o]) for o in others]
        key = (first["altitude_km"], first["factor"], *values)
        if key in shown:
            continue
        shown.add(key)
        if roll is None:  # every simulation of the setting failed: no outputs to show
            table.add_row(f"{first['altitude_km']:g}", str(first["factor"]), *values, "0", str(int(first["errors"])),
                          *["—"] * 7)
            continue
        table.add_row(f"{first['altitude_km']:g}", str(first["factor"]), *values,
                      str(int(roll["n"])), str(int(roll["errors"])), _cell4(roll["mean_abs"]), _cell4(roll["rms"]),
                      _cell4(roll["p95_abs"]), _cell4(pitch["mean_abs"]), _cell4(pitch["rms"]),
                      _cell4(pitch["p95_abs"]), _cell4(nadir["rms"]))
    fixed = spec.fixed
    atmosphere = ("; atmosphere and all: WGS84 solve with the position known (the solver does not apply), "
                  + ", ".join(f"{o.replace('_', ' ')} {fixed[o]}" for o in ("locator", "atmosphere_correction",
                                                                          "weather") if o in fixed)
                  if {"atmosphere", "all"} & set(names) else "")
    table.caption = (f"true roll in ±{roll_range_deg:g}°, pitch in ±{pitch_range_deg:g}°; solver {solver} with the "
                     "sensor's spherical model (a = 6378.137 km); the truth is that sphere but for `oblate` (WGS84, a "
                     "97.4° orbit), `atmosphere` and `all`" + atmosphere
                     + "; nadir: the angle between the true and the solved nadir")
    table.caption_justify = "left"
    out.print(table)
    _finish(result)


@study_app.command("cmos-plan")
@_study_errors
@user_errors
def cmos_plan(
    azimuths: str = typer.Option("4,8,16", "--azimuths", help="Azimuths of the plan, comma-separated (seed 003: 8)."),
    rings: str = typer.Option("4,7,13", "--rings", help="Zenith rings from 0 to --zenith-max-deg (seed 003: 7)."),
    repeats: str = typer.Option("1,4", "--repeats", help="Frames per direction (seed 003: 4)."),
    noise_px: str = typer.Option("0.02", "--noise-px", help="Centroid noise, one sigma per axis [px]."),
    zenith_max_deg: float = typer.Option(60.0, "--zenith-max-deg", min=5.0, max=80.0,
                                         help="The plan's and the check points' largest zenith [°] (seed 003: 60)."),
    check_points: int = typer.Option(400, "--check-points", min=10, max=100_000,
                                     help="Held-out directions per sensor, uniform over the field."),
    draws: int = typer.Option(20, "--draws", min=1, max=1_000_000, help="Simulated sensors per plan."),
    seed: int = typer.Option(0, "--seed", help="Seed of the study (which sensors are drawn)."),
    chunk_size: int = typer.Option(4, "--chunk-size", min=1, max=100_000, help="Simulations per Dask task."),
    out_path: Path = typer.Option(Path("cmos-plan.csv"), "--out", help="Results table (.csv, or .parquet with "
                                                                       "pyarrow); chunks in <out>.chunks/."),
    scheduler: Optional[str] = SchedulerOption,
    workers: Optional[int] = WorkersOption,
    plots: bool = typer.Option(True, "--plots/--no-plots", help="Write <stem>.html beside the table."),
    as_json: bool = typer.Option(False, "--json", help="Print the per-plan table as JSON."),
) -> None:
    """Plan density against CMOS accuracy: simulated flight sensors (their own ray-traced physics) calibrated with
    each plan by every method, scored at random held-out directions; comma-separated lists are swept."""
    from calibration.models import METHODS

    from .study_cmos import cmos_spec, plan_label, plan_table, write_cmos_plot

    spec = cmos_spec(azimuths=_numbers(azimuths, "--azimuths", int, 1, 360),
                     rings=_numbers(rings, "--rings", int, 2, 200),
                     repeats=_numbers(repeats, "--repeats", int, 1, 1000),
                     noise_px=_numbers(noise_px, "--noise-px", lo=0.0, hi=10.0), zenith_max_deg=zenith_max_deg,
                     check_points=check_points, draws=draws, seed=seed, chunk_size=chunk_size)
    result = _run(spec, out_path, scheduler, workers, write_cmos_plot, plots, as_json)
    plans = plan_table(result.table) if len(result.table) else None
    if as_json:
        out.print_json(plans.to_json(orient="records") if plans is not None else "[]")
        _finish(result, as_json=True)
        return
    if plans is not None:
        table = Table(title="Held-out vector error [°]: mean over sensors of the RMS / 95 % over sensors of the max",
                      title_justify="left")
        extra = [c for c in ("noise_px",) if c in plans.columns]
        for column in ("plan", *extra, "frames", "sensors", *METHODS):
            table.add_column(column, justify="left" if column == "plan" else "right")
        for _, row in plans.sort_values("frames").iterrows():
            cells = []
            for m in METHODS:
                text = f"{_cell4(row[f'{m}.mean_rms_deg'])} / {_cell4(row[f'{m}.p95_max_deg'])}"
                if row[f"{m}.failed"]:
                    text += f" ({int(row[f'{m}.failed'])} not fitted)"
                cells.append(text)
            table.add_row(plan_label(row), *[f"{row[c]:g}" for c in extra], str(int(row["frames"])),
                          str(int(row["sensors"])), *cells)
        table.caption = ("plan: azimuths × zenith rings × repeats (plus a centre stage of repeats + 1 frames at every "
                         "azimuth); not fitted: the method cannot be fitted from the plan (the `<method>.error` "
                         "column says why)")
        table.caption_justify = "left"
        out.print(table)
    _finish(result)
