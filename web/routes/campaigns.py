"""Campaigns: dry run, submit (queued, run by the bench service), list, fleet progress."""

from __future__ import annotations

from fastapi import APIRouter, Depends, status

from ..deps import CatalogueDep, ServiceDep
from ..schemas import CampaignCreate, CampaignQueued, CampaignsPublic, DryRunPublic, FleetPublic, Message
from ..security import require_read, require_token

router = APIRouter(prefix="/api/campaigns", tags=["campaigns"])

_REFUSED = {422: {"description": "Invalid campaign, or preflight refused it: "
                                 "`{\"detail\": {\"violations\": [...]}}` lists every violation"}}


@router.post("/dry-run", response_model=DryRunPublic, summary="Preflight a campaign",
             dependencies=[Depends(require_read)])
def dry_run_campaign(campaign: CampaignCreate, service: ServiceDep):
    """Expand the plan without moving anything: points, frames, moves, estimated duration with the lamp's
    warm-up apart, violations. A plan with a stopping rule (physical) is expanded to its cap: its figures are
    upper bounds, and `upper_bound` says so."""
    report = service.dry_run(campaign)
    return DryRunPublic(points=len(report.points), frames=report.n_frames, moves=report.n_moves,
                        duration_s=report.duration_s, warmup_s=report.warmup_s,
                        upper_bound=report.upper_bound is not None, upper_bound_reason=report.upper_bound,
                        violations=list(report.violations))


@router.post("", response_model=CampaignQueued, status_code=status.HTTP_202_ACCEPTED, summary="Queue a campaign",
             dependencies=[Depends(require_token)], responses=_REFUSED)
def create_campaign(campaign: CampaignCreate, service: ServiceDep):
    """Preflight and queue a campaign; it runs when the bench is free. Follow it on /api/events."""
    return CampaignQueued(campaign_id=service.submit(campaign))


@router.post("/{campaign_id}/resume", response_model=Message, status_code=status.HTTP_202_ACCEPTED,
             summary="Resume a campaign that stopped", dependencies=[Depends(require_token)],
             responses={404: {"description": "No such campaign"},
                        409: {"description": "Complete, or already queued or running"}})
def resume_campaign(campaign_id: int, service: ServiceDep):
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
def read_fleet(campaign_id: int, catalogue: CatalogueDep):
    """The campaign's sensor queue, each with its run and chosen calibration."""
    fleet = catalogue.fleet(campaign_id)
    return FleetPublic(campaign_id=campaign_id, data=fleet, count=len(fleet))
