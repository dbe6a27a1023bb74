"""``gearwatch figure-mci OUT.png``: the seed's Fig. 6 on a simulated healthy and spalled day."""

from __future__ import annotations

import argparse
from typing import Any


def register(subparsers: Any) -> None:
    parser = subparsers.add_parser(
        "figure-mci",
        help="plot the seed's Fig. 6 (time signal, average, MCI raw and filtered) on simulated days",
        description=(
            "Simulate a healthy day and the spall's onset day of a campaign (same gears, "
            "see simulate-campaign), run the project's chain on both and plot, per day: "
            "(a) the acceleration, (b) the pinion synchronous average, (c) the raw moving "
            "cepstrum integral, (d) the median-filtered MCI, with the spalled tooth's sector "
            "marked. The MCI form is the pipeline's default (written in the titles)."
        ),
    )
    parser.add_argument("out_png", help="PNG to write")
    parser.add_argument("--seed", type=int, default=0, help="campaign seed (default 0)")
    parser.add_argument("--spall-tooth", type=int, default=16, help="spalled pinion tooth")
    parser.add_argument("--seconds", type=float, default=6.0, help="record length (default 6)")
    parser.add_argument(
        "--days-after-onset",
        type=int,
        default=0,
        help="plot the spall this many days after its onset (default 0: the onset, mid-size)",
    )
    parser.set_defaults(func=run)


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np

    from gearwatch.floor.campaign import RecordData
    from gearwatch.floor.errors import InputError
    from gearwatch.usecases.analyze import analyze_record
    from ingest.manifest import parse_manifest
    from physics.campaign import campaign_plan, manifest_dict
    from physics.simulator import simulate

    if not args.out_png.lower().endswith(".png"):
        raise InputError(f"{args.out_png}: the figure is written as PNG (use a .png name)")
    if not args.seconds >= 2.0:
        raise InputError("--seconds must be ≥ 2 (enough revolutions to average)")
    if args.days_after_onset < 0:
        raise InputError("--days-after-onset must be ≥ 0")
    if not 1 <= args.spall_tooth <= 20:
        raise InputError("--spall-tooth must be within 1..20")
    onset = 2
    plan = campaign_plan(
        days=onset + args.days_after_onset,
        spall_tooth=args.spall_tooth,
        onset_day=onset,
        seed=args.seed,
    )
    days = [plan[0], plan[-1]]
    campaign = parse_manifest(manifest_dict(plan[0].model, [], "figure", "figure"), root=Path("."))
    tooth1 = campaign.rig.tooth1_pitch_angle_deg
    teeth = plan[0].model.geometry.pinion_teeth
    pitch = (tooth1 + (args.spall_tooth - 1) * 360.0 / teeth) % 360.0

    fig, axes = plt.subplots(4, 2, figsize=(12, 10), sharex="row", constrained_layout=True)
    for col, day in enumerate(days):
        result = simulate(day.model, seconds=args.seconds, seed=day.seed)
        record = RecordData(result.channels, result.sample_rate_hz, source=f"day {day.day}")
        channel = analyze_record(record, campaign, input_sha256="").channels[0]
        curves = channel.curves
        spalls = day.model.deviations.spalls
        title = (
            "healthy"
            if not spalls
            else (
                f"spall on tooth {spalls[0].tooth}: {spalls[0].depth_um:.0f} µm deep, "
                f"{spalls[0].face_width_mm / day.model.geometry.face_width_mm:.0%} of the face, "
                f"{spalls[0].profile_extent_mm:.1f} mm along the profile"
            )
        )
        fs = result.sample_rate_hz
        n_show = round(2 * 60.0 / day.model.operating.speed_rpm * fs)
        t_ms = np.arange(n_show) / fs * 1e3
        ax = axes[0, col]
        ax.plot(t_ms, result.channels["acc"][:n_show], lw=0.5)
        ax.set_title(f"day {day.day} — {title}", fontsize=9)
        ax.set_xlabel("time (ms)")
        ax.set_ylabel("(a) acceleration (m/s²)")
        spr = channel.samples_per_rev
        angle = np.arange(spr) * 360.0 / spr
        rows = [
            ("pinion_average", "(b) pinion average (m/s²)"),
            ("mci_raw", "(c) MCI raw (Np)"),
            ("mci", "(d) MCI median-filtered (Np)"),
        ]
        for row, (key, label) in enumerate(rows, start=1):
            ax = axes[row, col]
            ax.plot(angle, curves[key], lw=0.7)
            ax.axvspan(pitch - 180.0 / teeth, pitch + 180.0 / teeth, color="tab:red", alpha=0.12)
            ax.set_ylabel(label)
            ax.set_xlim(0, 360)
        axes[3, col].set_xlabel(
            f"pinion angle after the tach edge (°); shaded: tooth {args.spall_tooth}; "
            f"worst tooth {channel.worst_tooth}"
        )
    fig.suptitle(
        "Fig. 6 of El Badaoui et al. (2001) on simulated data: gear-pair model (six DOF per "
        f"wheel), {days[0].model.operating.speed_rpm:.0f} rpm, MCI window 64 samples "
        "(one mesh period), pipeline default MCI form",
        fontsize=10,
    )
    out = Path(args.out_png)
    out.parent.mkdir(parents=True, exist_ok=True)
    fig.savefig(out, dpi=110)
    plt.close(fig)
    print(f"wrote {out}")
    return 0
