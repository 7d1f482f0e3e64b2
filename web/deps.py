"""Typed dependencies: handlers take ``ServiceDep``, ``CatalogueDep``, ``SettingsDep`` as plain types."""

from __future__ import annotations

import queue
from typing import Annotated

from fastapi import Depends, Request

from bench.catalogue import Catalogue
from bench.service import BenchService

from .security import require_read, require_token
from .settings import WebSettings


def get_service(request: Request) -> BenchService:
    return request.app.state.service


def get_catalogue(request: Request) -> Catalogue:
    # the service's own catalogue: its read API is thread-safe, and a second writer would be refused
    return request.app.state.service.catalogue


def get_settings(request: Request) -> WebSettings:
    return request.app.state.settings


async def subscribe_events(request: Request):
    """A bounded queue of the bus's events for one client, dropped when its response ends.

    Subscribing here (before the response starts) rather than in the stream means no event published
    after the request was answered can be missed. Async, so the cleanup runs even when a disconnect
    cancels the request.
    """
    bus = request.app.state.service.bus
    q = bus.subscribe()
    try:
        yield q
    finally:
        bus.unsubscribe(q)


ServiceDep = Annotated[BenchService, Depends(get_service)]
CatalogueDep = Annotated[Catalogue, Depends(get_catalogue)]
SettingsDep = Annotated[WebSettings, Depends(get_settings)]
EventQueueDep = Annotated[queue.Queue, Depends(subscribe_events)]

#: router-level guards
TOKEN = [Depends(require_token)]
READ = [Depends(require_read)]
