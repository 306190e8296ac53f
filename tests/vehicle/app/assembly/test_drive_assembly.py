"""The drive-logic assembly helpers, run in a real Vehicle on simulated time."""

from __future__ import annotations

from vehicle import Vehicle
from vehicle.app.assembly.drive import (
    add_behavior,
    add_camera_watchdog,
    add_recording_rules,
    add_throttle_filter,
)
from vehicle.clock import SimulatedClock
from vehicle.config import Config


class Script:
    """A part replaying one tuple of outputs per loop."""

    def __init__(self, rows):
        self.rows = list(rows)
        self.i = 0

    def run(self):
        row = self.rows[min(self.i, len(self.rows) - 1)]
        self.i += 1
        return row


class Log:
    def __init__(self):
        self.rows = []

    def run(self, *values):
        self.rows.append(values)


def test_behavior_and_watchdog_in_a_vehicle():
    cfg = Config.defaults(TRAIN_BEHAVIORS=True, BEHAVIOR_LIST=["Left_Lane", "Right_Lane", "Stop"])
    V = Vehicle(clock=SimulatedClock())
    V.mem["cam/ok"] = True
    V.add(Script([(0, "local", 0.5, True), (1, "local", 0.5, False), (0, "local", 0.5, False),
                  (-1, "user", 0.5, False)]),
          outputs=["behavior/step", "user/mode", "user/throttle", "cam/ok"])
    watchdog = add_camera_watchdog(V, cfg)
    assert type(watchdog).__name__ == "CameraWatchdog"
    assert V.parts[-1].part is watchdog and V.parts[-1].outputs == ("user/mode", "user/throttle")
    part = add_behavior(V, cfg)
    assert V.parts[-1].part is part and V.parts[-1].inputs == ("behavior/step", "web/behavior_step")
    assert V.parts[-1].outputs == ("behavior/state", "behavior/label", "behavior/one_hot_state_array")
    assert add_camera_watchdog(V, cfg) is None  # only one watchdog per vehicle
    log = Log()
    V.add(log, inputs=["behavior/state", "behavior/label", "behavior/one_hot_state_array", "user/mode",
                       "user/throttle"])
    V.start(rate_hz=20, max_loop_count=4)
    assert log.rows == [(0, "Left_Lane", [1.0, 0.0, 0.0], "local", 0.5),
                        (1, "Right_Lane", [0.0, 1.0, 0.0], "user", 0.0),
                        (1, "Right_Lane", [0.0, 1.0, 0.0], "user", 0.0),
                        (0, "Left_Lane", [1.0, 0.0, 0.0], "user", 0.5)]


def test_behavior_off_and_no_camera_add_nothing():
    V = Vehicle(clock=SimulatedClock())
    assert add_behavior(V, Config.defaults()) is None
    assert V.parts == []


def test_throttle_filter_and_recording_rules_in_a_vehicle():
    V = Vehicle(clock=SimulatedClock())
    V.add(Script([("user", -0.5), ("user", -0.5), ("user", -0.5), ("local", 0.4)]),
          outputs=["user/mode", "throttle"])
    flt = add_throttle_filter(V, Config.defaults())
    assert type(flt).__name__ == "ThrottleFilter"
    assert V.parts[-1].part is flt and V.parts[-1].inputs == ("throttle",) and V.parts[-1].outputs == ("throttle",)
    add_recording_rules(V, Config.defaults())
    log = Log()
    V.add(log, inputs=["throttle", "recording"])
    V.start(rate_hz=20, max_loop_count=4)
    assert log.rows == [(-0.5, True), (0.0, False), (-0.5, True), (0.4, False)]


def test_throttle_filter_skipped_when_off_or_done_by_the_esc():
    V = Vehicle(clock=SimulatedClock())
    assert add_throttle_filter(V, Config.defaults(USE_THROTTLE_FILTER=False)) is None
    assert add_throttle_filter(V, Config.defaults(ESC_REVERSE_MODE="double_tap")) is None
    assert V.parts == []


class StallingSource:
    """A camera that delivers 3 frames, then none (each empty read takes 20 ms)."""

    paced = False
    name = "stalling"

    def __init__(self):
        self.left = 3

    def open(self):
        pass

    def read(self):
        import time

        import numpy as np

        if self.left:
            self.left -= 1
            return np.zeros((120, 160, 3), np.uint8)
        time.sleep(0.02)
        return None

    def close(self):
        pass


def test_stalled_camera_disengages_the_pilot_in_the_drive_path():
    from parts.cameras.base import Camera
    from vehicle.app.assembly.drive import add_drive_mode

    cfg = Config.defaults()
    V = Vehicle(clock=SimulatedClock())
    V.add(Camera(StallingSource(), timeout_s=0.1), outputs=["cam/image_array", "cam/timestamp", "cam/ok"])
    V.mem["cam/ok"] = False
    V.add(Script([("local", 0.0, 0.3, 0.1, 0.6)]),
          outputs=["user/mode", "user/angle", "user/throttle", "pilot/angle", "pilot/throttle"])
    add_camera_watchdog(V, cfg)
    add_drive_mode(V, cfg)
    log = Log()
    V.add(log, inputs=["cam/ok", "user/mode", "angle", "throttle"])
    V.start(rate_hz=20, max_loop_count=12)
    assert log.rows[0] == (True, "local", 0.1, 0.6)  # the pilot drives while frames come
    assert log.rows[-1] == (False, "user", 0.0, 0.0)  # stalled: user mode, throttle 0


def _simulated_car(cfg, limit, mode="user", throttle=1.0):
    from vehicle.app.assembly.drive import add_drive_mode, add_speed_limit
    from vehicle.app.assembly.sim import add_simulator

    V = Vehicle(clock=SimulatedClock())
    sim = add_simulator(V, cfg)
    V.add(Script([(0.0, throttle, mode, limit)]),
          outputs=["user/angle", "user/throttle", "user/mode", "user/speed_limit"])
    add_drive_mode(V, cfg)
    add_speed_limit(V, cfg)
    speeds = Log()
    V.add(speeds, inputs=["sim/speed", "throttle"])
    return V, sim, speeds


def test_the_pages_speed_limit_caps_the_car_in_user_mode():
    # issue 21: with PILOT_SPEED_CONTROL = "off" (the default) the limit did nothing
    # a 40 m track (room to reach top speed) drawn at 2 cm per pixel: no frame is looked at, and at
    # the default 1 cm a 4000x4000 texture made this the slowest test of the suite
    cfg = Config.defaults(SIM_RESET_OFF_TRACK=False, SIM_TRACK_SIZE=40.0, SIM_TEXTURE_RES=0.02)
    V, _, log = _simulated_car(cfg, 1.0)
    V.start(rate_hz=20, max_loop_count=200)
    speeds = [s for s, _ in log.rows]
    assert max(speeds) < 1.1 and speeds[-1] > 0.95  # held at the limit
    V, _, log = _simulated_car(cfg, None)
    V.start(rate_hz=20, max_loop_count=200)
    assert max(s for s, _ in log.rows) > 3.0  # without a limit: the car's own top speed


def test_no_speed_limit_part_without_a_speed_measurement():
    from vehicle.app.assembly.drive import add_drive_mode, add_speed_limit

    V = Vehicle(clock=SimulatedClock())
    V.add(Script([(0.0, 1.0, "user", 1.0)]), outputs=["user/angle", "user/throttle", "user/mode", "user/speed_limit"])
    add_drive_mode(V, Config.defaults())
    assert add_speed_limit(V, Config.defaults()) is None
