from __future__ import annotations

import logging
import termios
import threading

import pytest

from vehicle import ThreadedPart, Vehicle
from vehicle.clock import SimulatedClock
from vehicle.errors import PartError, WiringError
from vehicle.vehicle import ShutdownError


class Counter:
    def __init__(self):
        self.n = 0

    def run(self):
        self.n += 1
        return self.n


class Recorder:
    """Records calls into a shared log; optionally an actuator."""

    def __init__(self, name, log, fail_on=None):
        self.name = name
        self.log = log
        self.fail_on = fail_on
        self.seen = []

    def run(self, *inputs):
        self.seen.append(inputs)
        if self.fail_on is not None and len(self.seen) == self.fail_on:
            raise RuntimeError("boom")
        return None

    def shutdown(self):
        self.log.append(f"shutdown {self.name}")


class Actuator(Recorder):
    def neutral(self):
        self.log.append(f"neutral {self.name}")


def sim_vehicle():
    return Vehicle(clock=SimulatedClock())


def test_parts_run_in_order_and_share_memory():
    V = sim_vehicle()
    V.add(Counter(), outputs=["n"])
    V.add(lambda n: (n * 2, -n), inputs=["n"], outputs=["double", "neg"])
    log = []
    rec = Recorder("r", log)
    V.add(rec, inputs=["double", "neg"])
    loops, _ = V.start(rate_hz=20, max_loop_count=3)
    assert loops == 3
    assert rec.seen == [(2, -1), (4, -2), (6, -3)]


def test_unknown_input_is_an_error_with_hint_before_any_loop():
    V = sim_vehicle()
    c = Counter()
    V.add(c, outputs=["user/angle"])
    V.add(lambda a: a, inputs=["user/angel"], outputs=["x"])
    with pytest.raises(WiringError, match=r"part 'lambda' input 'user/angel' .* \(did you mean 'user/angle'\?\)"):
        V.start(rate_hz=10, max_loop_count=2)
    assert c.n == 0


def test_seeded_key_and_run_condition_key_are_checked():
    V = sim_vehicle()
    V.mem["seeded"] = 5
    V.add(lambda s: s, inputs=["seeded"], outputs=["y"])
    V.add(lambda: 1, outputs=["z"], run_condition="recordng")
    with pytest.raises(WiringError, match="run_condition 'recordng'"):
        V.start(rate_hz=10, max_loop_count=1)


@pytest.mark.parametrize(
    ("kwargs", "error", "message"),
    [
        ({"inputs": "cam/image_array"}, TypeError, "inputs must be a list"),
        ({"outputs": [1]}, TypeError, "outputs must be non-empty strings"),
        ({"threaded": "yes"}, TypeError, "threaded must be True or False"),
        ({"run_condition": 3}, TypeError, "run_condition must be a memory key"),
        ({"outputs": ["a", "a"]}, ValueError, r"listed more than once: \['a'\]"),
        ({"threaded": True}, TypeError, r"'Counter' \(Counter\) has no update, run_threaded"),
    ],
)
def test_bad_add_arguments_name_the_part(kwargs, error, message):
    with pytest.raises(error, match=message):
        sim_vehicle().add(Counter(), **kwargs)


def test_part_without_run_is_rejected():
    with pytest.raises(TypeError, match=r"'object' \(object\) has no run\(\)"):
        sim_vehicle().add(object())


def test_run_condition_gates_part():
    V = sim_vehicle()
    flips = iter([True, False, True, False])
    V.add(lambda: next(flips), outputs=["go"])
    gated = Counter()
    V.add(gated, outputs=["count"], run_condition="go")
    V.start(rate_hz=10, max_loop_count=4)
    assert gated.n == 2


def test_wrong_output_count_is_an_error_naming_the_part():
    V = sim_vehicle()
    log = []
    V.add(Actuator("motor", log), inputs=[])

    class Pair:
        def run(self):
            return 1, 2, 3

    V.add(Pair(), outputs=["a", "b"])
    with pytest.raises(PartError, match=r"part 'Pair' failed in run\(\): .*returned 3 values for 2 outputs"):
        V.start(rate_hz=10, max_loop_count=5)
    assert log == ["neutral motor", "shutdown motor"]


def test_none_result_clears_all_outputs():
    V = sim_vehicle()
    values = iter([(1, 2), None])
    V.add(lambda: next(values), outputs=["a", "b"])
    V.start(rate_hz=10, max_loop_count=2)
    assert V.mem.get(["a", "b"]) == [None, None]


def test_exception_takes_safe_path_neutral_first_then_reverse_shutdown():
    log = []
    V = sim_vehicle()
    V.add(Actuator("steering", log))
    V.add(Recorder("camera", log))
    V.add(Recorder("pilot", log, fail_on=3))
    V.add(Actuator("throttle", log))
    with pytest.raises(PartError) as info:
        V.start(rate_hz=10, max_loop_count=10)
    assert info.value.part_name == "pilot"
    assert isinstance(info.value.__cause__, RuntimeError)
    assert log == ["neutral steering", "neutral throttle", "shutdown throttle", "shutdown pilot",
                   "shutdown camera", "shutdown steering"]


