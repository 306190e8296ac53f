"""One evaluation across simulators: the Donkey protocol (our server) and the Udacity simulator (the fake)."""

from __future__ import annotations

import math
import socket
import threading
import time
from typing import Any, ClassVar

import pytest

from parts.bridges.donkey_server import DonkeyServer
from parts.sim.eval_report import format_table
from parts.sim.expert import Expert
from parts.sim.simulator import SimCar
from vehicle.app.cli import main
from vehicle.app.evaluate import evaluate
from vehicle.config import Config
from vehicle.errors import UserError


def free_port() -> int:
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


class TelemetryExpert:
    """A pilot that drives from the Donkey telemetry (pose) with the built-in expert's rule."""

    INPUTS: ClassVar[tuple[str, ...]] = ("sim/pos", "sim/extra", "sim/speed")

    def __init__(self, seed: int, cfg: Config, wander_after: float | None = None) -> None:
        self.shadow = SimCar.from_config(cfg, seeds=[seed])
        self.expert = Expert(self.shadow, speed=1.5)
        self.steps = 0
        self.wander_after = wander_after

    def run(self, pos: Any, extra: Any, speed: Any) -> tuple[float, float]:
        self.steps += 1
        if pos is None:
            return 0.0, 0.0
        st = self.shadow.car.state
        st.x, st.y = pos
        st.heading = math.radians(90.0 - extra["yaw"])
        st.speed = speed
        angle, throttle = self.expert.command()
        if self.wander_after is not None and self.steps * 0.05 > self.wander_after:
            return 1.0, 0.6  # full lock: the car leaves the road
        return angle, throttle


def test_donkey_evaluation_in_synchronous_steps_against_our_server():
    cfg = Config.defaults(DRIVE_LOOP_HZ=20)
    with DonkeyServer(port=0, seeds=[7]) as server:
        cfg = cfg.replace(SIM_PORT=server.port)
        report = evaluate(TelemetryExpert(7, cfg), laps=1, cfg=cfg, sim="donkey", scenes=["track_7"], max_time=120)
        wanderer = evaluate(TelemetryExpert(7, cfg, wander_after=3.0), laps=1, cfg=cfg, sim="donkey",
                            scenes=["track_7"], max_time=12)
        resets = server.sessions[-1].resets
    assert report["simulator"] == "donkey" and report["settings"]["synchronous"] is True
    track = report["tracks"][0]
    assert track["seed"] == "track_7"
    assert track["laps_completed"] == 1 and track["interventions"] == 0 and track["success"] is True
    assert 0 < track["mean_abs_cte"] < 0.2  # metres: our server reports them
    assert track["unavailable"] == {} and report["overall"]["unavailable"] == {}
    assert track["elapsed_s"] == pytest.approx(track["frames"] * 0.05)
    w = wanderer["tracks"][0]
    assert w["interventions"] >= 1 and w["autonomy"] < 100  # off the road: hit, then reset_car
    assert w["laps_completed"] == 0 and w["success"] is False
    assert resets == w["interventions"]  # each off-track event: one reset_car
    assert "not available" not in format_table(report)


class Constant:
    """A pilot that always drives straight at 0.3 (the Udacity frames are 160x320: no model needed)."""

    INPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)

    def run(self, image: Any) -> tuple[float, float]:
        if image is None:  # before the simulator's first frame
            return 0.0, 0.0
        assert image.shape == (160, 320, 3)
        return 0.0, 0.3


def test_udacity_evaluation_names_what_the_stock_simulator_cannot_report():
    from fixtures.fake_udacity_client import FakeUdacityClient

    port = free_port()
    cfg = Config.defaults(UDACITY_PORT=port, DRIVE_LOOP_HZ=20)
    sim = FakeUdacityClient(port)

    def takeover() -> None:  # the user holds W for a moment, once
        sim.wait_for(lambda c: len(c.steers) >= 10, 20)
        sim.hold_manual(True)
        time.sleep(0.4)
        sim.hold_manual(False)

    with sim:
        user = threading.Thread(target=takeover, daemon=True)
        user.start()
        report = evaluate(Constant(), laps=1, cfg=cfg, sim="udacity", max_time=2.5)
        user.join(5)
    track = report["tracks"][0]
    assert report["simulator"] == "udacity" and track["seed"] == "udacity"
    assert track["interventions"] == 1  # the manual override
    assert track["elapsed_s"] == pytest.approx(2.5, abs=0.06)
    assert track["mean_speed"] > 0 and track["steering_smoothness"] == 0.0
    assert set(track["unavailable"]) == {"cte", "lap", "progress", "pos"}
    for key in ("mean_abs_cte", "p95_abs_cte", "laps_completed", "success", "mean_lap_s", "progress"):
        assert track[key] is None, key
    table = format_table(report)
    assert "not available: the udacity simulator reports no cross-track error (mean|cte| m, p95|cte| m)" in table
    assert "no laps (laps, lap s)" in table
    row = table.splitlines()[2].split()
    assert row[2] == "-" and row[5] == "-"  # laps, mean|cte|: unknown, not 0



def test_a_model_file_is_checked_against_the_udacity_simulators_frames(tmp_path, make_model_file):
    # a model trained on the Udacity simulator's 320x160 frames was refused by `sim eval --sim
    # udacity`: it was checked against the built-in simulator's camera
    from fixtures.fake_udacity_client import FakeUdacityClient

    port = free_port()
    cfg = Config.defaults(UDACITY_PORT=port, DRIVE_LOOP_HZ=20, PILOT_BACKEND="torch", CAR_PATH=str(tmp_path))
    with FakeUdacityClient(port):
        report = evaluate(str(make_model_file("linear", name="udacity", frames=(160, 320))), laps=1, cfg=cfg,
                          sim="udacity", max_time=1.0)
    assert report["tracks"][0]["frames"] >= 10
    with pytest.raises(UserError, match=r"frame is 160x320x3 but the model was trained on 120x160x3 frames; "
                                        r"the Udacity simulator's frames are always 320x160"):
        evaluate(str(make_model_file("linear")), laps=1, cfg=cfg, sim="udacity", max_time=1.0)

def test_udacity_fork_keys_make_the_cte_metrics_available():
    from fixtures.fake_udacity_client import FakeUdacityClient

    port = free_port()
    cfg = Config.defaults(UDACITY_PORT=port)
    with FakeUdacityClient(port, extra={"cte": lambda car: car.lateral, "lapNumber": 0}):
        report = evaluate(Constant(), laps=1, cfg=cfg, sim="udacity", max_time=1.0)
    track = report["tracks"][0]
    assert set(track["unavailable"]) == {"progress", "pos"}
    assert track["mean_abs_cte"] is not None and track["laps_completed"] == 0


def test_eval_cli_checks_the_simulator_options(tmp_path, capsys):
    assert main(["sim", "eval", "--pilot", "expert", "--sim", "donkey", "--car", str(tmp_path)]) == 2
    assert "the expert drives the built-in simulator only" in capsys.readouterr().err
    assert main(["sim", "eval", "--pilot", "expert", "--sim", "udacity", "--png", "x.png",
                 "--car", str(tmp_path)]) == 2
    assert "--png draws the built-in simulator's tracks" in capsys.readouterr().err
    assert main(["sim", "eval", "--pilot", "expert", "--scenes", "warren", "--car", str(tmp_path)]) == 2
    assert "--scenes names Donkey simulator scenes" in capsys.readouterr().err
