"""Manual bench commands: jog the table, lamp, shutter, emergency stop and its acknowledgement. Token required.

An emergency stop latches: until it is acknowledged every move and every light (jog, lamp on, shutter open,
a campaign) answers 409 naming the latch; closing the shutter and the lamp's standby stay allowed."""

from __future__ import annotations

from fastapi import APIRouter

from ..deps import TOKEN, ServiceDep
from ..schemas import JogCommand, LampCommand, Message, ShutterCommand, StatusPublic

router = APIRouter(prefix="/api", tags=["bench"], dependencies=TOKEN)

_BUSY = {409: {"description": "A run owns the bench, or the emergency stop is latched"}}


@router.post("/table/jog", response_model=StatusPublic, summary="Move the table",
             responses={**_BUSY, 422: {"description": "Outside the soft limits (nothing moved)"}})
def jog_table(command: JogCommand, service: ServiceDep):
    """Move the table to an absolute pose; answers the refreshed status once it is there, or 409 when an
    emergency stop interrupted the move (the answer says where the table stopped)."""
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
    """Stop the table and close the shutter now (the lamp switched off if the shutter does not close), end any
    run or jog, and latch until acknowledged. Always allowed; the answer says what could not be made safe."""
    problems = service.emergency_stop()
    done = "; ".join(problems) if problems else "table stopped, shutter closed"
    return Message(message=f"emergency stop latched: {done}; acknowledge it before moving or lighting anything")


@router.post("/stop/acknowledge", response_model=Message, summary="Acknowledge the emergency stop",
             responses={409: {"description": "No emergency stop is latched, or its run is still being made safe"}})
def acknowledge_stop(service: ServiceDep):
    """Release the emergency stop's latch once the bench has been seen to: moves and lights are allowed again.
    Nothing moves by itself: a stopped campaign is resumed explicitly."""
    service.acknowledge_estop()
    return Message(message="emergency stop acknowledged: the bench may move and light again")
