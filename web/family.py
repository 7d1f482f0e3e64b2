"""The sensor family of the bench the dashboard serves, as its pages and its status show it.

The service knows which family its sensor is (:attr:`bench.engine.RunEngine.family`, from the bench file); the
launcher offers that family's plans only, and the live pages show what its readings are (frames and spots, or
currents). Nothing here is family-specific: it is read from the family's registry entry
(:class:`bench.families.Family`).
"""

from __future__ import annotations

from bench.families import family as family_named


def family_info(service) -> dict:
    """``family``, ``family_title``, ``plans`` (the campaign plans the bench runs) and ``has_frames`` (its sensor
    takes image frames: a latest frame and a spot map) of the service's bench; empty when it cannot say."""
    family = getattr(getattr(service, "engine", None), "family", None)  # the service's engine is its session's
    if family is None:
        return {}
    return {"family": family.name, "family_title": family.title, "plans": list(family.plans),
            "has_frames": bool(family.has_exposure)}


def bench_info(service) -> dict | None:
    """The service's :meth:`~bench.service.BenchService.bench_info` (simulated, time scale) with its family."""
    info = getattr(service, "bench_info", None)
    if info is None:
        return None
    return {**info(), **family_info(service)}


def results_view(family: str | None) -> str:
    """The dashboard's results view of a family's runs (its registry entry's), the family's name if unknown."""
    try:
        return family_named(family or "cmos").results_view
    except KeyError:
        return family or "cmos"
