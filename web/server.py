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
from urllib.parse import unquote_plus

import uvicorn
from fastapi import FastAPI


class Shutdown(threading.Event):
    """``app.state.shutdown``: a :class:`threading.Event` that also runs callbacks when it is set, so what
    sleeps in the event loop (an event stream waiting for the next event) ends at once without polling it.

    :meth:`set` runs in uvicorn's signal handler, on the event loop's thread, possibly while that thread is
    inside :meth:`add_callback`: so it takes no lock, it reads the callbacks' current tuple (replaced, never
    mutated, under the lock by add and remove).
    """

    def __init__(self):
        super().__init__()
        self._callbacks_lock = threading.Lock()
        self._callbacks: tuple[Callable[[], None], ...] = ()

    def set(self) -> None:
        super().set()
        for callback in self._callbacks:
            callback()

    def add_callback(self, callback: Callable[[], None]) -> None:
        """Call `callback` (in the thread that sets the event, so it must be thread-safe) when the event is set;
        at once if it already is."""
        with self._callbacks_lock:
            self._callbacks += (callback,)
        if self.is_set():
            callback()

    def remove_callback(self, callback: Callable[[], None]) -> None:
        with self._callbacks_lock:
            self._callbacks = tuple(c for c in self._callbacks if c is not callback)


class RedactToken(logging.Filter):
    """Masks the value of every ``token`` query parameter (however its name is percent-encoded: the API decodes
    it) in the arguments of uvicorn's access records (the request line's path and query is the third), leaving
    their shape as uvicorn's access formatter expects it."""

    _QUERY_ITEM = re.compile(r"(?<=[?&])([^=&\s]*)=([^&\s]*)")

    @classmethod
    def redact(cls, text: str) -> str:
        def item(match: re.Match) -> str:
            name = match.group(1)
            return f"{name}=***" if unquote_plus(name).lower() == "token" else match.group(0)
        return cls._QUERY_ITEM.sub(item, text)

    def filter(self, record: logging.LogRecord) -> bool:
        if isinstance(record.args, tuple):
            record.args = tuple(self.redact(a) if isinstance(a, str) else a for a in record.args)
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
