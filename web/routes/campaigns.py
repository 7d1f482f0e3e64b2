"""Campaigns: dry run, submit (queued, run by the bench service), list, fleet progress."""

from __future__ import annotations

from typing import Annotated

from fastapi import APIRouter, Depends, Header, HTTPException, Request, Response, status

from ..deps import CampaignId, CatalogueDep, ServiceDep
from ..idempotency import KeyReused
from ..schemas import CampaignCreate, CampaignQueued, CampaignsPublic, DryRunPublic, FleetPublic, Message
from ..security import require_read, require_token

router = APIRouter(prefix="/api/campaigns", tags=["campaigns"])

_REFUSED = {422: {"description": "Invalid campaign, or preflight refused it: "
                                 "`{\"detail\": {\"violations\": [...]}}` lists every violation"}}


@router.post("/dry-run", response_model=DryRunPublic, summary="Preflight a campaign",
             dependencies=[Depends(require_read)])
def dry_run_campaign(campaign: CampaignCreate, service: ServiceDep):
    """Expand the plan without moving anything: points, frames and moves per sensor, the estimated duration of
    every sensor in bench time and on the wall clock (they differ on a simulated bench) with the lamp's
    warm-up apart, violations. A plan with a stopping rule (physical) is expanded to its cap: its figures are
    upper bounds, and `upper_bound` says so."""
    report = service.dry_run(campaign)
    bench, sensors = service.bench_info(), len(campaign.sensors)
    return DryRunPublic(points=len(report.points), frames=report.n_frames, moves=report.n_moves, sensors=sensors,
                        duration_s=report.duration_s, duration_per_sensor_s=report.duration_s / sensors,
                        warmup_s=report.warmup_s, wall_duration_s=service.wall_time_s(report.duration_s),
                        simulated=bench["simulated"], time_scale=bench["time_scale"],
                        upper_bound=report.upper_bound is not None, upper_bound_reason=report.upper_bound,
                        violations=list(report.violations))


#: What an Idempotency-Key may be: printable ASCII without spaces (a UUID, as the launcher sends)
IdempotencyKey = Annotated[str | None, Header(
    min_length=1, max_length=200, pattern=r"^[\x21-\x7e]+$",
    description="The same key within 10 minutes queues nothing more: the answer is the campaign the first "
                "request with it queued (200 instead of 202). The launcher sends one per Start, so a double "
                "click queues one campaign.")]


@router.post("", response_model=CampaignQueued, status_code=status.HTTP_202_ACCEPTED, summary="Queue a campaign",
             dependencies=[Depends(require_token)],
             responses={**_REFUSED, 200: {"description": "Queued already, by an earlier request with the same "
                                                         "Idempotency-Key: its campaign", "model": CampaignQueued}})
def create_campaign(campaign: CampaignCreate, service: ServiceDep, request: Request, response: Response,
                    idempotency_key: IdempotencyKey = None):
    """Preflight and queue a campaign; it runs when the bench is free. Follow it on /api/events."""
    if idempotency_key is None:
        return CampaignQueued(campaign_id=service.submit(campaign))
    keys = request.app.state.idempotency
    try:
        campaign_id, replayed = keys.submit(idempotency_key, campaign.model_dump_json(),
                                            lambda: service.submit(campaign))
    except KeyReused as exc:
        raise HTTPException(422, str(exc)) from None
    if replayed:
        response.status_code = status.HTTP_200_OK
    return CampaignQueued(campaign_id=campaign_id, replayed=replayed)


@router.post("/{campaign_id}/resume", response_model=Message, status_code=status.HTTP_202_ACCEPTED,
             summary="Resume a campaign that stopped", dependencies=[Depends(require_token)],
             responses={404: {"description": "No such campaign"},
                        409: {"description": "Complete, or already queued or running"}})
def resume_campaign(campaign_id: CampaignId, service: ServiceDep):
    """Queue the rest of a campaign that stopped (aborted, failed, or left when the server stopped): its queued
    and failed sensors, each resumed from its last run when it has one (its points kept)."""
    service.resume_campaign(campaign_id)
    return Message(message=f"campaign {campaign_id} queued to resume")


@router.get("", response_model=CampaignsPublic, summary="List campaigns", dependencies=[Depends(require_read)])
def read_campaigns(catalogue: CatalogueDep):
    """Every campaign, oldest first, with its number of runs."""
    campaigns = catalogue.campaigns()
    return CampaignsPublic(data=campaigns, count=len(campaigns))


@router.get("/{campaign_id}/fleet", response_model=FleetPublic, summary="Fleet progress of a campaign",
            dependencies=[Depends(require_read)], responses={404: {"description": "No such campaign"}})
def read_fleet(campaign_id: CampaignId, catalogue: CatalogueDep):
    """The campaign's sensor queue, each with its run and chosen calibration."""
    fleet = catalogue.fleet(campaign_id)
    return FleetPublic(campaign_id=campaign_id, data=fleet, count=len(fleet))
