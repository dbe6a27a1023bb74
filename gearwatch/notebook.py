"""gearwatch from a notebook: analyse a file, read stored trends and alarms, get DataFrames.

Install the extra for DataFrames: ``pip install -e ".[notebook]"`` (pandas). Everything else
works without pandas (plain lists and dicts).

>>> from gearwatch import notebook as gw                                  # doctest: +SKIP
>>> result = gw.analyze_file("records/day10.wav", "campaign.toml")         # doctest: +SKIP
>>> result.teeth_frame().sort_values("mci_depth").tail(3)                  # doctest: +SKIP
>>> result.metrics_frame()                                                 # doctest: +SKIP
>>> store = gw.open_store("sqlite:///gearwatch-demo/gearwatch.db")         # doctest: +SKIP
>>> store.trend_frame("rig-1", "mci_depth")          # index taken_at, a column per tooth
>>> store.trend_frame("rig-1", "raw_kurtosis")       # a whole-record indicator: one column
>>> store.alarms_frame("rig-1")                      # tooth is None for whole-record alarms

Frames carry their unit in ``frame.attrs["unit"]`` and the record ids and labels as columns
(trends) so that a value can be traced back to its record.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gearwatch.floor.errors import InputError


def _pandas() -> Any:
    try:
        import pandas
    except ImportError:  # pragma: no cover - depends on the installation
        raise InputError(
            "DataFrames need pandas: pip install 'gearwatch[notebook]' (or pip install pandas)"
        ) from None
    return pandas


@dataclass
class FileResult:
    """The analysis of one record file (:class:`gearwatch.floor.results.RecordAnalysis`) with
    DataFrame views; ``analysis`` is the full result (curves, quality, provenance)."""

    analysis: Any
    campaign: Any

    def to_json(self, curves: bool = False) -> dict[str, Any]:
        return dict(self.analysis.to_json(curves=curves))

    def teeth_frame(self) -> Any:
        """One row per channel and pinion tooth: pitch angle and every per-tooth indicator."""
        pd = _pandas()
        rows = [
            {"channel": ch.channel, "tooth": t.tooth, "pitch_angle_deg": t.pitch_angle_deg,
             **t.indicators()}
            for ch in self.analysis.channels
            for t in ch.teeth
        ]
        frame = pd.DataFrame(rows)
        frame.attrs["units"] = {"mci_depth": "Np", "pitch_angle_deg": "deg"}
        return frame

    def metrics_frame(self) -> Any:
        """One row per channel, one column per whole-record metric."""
        pd = _pandas()
        frame = pd.DataFrame(
            [{"channel": ch.channel, **ch.metrics} for ch in self.analysis.channels]
        ).set_index("channel")
        return frame

    def curves_frame(self, channel: str | None = None) -> Any:
        """The per-revolution curves of one channel (default the first) against the pinion
        angle in degrees (curves of another length, e.g. the gear average, are left out)."""
        import numpy as np

        pd = _pandas()
        channels = {ch.channel: ch for ch in self.analysis.channels}
        ch = channels[channel] if channel is not None else self.analysis.channels[0]
        n = ch.samples_per_rev
        data = {name: np.asarray(v, dtype=float) for name, v in ch.curves.items() if len(v) == n}
        return pd.DataFrame(data, index=pd.Index(360.0 * np.arange(n) / n, name="angle_deg"))


def analyze_file(
    record: str | Path, campaign: str | Path | Any, **parameters: Any
) -> FileResult:
    """Run the chain on one record file described by a campaign manifest (path or loaded
    :class:`gearwatch.floor.campaign.Campaign`); ``parameters`` are :class:`gearwatch.floor.results.AnalysisParameters`
    fields (``samples_per_mesh=32``, ``mci_form="literal"`` …)."""
    from gearwatch.floor.results import AnalysisParameters
    from gearwatch.usecases.analyze import analyze_file as run
    from ingest.manifest import load_manifest

    loaded = load_manifest(campaign, check_files=False) if isinstance(campaign, str | Path) \
        else campaign
    try:
        params = AnalysisParameters(**parameters)
    except TypeError as error:
        raise InputError(f"unknown analysis parameter: {error}") from None
    return FileResult(run(Path(record), loaded, params), loaded)


class Store:
    """Read-only views of a gearwatch database (the same answers as the REST API)."""

    def __init__(self, url: str) -> None:
        from storage.db import open_database

        self.engine, self.factory = open_database(url, auto_migrate=False)

    def close(self) -> None:
        self.engine.dispose()

    def __enter__(self) -> Store:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    def rigs(self) -> list[str]:
        from storage.db import session_scope
        from storage.repositories import RigRepository

        with session_scope(self.factory) as session:
            return [r.name for r in RigRepository(session).list()]

    def trend(
        self, rig: str, indicator: str = "mci_depth", tooth: int | None = None,
        channel: str | None = None, campaign: str | None = None,
    ) -> dict[str, Any]:
        """The REST trend answer as a dict (``records``, ``teeth``, ``values``, ``unit`` …);
        ``campaign``: one campaign of the rig (default: its current gear pair's)."""
        from gearwatch.floor.errors import NotFound
        from storage.db import session_scope
        from storage.operator_queries import trend_data
        from storage.repositories import RigRepository

        with session_scope(self.factory) as session:
            found = RigRepository(session).get_by_name(rig)
            if found is None:
                raise NotFound(f"rig {rig!r} not found")
            data = trend_data(session, found, indicator, tooth, channel, campaign)
        for record in data["records"]:
            record["taken_at"] = record["taken_at"].isoformat()
        return data

    def trend_frame(
        self, rig: str, indicator: str = "mci_depth", tooth: int | None = None,
        channel: str | None = None, campaign: str | None = None,
    ) -> Any:
        """Index ``taken_at`` (UTC); columns ``record_id``, ``label``, then one per tooth
        (``1``, ``2`` …) or ``value`` for a whole-record indicator. ``attrs``: unit, indicator,
        channel."""
        pd = _pandas()
        trend = self.trend(rig, indicator, tooth, channel, campaign)
        columns = ["value" if t is None else t for t in trend["teeth"]]
        frame = pd.DataFrame(trend["values"], columns=columns, dtype=float)
        frame.insert(0, "label", [r["label"] for r in trend["records"]])
        frame.insert(0, "record_id", [r["record_id"] for r in trend["records"]])
        frame.index = pd.DatetimeIndex(
            pd.to_datetime([r["taken_at"] for r in trend["records"]], utc=True), name="taken_at"
        )
        frame.attrs.update(
            unit=trend["unit"], indicator=indicator, channel=trend["channel"], rig=rig
        )
        return frame

    def alarms(self, rig: str | None = None, *, open_only: bool = False) -> list[dict[str, Any]]:
        from storage.db import session_scope
        from storage.operator_queries import alarm_list

        with session_scope(self.factory) as session:
            return alarm_list(session, rig_name=rig, open_only=open_only, limit=None)

    def alarms_frame(self, rig: str | None = None, *, open_only: bool = False) -> Any:
        """One row per alarm (newest first); ``tooth`` is None for a whole-record alarm."""
        pd = _pandas()
        return pd.DataFrame(self.alarms(rig, open_only=open_only))


def open_store(url: str) -> Store:
    """Open a gearwatch database (an SQLAlchemy URL) for reading."""
    return Store(url)
