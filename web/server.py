"""Serve the API with uvicorn, ending the event streams as soon as shutdown is asked for.

uvicorn waits for open connections before it runs the app's lifespan shutdown, and an event stream never
closes by itself, so the lifespan alone would make Ctrl+C hang on every open dashboard. The server below
sets ``app.state.shutdown`` (a :class:`Shutdown`) from the signal handler instead, which closes every
stream's subscription at once.

The access log shows each request line, and an EventSource sends its token in the query
(``/api/events?token=...``): :class:`RedactToken` masks it.
"""

from __future__ import annotations

import logging
import re
import threading
from collections.abc import Callable

import uvicorn
from fastapi import FastAPI


class Shutdown(threading.Event):
    """``app.state.shutdown``: a :class:`threading.Event` that also runs callbacks when it is set, so what
    sleeps in the event loop (an event stream waiting for the next event) ends at once without polling it."""

    def __init__(self):
        super().__init__()
        self._callbacks_lock = threading.Lock()
        self._callbacks: set[Callable[[], None]] = set()

    def set(self) -> None:
        super().set()
        with self._callbacks_lock:
            callbacks = list(self._callbacks)
        for callback in callbacks:
            callback()

    def add_callback(self, callback: Callable[[], None]) -> None:
        """Call `callback` (in the thread that sets the event, so it must be thread-safe) when the event is set;
        at once if it already is."""
        with self._callbacks_lock:
            self._callbacks.add(callback)
        if self.is_set():
            callback()

    def remove_callback(self, callback: Callable[[], None]) -> None:
        with self._callbacks_lock:
            self._callbacks.discard(callback)


class RedactToken(logging.Filter):
    """Masks ``token=<value>`` in the arguments of uvicorn's access records (the request line's path and
    query is the third), leaving their shape as uvicorn's access formatter expects it."""

    _TOKEN = re.compile(r"(?<=[?&])token=[^&\s]*")

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple):
            record.args = tuple(self._TOKEN.sub("token=***", a) if isinstance(a, str) else a for a in record.args)
        return True


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
    config = uvicorn.Config(app, host=settings.host, port=settings.port, log_level="info")
    access = logging.getLogger("uvicorn.access")  # configured by uvicorn.Config above
    if not any(isinstance(f, RedactToken) for f in access.filters):
        access.addFilter(RedactToken())
    BenchServer(app, config).run()
