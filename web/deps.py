"""Typed dependencies: handlers take ``ServiceDep``, ``CatalogueDep``, ``SettingsDep`` as plain types."""

from __future__ import annotations

from collections.abc import Callable
from typing import Annotated

from fastapi import Depends, Path, Query, Request

from bench.catalogue import Catalogue
from bench.service import BenchService

from .security import require_read, require_token
from .settings import WebSettings


# async although they never wait: FastAPI runs a plain `def` dependency in its thread pool, and that hop on
# every request costs the event loop more than the lookup, and the engine's thread a GIL hand-off
async def get_service(request: Request) -> BenchService:
    return request.app.state.service


async def get_catalogue(request: Request) -> Catalogue:
    # the service's own catalogue: its read API is thread-safe, and a second writer would be refused
    return request.app.state.service.catalogue


async def get_settings(request: Request) -> WebSettings:
    return request.app.state.settings


def subscribe_events(encode: Callable[[dict], object] | None = None):
    """A dependency giving each request its own bounded buffer of the bus's events, dropped when its response
    ends and closed at shutdown. `encode` is what the buffer holds per event (see
    :meth:`bench.service.EventBus.subscribe_async`: it runs once per event for all clients).

    Subscribing in a dependency (before the response starts) rather than in the stream means no event
    published after the request was answered can be missed. Async, so the subscription belongs to the
    server's event loop and its cleanup runs even when a disconnect cancels the request.
    """
    async def subscription(request: Request):
        bus = request.app.state.service.bus
        shutdown = request.app.state.shutdown
        events = bus.subscribe_async(encode)
        shutdown.add_callback(events.close)
        try:
            yield events
        finally:
            shutdown.remove_callback(events.close)
            bus.unsubscribe_async(events)

    return subscription


#: The largest id the catalogue can hold (SQLite's INTEGER): a larger one is refused as a 422 naming the parameter,
#: not passed on to overflow in the database
MAX_ID = 2**63 - 1

#: ids in paths and queries, each bounded 1 … 2⁶³−1
RunId = Annotated[int, Path(ge=1, le=MAX_ID, description="A run's id")]
CampaignId = Annotated[int, Path(ge=1, le=MAX_ID, description="A campaign's id")]
CampaignFilter = Annotated[int | None, Query(ge=1, le=MAX_ID, description="Only this campaign's")]
AfterId = Annotated[int, Query(ge=0, le=MAX_ID, description="The id of the last event the client saw (0: none)")]

ServiceDep = Annotated[BenchService, Depends(get_service)]
CatalogueDep = Annotated[Catalogue, Depends(get_catalogue)]
SettingsDep = Annotated[WebSettings, Depends(get_settings)]

#: router-level guards
TOKEN = [Depends(require_token)]
READ = [Depends(require_read)]
