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
from physics.config import Acquisition, GearPairModel
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
    print(f"{'case':44s} {'cpu s':>7s} {'wall s':>7s} {'Msteps/s':>9s}")
    for dofs in ("full", "torsional"):
        for oversampling in (8, 16):
            model = GearPairModel(dofs=dofs, acquisition=Acquisition(oversampling=oversampling))
            cpu, wall = timed(simulate, model, seconds=12.0)
            steps = (12.0 + model.acquisition.warmup_s) * 20_000 * oversampling
            label = f"12 s record, 20 kHz, {dofs}, oversampling {oversampling}"
            print(f"{label:44s} {cpu:7.2f} {wall:7.2f} {steps / cpu / 1e6:9.2f}")
    if not args.quick:
        with tempfile.TemporaryDirectory() as tmp:
            cpu, wall = timed(write_campaign, tmp, days=12, seconds=12.0)
        print(f"{'12-day campaign, 12 s records, WAV':44s} {cpu:7.2f} {wall:7.2f} {'':>9s}")


if __name__ == "__main__":
    main()
