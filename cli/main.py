"""`sunbench`: the Typer app, composed of every layer's commands.

Each command module adds its commands with `register(app)`: `bench.cli` (fit, apply, header, demo, sim),
`bench.cli_runs` (run, runs, show, resume, export, fleet), `bench.cli_field` (field), `bench.cli_study` (study) and
`web.cli` (serve). They share `bench.cli_common` (consoles, user errors, options) and import nothing of each other.
"""

from __future__ import annotations

import typer

from bench import cli as bench_cli
from bench import cli_field, cli_runs, cli_study
from web import cli as web_cli


def build_app() -> typer.Typer:
    """A new `sunbench` app with every command (in the order `sunbench --help` lists them)."""
    app = typer.Typer(help="sunbench: sun-sensor calibration bench.", no_args_is_help=True, add_completion=False)
    for module in (bench_cli, cli_runs, cli_field, cli_study, web_cli):
        module.register(app)
    return app


app = build_app()
