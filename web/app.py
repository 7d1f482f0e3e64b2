"""The web API of the bench: ``create_app(service, settings=...)``.

The app only enqueues commands to the :class:`~bench.service.BenchService` and reads its status and its
catalogue; it holds no science. Errors of the layers below map to HTTP here, once, so routes stay thin:
an illegal engine transition or a busy bench is 409, a limit or a preflight refusal is 422, an unknown
catalogue id is 404.
"""

from __future__ import annotations

from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute

from bench.catalogue import CatalogueError
from bench.engine import IllegalTransition
from bench.runner import PreflightRefused, ResumeRefused
from drivers.errors import LimitError

from .routes import campaigns, commands, downloads, events, fits, pages, run, runs, status
from .server import Shutdown
from .settings import WebSettings

TAGS = [
    {"name": "status", "description": "The cached bench status and the live frame."},
    {"name": "bench", "description": "Manual commands (token required); refused while a run owns the bench."},
    {"name": "campaigns", "description": "Preflight, queue and follow calibration campaigns."},
    {"name": "run control", "description": "Pause, resume or abort the run in progress, confirm a fleet's next "
                                           "sensor (token required)."},
    {"name": "runs", "description": "Recorded runs, their points and fitted calibrations."},
    {"name": "downloads", "description": "Bench data CSV, calibration JSON and C headers."},
    {"name": "events", "description": "Server-sent events of the bench."},
]


def _operation_id(route: APIRoute) -> str:
    # stable ids ("runs-read_run") keep a generated client's method names stable
    return f"{route.tags[0]}-{route.name}".replace(" ", "_") if route.tags else route.name


def _detail(status_code: int, detail) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=status_code)


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(IllegalTransition)  # BenchBusy is one too
    async def _conflict(request: Request, exc: IllegalTransition):
        return _detail(409, str(exc))

    @app.exception_handler(ResumeRefused)
    async def _not_resumable(request: Request, exc: ResumeRefused):
        return _detail(409, str(exc))

    @app.exception_handler(LimitError)
    async def _limit(request: Request, exc: LimitError):
        return _detail(422, str(exc))

    @app.exception_handler(PreflightRefused)
    async def _refused(request: Request, exc: PreflightRefused):
        return _detail(422, {"violations": list(exc.violations)})

    @app.exception_handler(CatalogueError)
    async def _catalogue(request: Request, exc: CatalogueError):
        message = str(exc)
        return _detail(404 if message.startswith("no ") else 409, message)


def create_app(service, *, settings: WebSettings) -> FastAPI:
    """Build the API around a started bench service.

    Parameters
    ----------
    service : bench.service.BenchService
        Owned by the caller, who starts and closes it (tests build it on the simulated bench).
    settings : WebSettings

    Returns
    -------
    fastapi.FastAPI
    """
    shutdown = Shutdown()

    @asynccontextmanager
    async def lifespan(app: FastAPI):
        yield
        shutdown.set()  # closes the event streams, so the server does not wait on them to stop

    app = FastAPI(title="sunbench", summary="Sun-sensor calibration bench", version="1",
                  openapi_tags=TAGS, generate_unique_id_function=_operation_id, lifespan=lifespan)
    app.state.service = service
    app.state.settings = settings
    app.state.shutdown = shutdown
    _install_error_handlers(app)
    for module in (status, commands, campaigns, run, runs, fits, downloads, events):
        app.include_router(module.router)
    pages.install(app)  # the dashboard: /, /launch, /run, /results, /fleet and /static
    return app
