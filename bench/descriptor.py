"""What one reading of a sensor family is: its fields with dtype, unit and shape.

Bluesky's event descriptor (research note anchors-orchestration, lesson 1): a family declares its reading
once, the catalogue stores the declaration with the run and validates every reading against it, so one
``readings`` table holds any family's values (as JSON) and hands them back typed, without a table per
family. A reading also has the fields every family shares (repeat, status, time, frame file), which are
columns of their own.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import asdict, dataclass, field
from typing import Any

#: dtypes a field may have: a JSON number or string, or a list of them (a field with a shape)
DTYPES = {"number": float, "integer": int, "string": str, "boolean": bool}


class DescriptorError(ValueError):
    """A reading does not match its family's descriptor (the message names the field)."""


@dataclass(frozen=True)
class FieldSpec:
    """One field of a reading.

    Attributes
    ----------
    name : str
    dtype : str
        "number", "integer", "string" or "boolean".
    unit : str
        SI-ish unit ("px", "A", "degC", "DN" …); "" for a count or a flag word.
    shape : tuple of int
        () for a scalar, (4,) for four quadrant currents …
    required : bool
        A reading whose status is "ok" must have it (a failed reading may leave it out: NaN / null).
    doc : str
    """

    name: str
    dtype: str
    unit: str = ""
    shape: tuple[int, ...] = ()
    required: bool = True
    doc: str = ""

    def __post_init__(self) -> None:
        if self.dtype not in DTYPES:
            raise ValueError(f"field {self.name!r}: dtype must be one of {sorted(DTYPES)}, got {self.dtype!r}")

    def check(self, value: Any, where: str) -> Any:
        """`value` as stored (None for a missing or non-finite number); raises DescriptorError."""
        if value is None:
            return None
        if self.shape:
            if hasattr(value, "tolist"):
                value = value.tolist()
            if not isinstance(value, (list, tuple)) or len(value) != self.shape[0]:
                raise DescriptorError(f"{where}: {self.name} must be {self.shape[0]} values, got {value!r}")
            inner = FieldSpec(self.name, self.dtype, self.unit, self.shape[1:], self.required)
            return [inner.check(v, where) for v in value]
        kind = DTYPES[self.dtype]
        if hasattr(value, "item") and not isinstance(value, (list, tuple)):
            value = value.item()  # numpy scalars
        if kind is float:
            if isinstance(value, bool) or not isinstance(value, (int, float)):
                raise DescriptorError(f"{where}: {self.name} must be a number, not {value!r}")
            return float(value) if math.isfinite(value) else None
        if kind is int:
            if (isinstance(value, bool) or isinstance(value, str)
                    or (isinstance(value, float) and not value.is_integer())):
                raise DescriptorError(f"{where}: {self.name} must be an integer, not {value!r}")
            try:
                return int(value)
            except (TypeError, ValueError):
                raise DescriptorError(f"{where}: {self.name} must be an integer, not {value!r}") from None
        if not isinstance(value, kind):
            raise DescriptorError(f"{where}: {self.name} must be a {self.dtype}, not {value!r}")
        return value

    def to_json(self) -> dict:
        return {"name": self.name, "dtype": self.dtype, "unit": self.unit, "shape": list(self.shape),
                "required": self.required, "doc": self.doc}

    @classmethod
    def from_json(cls, d: Mapping) -> FieldSpec:
        return cls(d["name"], d["dtype"], d.get("unit", ""), tuple(d.get("shape", ())), d.get("required", True),
                   d.get("doc", ""))


@dataclass(frozen=True)
class ReadingDescriptor:
    """A family's reading: its name and fields (see the module docstring)."""

    family: str
    fields: tuple[FieldSpec, ...]
    version: int = 1

    @property
    def names(self) -> tuple[str, ...]:
        return tuple(f.name for f in self.fields)

    def validate(self, values: Mapping[str, Any], *, ok: bool, where: str) -> dict:
        """`values` checked against the fields and made JSON-ready; an "ok" reading must have every required
        field. Raises DescriptorError naming the field."""
        if not isinstance(values, Mapping):
            raise DescriptorError(f"{where}: the reading's values must be a mapping, not {type(values).__name__}")
        unknown = sorted(set(values) - set(self.names))
        if unknown:
            raise DescriptorError(f"{where}: unknown fields {unknown} for a {self.family} reading "
                                  f"(fields: {', '.join(self.names)})")
        checked = {}
        for spec in self.fields:
            value = spec.check(values.get(spec.name), where)
            if ok and spec.required and (value is None or (isinstance(value, list) and None in value)):
                raise DescriptorError(f"{where}: an ok {self.family} reading needs {spec.name}")
            checked[spec.name] = value
        return checked

    def to_json(self) -> dict:
        return {"family": self.family, "version": self.version, "fields": [f.to_json() for f in self.fields]}

    @classmethod
    def from_json(cls, d: Mapping) -> ReadingDescriptor:
        return cls(d["family"], tuple(FieldSpec.from_json(f) for f in d["fields"]), d.get("version", 1))


@dataclass(frozen=True)
class ReadingRecord:
    """One recorded reading as the catalogue hands it back: the fields every family shares, the point it
    belongs to, and the family's own `values` (by the run's descriptor; missing numbers are None)."""

    id: int
    point_id: int
    run_id: int
    key: str
    stage: str
    azimuth_deg: float
    zenith_stage_deg: float
    zenith_deg: float
    azimuth_body_deg: float
    exposure_ms: float | None
    repeat: int
    status: str
    t_s: float
    frame_path: str | None = None
    values: dict = field(default_factory=dict)

    @property
    def ok(self) -> bool:
        return self.status == "ok"

    def value(self, name: str, default: Any = None) -> Any:
        """A family field's value (`default` when missing)."""
        v = self.values.get(name)
        return default if v is None else v

    def to_dict(self) -> dict[str, Any]:
        """JSON-ready (an export)."""
        return asdict(self)
