"""Control of the run in progress: pause, resume, abort. Token required; 409 when the state forbids it."""

from __future__ import annotations

from fastapi import APIRouter

from ..deps import TOKEN, ServiceDep
from ..schemas import Message

router = APIRouter(prefix="/api/run", tags=["run control"], dependencies=TOKEN,
                   responses={409: {"description": "Not allowed in the engine's present state"}})


@router.post("/pause", response_model=Message, summary="Pause the run")
def pause_run(service: ServiceDep):
    """Pause at the next checkpoint (a point in progress is measured again on resume)."""
    service.pause()
    return Message(message="pausing")


@router.post("/resume", response_model=Message, summary="Resume the paused run")
def resume_run(service: ServiceDep):
    """Resume a paused (or pausing) run."""
    service.resume()
    return Message(message="resumed")


@router.post("/abort", response_model=Message, summary="Abort the run")
def abort_run(service: ServiceDep):
    """End the run; its recorded points stay, and a later run can resume it."""
    service.abort()
    return Message(message="aborting")
