"""What every calibration model is: fitted from bench data, applied to spot centres, saved as JSON."""

from __future__ import annotations

import dataclasses
from abc import ABC, abstractmethod
from typing import ClassVar

import numpy as np

from ..data import BenchData
from ..design import DEFAULT_SENSOR, SensorDesign
from ..errors import CalibrationFormatError

#: Identifies a sunbench calibration file; bumped when the meaning of a field changes.
FORMAT = "sunbench.calibration"
FORMAT_VERSION = 1


class Calibration(ABC):
    """A fitted calibration: spot centre (x_px, y_px) → sun direction (zenith_deg, azimuth_deg).

    Subclasses are frozen dataclasses whose fields are the calibration parameters; `method` names the
    model and `min_points` is the least data it can be fitted from.
    """

    method: ClassVar[str]
    min_points: ClassVar[int]
    #: Extra fit options for the leave-one-zenith-ring-out evaluation (see calibration.evaluation).
    ring_out_options: ClassVar[dict] = {}

    @classmethod
    @abstractmethod
    def fit(cls, data: BenchData, design: SensorDesign = DEFAULT_SENSOR) -> Calibration:
        """Fit the model to bench data; raises :class:`~calibration.errors.InsufficientDataError`."""

    @abstractmethod
    def apply(self, x_px, y_px) -> tuple[np.ndarray, np.ndarray]:
        """Sun direction (zenith_deg, azimuth_deg) in the body frame for spot centres [°]."""

    def parameters(self) -> dict:
        """The fitted parameters as plain JSON-able values."""
        return {f.name: _plain(getattr(self, f.name)) for f in dataclasses.fields(self)}

    def to_dict(self) -> dict:
        """The versioned JSON document of this calibration."""
        return {"format": FORMAT, "version": FORMAT_VERSION, "method": self.method,
                "parameters": self.parameters()}

    @classmethod
    def from_parameters(cls, parameters: dict) -> Calibration:
        names = {f.name for f in dataclasses.fields(cls)}
        required = {f.name for f in dataclasses.fields(cls)
                    if f.default is dataclasses.MISSING and f.default_factory is dataclasses.MISSING}
        missing = sorted(required - set(parameters))
        unknown = sorted(set(parameters) - names)
        if missing or unknown:
            raise CalibrationFormatError(
                f"{cls.method} calibration: missing parameters {missing}, unknown parameters {unknown}")
        kinds = {f.name: str(f.type) for f in dataclasses.fields(cls)}
        for name, value in parameters.items():
            problem = _type_problem(kinds[name], value)
            if problem:
                raise CalibrationFormatError(f"{cls.method} calibration: parameter `{name}` {problem}")
        try:
            return cls(**{k: _restore(v) for k, v in parameters.items()})
        except (TypeError, ValueError) as exc:
            raise CalibrationFormatError(f"{cls.method} calibration: invalid parameters ({exc})") from exc


#: Largest magnitude a stored number may have: far beyond any pixel coordinate or angle, far below overflow.
_LARGEST = 1e9


def _number_problem(value) -> str | None:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        return f"must be a number, got {json_type(value)}"
    if value != value or abs(value) == float("inf"):
        return f"must be a finite number, got {value}"
    if abs(value) > _LARGEST:
        return f"is out of range ({value:g}; |value| ≤ {_LARGEST:g})"
    return None


def json_type(value) -> str:
    """The JSON name of a value's type, for messages."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return "true/false"
    if isinstance(value, str):
        return "a string"
    if isinstance(value, (list, tuple)):
        return "a list"
    if isinstance(value, dict):
        return "an object"
    return type(value).__name__


def _type_problem(kind: str, value) -> str | None:
    """What is wrong with a stored parameter for its declared field type, or None (numbers finite and bounded,
    lists of numbers, objects of numbers)."""
    if kind == "float" or kind == "int":
        return _number_problem(value)
    if kind == "bool":
        return None if isinstance(value, bool) else f"must be true or false, got {json_type(value)}"
    if kind == "dict":
        if not isinstance(value, dict):
            return f"must be an object, got {json_type(value)}"
        for key, item in value.items():
            problem = _number_problem(item)
            if problem:
                return f"entry {key!r} {problem}"
        return None
    if kind == "tuple":
        if not isinstance(value, (list, tuple)):
            return f"must be a list, got {json_type(value)}"
        for item in value:
            if isinstance(item, str):
                continue  # names (the physical model's `fitted`)
            problem = _type_problem("tuple", item) if isinstance(item, (list, tuple)) else _number_problem(item)
            if problem:
                return f"has an item that {problem}"
        return None
    return None


def _plain(value):
    if isinstance(value, np.ndarray):
        return value.tolist()
    if isinstance(value, (np.floating, np.integer, np.bool_)):
        return value.item()
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    if isinstance(value, dict):
        return {k: _plain(v) for k, v in value.items()}
    if dataclasses.is_dataclass(value):
        return _plain(dataclasses.asdict(value))
    return value


def _restore(value):
    """JSON lists back to the tuples the frozen dataclasses hold (so they stay hashable and immutable)."""
    if isinstance(value, list):
        return tuple(_restore(v) for v in value)
    return value
