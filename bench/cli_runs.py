"""`sunbench run | runs | show | resume | export | fleet`: campaigns on the bench, from the command line."""

from __future__ import annotations

import contextlib
import json
import signal
from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeRemainingColumn
from rich.table import Table

from .benchfile import BenchFile, load_bench_file
from .campaign import load_campaign_file
from .cli_common import (
    DEFAULT_CATALOGUE,
    MAX_ID,
    BenchOption,
    CatalogueOption,
    TimeScaleOption,
    err,
    fmt,
    horizon_accuracy_table,
    horizon_parameters_table,
    metrics_table,
    open_catalogue,
    out,
    qd_metrics_table,
    user_errors,
)

#: `run`, `runs`, `show`, `resume`, `export`, `fleet`; `register` adds them to the `sunbench` app (cli/main.py).
commands = typer.Typer()

YesOption = typer.Option(False, "--yes", "-y", help="Confirm every sensor mount without asking (simulated benches "
                                                    "only: unattended simulations).")


def register(app: typer.Typer) -> None:
    """Add this module's commands to `app`."""
    app.registered_commands.extend(commands.registered_commands)


def _session(bench: Optional[Path], catalogue, time_scale: Optional[float]):
    from .runner import open_session
    bench_file = load_bench_file(bench) if bench else BenchFile()
    return open_session(bench_file, catalogue, time_scale=time_scale)


class _ProgressView:
    """A progress bar fed by the engine's point events (point i/N, ETA)."""

    def __init__(self):
        self.progress = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(),
                                 TextColumn("ETA"), TimeRemainingColumn(), console=err, transient=False)
        self.task = None

    def on_run(self, run_id, sensor_id):
        self.task = self.progress.add_task(f"run {run_id} · {sensor_id}", total=None)

    def on_event(self, event):
        if event.kind == "point" and self.task is not None:
            self.progress.update(self.task, completed=event.data["index"], total=event.data["total"] or None)
        elif event.kind in ("paused", "suspended"):
            self.progress.console.print(f"[yellow]{event.kind}:[/] {escape(event.data.get('reason', ''))}")
        elif event.kind == "warning":
            self.progress.console.print(f"[yellow]warning:[/] {escape(event.message)}", soft_wrap=True)
        elif event.kind == "unsafe":
            self.progress.console.print(f"[bold red]{escape(event.message)}[/]", soft_wrap=True)
        elif event.kind == "fit":  # what the fits at the run's end found (bench.families, journal)
            self.progress.console.print(f"fit: {escape(event.message)}", highlight=False, soft_wrap=True)


def _abort_on_signals(engine):
    def handler(signum, frame):  # Ctrl-C or a kill: end the run cleanly, the bench made safe
        try:
            engine.abort()
        except Exception:  # noqa: BLE001 - nothing to abort
            pass
    signal.signal(signal.SIGINT, handler)
    signal.signal(signal.SIGTERM, handler)


@commands.command("run")
@user_errors
def run_campaign_command(
    campaign_yaml: Path = typer.Argument(..., help="Campaign file (see examples/seed003.yaml)."),
    bench: Optional[Path] = BenchOption,
    catalogue: Optional[Path] = CatalogueOption,
    time_scale: Optional[float] = TimeScaleOption,
    dry_run: bool = typer.Option(False, "--dry-run", help="Only expand and check the plan."),
    yes: bool = YesOption,
) -> None:
    """Run a calibration campaign; prints the run id alone on its last line (exit 1 if it did not complete)."""
    from .runner import PreflightRefused, check_campaign, run_campaign

    campaign = load_campaign_file(campaign_yaml)
    if dry_run:  # it writes nothing, so it never opens the catalogue: it works beside a running server
        _refuse_a_busy_real_bench(bench, catalogue)
    else:
        _refuse_yes_on_a_real_bench(bench, yes)
    with (contextlib.nullcontext() if dry_run else open_catalogue(catalogue)) as cat:
        session = _session(bench, cat, time_scale)
        try:
            report = check_campaign(campaign, session)
            bound = "at most " if report.upper_bound else ""
            warmup = report.warmup_s * len(campaign.sensors)  # check_campaign scales the whole estimate
            out.print(f"preflight: {bound}{len(report.points)} points, {report.n_frames} frames, "
                      f"{report.n_moves} moves per sensor × {len(campaign.sensors)} sensor(s); {bound or 'about '}"
                      f"{report.duration_s / 60:.1f} min on the bench"
                      + (f" (of which {warmup / 60:.1f} min lamp warm-up)" if warmup > 0 else ""))
            if report.upper_bound:
                out.print(f"  upper bounds, every point counted: {escape(report.upper_bound)}")
            if not report.ok:
                raise PreflightRefused(report.violations)
            if dry_run:
                return
            view = _ProgressView()
            session.engine.subscribe(view.on_event)
            _abort_on_signals(session.engine)
            with view.progress:
                runs = run_campaign(campaign, session, confirm_mount=_confirm_mount(view, yes), on_run=view.on_run)
        finally:
            session.close()
        _end_of_campaign(cat, runs)


