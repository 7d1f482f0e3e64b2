"""What every `sunbench` command module shares: the consoles, the turning of bad input into one stderr line and
exit code 2, the metrics table, and the options several commands take (`--bench`, `--catalogue`,
`--time-scale`).

The command modules (`bench/cli.py`, `bench/cli_runs.py`, `web/cli.py`) import this and nothing of each other;
the `cli/` package, the composition root, builds the app from them.
"""

from __future__ import annotations

import functools
import os
import sys
from pathlib import Path
from typing import Optional

import typer
from rich.console import Console
from rich.markup import escape
from rich.table import Table

from calibration.errors import CalibrationError
from calibration.evaluation import MethodReport
from drivers.errors import DeviceError

from .benchfile import BenchFileError
from .campaign import CampaignFileError
from .catalogue import CatalogueError
from .datafile import DataFileError
from .runner import PreflightRefused, ResumeRefused

out = Console(width=None if sys.stdout.isatty() else 150)  # a pipe or a test gets whole tables
err = Console(stderr=True)

# an empty XDG_DATA_HOME counts as unset, as the XDG spec says
DEFAULT_CATALOGUE = (Path(os.environ.get("XDG_DATA_HOME") or Path.home() / ".local" / "share")
                     / "sunbench" / "catalogue.sqlite")

CatalogueOption = typer.Option(None, "--catalogue", envvar="SUNBENCH_CATALOGUE",
                               help=f"SQLite catalogue (default: {DEFAULT_CATALOGUE}).")
BenchOption = typer.Option(None, "--bench", "-b", help="Bench file (default: the simulated bench).")
TimeScaleOption = typer.Option(None, "--time-scale", min=0.0, max=1000.0,
                               help="Simulated clock (0 = instant, at most 1000× real time).")
#: Catalogue ids are SQLite integers: a larger number is refused as bad input, not a traceback.
MAX_ID = 2**63 - 1


def open_catalogue(path: Optional[Path], *, readonly: bool = False):
    """The catalogue at `path` (default: DEFAULT_CATALOGUE)."""
    from .catalogue import Catalogue
    return Catalogue(path or DEFAULT_CATALOGUE, readonly=readonly)