def test_failing_shutdown_does_not_stop_others_and_is_not_swallowed(caplog):
    log = []

    class BadShutdown(Recorder):
        def shutdown(self):
            raise OSError("bus gone")

    V = sim_vehicle()
    V.add(Actuator("first", log))
    V.add(BadShutdown("bad", log))
    V.add(Recorder("last", log))
    with caplog.at_level(logging.ERROR), pytest.raises(ShutdownError, match=r"bad.shutdown\(\)"):
        V.start(rate_hz=10, max_loop_count=2)
    assert log == ["neutral first", "shutdown last", "shutdown first"]
    assert "part 'bad' failed to shut down" in caplog.text


class PulledCable(Actuator):
    """A serial drivetrain whose USB cable was pulled: draining its tty at shutdown fails with EIO
    (termios.error from tcdrain, wrapped by close_serial into the part's one-line error)."""

    class Port:
        def flush(self):
            raise termios.error(5, "Input/output error")

        def close(self):
            pass

    def shutdown(self):
        from parts.serial_port import close_serial

        close_serial(self.Port(), "VESC_SERIAL_PORT", "/dev/ttyACM0", "the VESC's own timeout stops the motor")


@pytest.mark.parametrize("failing", ["pulled_cable", "termios", "oserror"])
def test_a_failing_shutdown_is_one_log_line_with_the_traceback_at_debug(caplog, failing):
    """Item 5(c): two chained tracebacks (~20 lines) for a pulled cable became one ERROR line that
    names the part and the error; the traceback is kept at DEBUG; the other parts still stop."""
    log = []
    errors = {"termios": termios.error(5, "Input/output error"), "oserror": OSError(5, "Input/output error")}

    class Raw(Actuator):
        def shutdown(self):
            raise errors[failing]

    V = sim_vehicle()
    V.add(Actuator("steering", log))
    V.add(PulledCable("drive", log) if failing == "pulled_cable" else Raw("drive", log))
    with caplog.at_level(logging.DEBUG, logger="vehicle.vehicle"), \
            pytest.raises(ShutdownError, match=r"drive.shutdown\(\)"):
        V.start(rate_hz=10, max_loop_count=2)
    assert log == ["neutral steering", "neutral drive", "shutdown steering"]  # the other part stopped
    loud = [r for r in caplog.records if r.levelno >= logging.WARNING and "'drive'" in r.getMessage()]
    assert len(loud) == 1 and loud[0].levelno == logging.ERROR and loud[0].exc_info is None
    message = loud[0].getMessage()
    assert "\n" not in message and message.startswith("part 'drive' failed to shut down: ")
    assert "[Errno 5] Input/output error" in message and "((" not in message
    if failing == "pulled_cable":
        assert "VESC_SERIAL_PORT = '/dev/ttyACM0': the serial link failed ([Errno 5] Input/output error)" in message
    quiet = [r for r in caplog.records if r.levelno == logging.DEBUG and r.exc_info]
    assert len(quiet) == 1 and "'drive'" in quiet[0].getMessage()


def test_a_failing_neutral_is_one_log_line_and_shutdown_still_runs(caplog):
    log = []

    class NoNeutral(Actuator):
        def neutral(self):
            raise OSError(5, "Input/output error")

    V = sim_vehicle()
    V.add(NoNeutral("drive", log))
    V.add(Actuator("steering", log))
    with caplog.at_level(logging.INFO, logger="vehicle.vehicle"), \
            pytest.raises(ShutdownError, match=r"drive.neutral\(\)"):
        V.start(rate_hz=10, max_loop_count=2)
    assert log == ["neutral steering", "shutdown steering", "shutdown drive"]
    [record] = [r for r in caplog.records if r.levelno >= logging.WARNING]
    assert record.getMessage() == "part 'drive' failed to go neutral: OSError: [Errno 5] Input/output error"
    assert record.exc_info is None


def test_ctrl_c_takes_safe_path_and_reraises():
    log = []

    class CtrlC(Recorder):
        def run(self):
            raise KeyboardInterrupt

    V = sim_vehicle()
    V.add(Actuator("esc", log))
    V.add(CtrlC("kbd", log))
    with pytest.raises(KeyboardInterrupt):
        V.start(rate_hz=10)
    assert log == ["neutral esc", "shutdown kbd", "shutdown esc"]


def test_duplicate_names_are_numbered():
    V = sim_vehicle()
    V.add(Counter(), outputs=["a"])
    V.add(Counter(), outputs=["b"])
    assert [e.name for e in V.parts] == ["Counter", "Counter#2"]
    assert "Counter#2: [] -> ['b']" in V.describe()


