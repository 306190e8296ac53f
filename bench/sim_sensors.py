"""Benchmark of the simulated sensors: what SimSensors adds to a simulator step.

Per CPU second (``time.process_time``, one core: other processes on a shared machine do not count
against it), a step of the simulated car (physics and telemetry, no camera render) alone as the
baseline, measured in the same run, then with the sensors of a simulator car: encoder ticks; encoder
+ IMU + GPS; and those plus a 360-bin LiDAR ray-cast against the indoor theme's four walls and 8
distractors (the worst geometry the built-in worlds have).

Usage: .venv/bin/python bench/sim_sensors.py [--steps 3000] [--repeats 5] [--bins 360]
"""

from __future__ import annotations

import argparse
import statistics
import time

from parts.sim.sensors import SimSensors
from parts.sim.simulator import SimCar


def rate(sim: SimCar, sensors: SimSensors | None, steps: int) -> float:
    """Steps per CPU second, driving a gentle circle."""
    start = time.process_time()
    for _ in range(steps):
        sim.step(-0.3, 0.4)
        if sensors is not None:
            sensors.run()
    return steps / (time.process_time() - start)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=3000)
    ap.add_argument("--repeats", type=int, default=5)
    ap.add_argument("--bins", type=int, default=360)
    args = ap.parse_args()
    sim = SimCar([5], themes="indoor", world={"distractors": 8, "res": 0.02}, realtime=False,
                 reset_off_track=False, measured_speed=False)
    setups = {
        "step alone (baseline)": None,
        "+ encoder": SimSensors(sim),
        "+ encoder, IMU, GPS": SimSensors(sim, imu=True, gps=True),
        f"+ encoder, IMU, GPS, LiDAR {args.bins} bins": SimSensors(sim, imu=True, gps=True, lidar=True,
                                                                   lidar_bins=args.bins),
    }
    walls, circles = setups[f"+ encoder, IMU, GPS, LiDAR {args.bins} bins"]._geometry()
    print(f"geometry: {len(walls)} wall segments, {len(circles)} distractors")  # noqa: T201
    base = None
    for name, sensors in setups.items():
        med = statistics.median(rate(sim, sensors, args.steps) for _ in range(args.repeats))
        base = base or med
        print(f"{name:<40} {med:9.0f} steps/s  ({med / base:.2f}x the bare step, "  # noqa: T201
              f"{1e6 / med - 1e6 / base:6.1f} µs added per step)")


if __name__ == "__main__":
    main()