def _end_of_campaign(cat, runs: list[int]) -> None:
    """Every run's summary, the last run's id alone on the last line; exit 1 unless the campaign completed."""
    if not runs:
        out.print("no run was started: the sensor was not confirmed mounted")
        raise typer.Exit(1)
    for run_id in runs:
        _print_run_summary(cat, run_id)
    last = cat.run(runs[-1])
    campaign_done = True
    if last["campaign_id"] is not None:
        campaign = cat.campaign(last["campaign_id"])
        campaign_done = campaign["status"] == "completed"
        if not campaign_done:
            out.print(f"campaign {last['campaign_id']}: {campaign['status']}; `sunbench resume {runs[-1]}` goes on "
                      "with it")
    print(runs[-1])
    if last["status"] != "completed" or not campaign_done:
        raise typer.Exit(1)  # aborted, failed or not mounted: scripts must not take it for a finished campaign
    if any(_ended_unsafe(cat, run_id) for run_id in runs):
        raise typer.Exit(1)  # the bench was left unsafe: nothing must start on it before someone looks


def _refuse_yes_on_a_real_bench(bench: Optional[Path], yes: bool) -> None:
    if yes and bench and load_bench_file(bench).simulation is None:
        raise typer.BadParameter("--yes confirms sensor mounts only on a simulated bench; on a real one the "
                                 "operator confirms each sensor when asked", param_hint="--yes")


def _refuse_a_busy_real_bench(bench: Optional[Path], catalogue: Optional[Path]) -> None:
    """A real bench's devices belong to the process driving it: a dry run there would home its table."""
    from .catalogue import Catalogue, CatalogueError

    holder = Catalogue.writer(catalogue or DEFAULT_CATALOGUE)
    if holder and bench and load_bench_file(bench).simulation is None:
        raise CatalogueError(f"the bench is in use by {holder}; dry-run the campaign on its dashboard (the "
                             "launcher's Dry run), or stop it first")


def _confirm_mount(view: _ProgressView, yes: bool):
    """The operator confirms each sensor to mount at the terminal (or `--yes` does, on a simulated bench)."""
    def confirm(request) -> bool:
        if yes:
            view.progress.console.print(f"{request.prompt()}: confirmed (--yes)")
            return True
        view.progress.stop()  # the question below the bar, not redrawn over
        try:
            prompt = request.prompt()
            return typer.confirm(f"{prompt[0].upper()}{prompt[1:]}. Is it mounted?", default=False, err=True)
        except typer.Abort:  # end of input: nobody to answer
            err.print("no answer: the sensor was not confirmed (pass --yes for an unattended simulated bench)")
            return False
        finally:
            view.progress.start()
    return confirm


def _print_run_summary(cat, run_id: int) -> None:
    run = cat.run(run_id)
    reason, unsafe = _reason_and_unsafe(cat, run)
    out.print(f"run {run_id} ({run['sensor_id']}): {run['status']}" + (f" — {escape(reason)}" if reason else ""))
    _print_unsafe(run_id, unsafe)


