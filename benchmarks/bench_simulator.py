"""Simulator speed: a 12 s record at 20 kHz and a 12-day campaign (targets: ≤ 1 s, ≤ 20 s).

Run: ``.venv/bin/python benchmarks/bench_simulator.py [--quick]``. Prints CPU time (one core:
the integrator is single-threaded, so CPU time is what a dedicated core would take; the
wall time on a shared machine is printed beside it) after a warm-up call that compiles.
"""

from __future__ import annotations

import argparse
import tempfile
import time

from physics.campaign import write_campaign
from physics.config import Acquisition, GearPairModel, Mesh, Sensor, WheelBody
from physics.simulator import simulate


def timed(fn: object, *args: object, **kwargs: object) -> tuple[float, float]:
    wall, cpu = time.perf_counter(), time.process_time()
    fn(*args, **kwargs)  # type: ignore[operator]
    return time.process_time() - cpu, time.perf_counter() - wall


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="skip the campaign")
    args = parser.parse_args()
    simulate(GearPairModel(), seconds=0.05)  # compile (or load the numba cache)
    print(f"{'case':58s} {'cpu s':>7s} {'wall s':>7s} {'Msteps/s':>9s}")
    for dofs in ("full", "torsional"):
        for oversampling in (8, 16):
            model = GearPairModel(dofs=dofs, acquisition=Acquisition(oversampling=oversampling))
            cpu, wall = timed(simulate, model, seconds=12.0)
            steps = (12.0 + model.acquisition.warmup_s) * 20_000 * oversampling
            label = f"12 s record, 20 kHz, {dofs}, oversampling {oversampling}"
            print(f"{label:58s} {cpu:7.2f} {wall:7.2f} {steps / cpu / 1e6:9.2f}")
    # Issue 6 extensions: sliding friction (keeps y and rx: 12 instead of 8 DOF), an
    # off-line sensor, an oblique anisotropic support, a stiffness profile.
    extensions = {
        "friction μ=0.08": GearPairModel(mesh=Mesh(friction_coefficient=0.08)),
        "friction μ=0.08 + off-line sensor": GearPairModel(
            mesh=Mesh(friction_coefficient=0.08),
            sensors=[Sensor(), Sensor(name="acc_y", direction="off_line_of_action")],
        ),
        "oblique anisotropic support": GearPairModel(
            pinion=WheelBody(bearing_radial_stiffness_ratio=0.5, bearing_principal_axis_deg=30.0)
        ),
        "parabolic stiffness profile": GearPairModel(
            mesh=Mesh(stiffness_profile="parabolic", stiffness_profile_variation=0.5)
        ),
    }
    for name, model in extensions.items():
        cpu, wall = timed(simulate, model, seconds=12.0)
        steps = (12.0 + model.acquisition.warmup_s) * 20_000 * model.acquisition.oversampling
        label = f"12 s, 20 kHz, full, os 16, {name}"
        print(f"{label:58s} {cpu:7.2f} {wall:7.2f} {steps / cpu / 1e6:9.2f}")
    if not args.quick:
        with tempfile.TemporaryDirectory() as tmp:
            cpu, wall = timed(write_campaign, tmp, days=12, seconds=12.0)
        print(f"{'12-day campaign, 12 s records, WAV':58s} {cpu:7.2f} {wall:7.2f} {'':>9s}")


if __name__ == "__main__":
    main()
