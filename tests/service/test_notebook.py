"""The notebook API: a file analysed into DataFrames, stored trends and alarms as DataFrames."""

from __future__ import annotations

from pathlib import Path

import pytest

from gearwatch import notebook
from tests.service.seed import Seeded, seed_campaign

pd = pytest.importorskip("pandas")


@pytest.fixture(scope="module")
def store(tmp_path_factory: pytest.TempPathFactory) -> tuple[notebook.Store, Seeded]:
    from storage.db import open_database, session_scope

    url = f"sqlite:///{tmp_path_factory.mktemp('notebook') / 'gw.db'}"
    engine, factory = open_database(url)
    with session_scope(factory) as session:
        seeded = seed_campaign(session)
    engine.dispose()
    return notebook.open_store(url), seeded


def test_a_stored_per_tooth_trend_is_a_frame_indexed_by_time(
    store: tuple[notebook.Store, Seeded],
) -> None:
    db, seeded = store
    assert db.rigs() == [seeded.rig]
    frame = db.trend_frame(seeded.rig, "mci_depth")
    assert list(frame["record_id"]) == seeded.record_ids
    assert frame.index.name == "taken_at" and str(frame.index.tz) == "UTC"
    assert frame.attrs["unit"] == "Np"
    last = frame.iloc[-1]
    assert last[seeded.spall_tooth] == pytest.approx(seeded.depths[-1][seeded.spall_tooth])
    assert frame.drop(columns=["record_id", "label"]).iloc[-1].idxmax() == seeded.spall_tooth


def test_a_whole_record_trend_has_one_value_column(store: tuple[notebook.Store, Seeded]) -> None:
    db, seeded = store
    frame = db.trend_frame(seeded.rig, "kurtosis")
    assert list(frame.columns) == ["record_id", "label", "value"]
    assert (frame["value"] == 3.0).all()


def test_alarms_are_a_frame_with_a_null_tooth_for_whole_record_ones(
    store: tuple[notebook.Store, Seeded],
) -> None:
    db, seeded = store
    frame = db.alarms_frame(seeded.rig)
    mci = frame[frame["indicator"] == "mci_depth"]
    assert list(mci["tooth"]) == [seeded.spall_tooth]


def test_analyze_file_gives_teeth_metrics_and_curves_frames(simulated_campaign: Path) -> None:
    record = sorted((simulated_campaign / "records").iterdir())[-1]
    result = notebook.analyze_file(record, simulated_campaign / "campaign.toml")
    teeth = result.teeth_frame()
    assert len(teeth) == 20 and set(teeth.columns) >= {"tooth", "mci_depth", "diff_kurtosis"}
    assert teeth.loc[teeth["mci_depth"].idxmax(), "tooth"] == 16  # the spalled tooth
    metrics = result.metrics_frame()
    assert {"rms", "kurtosis", "fm4", "raw_kurtosis"} <= set(metrics.columns)
    curves = result.curves_frame()
    assert curves.index.name == "angle_deg" and "mci" in curves.columns
    with pytest.raises(Exception, match="unknown analysis parameter"):
        notebook.analyze_file(record, simulated_campaign / "campaign.toml", nope=1)
