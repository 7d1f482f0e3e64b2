"""Simulated time, shared by every model of a simulated bench."""

from __future__ import annotations

import threading
import time


class SimClock:
    """Simulated time [s] = time scale × wall time elapsed + explicit jumps.

    Parameters
    ----------
    time_scale : float
        1 runs in real time (demos), 10 ten times faster, 0 is *instant*: simulated time stands still
        except when a model jumps it forward to the end of what a caller is waiting for (a move, a
        warm-up, an exposure), so tests run without sleeping and timestamps stay consistent.
    wall : callable
        Source of wall time [s] (injectable for tests).
    """

    def __init__(self, time_scale: float = 1.0, wall=time.monotonic):
        if not time_scale >= 0:
            raise ValueError(f"`time_scale` must be >= 0, got {time_scale}")
        self.time_scale = float(time_scale)
        self._wall = wall
        self._wall0 = wall()
        self._offset = 0.0
        self._lock = threading.Lock()

    @property
    def instant(self) -> bool:
        return self.time_scale == 0.0

    def now(self) -> float:
        with self._lock:
            return self._offset + self.time_scale * (self._wall() - self._wall0)

    def advance(self, dt_s: float) -> None:
        """Jump simulated time forward by `dt_s` [s]."""
        if dt_s > 0:
            with self._lock:
                self._offset += dt_s

    def advance_to(self, t_s: float) -> None:
        """Jump simulated time forward to `t_s` if it lies ahead [s]."""
        self.advance(t_s - self.now())
