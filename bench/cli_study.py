"""`sunbench study …`: method studies on simulated sensors.

`css-attitude` calibrates a simulated coarse-sun-sensor head on the simulated bench, flies it on a tumbling orbit and
compares seed 000's LUT algorithm with the least-squares estimator (:mod:`bench.css_study`). Bad input ends in one
stderr line and exit code 2 (`cli_common.user_errors`).
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Optional

import typer
from rich.table import Table

from .cli_common import out, user_errors

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
