"""Serve the API with uvicorn, ending the event streams as soon as shutdown is asked for.

uvicorn waits for open connections before it runs the app's lifespan shutdown, and an event stream never
closes by itself, so the lifespan alone would make Ctrl+C hang on every open dashboard. The server below
sets ``app.state.shutdown`` from the signal handler instead, and the streams end within one poll.
"""

from __future__ import annotations

import uvicorn
from fastapi import FastAPI


class BenchServer(uvicorn.Server):
    """A :class:`uvicorn.Server` that tells the app's event streams to end when it is asked to exit."""

    def __init__(self, app: FastAPI, config: uvicorn.Config):
        super().__init__(config)
        self._shutdown = app.state.shutdown

    def handle_exit(self, sig, frame) -> None:
        self._shutdown.set()
        super().handle_exit(sig, frame)


def serve(app: FastAPI) -> None:
    """Run `app` (from :func:`web.app.create_app`) on its settings' host and port until interrupted."""
    settings = app.state.settings
    BenchServer(app, uvicorn.Config(app, host=settings.host, port=settings.port, log_level="info")).run()