def _ended_unsafe(cat, run_id: int) -> str | None:
    """What the engine could not make safe when the run ended (its journal's "unsafe" event), or None."""
    return next((e["message"] for e in cat.events(run_id) if e["kind"] == "unsafe"), None)


def _reason_and_unsafe(cat, run: dict) -> tuple[str | None, str | None]:
    """The run's exit reason, and apart from it (the exit reason ends with it) what was left unsafe."""
    reason, unsafe = run.get("exit_reason"), _ended_unsafe(cat, run["id"])
    if unsafe and reason and reason.endswith(unsafe):
        reason = reason[: -len(unsafe)].rstrip("; ") or None
    return reason, unsafe


def _print_unsafe(run_id: int, unsafe: str | None) -> None:
    if unsafe:
        out.print(f"[bold red]run {run_id} {escape(unsafe)}[/]: see to the bench before the next run",
                  highlight=False)


@commands.command("runs")
@user_errors
def list_runs(catalogue: Optional[Path] = CatalogueOption) -> None:
    """The runs in the catalogue."""
    with open_catalogue(catalogue, readonly=True) as cat:
        table = Table(title="Runs")
        for name in ("run", "campaign", "sensor", "plan", "status", "points", "parent", "started (UTC)"):
            table.add_column(name)
        for r in cat.runs():
            table.add_row(str(r["id"]), str(r["campaign_id"] or ""), r["sensor_id"] or "", r["plan_name"], r["status"],
                          f"{r.get('n_points_recorded', 0)}/{r.get('n_points_planned') or '?'}",
                          str(r["parent_run_id"] or ""), (r.get("started_utc") or "")[:19])
        out.print(table)


@commands.command("show")
@user_errors
def show_run(run_id: int = typer.Argument(..., min=1, max=MAX_ID), catalogue: Optional[Path] = CatalogueOption) -> None:
    """A run: status, provenance, stages, calibrations with their accuracy."""
    from calibration.evaluation import AccuracyMetrics, MethodReport

    with open_catalogue(catalogue, readonly=True) as cat:
        run = cat.run(run_id)
        reason, unsafe = _reason_and_unsafe(cat, run)
        out.print(f"[bold]run {run_id}[/] · sensor {run['sensor_id']} ({run['family']}) · plan {run['plan_name']} "
                  f"· {run['status']}" + (f" ({escape(reason)})" if reason else ""))
        _print_unsafe(run_id, unsafe)
        lineage = cat.lineage(run_id)
        if len(lineage) > 1:
            out.print(f"lineage: runs {' → '.join(map(str, lineage))}")
        out.print(f"points recorded (lineage): {len(cat.completed_keys(lineage))} of {run['n_points_planned'] or '?'}")
        prov = run["provenance"]
        out.print(f"provenance: {'simulated' if prov.get('simulated') else 'real'} bench, "
                  f"config {prov.get('bench_config_hash', '')[:12]}, "
                  f"sunbench {prov.get('software_version')}, operator {prov.get('operator')}")
        for role, identity in (prov.get("devices") or {}).items():
            out.print(f"  {role}: {escape(str(identity))}")
        for key in ("exposure_ms", "centre_px", "tilt_stage"):
            value = cat.run_value(run_id, key)
            if value is not None:
                out.print(f"{key}: {escape(json.dumps(value))}")
        if run.get("family") == "qd":
            _show_qd_calibrations(cat, run_id)
            return
        if run.get("family") == "camera":
            _show_camera_calibrations(cat, run_id)
            return
        if run.get("family") == "css":
            _show_css_calibrations(cat, run_id)
            return
        if run.get("family") == "horizon":
            _show_horizon_calibration(cat, run_id)
            return
        reports, chosen, document = [], None, {}
        metrics = lambda m, key: AccuracyMetrics(**m[key]) if m.get(key) else None  # noqa: E731
        for c in cat.calibrations(run_id):
            m = c["metrics"]
            heldout, by_azimuth, by_ring = (metrics(m, "heldout"), metrics(m, "heldout_azimuth"),
                                            metrics(m, "heldout_ring"))
            if m.get("heldout_scheme") == "ring":
                heldout = by_ring
            elif m.get("heldout_scheme") == "azimuth":
                heldout = by_azimuth
            reports.append(MethodReport(c["method"], object(), metrics(m, "fitted"), heldout, m.get("error"),
                                        by_azimuth, by_ring, m.get("chi2_dof")))
            if c["chosen"]:
                chosen, document = c["method"], c["document"]
        if reports:
            out.print(metrics_table(reports, chosen))
        print_quality(document)


