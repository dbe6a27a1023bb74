"""Campaigns: a manifest (rig, tachometer, channels) that records are uploaded into."""

from __future__ import annotations

from pathlib import Path
from typing import Annotated, Any

from fastapi import APIRouter, Body, Response

from gearwatch.floor.errors import InputError, ManifestError
from ingest.manifest import parse_manifest
from service import schemas
from service.convert import Names, campaign_by_name, campaign_out, rig_by_name
from service.deps import CurrentKey, DbSession, OperatorKey
from service.routers.common import CampaignName, RigFilter, errors
from storage.repositories import (
    AlarmRuleRepository,
    AuditRepository,
    CampaignRepository,
    RigRepository,
)

router = APIRouter(prefix="/api/v1/campaigns", tags=["campaigns"])

MANIFEST_EXAMPLE: dict[str, Any] = {
    "campaign": {"id": "fatigue-2026-03", "description": "spur pair fatigue test"},
    "rig": {"id": "rig-a", "pinion_teeth": 20, "gear_teeth": 21, "tooth1_pitch_angle_deg": 337.4},
    "acquisition": {"sample_rate_hz": 20000},
    "tachometer": {"channel": "tach", "kind": "pulses", "shaft": "pinion", "pulses_per_rev": 1},
    "channels": [
        {"name": "acc", "kind": "accelerometer", "unit": "m/s^2"},
        {"name": "tach", "kind": "tachometer", "unit": "V"},
    ],
}


@router.get(
    "", response_model=schemas.CampaignList, summary="List campaigns", responses=errors(401, 404)
)
def list_campaigns(
    db: DbSession, _caller: CurrentKey, rig_id: RigFilter = None
) -> schemas.CampaignList:
    rig_pk = None if rig_id is None else rig_by_name(db, rig_id).id
    names = Names(db)
    return schemas.CampaignList(
        items=[campaign_out(db, c, names) for c in CampaignRepository(db).list(rig_pk)]
    )


@router.get(
    "/{campaign_id}",
    response_model=schemas.CampaignOut,
    summary="One campaign",
    responses=errors(401, 404),
)
def get_campaign(
    campaign_id: CampaignName, db: DbSession, _caller: CurrentKey
) -> schemas.CampaignOut:
    return campaign_out(db, campaign_by_name(db, campaign_id), Names(db))


@router.post(
    "",
    response_model=schemas.CampaignOut,
    status_code=201,
    summary="Create or update a campaign from its manifest (operator)",
    description="The body is `campaign.toml` as JSON (same keys; `[[records]]` is ignored: "
    "upload each record with `POST /api/v1/campaigns/{campaign_id}/records`). The rig is "
    "created or brought up to date; a new rig gets the default alarm rules. Answers 201 when "
    "the campaign is new, 200 when it was updated.",
    responses={
        200: {"model": schemas.CampaignOut, "description": "Updated"},
        **errors(401, 403, 409, 422),
    },
)
def create_campaign(
    manifest: Annotated[dict[str, Any], Body(examples=[MANIFEST_EXAMPLE])],
    response: Response,
    db: DbSession,
    caller: OperatorKey,
) -> schemas.CampaignOut:
    data = {k: v for k, v in manifest.items() if k != "records"}
    _refuse_control_characters(data, "manifest")
    try:
        config = parse_manifest(data, root=Path("."), source="uploaded manifest", check_files=False)
    except InputError:
        raise
    except (TypeError, ValueError, KeyError, AttributeError) as error:
        # The manifest parser validates TOML-shaped input; JSON can hold shapes TOML cannot.
        raise ManifestError(f"manifest: {error}") from None
    campaigns = CampaignRepository(db)
    is_new = campaigns.get_by_name(config.id) is None
    is_new_rig = RigRepository(db).get_by_name(config.rig.id) is None
    campaign = campaigns.ensure(config)
    if is_new_rig:
        AlarmRuleRepository(db).ensure_defaults(campaign.rig_id)
    AuditRepository(db).add(
        who=caller.who,
        action="campaign.create" if is_new else "campaign.update",
        target=f"campaign:{config.id}",
        details={"rig": config.rig.id},
    )
    db.commit()
    if not is_new:
        response.status_code = 200
    return campaign_out(db, campaign, Names(db))


def _refuse_control_characters(value: Any, where: str) -> None:
    """Names and units are printable text (PostgreSQL refuses NUL; none belongs in a name)."""
    if isinstance(value, str):
        if any(ord(c) < 0x20 or ord(c) == 0x7F for c in value):
            raise ManifestError(f"{where}: control characters are not allowed")
    elif isinstance(value, dict):
        for key, item in value.items():
            _refuse_control_characters(key, where)
            _refuse_control_characters(item, f"{where}.{key}")
    elif isinstance(value, list):
        for index, item in enumerate(value):
            _refuse_control_characters(item, f"{where}[{index}]")
