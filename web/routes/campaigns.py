"""Campaigns: dry run, submit (queued, run by the bench service), list, fleet progress."""

from __future__ import annotations

from fastapi import APIRouter, Depends, status

from ..deps import CatalogueDep, ServiceDep
from ..schemas import CampaignCreate, CampaignQueued, CampaignsPublic, DryRunPublic, FleetPublic
from ..security import require_read, require_token

router = APIRouter(prefix="/api/campaigns", tags=["campaigns"])

_REFUSED = {422: {"description": "Invalid campaign, or preflight refused it: "
                                 "`{\"detail\": {\"violations\": [...]}}` lists every violation"}}


@router.post("/dry-run", response_model=DryRunPublic, summary="Preflight a campaign",
             dependencies=[Depends(require_read)])
def dry_run_campaign(campaign: CampaignCreate, service: ServiceDep):
    """Expand the plan without moving anything: points, frames, moves, estimated duration, violations."""
    report = service.dry_run(campaign)
    return DryRunPublic(points=len(report.points), frames=report.n_frames, moves=report.n_moves,
                        duration_s=report.duration_s, violations=list(report.violations))


@router.post("", response_model=CampaignQueued, status_code=status.HTTP_202_ACCEPTED, summary="Queue a campaign",
             dependencies=[Depends(require_token)], responses=_REFUSED)
def create_campaign(campaign: CampaignCreate, service: ServiceDep):
    """Preflight and queue a campaign; it runs when the bench is free. Follow it on /api/events."""
    return CampaignQueued(campaign_id=service.submit(campaign))


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