def _show_qd_calibrations(cat, run_id: int) -> None:
    """A QD run's calibrations: every method's held-out figures, the chosen one's rejected rows and warnings."""
    from calibration.qd.evaluation import AngularMetrics, QdMethodReport

    angular = lambda m: AngularMetrics(**m) if m else None  # noqa: E731
    reports, chosen, document = [], None, {}
    for c in cat.calibrations(run_id):
        m = c["metrics"]
        reports.append(QdMethodReport(c["method"], None if m.get("error") else c["document"], c["document"],
                                      angular(m.get("at_nodes")), angular(m.get("heldout")), m.get("heldout_scheme"),
                                      {k: angular(v) for k, v in (m.get("heldout_by_scheme") or {}).items()},
                                      m.get("chi2_dof"), m.get("error")))
        if c["chosen"]:
            chosen, document = c["method"], c["document"]
    if reports:
        out.print(qd_metrics_table(reports, chosen))
    for row in document.get("rejected") or []:
        out.print(f"rejected: row {row.get('row_id')}: {escape(str(row.get('reason')))}", highlight=False)
    for warning in document.get("warnings") or []:
        out.print(f"[yellow]warning:[/] {escape(warning)}")


def _show_camera_calibrations(cat, run_id: int) -> None:
    """A camera run's calibration: the held-out figures by scheme and the fit's, and its warnings."""
    def num(value, digits: int) -> str:
        return fmt(float("nan") if value is None else value, digits)

    for c in cat.calibrations(run_id):
        m, document = c["metrics"], c["document"]
        out.print(f"calibration {c['method']}{' (chosen)' if c['chosen'] else ''}: {m.get('n_points')} spots, fit RMS "
                  f"{num(m.get('fit_rms_deg'), 4)}°, χ²/dof {num(m.get('reduced_chi2'), 2)}", highlight=False)
        held = m.get("held_out") or {}
        for name in ("rings", "azimuths"):
            scheme = held.get(name) or {}
            if scheme:
                out.print(f"  held out, {name} left out: RMS {num(scheme.get('rms_deg'), 4)}°, max "
                          f"{num(scheme.get('max_deg'), 4)}° over {scheme.get('n_points')} spots", highlight=False)
        for warning in document.get("warnings") or []:
            out.print(f"[bold yellow]warning:[/] {escape(warning)}", highlight=False, soft_wrap=True)


def _show_horizon_calibration(cat, run_id: int) -> None:
    """A horizon run's calibration: the sensor's own errors ± 1σ, roll and pitch held out (check points, each disc
    radius left out) beside the nominal sensor's, its rejected edges and warnings."""
    for c in cat.calibrations(run_id):
        document = c["document"]
        if not c["chosen"] or not document:
            continue
        fit = document.get("fit") or {}
        out.print(horizon_parameters_table(document))
        out.print(f"χ²/dof {fmt(fit.get('chi2_dof', float('nan')), 2)} against the repeat scatter; phase residual RMS "
                  f"{fmt(fit.get('rms_deg', float('nan')), 4)}° over {fit.get('n_edges')} edges", highlight=False)
        out.print(horizon_accuracy_table(document.get("heldout")))
        for r in document.get("rejected") or []:
            out.print(f"rejected: {escape(json.dumps(r))}", highlight=False, soft_wrap=True)
        for warning in document.get("warnings") or []:
            out.print(f"[yellow]warning:[/] {escape(warning)}")


