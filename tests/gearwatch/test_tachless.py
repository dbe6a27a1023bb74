"""Records without a tachometer (issue 11): the mesh-phase angle in the pipeline, the campaign's
tooth frame across days (tach-less and mixed campaigns, stored in the database), the refusals,
and whole-record raw metrics kept when no angle can be had."""

from __future__ import annotations

import json
import re
from pathlib import Path

import numpy as np
import pytest
import sqlalchemy as sa

from gearwatch.cli.main import main
from gearwatch.floor.campaign import Campaign, ChannelConfig, RecordData, RigConfig
from gearwatch.floor.results import AnalysisParameters, RecordAnalysis, ToothFrameReference
from gearwatch.usecases.analyze import analyze_file, analyze_record
from gearwatch.usecases.replay import replay_campaign
from ingest.manifest import load_manifest
from storage.db import session_factory, session_scope
from storage.raw_store import RawStore
from storage.repositories import AlarmRepository, RecordRepository
from storage.tooth_frames import ToothFrameRepository
from tests.gearwatch import tachlessfixtures as fx
from tests.storage import dbfixtures

_postgres_schema = dbfixtures._postgres_schema
db_url = dbfixtures.db_url
db_engine_migrated = dbfixtures.db_engine_migrated
db_engine = dbfixtures.db_engine

SPALL_TOOTH, ONSET = 7, 9


@pytest.fixture(scope="module")
def tachless_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return fx.write_campaign(tmp_path_factory.mktemp("tl") / "only", 11, onset_day=ONSET,
                             spall_tooth=SPALL_TOOTH)


