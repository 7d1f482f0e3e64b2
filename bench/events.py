"""The bench's one event type, and the journal that keeps the events worth keeping.

The engine emits a :class:`BenchEvent` for everything it does and reads; whoever wants them subscribes: the
journal (the catalogue's ``events`` table, for the events marked ``journal``), the service's event stream
and status cache, and the CLI's progress view. One vocabulary for all of them (research note
anchors-orchestration: Bluesky's documents go to callbacks, the engine knows none of them).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any


@dataclass(frozen=True)
class BenchEvent:
    """Something the bench did or read.

    Attributes
    ----------
    kind : str
        "state", "point", "table", "source", "sensor", "log", "warning", "record", "paused", "suspended",
        "running", "unsafe", "error", "finished" …
    run_id : int or None
        The run it belongs to (None between runs: a jog, the lamp switched by hand).
    data : dict
        The event's values (JSON-ready).
    message : str
        The journal's line, in words ("" for readings that only a live view wants).
    journal : bool
        Kept in the run's journal (the catalogue's ``events`` table).
    t_s : float
        When, as seconds since the epoch.
    """

    kind: str
    run_id: int | None
    data: dict = field(default_factory=dict)
    message: str = ""
    journal: bool = False
    t_s: float = field(default_factory=time.time)

    def to_dict(self) -> dict[str, Any]:
        """The event as the event stream sends it: kind, run id, its data and, when it has one, its message."""
        out = {"kind": self.kind, "run_id": self.run_id, **self.data}
        if self.message and "message" not in out:
            out["message"] = self.message
        return out


class Journal:
    """Subscriber that writes the journaled events to the catalogue (a run's, or the bench's when no run is
    going on: an emergency stop between runs)."""

    def __init__(self, catalogue):
        self.catalogue = catalogue

    def __call__(self, event: BenchEvent) -> None:
        if event.journal:
            self.catalogue.log_event(event.run_id, event.kind, event.message or event.kind, event.data or None)
