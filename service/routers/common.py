"""Shared parameter types and response declarations of the routers."""

from __future__ import annotations

from typing import Annotated, Any

from fastapi import Path, Query

from service.schemas import NAME_PATTERN, ErrorBody

MAX_ID = 2**31 - 1

RigName = Annotated[
    str,
    Path(
        min_length=1,
        max_length=200,
        pattern=NAME_PATTERN,
        description="The rig's id as written in its campaign manifest.",
        examples=["rig-a"],
    ),
]
CampaignName = Annotated[
    str,
    Path(
        min_length=1,
        max_length=200,
        pattern=NAME_PATTERN,
        description="The campaign's id as written in its manifest.",
        examples=["fatigue-2026-03"],
    ),
]
RecordId = Annotated[int, Path(ge=1, le=MAX_ID, description="Record id.", examples=[42])]
Limit = Annotated[int, Query(ge=1, le=1000, description="Page size.")]
Offset = Annotated[int, Query(ge=0, le=10_000_000, description="Items to skip.")]
RigFilter = Annotated[
    str | None,
    Query(min_length=1, max_length=200, pattern=NAME_PATTERN, description="Only this rig."),
]
CampaignFilter = Annotated[
    str | None,
    Query(min_length=1, max_length=200, pattern=NAME_PATTERN,
          description="Only this campaign (its manifest id, e.g. an earlier gear pair's).",
          examples=["pair-1"]),
]
ChannelFilter = Annotated[
    str | None,
    Query(min_length=1, max_length=200, pattern=NAME_PATTERN, description="One channel by name.",
          examples=["acc1"]),
]


def errors(*statuses: int) -> dict[int | str, dict[str, Any]]:
    """OpenAPI ``responses`` entries for error statuses (all share :class:`ErrorBody`)."""
    text = {
        401: "Missing, unknown or revoked API key",
        403: "The key's role does not allow this",
        404: "Not found",
        409: "Conflicts with the current state",
        413: "Upload too large",
        422: "Invalid request",
    }
    return {s: {"model": ErrorBody, "description": text.get(s, "Error")} for s in statuses}