def _show_css_calibrations(cat, run_id: int) -> None:
    """A CSS run's calibrations (one per response law): the Sun's direction held out, at the check directions and at
    the fitted ones, the channels left out, and the chosen one's rejected readings and warnings."""
    def figures(m) -> str:
        if not m or not m.get("n_points"):
            return "—"
        return (f"RMS {fmt(m['rms_deg'] if m['rms_deg'] is not None else float('nan'), 4)}°, max "
                f"{fmt(m['max_deg'] if m['max_deg'] is not None else float('nan'), 4)}° over {m['n_points']} readings"
                + (f" ({m['n_degenerate']} degenerate)" if m.get("n_degenerate") else ""))

    chosen = {}
    for c in cat.calibrations(run_id):
        m = c["metrics"]
        out.print(f"calibration {c['method']} law{' (chosen)' if c['chosen'] else ''}: {len(m.get('channels') or [])} "
                  f"detector(s); the Sun's direction held out {figures(m.get('held_out'))}; check directions "
                  f"{figures(m.get('check'))}; fitted directions {figures(m.get('at_nodes'))}", highlight=False,
                  soft_wrap=True)
        for channel, fault in (m.get("faulty") or {}).items():
            out.print(f"  {channel} left out: {escape(str(fault))}", highlight=False)
        if c["chosen"]:
            chosen = c["document"]
    rejected = chosen.get("rejected") or []
    if rejected:
        out.print(f"[bold]{len(rejected)} rejected reading(s)[/]:", highlight=False)
        for r in rejected[:20]:
            out.print(f"  reading {r.get('row')}: {escape(str(r.get('channel') or 'every channel'))} "
                      f"{escape(str(r.get('reason')))}", highlight=False, soft_wrap=True)
        if len(rejected) > 20:
            out.print(f"  … and {len(rejected) - 20} more (the calibration document lists them)", highlight=False)
    for warning in chosen.get("warnings") or []:
        out.print(f"[bold yellow]warning:[/] {escape(warning)}", highlight=False, soft_wrap=True)


def print_quality(document: dict) -> None:
    """The chosen calibration's residual against the repeat scatter, its rejected frames and its warnings."""
    quality = document.get("quality")
    if quality:
        scatter, chi2 = quality.get("repeat_scatter_px"), quality.get("chi2_dof")
        out.print(f"{quality.get('frames')} frames at {quality.get('directions')} directions; repeat scatter "
                  + (f"{scatter:.4f} px per frame" if scatter is not None else "unknown (no repeats)")
                  + (f"; χ²/dof = {chi2:.2f}" if chi2 is not None else ""), highlight=False)
    rejected = document.get("rejected") or []
    if rejected:
        out.print(f"[bold]{len(rejected)} rejected frame(s)[/] (left out of every fit):", highlight=False)
        for r in rejected:
            where = f"reading {r['row']}" if r.get("row") is not None else "a frame"
            out.print(f"  {where} (zenith {r['zenith_deg']:.3f}°, azimuth {r['azimuth_deg']:.3f}°): "
                      f"{r['offset_px']:.2f} px off; {escape(r['reason'])}", highlight=False)
    for warning in (quality or {}).get("warnings", []):
        out.print(f"[bold yellow]warning:[/] {escape(warning)}", highlight=False, soft_wrap=True)


@commands.command("resume")
@user_errors
def resume_command(
    run_id: int = typer.Argument(..., min=1, max=MAX_ID, help="The interrupted run."),
    bench: Optional[Path] = BenchOption,
    catalogue: Optional[Path] = CatalogueOption,
    time_scale: Optional[float] = TimeScaleOption,
    yes: bool = YesOption,
) -> None:
    """Start a new run linked to RUN that measures only the missing points, then the rest of its campaign;
    prints the last run's id on the last line."""
    from .runner import resume_and_continue

    _refuse_yes_on_a_real_bench(bench, yes)
    with open_catalogue(catalogue) as cat:
        cat.mark_interrupted_runs()
        cat.mark_interrupted_campaigns()
        session = _session(bench, cat, time_scale)
        try:
            view = _ProgressView()
            session.engine.subscribe(view.on_event)
            _abort_on_signals(session.engine)
            with view.progress:
                runs = resume_and_continue(run_id, session, confirm_mount=_confirm_mount(view, yes), on_run=view.on_run)
        finally:
            session.close()
        _end_of_campaign(cat, runs)


