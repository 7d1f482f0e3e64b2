"""`sunbench serve`: the dashboard and its API on the bench. `register` adds it to the `sunbench` app
(cli/main.py); the web modules are imported when the command runs, so the rest of the command line starts
without FastAPI.
"""

from __future__ import annotations

from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape

from bench.benchfile import BenchFile, load_bench_file
from bench.cli_common import BenchOption, CatalogueOption, TimeScaleOption, open_catalogue, out, user_errors


def register(app: typer.Typer) -> None:
    """Add `serve` to `app`."""
    app.command("serve")(serve_command)


@user_errors
def serve_command(
    bench: Optional[Path] = BenchOption,
    catalogue: Optional[Path] = CatalogueOption,
    host: str = typer.Option("127.0.0.1", help="Interface to listen on (loopback only by default)."),
    port: int = typer.Option(8000, help="TCP port."),
    time_scale: Optional[float] = TimeScaleOption,
    public_read: bool = typer.Option(False, "--public-read", help="Let read-only views work without the token."),
    allowed_host: Optional[list[str]] = typer.Option(
        None, "--allowed-host", help="Another name the server answers to (besides 127.0.0.1, localhost, [::1] and "
                                     "--host); repeatable. Requests naming any other host get 400 (DNS rebinding)."),
) -> None:
    """Serve the bench's web API (OpenAPI at /docs); commands need the token printed at first start."""
    from bench.service import BenchService

    from .app import create_app
    from .security import default_config_dir, load_or_create_token
    from .server import serve
    from .settings import WebSettings

    token, created = load_or_create_token()
    token_file = escape(str(default_config_dir() / "token"))
    if created:  # shown once; it stays in the user's config directory
        out.print(f"API token (created now, kept in {token_file}): [bold]{token}[/]", soft_wrap=True)
    settings = WebSettings(host=host, port=port, public_read=public_read, token=token,
                           allowed_hosts=tuple(allowed_host or ()))
    bench_file = load_bench_file(bench) if bench else BenchFile()
    with open_catalogue(catalogue) as cat:
        service = BenchService(bench_file, cat, time_scale=time_scale).start()
        try:
            where = escape(str(bench)) if bench else "the simulated bench"
            if bench_file.simulation is not None and time_scale is not None:
                where += f", simulated time ×{time_scale:g}"
            out.print(f"sunbench dashboard on http://{host}:{port}/ ({where})", soft_wrap=True)
            out.print(f"API and its documentation: http://{host}:{port}/docs · the token: {token_file} · Ctrl-C stops",
                      soft_wrap=True)
            serve(create_app(service, settings=settings))
        finally:
            service.close()
