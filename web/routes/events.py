"""The bench's events as server-sent events."""

from __future__ import annotations

import json
from collections.abc import AsyncIterator
from typing import Annotated

import numpy as np
from fastapi import APIRouter, Depends
from fastapi.responses import StreamingResponse
from fastapi.sse import EventSourceResponse, format_sse_event

from bench.service import AsyncSubscription

from ..deps import SettingsDep, subscribe_events
from ..security import require_read_stream

# the token may also come as ?token=: a browser's EventSource cannot send headers
router = APIRouter(prefix="/api", tags=["events"], dependencies=[Depends(require_read_stream)])

KEEP_ALIVE = format_sse_event(comment="keep-alive")
_STREAM_DOC = {200: {"description": "An endless `text/event-stream` of named events, each a JSON object",
                     "content": {"text/event-stream": {"schema": {"type": "string"}}}}}


def _plain(value):
    if isinstance(value, np.generic | np.ndarray):
        return value.tolist()
    raise TypeError(f"{type(value).__name__} is not JSON serialisable")


def sse_message(event: dict) -> bytes:
    """One bus event on the wire: its `kind` is the SSE event name, the whole dict is the JSON data."""
    return format_sse_event(event=str(event.get("kind", "message")), data_str=json.dumps(event, default=_plain))


# the bus encodes each event once, in the server's loop, for every stream
Subscription = Annotated[AsyncSubscription, Depends(subscribe_events(encode=sse_message))]


@router.get("/events", response_class=StreamingResponse, responses=_STREAM_DOC, summary="Live bench events (SSE)")
async def stream_events(events: Subscription, settings: SettingsDep) -> EventSourceResponse:
    """Server-sent events of the bench: ``status``, ``queued``, ``run-started``, ``state``, ``point`` (its key,
    stage, table and body angles, exposure, spots and which of them were clipped at the detector's edge),
    ``record`` (a stage's result: the exposure, the centre, the tilt stage, a physical batch's decision), ``log``,
    ``warning``, ``unsafe`` (the run ended without the bench made safe), ``finished``, ``campaign-finished``,
    ``mount``, ``mount-answered``, ``resume-queued``, ``error``; each event's name is its kind and its data the
    JSON event. A ``: keep-alive`` comment is sent when idle. Each client has its own bounded
    buffer: a slow client loses its oldest events, it never holds up the bench."""

    async def body() -> AsyncIterator[bytes]:
        # sleeps until an event, the keep-alive time or shutdown (which closes the subscription): no polling
        while not events.closed:
            batch = await events.next_batch(settings.sse_keepalive_s)
            if batch:
                yield b"".join(batch)  # what queued while the client was busy goes out in one write
            elif not events.closed:
                yield KEEP_ALIVE

    # not FastAPI's own SSE streaming (a generator endpoint): its two tasks and two memory streams per client
    # cost the event loop more per event than the write itself
    return EventSourceResponse(body(), headers={"Cache-Control": "no-cache", "X-Accel-Buffering": "no"})