@commands.command("export")
@user_errors
def export_run(
    run_id: int = typer.Argument(..., min=1, max=MAX_ID),
    format: str = typer.Option("csv", "--format", "-f", help="csv (the bench data CSV `sunbench fit cmos` or, "
                                                             "for a QD run, `fit qd` reads) or json."),
    output: Optional[Path] = typer.Option(None, "--output", "-o", help="File to write (default: stdout)."),
    catalogue: Optional[Path] = CatalogueOption,
) -> None:
    """Export a run (with the runs it resumed) as bench data CSV or as JSON."""
    from .families import family

    if format not in ("csv", "json"):
        raise typer.BadParameter("--format must be csv or json")
    with open_catalogue(catalogue, readonly=True) as cat:
        run = cat.run(run_id)
        lineage = cat.lineage(run_id)
        if format == "csv":
            target = output or Path("/dev/stdout")
            family(run["family"]).export_csv(cat, lineage, target, run["sensor_id"])  # what `fit <family>` reads
        else:
            document = {"run": run, "lineage": lineage, "points": cat.points(lineage),
                        "readings": [r.to_dict() for r in cat.readings(lineage)],
                        "calibrations": cat.calibrations(run_id), "events": cat.events(run_id)}
            text = json.dumps(document, indent=2, default=str)
            if output:
                output.write_text(text + "\n")
            else:
                print(text)
        if output:
            err.print(f"run {run_id} exported to {escape(str(output))}")


@commands.command("fleet")
@user_errors
def fleet_command(campaign_id: int = typer.Argument(..., min=1, max=MAX_ID),
                  catalogue: Optional[Path] = CatalogueOption) -> None:
    """One row per sensor of a fleet campaign, in the columns of seed 003 Table 6.1 (held out)."""
    with open_catalogue(catalogue, readonly=True) as cat:
        campaign = cat.campaign(campaign_id)
        table = Table(title=f"Campaign {campaign_id} ({escape(campaign['name'])}): accuracy held out [°]")
        for name in ("No.", "sensor", "status", "run", "method", "RMS zenith", "RMS azimuth", "RMS vector",
                     "held out, other families"):
            table.add_column(name, justify="right" if name.startswith("RMS") else "left")
        for i, row in enumerate(cat.fleet(campaign_id), 1):
            metrics = row.get("metrics") or {}
            h = metrics.get("heldout") or {}
            table.add_row(str(i), row["sensor_id"], row["status"], str(row.get("run_id") or ""),
                          row.get("method") or "",
                          fmt(h.get("rms_zenith_deg", float("nan"))), fmt(h.get("rms_azimuth_deg", float("nan"))),
                          fmt(h.get("rms_vector_deg", float("nan"))), _fleet_other_figures(metrics))
        out.print(table)


def _fleet_other_figures(metrics: dict) -> str:
    """A fleet row's held-out figure for a family whose reading is no direction in the body frame: a horizon
    sensor's roll and pitch at the check points, a CSS head's Sun direction held out."""
    calibrated = (metrics.get("check") or {}).get("calibrated") if isinstance(metrics.get("check"), dict) else None
    if calibrated and calibrated.get("n_scans"):
        return (f"check points: roll RMS {fmt(calibrated['roll_rms_deg'], 4)}°, pitch RMS "
                f"{fmt(calibrated['pitch_rms_deg'], 4)}°")
    sun = metrics.get("held_out") or {}
    if sun.get("n_points") and sun.get("rms_deg") is not None:
        return f"the Sun's direction: RMS {fmt(sun['rms_deg'], 4)}°"
    return ""
