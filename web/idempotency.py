"""Idempotency keys for queuing campaigns: a Start clicked twice (or a request sent again after a lost answer)
queues one campaign.

The launcher sends an ``Idempotency-Key`` header with each Start, the same key for the same form. The first
request with a key queues the campaign; another one with the same key within :data:`TTL_S` answers the first
one's campaign id (200 instead of 202) and queues nothing; with the same key but another campaign it is refused
(422), as the IETF draft on the header has it.
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable
from dataclasses import dataclass

#: How long a key is remembered [s]: a few minutes covers a double click and a client's retries
TTL_S = 600.0


class KeyReused(Exception):
    """The key already queued another campaign."""


@dataclass(frozen=True)
class _Entry:
    at: float
    fingerprint: str
    campaign_id: int


class IdempotencyKeys:
    """Keys seen in the last `ttl_s` seconds and the campaign each queued (in memory: a restart forgets them,
    and a client retrying across a restart gets a second campaign, which it can see in the list)."""

    def __init__(self, ttl_s: float = TTL_S, clock: Callable[[], float] = time.monotonic):
        self.ttl_s = ttl_s
        self._clock = clock
        self._lock = threading.Lock()
        self._entries: dict[str, _Entry] = {}

    def submit(self, key: str, fingerprint: str, submit: Callable[[], int]) -> tuple[int, bool]:
        """``(campaign id, replayed)``: `submit()`'s campaign the first time `key` is seen, else the campaign it
        queued then (replayed True). Raises :class:`KeyReused` when that was another campaign (`fingerprint`).

        The lock is held while `submit` runs, so a second request with the key that arrives meanwhile (the
        double click) waits for the first one's answer instead of queuing its own campaign."""
        with self._lock:
            now = self._clock()
            self._entries = {k: e for k, e in self._entries.items() if now - e.at < self.ttl_s}
            entry = self._entries.get(key)
            if entry is not None:
                if entry.fingerprint != fingerprint:
                    raise KeyReused(f"the Idempotency-Key {key!r} already queued campaign {entry.campaign_id}, "
                                    "another campaign than this one: send a new key for a new campaign")
                return entry.campaign_id, True
            campaign_id = submit()  # a refusal raises: the key stays free for a corrected campaign
            self._entries[key] = _Entry(now, fingerprint, campaign_id)
            return campaign_id, False
