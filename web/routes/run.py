"""Control of the run in progress: pause, resume, abort, and the confirmation of a fleet's next sensor.
Token required; 409 when the state forbids it."""

from __future__ import annotations

from fastapi import APIRouter

from ..deps import TOKEN, ServiceDep
from ..schemas import Message, MountConfirm

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


@router.post("/mount", response_model=Message, summary="Confirm the sensor mount the bench waits for")
def confirm_mount(command: MountConfirm, service: ServiceDep):
    """Between the sensors of a fleet the bench waits (status `mount`) until the operator has mounted the next
    one and confirms it here, naming it; its serial is then read from the module where it has one, and a
    mismatch fails its run before anything is measured. 409 when no mount, or another sensor's, is awaited."""
    service.confirm_mount(command.sensor_id)
    return Message(message=f"sensor {command.sensor_id} confirmed mounted")


@router.post("/abort", response_model=Message, summary="Abort the run")
def abort_run(service: ServiceDep):
    """End the run; its recorded points stay, and a later run can resume it. While the bench waits for a
    sensor mount, stop the campaign there instead."""
    service.abort()
    return Message(message="aborting")
