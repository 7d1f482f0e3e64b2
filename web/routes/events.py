"""The bench's events as server-sent events."""

from __future__ import annotations

import json
import queue
import time
from collections.abc import AsyncIterator

import anyio
import numpy as np
from fastapi import APIRouter, Depends, Request
from fastapi.sse import EventSourceResponse, ServerSentEvent

from ..deps import EventQueueDep, SettingsDep
from ..security import require_read_stream

# the token may also come as ?token=: a browser's EventSource cannot send headers
router = APIRouter(prefix="/api", tags=["events"], dependencies=[Depends(require_read_stream)])


def _plain(value):
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def to_sse(event: dict) -> ServerSentEvent:
    """One bus event: its `kind` is the SSE event name, the whole dict is the JSON data."""
    return ServerSentEvent(event=str(event.get("kind", "message")), raw_data=json.dumps(event, default=_plain))


@router.get("/events", response_class=EventSourceResponse, summary="Live bench events (SSE)")
async def stream_events(request: Request, events: EventQueueDep, settings: SettingsDep) -> AsyncIterator[ServerSentEvent]:
    """Server-sent events of the bench: ``status``, ``queued``, ``run-started``, ``state``, ``point``,
    ``log``, ``warning``, ``finished``, ``campaign-finished``, ``error``; each event's name is its kind and its
    data the JSON event. A ``: keep-alive`` comment is sent when idle. Each client has its own bounded
    queue: a slow client loses its oldest events, it never holds up the bench."""
    idle_since = time.monotonic()
    shutdown = request.app.state.shutdown
    while not shutdown.is_set():
        try:
            event = events.get_nowait()
        except queue.Empty:
            if time.monotonic() - idle_since >= settings.sse_keepalive_s:
                idle_since = time.monotonic()
                yield ServerSentEvent(comment="keep-alive")
            # polling, not a blocking get in a worker thread: a cancelled request ends here at once,
            # and idle clients hold no threads
            await anyio.sleep(settings.sse_poll_s)
            continue
        idle_since = time.monotonic()
        yield to_sse(event)
