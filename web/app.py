"""The web API of the bench: ``create_app(service, settings=...)``.

The app only enqueues commands to the :class:`~bench.service.BenchService` and reads its status and its
catalogue; it holds no science. Errors of the layers below map to HTTP here, once, so routes stay thin:
an illegal engine transition or a busy bench is 409, a limit or a preflight refusal is 422, an unknown
catalogue id is 404. Every request first passes :class:`web.guard.Guard` (host check, body limit, security
headers).
"""

from __future__ import annotations

import math
from contextlib import asynccontextmanager

from fastapi import FastAPI, Request
from fastapi.encoders import jsonable_encoder
from fastapi.exceptions import RequestValidationError
from fastapi.responses import JSONResponse
from fastapi.routing import APIRoute

from bench.catalogue import CatalogueError
from bench.engine import IllegalTransition
from bench.runner import PreflightRefused, ResumeRefused
from drivers.errors import LimitError

from .guard import Guard
from .idempotency import IdempotencyKeys
from .routes import (
    camera,
    campaigns,
    commands,
    css,
    docs,
    downloads,
    events,
    field,
    fits,
    horizon,
    pages,
    qd,
    run,
    runs,
    status,
)
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
    {"name": "field", "description": "Field data against the real Sun: the errors over time, the site located."},
]


def _operation_id(route: APIRoute) -> str:
    # stable ids ("runs-read_run") keep a generated client's method names stable
    return f"{route.tags[0]}-{route.name}".replace(" ", "_") if route.tags else route.name


def _detail(status_code: int, detail) -> JSONResponse:
    return JSONResponse({"detail": detail}, status_code=status_code)


def _json_safe(value):
    """`value` with every non-finite float as its name: a refused NaN must not make the refusal unencodable."""
    if isinstance(value, float) and not math.isfinite(value):
        return str(value)
    if isinstance(value, dict):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_json_safe(v) for v in value]
    return value


def _install_error_handlers(app: FastAPI) -> None:
    @app.exception_handler(RequestValidationError)
    async def _invalid(request: Request, exc: RequestValidationError):
        # FastAPI's own handler echoes each error's input, and a NaN there (Python's JSON reader takes `NaN`)
        # made the 422 itself fail as a 500
        return _detail(422, _json_safe(jsonable_encoder(exc.errors())))

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


class BenchApp(FastAPI):
    """FastAPI with :class:`~web.guard.Guard` around its whole middleware stack, so that even the answer of its
    server-error handler (a 500) carries the security headers."""

    def build_middleware_stack(self):
        return Guard(super().build_middleware_stack(), self.state.settings)


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

    # /docs is served from the installed Swagger UI (web/routes/docs.py), not FastAPI's CDN page; no /redoc
    app = BenchApp(title="sunbench", summary="Sun-sensor calibration bench", version="1",
                   openapi_tags=TAGS, generate_unique_id_function=_operation_id, lifespan=lifespan,
                   docs_url=None, redoc_url=None)
    app.state.service = service
    app.state.settings = settings
    app.state.shutdown = shutdown
    app.state.idempotency = IdempotencyKeys()
    _install_error_handlers(app)
    for module in (status, commands, campaigns, run, runs, fits, qd, camera, css, horizon, field, downloads, events,
                   docs):
        app.include_router(module.router)
    pages.install(app)  # the dashboard: /, /launch, /run, /results, /fleet, /field and /static
    return app