class Ticker(ThreadedPart):
    """Publishes an increasing number every 1 ms; records the inputs it was given."""

    period = 0.001

    def __init__(self):
        super().__init__()
        self.n = 0
        self.closed = False

    def poll(self):
        self.n += 1
        return self.n

    def close(self):
        self.closed = True


def test_threaded_part_lifecycle_thread_joined_after_stop():
    ticker = Ticker()
    V = Vehicle()  # real clock: the thread must really run
    V.mem["x"] = 7
    V.add(ticker, inputs=["x"], outputs=["tick"], threaded=True)
    V.start(rate_hz=200, max_loop_count=20)
    assert not ticker.running
    assert ticker.closed
    assert ticker.inputs == (7,)
    assert ticker._thread is not None and not ticker._thread.is_alive()
    assert ticker.n >= 1


def test_donkey_style_threaded_part_is_joined():
    class DonkeyCam:
        def __init__(self):
            self.on = True
            self.frame = None
            self.stopped = threading.Event()

        def update(self):
            while self.on:
                self.frame = "frame"
                self.stopped.wait(0.001)

        def run_threaded(self):
            return self.frame

        def shutdown(self):
            self.on = False

    cam = DonkeyCam()
    V = Vehicle()
    V.add(cam, outputs=["cam/image_array"], threaded=True)
    V.start(rate_hz=100, max_loop_count=5)
    assert not V.parts[0].thread.is_alive()


def test_crashed_thread_stops_the_vehicle_naming_the_part():
    class Dies(ThreadedPart):
        def poll(self):
            raise OSError("camera unplugged")

    V = Vehicle()
    V.add(Dies(), outputs=["cam/image_array"], threaded=True)
    with pytest.raises(PartError, match=r"'Dies' failed in update\(\): OSError: camera unplugged"):
        V.start(rate_hz=100, max_loop_count=500)


def test_summary_has_per_part_percentiles_in_bounded_memory():
    V = sim_vehicle()
    V.add(Counter(), outputs=["n"])
    V.start(rate_hz=100, max_loop_count=5000)
    s = V.summary
    assert s.loops == 5000 and s.overruns == 0
    assert s.achieved_hz == pytest.approx(100.0)
    assert s.parts[0].calls == 5000
    assert len(V.parts[0].timing.recent()) == 2048  # bounded ring, not 5000 samples
    assert V.mem["loop/count"] == 5000 and V.mem["loop/rate_hz"] == pytest.approx(100.0)


def test_summary_shows_a_stall_of_one_loop():
    """Hardening item 13: a part that held one loop for seconds (a 43 MB path file read in run())
    did not show in the summary's first lines; the longest loop and a STALL line now do."""
    clock = SimulatedClock()
    V = Vehicle(clock=clock)
    V.add(lambda: clock.advance(8.0) if round(clock.now() * 20) == 3 else None)
    V.start(rate_hz=20, max_loop_count=10, log_summary=False)
    s = V.summary
    assert s.longest_loop_s == pytest.approx(8.0) and s.stalled
    text = s.format()
    assert "longest loop 8000.0 ms" in text and "STALL: one loop took 8.00 s, 160 loop periods" in text
    V2 = Vehicle(clock=SimulatedClock())
    V2.add(lambda: None)
    V2.start(rate_hz=20, max_loop_count=10, log_summary=False)
    assert not V2.summary.stalled and "STALL" not in V2.summary.format()


def test_simulated_time_loop_has_exact_deadlines():
    clock = SimulatedClock()
    V = Vehicle(clock=clock)
    starts = []
    V.add(lambda: starts.append(clock.now()))
    V.start(rate_hz=20, max_loop_count=400)
    assert starts[0] == 0.0
    assert starts[-1] == pytest.approx(399 / 20, abs=1e-9)
    assert all(b - a == pytest.approx(0.05, abs=1e-9) for a, b in zip(starts, starts[1:], strict=False))


def test_stop_from_a_part_ends_the_loop_and_shuts_down():
    log = []
    V = sim_vehicle()
    count = Counter()
    V.add(count, outputs=["n"])
    V.add(lambda n: V.stop() if n == 4 else None, inputs=["n"])
    V.add(Actuator("esc", log))
    loops, _ = V.start(rate_hz=10)
    assert loops == 4 and log == ["neutral esc", "shutdown esc"]


def test_recorded_follows_the_parts_declarations_and_their_renaming():
    class Sonar:
        OUTPUTS = ("sonar/distance", "sonar/ok")
        RECORDED = {"sonar/distance": "float"}

        def run(self):
            return 1.0, True

    V = Vehicle()
    V.add(Sonar())
    V.add(Sonar(), outputs=["sonar/rear_distance", "sonar/rear_ok"])  # a second one, renamed
    V.add(lambda: 2.0, outputs=["other/x"])  # declares nothing: records nothing
    assert V.recorded() == {"sonar/distance": "float", "sonar/rear_distance": "float"}
