"""A manual rotation stage: the operator turns it and types in the angle read from its scale.

Seed 003's stages (LJ750/M, PR01/M, Standa 7VT188-20) are most likely manual (anchors-protocols §0, which
asks for "a *manual axis* backend (operator prompt / typed-in reading) beside the motorised ones"). The
driver asks through an injectable callback, so the bench (console, web dashboard) chooses how to ask and
tests answer without a human.
"""

from __future__ import annotations

import math
from collections.abc import Callable

from .errors import DeviceError, DeviceFault
from .interfaces import Limits, RotaryAxis

#: ``ask(axis_name, target_deg) -> angle read from the scale [°]``, or None when the operator cancels.
AskCallback = Callable[[str, float], "float | None"]


class OperatorCancelled(DeviceError):
    """The operator declined to set the stage (the ask callback returned None)."""


def console_ask(axis_name: str, target_deg: float) -> float | None:
    """Ask on the console: set `axis_name` to `target_deg` [°] and type the angle read from the scale.

    Returns the typed angle [°], or None when the operator types ``c`` (cancel) or closes the input.
    Not used by the tests (it calls :func:`input`).
    """
    prompt = (f"Set {axis_name} to {target_deg:.3f}° and type the angle you read on its scale "
              f"(c = cancel): ")
    while True:
        try:
            text = input(prompt).strip()
        except EOFError:
            return None
        if text.lower() in ("c", "cancel", "q"):
            return None
        try:
            value = float(text.replace(",", "."))
        except ValueError:
            print(f"{text!r} is not a number; type the angle in degrees, e.g. {target_deg:.2f}")
            continue
        if math.isfinite(value):
            return value
        print("type a finite angle in degrees")


class ManualAxis(RotaryAxis):
    """A rotation stage moved by hand (see the module docstring).

    Parameters
    ----------
    name : str
        Name shown to the operator and in errors.
    ask : callable, optional
        ``ask(axis_name, target_deg) -> float | None`` (:data:`AskCallback`); default :func:`console_ask`.
    limits : Limits
        Soft limits [°], checked before the operator is asked.
    initial_deg : float
        What the scale reads before the first move [°].

    Notes
    -----
    :meth:`position_deg` is the last confirmed reading, not the target: the bench records what the
    operator actually set.
    """

    def __init__(self, name: str, *, ask: AskCallback | None = None, limits: Limits = Limits(-360.0, 360.0),
                 initial_deg: float = 0.0):
        self.name = name
        self.ask = ask or console_ask
        self.limits = limits
        self._position_deg = float(initial_deg)

    def _confirm(self, target_deg: float) -> float:
        reading = self.ask(self.name, target_deg)
        if reading is None:
            raise OperatorCancelled(self.name, f"operator cancelled the move to {target_deg}°")
        try:
            value = float(reading)
        except (TypeError, ValueError):
            raise DeviceFault(self.name, f"the reading {reading!r} is not an angle") from None
        if not math.isfinite(value):
            raise DeviceFault(self.name, f"the reading {value} is not a finite angle")
        self._position_deg = value
        return value

    def _start_move(self, angle_deg: float) -> None:
        self._confirm(angle_deg)

    def position_deg(self) -> float:
        """Last angle the operator confirmed [°]."""
        return self._position_deg

    def is_moving(self) -> bool:
        """Always False: the move is over once the operator confirmed it."""
        return False

    def stop(self) -> None:
        """Nothing to stop."""

    def home(self, *, wait: bool = True, timeout_s: float = 300.0) -> None:
        """Ask the operator to set the scale's zero; the confirmed reading becomes the position."""
        self._confirm(0.0)

    def identify(self) -> str:
        return f"manual stage {self.name}"