@pytest.fixture(scope="module")
def mixed_campaign(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return fx.write_campaign(tmp_path_factory.mktemp("tl") / "mixed", 11, onset_day=ONSET,
                             spall_tooth=SPALL_TOOTH, with_tach_channel=True,
                             tach_days=(1, 2, 3, 5, 8, 11))


def _campaign(teeth: bool = True) -> Campaign:
    rig = RigConfig("r", fx.PINION if teeth else None, fx.GEAR if teeth else None,
                    nominal_pinion_rpm=fx.RPM)
    return Campaign("c", "", rig, fx.FS, None, (ChannelConfig("acc", "accelerometer"),))


def test_a_tachless_record_gets_its_angle_from_the_mesh_phase_and_says_so() -> None:
    data = fx.record(1)
    analysis = analyze_record(RecordData({"acc": data["acc"]}, fx.FS), _campaign(), input_sha256="a")
    quality = analysis.quality
    assert quality.angle_source == "mesh_phase"
    assert quality.tachless is not None
    assert quality.tachless["pulse_jitter_rev"] < 1e-3 and quality.tachless["line_prominence_db"] > 15
    assert abs(analysis.speed_rpm - fx.RPM) < 0.03 * fx.RPM
    channel = analysis.channels[0]
    assert len(channel.teeth) == fx.PINION
    assert channel.tooth_frame["kind"] == "own"  # no campaign context: said so
    out = analysis.to_json()
    assert out["tooth_frame"]["kind"] == "own" and out["quality"]["angle_source"] == "mesh_phase"


def test_a_tach_recorded_alongside_finds_every_aligned_day_at_one_shaft_angle() -> None:
    # quality.tachless.first_pulse_s (angle 0 of the record's own average) and the campaign
    # frame's pinion_delay_samples let a tach recorded alongside audit the frame: sample 0 of
    # every aligned day's campaign-frame average is at one pinion angle, whatever angle each
    # record started at (benchmarks/bench_tachless.py scores the frame this way).
    from dsp.tach import pulse_times_from_waveform
    from gearwatch.usecases.tachless import fold_reference

    reference = None
    angles = []
    for day in (1, 2, 3):
        data = fx.record(day, start_rev=0.37 * day, tach="ok")
        analysis = analyze_record(RecordData({"acc": data["acc"]}, fx.FS), _campaign(), input_sha256=f"d{day}",
                                  tooth_frames={} if reference is None else {"acc": reference})
        channel = analysis.channels[0]
        assert channel.tooth_frame["kind"] == "campaign", channel.tooth_frame
        assert analysis.quality.tachless is not None
        pulses = pulse_times_from_waveform(data["tach"].astype(float), fx.FS)
        own = float(np.interp(analysis.quality.tachless["first_pulse_s"], pulses, np.arange(pulses.size)))
        angles.append((own - channel.tooth_frame["pinion_delay_samples"] / channel.samples_per_rev) % 1.0)
        reference = fold_reference(reference, channel, f"d{day}") or reference
    offsets_teeth = [((a - angles[0] + 0.5) % 1.0 - 0.5) * fx.PINION for a in angles[1:]]
    assert max(abs(o) for o in offsets_teeth) < 0.25, offsets_teeth


@pytest.mark.parametrize(("speed_variation", "chosen"), [(0.01, 1), (0.17, 4)])
def test_a_sweeping_speed_takes_the_highest_harmonic_not_the_steadiest_pulses(
    speed_variation: float, chosen: int,
) -> None:
    # As the mesh frequency sweeps, the path's phase at it turns and the angle read from harmonic
    # h wanders by phase / (2π h) teeth: a 66-tooth day sweeping ±8 % whose harmonic-1 pulses
    # were the steadiest landed 1.4 teeth off. At a steady speed the steadiest pulses still win.
    from dsp.tachless import ShaftAngleEstimate
    from gearwatch.usecases.tachless import _chosen_estimate

    def estimate(harmonic: int) -> ShaftAngleEstimate:
        return ShaftAngleEstimate(np.arange(10.0), 1.0, 66.0 * harmonic, 20.0, 0.5, speed_variation, 66, harmonic)

    working = [(1e-4, estimate(1), "acc"), (5e-4, estimate(4), "acc")]
    assert _chosen_estimate(working, followed_drift=False)[1].harmonic == chosen
    assert _chosen_estimate(working, followed_drift=True)[1].harmonic == 4


def test_a_corrupt_sample_does_not_cost_a_tachless_record_its_angle() -> None:
    # One float32-fitting 3e38 sample flattens the whole record's spectrum: the mesh phase is
    # read with the defect bridged, as the averages are, and the repair is counted.
    data = fx.record(1)["acc"].copy()
    data[data.size // 3] = 3.0e38
    analysis = analyze_record(RecordData({"acc": data}, fx.FS), _campaign(), input_sha256="g")
    assert analysis.quality.angle_source == "mesh_phase", analysis.quality.per_tooth
    assert analysis.quality.glitch_samples == 1
    assert abs(analysis.speed_rpm - fx.RPM) < 0.03 * fx.RPM


def test_a_speed_swinging_by_a_third_within_the_record_is_followed_without_a_tach() -> None:
    # The independent generator's speed shape (a ramp plus a slow swell), ±20 %: each mesh
    # harmonic sweeps across its neighbours' search windows and smears over hundreds of bins.
    # The speed tracked on the mesh comb gives pulses at one shaft angle, as the tach's.
    from dsp.tach import pulse_times_from_waveform
    from gearwatch.usecases.tachless import mesh_phase_angle
    from physics.independent import generate_record, random_model

    model = random_model(7, pinion_teeth=23, gear_teeth=61, noise_to_signal=0.5,
                         speed_drift_fraction=0.2, seconds=8.0, dynamics="linear")
    rec = generate_record(model, seed=7)
    angle = mesh_phase_angle({"acc": np.asarray(rec.channels["acc"], dtype=float)}, rec.sample_rate_hz,
                             23, 61, AnalysisParameters(), nominal_pinion_rpm=model.operating.speed_rpm)
    assert not isinstance(angle, str), angle
    assert angle.summary["line_followed_along_drift"] is True
    assert angle.tach.speed_variation > 0.3  # a third of the speed, and not refused for it
    true = pulse_times_from_waveform(np.asarray(rec.channels["tach"], dtype=float), rec.sample_rate_hz)
    revs = np.interp(angle.tach.pulse_times_s, true, np.arange(true.size))
    inside = (angle.tach.pulse_times_s > true[0]) & (angle.tach.pulse_times_s < true[-1])
    phase = revs[inside] - np.round(revs[inside] - revs[inside][0])  # the shaft angle of each pulse
    assert np.ptp(np.diff(np.round(revs[inside]))) == 0  # one pulse per revolution, none missed
    assert float(np.max(np.abs(phase - np.median(phase)))) < 0.25 / 23  # within a quarter pitch


def test_the_angle_comes_from_a_mesh_harmonic_not_from_a_tall_tone_near_one() -> None:
    # On the real SpectraQuest records a fixed 5957-Hz tone, 37 dB high, stands 3.8 % above
    # harmonic 6 of the 32-tooth wheel. A line within ±20 % of h × the speed hint was taken as
    # harmonic h: the tone won (a pure tone has no jitter) and the angle ran 3.8 % fast, so those
    # records matched no other day. The comb's speed now puts each harmonic within 2 %.
    from gearwatch.usecases.tachless import mesh_phase_angle

    fs, teeth, shaft_hz = 12_800.0, 24, 16.0
    t = np.arange(int(6 * fs)) / fs
    revs = shaft_hz * t
    x = sum(0.3 * np.cos(2 * np.pi * h * teeth * revs + h) for h in (1, 2, 3, 4))
    x = x + 10.0 * np.cos(2 * np.pi * 1.038 * 6 * teeth * shaft_hz * t)
    x = x + 0.2 * np.random.default_rng(5).standard_normal(t.size)
    angle = mesh_phase_angle({"acc": x}, fs, teeth, 48, AnalysisParameters(), nominal_pinion_rpm=60 * shaft_hz)
    assert not isinstance(angle, str), angle
    assert angle.summary["harmonic"] in (1, 2, 3, 4)
    assert abs(angle.tach.mean_rpm / (60 * shaft_hz) - 1) < 1e-3, angle.summary
    pulses_in_revs = shaft_hz * angle.tach.pulse_times_s
    assert np.ptp(pulses_in_revs - np.round(pulses_in_revs)) < 0.25 / teeth  # one shaft angle


def test_too_few_clean_revolutions_under_a_mesh_phase_angle_keep_the_raw_metrics() -> None:
    # Revolutions touched by defects are left out of the averages; when too few remain, a
    # tach record is rejected, a tach-less one keeps its whole-record metrics, with the reason.
    data = fx.record(1)["acc"].copy()
    whole = analyze_record(RecordData({"acc": data}, fx.FS), _campaign(), input_sha256="w")
    params = AnalysisParameters(min_revolutions=whole.revolutions - 1)
    for at in (0.2, 0.5, 0.8):  # three corrupt samples in three revolutions
        data[int(at * data.size)] = 3.0e38
    analysis = analyze_record(RecordData({"acc": data}, fx.FS), _campaign(), params, input_sha256="v")
    assert analysis.quality.angle_source == "none"
    assert analysis.quality.per_tooth.startswith("mesh-phase angle: only"), analysis.quality.per_tooth
    assert analysis.channels[0].metrics["raw_rms"] > 0 and not analysis.channels[0].teeth


def test_without_an_angle_the_raw_metrics_are_kept_with_the_reason() -> None:
    noise = np.random.default_rng(0).standard_normal(int(2 * fx.FS))
    analysis = analyze_record(RecordData({"acc": noise}, fx.FS), _campaign(), input_sha256="b")
    assert analysis.quality.angle_source == "none"
    reason = analysis.quality.per_tooth
    assert "manifest has no [tachometer]" in reason and "mesh line" in reason  # dsp.tachless's words
    corrupt = noise.copy()
    corrupt[100] = np.nan  # counted even when no average uses the repair
    assert analyze_record(RecordData({"acc": corrupt}, fx.FS), _campaign(), input_sha256="c").quality.glitch_samples == 1
    channel = analysis.channels[0]
    assert not channel.teeth and channel.tooth_frame["kind"] == "none"
    assert channel.metrics["raw_rms"] == pytest.approx(float(np.std(noise)), rel=1e-6)
    assert set(channel.metrics) == {"raw_rms", "raw_kurtosis"}

    data = fx.record(1)
    without_teeth = analyze_record(RecordData({"acc": data["acc"]}, fx.FS), _campaign(teeth=False),
                                   input_sha256="c")
    assert "without tooth counts" in without_teeth.quality.per_tooth
    assert without_teeth.channels[0].metrics["raw_rms"] > 0


def test_a_tachless_campaign_replays_every_record_accepted_and_alarms_the_spall_in_its_frame(
    db_engine: sa.Engine, tachless_campaign: Path, tmp_path: Path
) -> None:
    factory = session_factory(db_engine)
    summary = replay_campaign(tachless_campaign, factory, RawStore(tmp_path / "store"), progress=False)
    assert summary.outcomes == {"accepted": 11}
    with session_scope(factory) as session:
        records = RecordRepository(session).list(limit=None)
        frames = [r.quality["tooth_frames"]["acc"] for r in records]
        assert all(r.quality["angle_source"] == "mesh_phase" for r in records)
        assert frames[0]["founds_reference"] and frames[0]["reference_frame"] == "mesh_phase"
        assert all(f["kind"] == "campaign" for f in frames)
        assert {f["reference_sha256"] for f in frames} == {records[0].sha256}
        assert all(f["pinion"]["margin"] > 0.3 for f in frames[1:])
        reference = ToothFrameRepository(session).references(records[0].campaign_id)["acc"]
        assert reference.frame == "mesh_phase" and reference.records == 5  # folded, then frozen
        assert reference.speed_rpm == pytest.approx(records[-1].speed_rpm)  # the last day's
        alarms = AlarmRepository(session).list()
        tooth_alarms = {a.tooth for a in alarms if a.tooth}  # 0: whole-record metrics
        assert len(tooth_alarms) == 1, alarms
        alarmed = tooth_alarms.pop()
        # the same campaign-frame tooth is the worst on every spalled day
        worst = [RecordRepository(session).current_result(r.id).channels[0].worst_tooth
                 for r in records[ONSET - 1 :]]
        assert worst == [alarmed] * len(worst)
        # raw metrics trend on, as for any record
        metrics = {m.metric for m in RecordRepository(session).metrics(
            RecordRepository(session).current_result(records[-1].id).id)}
        assert {"raw_rms", "raw_kurtosis", "kurtosis"} <= metrics
        # the report a test engineer hands on says where the angle and the tooth numbers came from
        from gearwatch.usecases.report import collect, render_html

        report = collect(session, "rig-only")
        assert report.mesh_phase_records == 11
        assert all(r.tach_repairs is None for r in report.records)  # no tach, no tach repairs
        assert report.records[0].angle == "mesh phase; campaign's tach-less frame (founds it)"
        assert all(re.fullmatch(r"mesh phase; campaign's tach-less frame \(\d+\.\d SE.*\)", r.angle)
                   for r in report.records[1:]), [r.angle for r in report.records]
        assert "11 record(s) without a tachometer" in render_html(report)


def test_a_mixed_campaign_keeps_the_tach_frame_on_the_days_the_tach_is_dead(
    mixed_campaign: Path,
) -> None:
    from gearwatch.usecases.tachless import fold_reference

    campaign = load_manifest(mixed_campaign)
    reference = None
    seen = []
    for entry in campaign.records:
        analysis = analyze_file(campaign.record_path(entry), campaign,
                                tooth_frames={} if reference is None else {"acc": reference})
        channel = analysis.channels[0]
        seen.append((analysis.quality.angle_source, channel.tooth_frame.get("reference_frame"),
                     channel.worst_tooth))
        if analysis.quality.angle_source == "mesh_phase":
            assert "no tachometer pulses" in analysis.quality.tach_failure
        reference = fold_reference(reference, channel, entry.file) or reference
    dead_days = [s for s in seen if s[0] == "mesh_phase"]
    assert len(dead_days) == 5
    assert all(frame == "tachometer" for _, frame, _ in dead_days)
    # physical tooth numbers on tach-less days: the spall is the tach's tooth 7 on every day
    assert [worst for _, _, worst in seen[ONSET - 1 :]] == [SPALL_TOOTH] * 3


def test_a_dead_tach_record_is_accepted_not_rejected_in_the_database(
    db_engine: sa.Engine, mixed_campaign: Path, tmp_path: Path
) -> None:
    factory = session_factory(db_engine)
    summary = replay_campaign(mixed_campaign, factory, RawStore(tmp_path / "store"), progress=False,
                              only=["day01.npz", "day04.npz"])
    assert summary.outcomes == {"accepted": 2}
    with session_scope(factory) as session:
        day4 = next(r for r in RecordRepository(session).list(limit=None) if r.file_name == "day04.npz")
        frame = day4.quality["tooth_frames"]["acc"]
        assert frame["kind"] == "campaign" and frame["reference_frame"] == "tachometer"
        assert day4.quality["tach_failure"].startswith("tachometer:")


def test_cli_analyze_numbers_teeth_in_a_reference_records_frame(tachless_campaign: Path, capsys) -> None:
    folder = tachless_campaign.parent
    assert main(["analyze", str(folder / "day11.npz"), "--campaign", str(tachless_campaign), "--json",
                 "--reference", str(folder / "day01.npz")]) == 0
    out = json.loads(capsys.readouterr().out)
    assert out["tooth_frame"]["kind"] == "campaign"
    assert out["tooth_frame"]["reference_frame"] == "mesh_phase"
    spalled = out["worst_tooth"]
    assert main(["analyze", str(folder / "day10.npz"), "--campaign", str(tachless_campaign), "--json",
                 "--reference", str(folder / "day01.npz")]) == 0
    assert json.loads(capsys.readouterr().out)["worst_tooth"] == spalled  # one frame for both
    assert main(["analyze", str(folder / "day11.npz"), "--campaign", str(tachless_campaign)]) == 0
    assert "tooth frame: own" in capsys.readouterr().out
    assert main(["analyze", str(folder / "day11.npz"), "--campaign", str(tachless_campaign),
                 "--reference", str(folder / "missing.npz")]) == 2
    assert "no such reference record" in capsys.readouterr().err


def test_analysis_parameters_are_unchanged_by_the_frame() -> None:
    # the frame is not a parameter: re-ingesting the same file stays idempotent
    assert "tooth_frames" not in AnalysisParameters().to_dict()


SPECTRAQUEST = Path(__file__).resolve().parents[3] / "shared" / "data" / "real" / "spectraquest-gfd"


def test_the_real_spectraquest_records_get_a_tachless_angle_and_one_frame() -> None:
    import os

    if not SPECTRAQUEST.is_dir():
        if os.environ.get("CI"):
            pytest.fail(f"{SPECTRAQUEST} is missing: CI must clone the repository with shared/ beside it")
        pytest.skip("shared real data not present")
    from gearwatch.usecases.tachless import fold_reference

    manifest = Path(__file__).resolve().parents[2] / "examples" / "spectraquest-gfd" / "campaign.toml"
    campaign = load_manifest(manifest)
    first = analyze_file(SPECTRAQUEST / "h30hz0.csv.gz", campaign, tooth_frames={})
    assert first.quality.angle_source == "mesh_phase"
    assert first.quality.tachless is not None and first.quality.tachless["pulse_jitter_rev"] < 1e-3
    assert abs(first.speed_rpm - 1800) < 0.02 * 1800  # 430 samples/rev at the assumed 12.9 kHz
    references = {c.channel: fold_reference(None, c, "h30hz0") for c in first.channels}
    same_box = analyze_file(SPECTRAQUEST / "h30hz10.csv.gz", campaign, tooth_frames=references)
    frame = same_box.channels[0].tooth_frame
    assert frame["kind"] == "campaign" and frame["pinion"]["margin"] > 0.3, frame


def _without_hint(record: dict[str, np.ndarray], reference: ToothFrameReference | None = None) -> RecordAnalysis:
    rig = RigConfig("r", fx.PINION, fx.GEAR)  # no nominal_pinion_rpm
    campaign = Campaign("c", "", rig, fx.FS, None, (ChannelConfig("acc", "accelerometer"),))
    return analyze_record(RecordData({"acc": record["acc"]}, fx.FS), campaign, input_sha256="d",
                          tooth_frames={} if reference is None else {"acc": reference})


def test_without_a_speed_hint_the_revolutions_confirm_the_spectrum_speed() -> None:
    analysis = _without_hint(fx.record(2))
    channel = analysis.channels[0]
    assert analysis.quality.angle_source == "mesh_phase"
    assert analysis.quality.tachless is not None
    assert analysis.quality.tachless["speed_from"] == "spectrum"
    assert abs(analysis.speed_rpm / fx.RPM - 1) < 0.03
    assert channel.tooth_frame["kind"] == "campaign", channel.tooth_frame
    assert channel.tooth_frame["period_check"]["confirmed"] is True
    assert len(channel.teeth) == fx.PINION


def test_a_spectrum_speed_twice_the_true_one_is_corrected_by_its_revolutions() -> None:
    # no odd mesh harmonic: the line family of twice the speed explains the spectrum better
    # (the premise is checked), but then consecutive "revolutions" are the two halves of a true
    # one and differ: the speed is halved and confirmed
    from dsp.meshspectrum import estimate_pair_speed

    record = fx.record(2, harmonics=(0.0, 1.0, 0.0, 0.6, 0.0, 0.4))
    spectrum_hz = estimate_pair_speed(record["acc"].astype(float), fx.FS, fx.PINION, fx.GEAR,
                                      min_shaft_hz=10 / 3.0)
    assert abs(60 * spectrum_hz / fx.RPM - 2) < 0.06
    analysis = _without_hint(record)
    assert analysis.quality.tachless is not None
    assert analysis.quality.tachless["speed_corrected_by"] == "1/2"
    assert abs(analysis.speed_rpm / fx.RPM - 1) < 0.03
    frame = analysis.channels[0].tooth_frame
    assert frame["kind"] == "campaign" and frame["period_check"]["confirmed"] is True, frame


def test_without_a_speed_hint_and_without_a_tooth_pattern_the_tooth_numbers_are_refused() -> None:
    # nothing tooth-specific: the revolutions cannot show that they are true ones
    analysis = _without_hint(fx.record(2, pattern=0.0))
    channel = analysis.channels[0]
    assert channel.tooth_frame["kind"] == "refused"
    assert "not confirmed by the revolutions" in channel.tooth_frame["reason"]
    assert "too little tooth-specific vibration" in channel.tooth_frame["reason"]
    assert not channel.teeth and channel.metrics["raw_rms"] > 0
    assert channel.tooth_frame["period_check"]["confirmed"] is False


@pytest.mark.parametrize(("hint_rpm", "corrected_by"), [(1300.0, "2/3"), (1500.0, "1/2"), (2500.0, "1/3")])
def test_a_speed_hint_far_off_that_day_is_overruled_by_the_revolutions(hint_rpm: float, corrected_by: str) -> None:
    # the rig ran at 900 rpm; within ±20 % of the hint the search found another mesh harmonic
    # (1.5×, 2×, 3× the speed): every tooth number would be wrong. The revolutions show it, and
    # the corrected angle's revolutions are confirmed.
    rig = RigConfig("r", fx.PINION, fx.GEAR, nominal_pinion_rpm=hint_rpm)
    campaign = Campaign("c", "", rig, fx.FS, None, (ChannelConfig("acc", "accelerometer"),))
    analysis = analyze_record(RecordData({"acc": fx.record(2)["acc"]}, fx.FS), campaign,
                              input_sha256="d", tooth_frames={})
    assert analysis.quality.tachless is not None
    assert analysis.quality.tachless["hint_overruled"] is True
    assert analysis.quality.tachless["speed_from"] == "nominal_pinion_rpm, corrected by the revolutions"
    assert analysis.quality.tachless["hint_speed_rpm"] > 1.4 * fx.RPM  # the hint's own angle
    assert analysis.quality.tachless["speed_corrected_by"] == corrected_by
    assert abs(analysis.speed_rpm / fx.RPM - 1) < 0.03
    frame = analysis.channels[0].tooth_frame
    assert frame["kind"] == "campaign" and frame["period_check"]["confirmed"] is True


def test_a_speed_hint_that_gives_no_angle_falls_back_to_the_checked_spectrum_speed() -> None:
    rig = RigConfig("r", fx.PINION, fx.GEAR, nominal_pinion_rpm=450.0)  # half the day's speed
    campaign = Campaign("c", "", rig, fx.FS, None, (ChannelConfig("acc", "accelerometer"),))
    analysis = analyze_record(RecordData({"acc": fx.record(2)["acc"]}, fx.FS), campaign,
                              input_sha256="d", tooth_frames={})
    assert analysis.quality.tachless is not None
    assert "at least 20 are required" in analysis.quality.tachless["hint_failed"]
    assert abs(analysis.speed_rpm / fx.RPM - 1) < 0.03
    assert analysis.channels[0].tooth_frame["period_check"]["confirmed"] is True


def test_a_right_speed_hint_is_kept_and_not_checked_into_a_refusal() -> None:
    # the hint's angle is only replaced by a confirmed correction: a right one stays as it was
    rig = RigConfig("r", fx.PINION, fx.GEAR, nominal_pinion_rpm=fx.RPM)
    campaign = Campaign("c", "", rig, fx.FS, None, (ChannelConfig("acc", "accelerometer"),))
    analysis = analyze_record(RecordData({"acc": fx.record(2, pattern=0.0)["acc"]}, fx.FS), campaign,
                              input_sha256="d", tooth_frames={})
    assert analysis.quality.tachless is not None
    assert analysis.quality.tachless["speed_from"] == "nominal_pinion_rpm"
    assert "hint_overruled" not in analysis.quality.tachless
    assert "period_check" not in analysis.channels[0].tooth_frame


def test_without_a_speed_hint_the_campaigns_learned_speed_numbers_what_the_revolutions_cannot_confirm() -> None:
    # day 1's spectrum speed is confirmed by its revolutions and founds the frame with its speed;
    # day 2's tooth pattern is too weak for its revolutions to confirm the spectrum's speed
    # alone (refused, the premise is checked), but the campaign's speed is trusted as a nominal
    # speed is: the day is numbered, in the same frame as with the rig's true nominal speed
    from gearwatch.usecases.tachless import fold_reference

    first = _without_hint(fx.record(1))
    reference = fold_reference(None, first.channels[0], "d1")
    assert reference is not None and reference.speed_rpm == pytest.approx(first.speed_rpm)
    weak = fx.record(2, pattern=0.05)
    alone = _without_hint(weak)
    assert alone.channels[0].tooth_frame["kind"] == "refused" and not alone.channels[0].teeth

    rig = RigConfig("r", fx.PINION, fx.GEAR)
    campaign = Campaign("c", "", rig, fx.FS, None, (ChannelConfig("acc", "accelerometer"),))
    learned = analyze_record(RecordData({"acc": weak["acc"]}, fx.FS), campaign, input_sha256="d2",
                             tooth_frames={"acc": reference})
    assert learned.quality.tachless is not None
    assert learned.quality.tachless["speed_from"] == "campaign_speed_rpm"
    assert learned.quality.tachless["campaign_speed_rpm"] == reference.speed_rpm
    frame = learned.channels[0].tooth_frame
    assert frame["kind"] == "campaign" and "period_check" not in frame, frame
    nominal = analyze_record(RecordData({"acc": weak["acc"]}, fx.FS), _campaign(), input_sha256="d2",
                             tooth_frames={"acc": reference})
    assert frame["pinion"]["shift_teeth"] == nominal.channels[0].tooth_frame["pinion"]["shift_teeth"]
    assert learned.channels[0].worst_tooth == nominal.channels[0].worst_tooth


def test_a_learned_speed_far_off_that_day_is_overruled_like_a_nominal_one() -> None:
    from dataclasses import replace

    from gearwatch.usecases.tachless import fold_reference

    first = _without_hint(fx.record(1))
    reference = fold_reference(None, first.channels[0], "d1")
    assert reference is not None
    rig = RigConfig("r", fx.PINION, fx.GEAR)
    campaign = Campaign("c", "", rig, fx.FS, None, (ChannelConfig("acc", "accelerometer"),))
    # the rig ran at 900 rpm; the campaign's last numbered day had run at 1500
    analysis = analyze_record(RecordData({"acc": fx.record(2)["acc"]}, fx.FS), campaign, input_sha256="d2",
                              tooth_frames={"acc": replace(reference, speed_rpm=1500.0)})
    assert analysis.quality.tachless is not None
    assert analysis.quality.tachless["speed_from"] == "campaign_speed_rpm, corrected by the revolutions"
    assert abs(analysis.speed_rpm / fx.RPM - 1) < 0.03
    assert analysis.channels[0].tooth_frame["period_check"]["confirmed"] is True


def test_every_numbered_record_leaves_its_speed_in_the_reference() -> None:
    from gearwatch.usecases.tachless import FOLD_RECORDS, fold_reference

    reference = None
    for day in range(1, FOLD_RECORDS + 3):
        analysis = _without_hint(fx.record(day), reference)
        assert analysis.quality.tachless is not None
        assert analysis.quality.tachless["speed_from"] == ("spectrum" if day == 1 else "campaign_speed_rpm")
        channel = analysis.channels[0]
        folded = fold_reference(reference, channel, f"d{day}")
        # the fingerprints stop changing after FOLD_RECORDS records; the speed follows every day
        assert folded is not None and folded.speed_rpm == pytest.approx(channel.speed_rpm)
        assert folded.records == min(day, FOLD_RECORDS)
        reference = folded
    assert reference is not None
    refused = _without_hint(fx.record(9, pattern=0.0), reference).channels[0]
    assert refused.tooth_frame["kind"] == "refused"
    assert fold_reference(reference, refused, "d9") is None  # a refused day leaves nothing


def test_a_campaign_without_a_speed_hint_replays_on_the_speed_its_first_numbered_day_confirmed(
    db_engine: sa.Engine, tmp_path: Path
) -> None:
    manifest = fx.write_campaign(tmp_path / "nohint", 4, nominal_speed=False)
    factory = session_factory(db_engine)
    summary = replay_campaign(manifest, factory, RawStore(tmp_path / "store"), progress=False)
    assert summary.outcomes == {"accepted": 4}
    with session_scope(factory) as session:
        records = RecordRepository(session).list(limit=None)
        sources = [r.quality["tachless"]["speed_from"] for r in records]
        assert sources == ["spectrum"] + ["campaign_speed_rpm"] * 3
        frames = [r.quality["tooth_frames"]["acc"] for r in records]
        assert all(f["kind"] == "campaign" for f in frames), frames
        reference = ToothFrameRepository(session).references(records[0].campaign_id)["acc"]
        assert reference.speed_rpm == pytest.approx(records[-1].speed_rpm)
        assert [r.quality["tachless"].get("campaign_speed_rpm") for r in records[1:]] == pytest.approx(
            [r.speed_rpm for r in records[:-1]])