def user_errors(command):
    """Turn the typed errors of bad input into one stderr line and exit code 2."""

    @functools.wraps(command)
    def wrapper(*args, **kwargs):
        try:
            return command(*args, **kwargs)
        except (DataFileError, CalibrationError, BenchFileError, CampaignFileError, CatalogueError,
                PreflightRefused, ResumeRefused) as exc:
            err.print(f"[bold red]error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None
        except DeviceError as exc:  # a device that does not answer as it should: not the user's input
            err.print(f"[bold red]device error:[/] {escape(str(exc))}", highlight=False, soft_wrap=True)
            raise typer.Exit(1) from None
        except OSError as exc:
            err.print(f"[bold red]error:[/] {escape(str(exc.filename or ''))}: {escape(str(exc.strerror))}",
                      highlight=False, soft_wrap=True)
            raise typer.Exit(2) from None

    return wrapper


def fmt(value: float, digits: int = 3) -> str:
    return "—" if value != value else f"{value:.{digits}f}"  # NaN → dash


def _method_table(title: str, columns: dict[str, dict], rows, chosen: str | None) -> Table:
    """One row per method, the chosen one marked `*`; `rows` are (method, cells, notes), cells None for a method
    that could not be fitted (dashes then); every note goes in the caption."""
    notes: list[str] = []
    table = Table(title=title, title_justify="left")
    table.add_column("method", no_wrap=True)
    for name, options in columns.items():
        table.add_column(name, **options)
    for method, cells, row_notes in rows:
        table.add_row(method + (" *" if method == chosen else ""),
                      *(["[dim]—[/]"] * len(columns) if cells is None else cells))
        notes += row_notes
    table.caption = "\n".join(escape(n) for n in notes) or None
    table.caption_justify = "left"
    return table


def metrics_table(reports: list[MethodReport], chosen: str | None) -> Table:
    """Seed 003 Table 4.1 columns for every method: held out (the worse of two schemes), and more."""
    def row(r: MethodReport):
        if r.calibration is None:
            return r.method, None, [f"not fitted: {r.error}"]
        h = r.heldout
        cells = [fmt(h.rms_zenith_deg, 4), fmt(h.rms_azimuth_deg, 4), fmt(h.rms_vector_deg, 4), fmt(h.bound95_deg, 4),
                 fmt(h.max_vector_deg, 4)] if h else ["—"] * 5
        cells += [fmt(r.heldout_azimuth.rms_vector_deg, 4) if r.heldout_azimuth else "—",
                  fmt(r.heldout_ring.rms_vector_deg, 4) if r.heldout_ring else "—",
                  fmt(r.fitted.rms_vector_deg, 4), fmt(r.chi2_dof, 1) if r.chi2_dof is not None else "—"]
        return r.method, cells, [f"{r.method}: {r.error}"] if r.error else []

    columns = {name: {"justify": "right", "max_width": 9} for name in (
        "RMS zenith", "RMS azimuth", "RMS vector", "95 % (2×RMS)", "max vector", "azimuth out", "ring out",
        "RMS at nodes", "χ²/dof")}
    return _method_table("Accuracy held out [°] — the worse of leave-one-azimuth-out and leave-one-zenith-ring-out; "
                         "* = chosen", columns, map(row, reports), chosen)


def qd_metrics_table(reports, chosen: str | None) -> Table:
    """Every QD method's angular error [°]: held out between the grid's nodes (what it is judged by), at them."""
    def row(r):
        if r.model is None:
            return r.method, None, [f"{r.method} not fitted: {r.error}"]
        h, n = r.heldout, r.at_nodes
        cells = [fmt(h.max_deg, 4), fmt(h.rms_deg, 4), fmt(h.p99_deg, 4), r.heldout_scheme or "—"] if h else ["—"] * 4
        cells.append(" · ".join(f"{k} {fmt(v.max_deg, 4)}" for k, v in r.heldout_by_scheme.items()) or "—")
        cells += [fmt(n.max_deg, 4), fmt(n.rms_deg, 4)] if n else ["—"] * 2
        cells.append(fmt(r.chi2_dof, 1) if r.chi2_dof is not None else "—")
        notes = []
        if h is not None and h.n_failed:
            notes.append(f"{r.method}: no direction for {h.n_failed} of {h.n_points} held-out points (left out of "
                         "its figures)")
        if r.error:
            notes.append(f"{r.method}: {r.error}")
        return r.method, cells, notes

    columns = {name: {"justify": "left" if name in ("scheme", "max by scheme") else "right",
                      "no_wrap": name == "max by scheme"}
               for name in ("held-out max", "held-out RMS", "held-out p99", "scheme", "max by scheme", "max at nodes",
                            "RMS at nodes", "χ²/dof")}
    return _method_table("Accuracy [°] — held out: the worst, by max, of the off-node check points and the grid "
                         "columns / rows left out; * = chosen", columns, map(row, reports), chosen)


def horizon_parameters_table(document: dict) -> Table:
    """A horizon calibration's parameters ± 1σ beside the design's (seed 004 §3-5: γ = 70°), the mount's pitch marked
    as folded into the phase offsets; the title gives the crossing model (with the IFOV's limb-curvature bias b when the
    document carries the design's IFOV)."""
    alpha = (document.get("design") or {}).get("ifov_half_angle_deg")
    radius = f"ρ − b(ρ, α = {alpha:g}°) + Δρ" if alpha else "ρ + Δρ"
    table = Table(title=f"Horizon sensor: S_k(δ − o_k)·n_b = cos({radius}), n_b = Mᵀ n_table; each fitted parameter "
                        "± 1σ", title_justify="left")
    for name in ("parameter", "value [°]", "± 1σ [°]", "nominal [°]"):
        table.add_column(name, justify="left" if name == "parameter" else "right")
    order = ("gamma1_deg", "gamma2_deg", "phase_offset1_deg", "phase_offset2_deg", "radius_bias_deg", "mount_roll_deg",
             "mount_yaw_deg", "mount_pitch_deg")  # the document's order, whatever a catalogue's JSON did with its keys
    parameters = sorted(document["parameters"].items(),
                        key=lambda item: order.index(item[0]) if item[0] in order else len(order))
    for name, entry in parameters:
        sd = entry.get("sd")
        note = "" if entry.get("fitted") else " (not fitted)" if name != "mount_pitch_deg" else \
            " (folded into the offsets)"
        table.add_row(name + note, f"{entry['value']:.5f}", "—" if sd is None else f"{sd:.5f}",
                      f"{entry['nominal']:g}")
    return table


def horizon_accuracy_table(heldout: dict | None) -> Table:
    """Roll and pitch the calibrated sensor reports against the table's [°]: at the check points (never fitted), with
    each disc radius left out (refitted without it) and at the fitted scans; the nominal sensor beside them."""
    table = Table(title="Roll and pitch against the table [°] (the sensor's crossings solved with the calibration)",
                  title_justify="left")
    for name in ("scored", "scans", "roll RMS", "roll max", "pitch RMS", "pitch max", "phase RMS / σ"):
        table.add_column(name, justify="left" if name == "scored" else "right")
    heldout = heldout or {}

    def row(label, entry, scores=None):
        if not entry or not entry.get("n_scans"):
            table.add_row(label, *["—"] * 6)
            return
        sigma = (scores or {}).get("phase_rms_sigma")
        table.add_row(label, str(entry["n_scans"]), f"{entry['roll_rms_deg']:.4f}", f"{entry['roll_max_deg']:.4f}",
                      f"{entry['pitch_rms_deg']:.4f}", f"{entry['pitch_max_deg']:.4f}",
                      "—" if sigma is None else f"{sigma:.2f}")

    check = heldout.get("check")
    row("check points *", (check or {}).get("calibrated"), check)
    row("check points, nominal sensor", (check or {}).get("nominal"))
    for entry in heldout.get("radius_out", []):
        row(f"ρ {entry['disc_radius_deg']:.3f}° left out", entry.get("calibrated"), entry)
    nodes = heldout.get("at_nodes")
    row("fitted scans", (nodes or {}).get("calibrated"), nodes)
    row("fitted scans, nominal sensor", (nodes or {}).get("nominal"))
    table.caption = "* = the calibration's held-out figure (check points never fitted)"
    table.caption_justify = "left"
    return table
