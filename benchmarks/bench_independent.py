"""What gearwatch's current pipeline does on records of the independent generator.

Run: ``nice -n 10 .venv/bin/python benchmarks/bench_independent.py [--seeds 5] [--seconds 8]``

1. Speed: CPU time of one 12 s record (20 kHz) of :mod:`physics.independent` at oversampling
   4 and 8, and of the project's simulator on its default model in the same process.
2. Attribution: per geometry (contact ratio × tooth counts) and pit size, the share of records
   whose ``worst_tooth`` is the pitted tooth (exact, and within ±1 tooth), and the median MCI
   depth of that tooth against the deepest healthy tooth of the same rig. Rigs are drawn by
   :func:`physics.independent.random_model` (seeds 1000 + i; nothing here is tuned on them).
3. Operating cases on one rig: drift, glitch, dropout, clipping, gain, hum, no tachometer —
   analysed or refused (with the reason).
4. Campaigns (:func:`physics.independent.random_campaign`, seeds 2000 + i): per day, the
   pipeline's worst tooth and the pitted tooth's MCI depth (day 0 = onset).
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np

from gearwatch.floor.errors import RecordRejected
from gearwatch.usecases.analyze import analyze_record
from physics.independent import (
    Acquisition,
    Artefacts,
    IndependentModel,
    Operating,
    Spall,
    Tachometer,
    generate_record,
    random_campaign,
    random_model,
)
from physics.independent.campaign import generate_campaign

SIZES = (  # (label, depth µm, face fraction, extent fraction)
    ("4 µm, 15 % face, 0.15 path", 4.0, 0.15, 0.15),
    ("8 µm, 25 % face, 0.25 path", 8.0, 0.25, 0.25),
    ("15 µm, 40 % face, 0.40 path", 15.0, 0.40, 0.40),
    ("25 µm, 60 % face, 0.55 path", 25.0, 0.60, 0.55),
)
GEOMETRIES = ((1.4, 20, 21), (1.6, 20, 21), (1.9, 20, 21), (1.6, 17, 43), (1.4, 17, 43), (1.9, 17, 43))


def depths(model: IndependentModel, seed: int) -> tuple[int | None, np.ndarray]:
    rec = generate_record(model, seed=seed)
    analysis = analyze_record(rec.record_data(), rec.campaign(), input_sha256="0" * 64)
    ch = analysis.channels[0]
    return ch.worst_tooth, np.array([t.mci_depth for t in ch.teeth])


def speed_table() -> None:
    from physics.config import GearPairModel
    from physics.simulator import simulate

    base = IndependentModel(spalls=(Spall(tooth=5),))
    generate_record(base.replace(acquisition=Acquisition(seconds=0.5)))
    simulate(GearPairModel(), seconds=0.5, seed=0)
    print("| generator (12 s record, 20 kHz) | CPU s |\n|---|---|")
    for os_ in (4, 8):
        t = time.process_time()
        generate_record(base.replace(acquisition=Acquisition(oversampling=os_)))
        print(f"| independent, oversampling {os_} | {time.process_time() - t:.2f} |")
    t = time.process_time()
    simulate(GearPairModel(), seconds=12.0, seed=0)
    print(f"| project's simulator, default (six DOF, oversampling 16) | {time.process_time() - t:.2f} |")


def attribution_table(seeds: int, seconds: float, noise: float) -> None:
    print(f"\nnoise {noise}× the signal RMS, {seconds:g} s records, rigs random_model(1000 + i), "
          f"i < {seeds}; pit centre along the path drawn in 0.3–0.6")
    print("| ε | Z1/Z2 | pit | exact | ±1 tooth | median depth (Np) pitted / deepest healthy |")
    print("|---|---|---|---|---|---|")
    for eps, z1, z2 in GEOMETRIES:
        rigs = []
        for i in range(seeds):
            seed = 1000 + i
            model = random_model(seed, contact_ratio=eps, pinion_teeth=z1, gear_teeth=z2,
                                 noise_to_signal=noise, speed_drift_fraction=0.0, seconds=seconds)
            rng = np.random.default_rng(seed)
            tooth = int(rng.integers(1, z1 + 1))
            centre = float(rng.uniform(0.3, 0.6))
            _, healthy = depths(model, seed)
            rigs.append((seed, model, tooth, centre, float(np.max(healthy))))
        for label, depth, face, extent in SIZES:
            exact = near = 0
            pitted_depths = []
            for seed, model, tooth, centre, _ in rigs:
                pit = Spall(tooth=tooth, depth_um=depth, face_fraction=face, extent_fraction=extent,
                            centre_fraction=centre)
                worst, d = depths(model.replace(spalls=(pit,)), seed)
                exact += worst == tooth
                near += worst is not None and min((worst - tooth) % z1, (tooth - worst) % z1) <= 1
                pitted_depths.append(float(d[tooth - 1]))
            healthy_depth = statistics.median(r[4] for r in rigs)
            print(f"| {eps} | {z1}/{z2} | {label} | {exact}/{seeds} | {near}/{seeds} | "
                  f"{statistics.median(pitted_depths):.2f} / {healthy_depth:.2f} |", flush=True)


def operating_table(seconds: float) -> None:
    model = random_model(2024, contact_ratio=1.6, pinion_teeth=20, gear_teeth=21,
                         noise_to_signal=0.5, speed_drift_fraction=0.0, seconds=seconds)
    tooth = 9
    model = model.replace(spalls=(Spall(tooth=tooth, depth_um=15, face_fraction=0.4,
                                        extent_fraction=0.4, centre_fraction=0.45),))
    cases = {
        "plain": model,
        "speed drift 15 % within the record": model.replace(
            operating=Operating(**{**model.operating.__dict__, "speed_drift_fraction": 0.15})),
        "one glitch sample (ADC spike, 20× the peak)": model.replace(artefacts=Artefacts(glitches=1)),
        "one glitch sample (3e38)": model.replace(artefacts=Artefacts(glitches=1, glitch_value=3e38)),
        "two 20 ms dropouts": model.replace(artefacts=Artefacts(dropouts=2)),
        "clipped at 60 % of the peak": model.replace(artefacts=Artefacts(clip_fraction_of_peak=0.6)),
        "gain ×3": model.replace(acquisition=Acquisition(
            **{**model.acquisition.__dict__, "gain": 3.0})),
        "mains hum at the signal's RMS": model.replace(artefacts=Artefacts(hum_to_signal=1.0)),
        "no tachometer": model.replace(tachometer=Tachometer(
            **{**model.tachometer.__dict__, "present": False})),
    }
    print(f"\nrig random_model(2024), ε 1.6, 20/21, pit 15 µm / 40 % face / 0.4 path on tooth {tooth}")
    print("| case | pipeline | worst tooth | depth of tooth 9 (Np) |\n|---|---|---|---|")
    for name, case in cases.items():
        try:
            worst, d = depths(case, 7)
            print(f"| {name} | analysed | {worst} | {d[tooth - 1]:.2f} |", flush=True)
        except RecordRejected as exc:
            print(f"| {name} | refused: {str(exc)[:90]} | — | — |", flush=True)


def campaign_table(campaigns: int, seconds: float) -> None:
    print(f"\ncampaigns random_campaign(2000 + i, days=6, onset_day=3, speed_drift_fraction=0), "
          f"{seconds:g} s records (no drift within a record, so that today's pipeline analyses every day)")
    print("| seed | ε | Z1/Z2 | pitted tooth | per day: worst tooth (pitted tooth's depth, Np) |")
    print("|---|---|---|---|---|")
    for i in range(campaigns):
        seed = 2000 + i
        plan = random_campaign(seed, days=6, onset_day=3, seconds=seconds, speed_drift_fraction=0.0)
        model = plan[-1].model
        tooth = model.spalls[0].tooth
        cells = []
        for day, rec in zip(plan, generate_campaign(plan), strict=True):
            try:
                analysis = analyze_record(rec.record_data(), rec.campaign(), input_sha256="0" * 64)
            except RecordRejected as exc:
                cells.append(f"d{day.day}: refused ({str(exc)[:40]})")
                continue
            ch = analysis.channels[0]
            depth = ch.teeth[tooth - 1].mci_depth
            mark = "" if "spall_depth_um" not in day.changes else f"{day.changes['spall_depth_um']:.0f}µm "
            cells.append(f"d{day.day} {mark}→ {ch.worst_tooth} ({depth:.2f})")
        g = model.geometry
        print(f"| {seed} | {g.contact_ratio:.2f} | {g.pinion_teeth}/{g.gear_teeth} | {tooth} | "
              f"{'; '.join(cells)} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=5)
    parser.add_argument("--seconds", type=float, default=8.0)
    parser.add_argument("--noise", type=float, default=0.5)
    parser.add_argument("--campaigns", type=int, default=4)
    parser.add_argument("--skip-speed", action="store_true")
    args = parser.parse_args()
    if not args.skip_speed:
        speed_table()
    operating_table(args.seconds)
    campaign_table(args.campaigns, args.seconds)
    attribution_table(args.seeds, args.seconds, args.noise)


if __name__ == "__main__":
    main()
