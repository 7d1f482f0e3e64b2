"""The bench's cached status and its latest frame (never a device call)."""

from __future__ import annotations

import cv2
import numpy as np
from fastapi import APIRouter, HTTPException, Response

from bench.families.cmos import FULL_SCALE_DN

from ..deps import READ, ServiceDep
from ..family import family_info
from ..schemas import SpotPublic, StatusPublic

router = APIRouter(prefix="/api", tags=["status"], dependencies=READ)


def _no_frame(service) -> HTTPException:
    """Why there is no frame: none yet, or a sensor family that takes none (a photodiode)."""
    family = service.engine.family
    if not family.has_exposure:
        return HTTPException(404, f"the {family.name} sensor on this bench takes no frames (see its currents in "
                                  "/api/status)")
    return HTTPException(404, "no frame yet: open the shutter (or start a run) first")


def frame_png(frame: np.ndarray, full_scale_dn: float) -> bytes:
    """An 8-bit PNG of a raw frame, full scale (10-bit) mapped to 255."""
    scaled = np.clip(frame.astype(np.float32) * (255.0 / full_scale_dn), 0, 255).astype(np.uint8)
    ok, buffer = cv2.imencode(".png", scaled)
    if not ok:  # pragma: no cover - OpenCV refuses only impossible images
        raise RuntimeError("PNG encoding failed")
    return buffer.tobytes()


@router.get("/status", response_model=StatusPublic, summary="Cached bench status")
async def read_status(service: ServiceDep):
    """Table, source, sensor and engine as last seen; refreshed in the background, so this never waits
    (hence async: it needs no worker thread). `bench` says what the bench is: simulated or not, and its sensor
    family with the campaign plans it runs."""
    status = service.status()
    return {**status, "bench": {**(status.get("bench") or {}), **family_info(service)}}


@router.get("/frame.png", summary="Latest frame as a PNG", response_class=Response,
            responses={200: {"content": {"image/png": {}}}, 404: {"description": "No frame yet"}})
def read_frame_png(service: ServiceDep):
    """The latest sensor frame, scaled to 8 bits. 404 until the shutter has been open."""
    frame, _ = service.latest_frame()
    if frame is None:
        raise _no_frame(service)
    return Response(frame_png(frame, FULL_SCALE_DN), media_type="image/png",
                    headers={"Cache-Control": "no-store"})


@router.get("/frame/spot", response_model=SpotPublic, summary="Spot of the latest frame",
            responses={404: {"description": "No frame yet"}})
def read_frame_spot(service: ServiceDep):
    """The centroid of the latest frame, or the centroid's error when it found no usable spot."""
    frame, spot = service.latest_frame()
    if frame is None or spot is None:
        raise _no_frame(service)
    return spot
