"""Write a simulated campaign folder (``campaign.toml``, one record per day, the day models);
read a simulator model file."""

from __future__ import annotations

import datetime as dt
from collections.abc import Callable
from pathlib import Path
from typing import Any

from gearwatch.floor.errors import InputError


def write_simulated_campaign(
    out_dir: str | Path,
    *,
    days: int = 12,
    spall_tooth: int | None = 16,
    onset_day: int = 10,
    seed: int = 0,
    record_format: str = "wav",
    seconds: float = 12.0,
    model: str | Path | None = None,
    campaign_id: str | None = None,
    start: str = "2026-03-01T09:00:00Z",
    force: bool = False,
    progress: Callable[[int, int], None] | None = None,
) -> Path:
    """Check the arguments (messages name the command-line flags), simulate with
    :func:`physics.campaign.write_campaign` and return the manifest's path.

    ``spall_tooth`` None is a healthy campaign; ``model`` is a base model TOML file (None: the
    CETIM-like pair); ``force`` writes into a non-empty folder.
    """
    from physics.campaign import write_campaign
    out = Path(out_dir)
    if out.exists() and not out.is_dir():
        raise InputError(f"{out}: exists and is not a directory")
    if out.is_dir() and any(out.iterdir()) and not force:
        raise InputError(f"{out}: directory is not empty (use --force)")
    if days < 1:
        raise InputError("--days must be ≥ 1")
    if not seconds > 0:
        raise InputError("--seconds must be > 0")
    if not 1 <= onset_day:
        raise InputError("--onset-day must be ≥ 1")
    try:
        dt.datetime.fromisoformat(start.replace("Z", "+00:00"))
    except ValueError:
        raise InputError(f"--start: not an ISO 8601 timestamp: {start!r}") from None
    base_model = load_model(None if model is None else str(model))
    teeth = base_model.geometry.pinion_teeth
    if spall_tooth is not None and not 1 <= spall_tooth <= teeth:
        raise InputError(f"--spall-tooth must be within 1..{teeth}")
    try:
        return Path(write_campaign(
            out,
            days=days,
            spall_tooth=spall_tooth,
            onset_day=onset_day,
            seed=seed,
            record_format=record_format,
            seconds=seconds,
            campaign_id=campaign_id,
            start=start,
            base_model=base_model,
            progress=progress,
        ))
    except ValueError as error:  # SimulationError and bad lengths: input, not a bug
        raise InputError(str(error)) from None


def load_model(path: str | None) -> Any:
    """Read a model TOML, turning every problem into one InputError line."""
    from physics.config import GearPairModel, ModelConfigError, model_from_toml
    from physics.geometry import GeometryError
    from physics.simulator import model_geometry

    if path is None:
        return GearPairModel()
    model_path = Path(path)
    if not model_path.is_file():
        raise InputError(f"{model_path}: no such model file")
    try:
        model = model_from_toml(model_path.read_text(encoding="utf-8"))
        model_geometry(model)
    except (ModelConfigError, GeometryError) as error:
        raise InputError(f"{model_path}: {error}") from None
    return model
