"""Bench files (YAML): what the bench is made of.

For now a bench file holds the ``simulation:`` section (the simulated world's truth,
:class:`drivers.sim.bench.SimBenchConfig`); device URLs and limits join it with the run engine. Every
problem is a :class:`BenchFileError` naming the file and the field.
"""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import BaseModel, ConfigDict, ValidationError

from drivers.sim.bench import SimBenchConfig


class BenchFileError(Exception):
    """A bench file that cannot be used; the message names the file and the field."""


class BenchFile(BaseModel):
    model_config = ConfigDict(extra="forbid", frozen=True)

    simulation: SimBenchConfig = SimBenchConfig()


def _field(loc) -> str:
    return ".".join(str(p) for p in loc) or "(top level)"


def load_bench_file(path) -> BenchFile:
    """Read and validate a bench YAML file."""
    path = Path(path)
    try:
        document = yaml.safe_load(path.read_text()) or {}
    except FileNotFoundError:
        raise BenchFileError(f"{path}: no such file") from None
    except yaml.YAMLError as exc:
        raise BenchFileError(f"{path}: not valid YAML ({exc})") from None
    if not isinstance(document, dict):
        raise BenchFileError(f"{path}: expected a mapping at the top level")
    try:
        return BenchFile.model_validate(document)
    except ValidationError as exc:
        problems = "; ".join(f"field {_field(e['loc'])}: {e['msg']}" for e in exc.errors())
        raise BenchFileError(f"{path}: {problems}") from None
