"""What suspends a run: the one definition of the bench's interlocks.

The bench file's ``interlocks:`` section (:class:`bench.benchfile.InterlocksConfig`) builds an
:class:`Interlocks` with :meth:`~bench.benchfile.InterlocksConfig.interlocks`; the run engine looks at it
between frames and at every checkpoint.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass


@dataclass(frozen=True)
class Interlocks:
    """What suspends a run.

    Attributes
    ----------
    sensor_max_temperature_c : float
        Above this the sensor is too hot [°C].
    lamp_fault : bool
        A lamp fault (or open interlock of the supply) suspends the run.
    enclosure_open : callable or None
        Returns True while the enclosure is open (a door switch); None when the bench has none.
    poll_s : float
        How often a suspended run looks at the interlocks [s].
    hold_off_s : float
        How long a cleared interlock must stay clear before the run goes on [s].
    """

    sensor_max_temperature_c: float = 60.0
    lamp_fault: bool = True
    enclosure_open: Callable[[], bool] | None = None
    poll_s: float = 0.5
    hold_off_s: float = 1.0


#: The interlocks of a bench file without an ``interlocks:`` section (and of an engine given none).
DEFAULT_INTERLOCKS = Interlocks()

#: Polling and hold-off of a simulated bench, whose door and lamp change only when a test says so [s].
SIMULATED_TIMING = {"poll_s": 0.05, "hold_off_s": 0.0}
