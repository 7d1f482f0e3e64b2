"""Manual bench commands: jog the table, lamp, shutter, emergency stop. Token required."""

from __future__ import annotations

from fastapi import APIRouter

from ..deps import TOKEN, ServiceDep
from ..schemas import JogCommand, LampCommand, Message, ShutterCommand, StatusPublic

router = APIRouter(prefix="/api", tags=["bench"], dependencies=TOKEN)

_BUSY = {409: {"description": "A run owns the bench"}}


@router.post("/table/jog", response_model=StatusPublic, summary="Move the table",
             responses={**_BUSY, 422: {"description": "Outside the soft limits (nothing moved)"}})
def jog_table(command: JogCommand, service: ServiceDep):
    """Move the table to an absolute pose; answers the refreshed status once it is there."""
    service.jog(command.azimuth_deg, command.zenith_deg)
    return service.status()


@router.post("/source/lamp", response_model=StatusPublic, summary="Lamp on or standby", responses=_BUSY)
def set_lamp(command: LampCommand, service: ServiceDep):
    """Switch the sun simulator's lamp on, or to standby."""
    service.set_lamp(command.on)
    return service.status()


@router.post("/source/shutter", response_model=StatusPublic, summary="Open or close the shutter", responses=_BUSY)
def set_shutter(command: ShutterCommand, service: ServiceDep):
    """Open or close the sun simulator's shutter."""
    service.set_shutter(command.open)
    return service.status()


@router.post("/stop", response_model=Message, summary="Emergency stop")
def stop_bench(service: ServiceDep):
    """Stop the table and close the shutter now, and end any run. Always allowed."""
    service.emergency_stop()
    return Message(message="emergency stop: table stopped, shutter closed")
