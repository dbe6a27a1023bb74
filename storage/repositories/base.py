"""What every repository shares: the session it works in, ``get`` by primary key (a missing row
is :class:`~gearwatch.floor.errors.NotFound`), and the JSON helpers of stored values."""

from __future__ import annotations

import hashlib
import json
import math
from typing import Any, ClassVar, Generic, TypeVar

import numpy as np
from sqlalchemy.orm import Session

from gearwatch.floor.errors import NotFound

RowT = TypeVar("RowT")


class Repository(Generic[RowT]):
    """Queries of one aggregate in ``session``: they add and ``flush``, never commit.

    ``model`` is the aggregate root's row class and ``noun`` names it in messages; ``get`` finds
    a row by primary key.
    """

    model: ClassVar[type[Any]]
    noun: ClassVar[str]

    def __init__(self, session: Session) -> None:
        self.session = session

    def get(self, key: int) -> RowT:
        row: RowT = _get(self.session, self.model, key, self.noun)
        return row


def parameters_sha256(parameters: dict[str, Any]) -> str:
    """sha256 of the canonical JSON of an analysis parameter set (identifies a result version)."""
    canonical = json.dumps(parameters, sort_keys=True, separators=(",", ":"), default=str)
    return hashlib.sha256(canonical.encode()).hexdigest()


def json_safe(value: Any) -> Any:
    """Plain JSON: NaN and infinities become ``None`` (PostgreSQL's json refuses them)."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, dict):
        return {str(k): json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [json_safe(v) for v in value]
    if isinstance(value, np.generic):
        return json_safe(value.item())
    return value


def _get(session: Session, model: type[Any], key: int, what: str) -> Any:
    row = session.get(model, key)
    if row is None:
        raise NotFound(f"{what} {key} not found")
    return row
