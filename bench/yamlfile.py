"""Reading the project's YAML files (bench and campaign files) with errors that name the file and the field."""

from __future__ import annotations

from pathlib import Path

import yaml
from pydantic import ValidationError


def read_yaml(path, error: type[Exception]):
    """The parsed document of a YAML file; a missing file or bad YAML raises `error` naming the file."""
    path = Path(path)
    try:
        return yaml.safe_load(path.read_text())
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise error(f"{path}: not valid YAML ({exc})") from None


def field_problems(exc: ValidationError) -> str:
    """Every problem of a validation error as ``field a.b.c: message``, joined by "; "."""
    return "; ".join(f"field {'.'.join(str(p) for p in e['loc']) or '(top level)'}: {e['msg']}" for e in exc.errors())
