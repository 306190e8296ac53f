"""The Donkey simulator client part against the faithful fake simulator (fixtures.fake_donkey_sim)."""

from __future__ import annotations

import json
import logging
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
import pytest
from fixtures.carpath import unity_cross_track_err
from fixtures.fake_donkey_sim import FakeDonkeySim
from fixtures.load import scaled, wait_until

from parts.bridges import donkey_protocol as proto
from parts.bridges.donkey_client import CarLook, DonkeySim
from parts.bridges.errors import BridgeError


@contextmanager
def client(sim: FakeDonkeySim, **kwargs: Any) -> Iterator[DonkeySim]:
    part = DonkeySim(port=sim.port, connect_timeout_s=scaled(3), **kwargs)
    part.start()
    try:
        yield part
    finally:
        part.neutral()
        part.shutdown()


def outputs(part: DonkeySim, *inputs: Any) -> dict[str, Any]:
    return dict(zip(DonkeySim.OUTPUTS, part.run_threaded(*inputs), strict=True))


def drive(part: DonkeySim, seconds: float, angle: float = 0.0, throttle: float = 0.3,
          reset: bool = False) -> dict[str, Any]:
    end = time.monotonic() + seconds
    out: dict[str, Any] = {}
    while time.monotonic() < end:
        out = outputs(part, angle, throttle, reset)
        time.sleep(0.05)
    return out


def test_session_sequence_and_configuration() -> None:
    look = CarLook("f1", (255, 0, 10), "Speedy", 50)
    with FakeDonkeySim(port=0) as sim:
        with client(sim, scene="donkey-warren-track-v0", look=look, image_w=128, image_h=96) as part:
            out = drive(part, 0.5)
        assert sim.wait_for(lambda s: s.messages(0, "exit_scene"), 5)
    sent = sim.messages(0)
    kinds = [m["msg_type"] for m in sent]
    assert kinds[:6] == ["get_scene_names", "load_scene", "control", "car_config", "cam_config", "control"]
    assert kinds[-1] == "exit_scene" and kinds[-2] == "control"
    assert sent[1]["scene_name"] == "warren"
    assert sent[2] == {"msg_type": "control", "steering": "0.0", "throttle": "0.0", "brake": "1.0"}
    assert sent[3] == {"msg_type": "car_config", "body_style": "f1", "body_r": "255", "body_g": "0",
                       "body_b": "10", "car_name": "Speedy", "font_size": "50"}
    assert sent[4]["img_w"] == "128" and sent[4]["img_h"] == "96"
    # every value of every message is a string
    assert all(isinstance(v, str) for m in sent for v in m.values())
    assert sent[-2]["brake"] == "1.0" and sent[-2]["throttle"] == "0.0"
    assert sim.cars[0].parse_failures == 0
    assert out["cam/ok"] is True
    assert out["cam/image_array"].shape == (96, 128, 3)


def test_telemetry_becomes_memory_values() -> None:
    with FakeDonkeySim(port=0) as sim, client(sim) as part:
        out = drive(part, 1.0, angle=0.2, throttle=0.5)
        car = sim.cars[0]
    assert out["cam/image_array"].shape == (120, 160, 3) and out["cam/image_array"].dtype == np.uint8
    assert out["sim/speed"] > 0 and out["enc/speed"] == out["sim/speed"]
    # steering right drifts the car right: sim/cte is positive right, as the simulator's is
    assert out["sim/cte"] > 0 and car.right > 0
    assert out["sim/hit"] == "none" and out["sim/off_track"] is False
    assert 0 <= out["sim/progress"] < 1 and out["sim/time"] > 0
    x, z = out["sim/pos"]
    assert np.hypot(x, z) == pytest.approx(20 + car.right, abs=1.0)
    assert out["sim/extra"]["totalNodes"] == 200 and "gyro_x" in out["sim/extra"]
    assert "image" not in out["sim/extra"]
    controls = [m for m in sim.messages(0, "control") if m["brake"] == "0.0"]
    assert controls and controls[-1]["steering"] == "0.2" and controls[-1]["throttle"] == "0.5"


def test_every_message_is_one_send_and_sends_are_spaced(monkeypatch: pytest.MonkeyPatch) -> None:
    """The real simulator reads each TCP chunk as one message: the client sends one message per
    send, configuration messages 0.1 s apart and controls at least send_gap_s apart."""
    sends: list[tuple[float, bytes]] = []
    original = DonkeySim._send

    def record(self: DonkeySim, data: bytes) -> None:
        sends.append((time.monotonic(), data))
        original(self, data)

    monkeypatch.setattr(DonkeySim, "_send", record)
    with FakeDonkeySim(port=0, strict=True) as sim:
        with client(sim, send_gap_s=0.02) as part:
            for _ in range(40):
                outputs(part, 0.1, 0.2, False)
                time.sleep(0.001)  # a loop much faster than the gap: the mailbox keeps only the newest
            drive(part, 0.3)
        assert sim.wait_for(lambda s: s.messages(0, "exit_scene"), 5)
    for _, data in sends:
        json.loads(data)  # exactly one object per send (two would not parse)
    kinds = [json.loads(d)["msg_type"] for _, d in sends]
    gaps = [b[0] - a[0] for a, b in zip(sends, sends[1:], strict=False)]
    config_end = kinds.index("cam_config") + 1
    assert min(gaps[:config_end]) >= 0.1 - 1e-3  # the session's messages, as gym-donkeycar spaces them
    assert min(gaps) >= 0.02 - 1e-3
    assert len(sends) < 40  # the 40 fast loops did not become 40 controls
    assert sim.cars[0].received[-1]["msg_type"] == "exit_scene"


def test_strict_fake_fails_like_the_real_simulator_on_coalesced_messages() -> None:
    """The fake is faithful: two messages in one chunk are both lost."""
    import socket

    with FakeDonkeySim(port=0, strict=True) as sim, socket.create_connection(("127.0.0.1", sim.port)) as s:
        s.sendall(proto.client_message("get_protocol_version") + proto.client_message("get_scene_names"))
        assert sim.wait_for(lambda f: f.cars and f.cars[0].parse_failures == 1, 5)
        time.sleep(0.05)
        s.sendall(proto.client_message("get_protocol_version"))
        assert sim.wait_for(lambda f: len(f.messages(0)) == 1, 5)


def test_split_merged_and_comma_messages_are_read() -> None:
    with FakeDonkeySim(port=0, comma_floats=True, merge_every=3, split_every=4, imageb=True) as sim, \
            client(sim) as part:
        out = drive(part, 1.5, angle=-0.3, throttle=0.6)
        sent = sim.cars[0].telemetry_sent
    assert part.telemetry_count >= sent - 2  # merged and split messages are not lost
    assert part._stream.errors == 0
    assert isinstance(out["sim/cte"], float) and out["sim/cte"] < 0  # steering left
    assert out["sim/speed"] > 0.5
    assert "imageb" not in out["sim/extra"]


def test_laps_follow_gym_donkeycar_and_reset_restarts_them() -> None:
    with FakeDonkeySim(port=0, time_scale=10) as sim, client(sim) as part:
        # hold the circle: steer left just enough for radius 20 (wheelbase 1.5, 16 deg full lock)
        steer = -np.degrees(np.arctan(1.5 / 20)) / 16
        assert sim.wait_for(lambda f: f.cars[0].laps_crossed >= 3 or not outputs(part, steer, 1.0, False), 30)
        # the first crossing starts the clock (the client may be a telemetry behind the fake: wait)
        assert sim.wait_for(lambda f: outputs(part, steer, 1.0, False)["sim/lap"] == f.cars[0].laps_crossed - 1, 5)
        out = outputs(part, steer, 1.0, False)
        assert out["sim/lap_time"] > 0
        laps = out["sim/lap"]
        out = drive(part, 0.3, angle=0.0, throttle=0.0, reset=True)
        assert sim.wait_for(lambda f: f.messages(0, "reset_car"), 5)
        out = drive(part, 0.2, throttle=0.0, reset=True)  # held: no second reset
        assert out["sim/lap"] == laps  # laps completed still count after a reset
        crossings = sim.cars[0].laps_crossed
        out = drive(part, 0.1)
        # the first crossing after the reset only starts the clock again (gym-donkeycar's rule)
        assert sim.wait_for(lambda f: f.cars[0].laps_crossed > crossings or not outputs(part, steer, 1.0, False), 30)
        out = drive(part, 0.1, angle=steer, throttle=1.0)
        assert out["sim/lap"] == laps
    assert len(sim.messages(0, "reset_car")) == 1


def test_a_hit_is_kept_until_the_loop_sees_it() -> None:
    with FakeDonkeySim(port=0, telemetry_hz=100) as sim, client(sim) as part:
        drive(part, 0.2)
        sim.crash(0, "cone")
        time.sleep(0.3)  # many telemetries after the one with the hit
        out = outputs(part, 0.0, 0.0, False)
        assert out["sim/hit"] == "cone" and out["sim/off_track"] is True
        out = outputs(part, 0.0, 0.0, False)
        assert out["sim/hit"] == "none" and out["sim/off_track"] is False


def test_off_track_follows_gym_max_cte() -> None:
    with FakeDonkeySim(port=0, wall_cte=100) as sim, client(sim, max_cte=1.0) as part:
        sim.cars[0].right = 1.5
        time.sleep(0.2)
        assert outputs(part, 0.0, 0.0, False)["sim/off_track"] is True
        sim.cars[0].right = 2.5  # beyond 2 x max_cte: a spawn glitch for gym, ignored
        time.sleep(0.2)
        assert outputs(part, 0.0, 0.0, False)["sim/off_track"] is False


def test_race_scene_gets_racer_info_and_car_config() -> None:
    with FakeDonkeySim(port=0, race=True) as sim, client(sim, look=CarLook(car_name="Bolt")) as part:
        drive(part, 0.3)
        assert sim.wait_for(lambda f: f.messages(0, "racer_info"), 5)
    racer = sim.messages(0, "racer_info")[0]
    assert racer["car_name"] == "Bolt"
    assert len(sim.messages(0, "car_config")) == 2


def test_several_clients_get_a_car_each() -> None:
    with FakeDonkeySim(port=0) as sim, client(sim) as a, client(sim) as b:
        drive(a, 0.3, throttle=0.8)
        drive(b, 0.3, throttle=0.0)
        assert len(sim.cars) == 2
        assert sim.cars[0].speed > sim.cars[1].speed


def test_lost_connection_goes_stale_says_so_once_and_reconnects_on_next_start(
        caplog: pytest.LogCaptureFixture) -> None:
    with FakeDonkeySim(port=0) as sim:
        part = DonkeySim(port=sim.port, connect_timeout_s=3)
        try:
            part.start()
            assert drive(part, 0.3)["cam/ok"] is True
            with caplog.at_level(logging.INFO, logger="parts.bridges.donkey_client"):
                sim.drop_clients()
                out = drive(part, 0.5)  # the loop goes on, never blocked
            assert out["cam/ok"] is False
            lost = [r for r in caplog.records if "lost the connection" in r.getMessage()]
            assert len(lost) == 1 and "Restart the drive" in lost[0].getMessage()
            part.start()  # the next start connects again: a new car
            assert drive(part, 0.5)["cam/ok"] is True
            assert len(sim.cars) == 2
        finally:
            part.shutdown()


def test_unreachable_simulator_is_one_clear_error() -> None:
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]  # nothing listens here
    with pytest.raises(BridgeError, match=rf"cannot reach the Donkey simulator at 127.0.0.1:{port}.*SIM_PORT"):
        DonkeySim(port=port, connect_timeout_s=0.3).start()


def test_missing_scene_names_the_choices() -> None:
    expected = r"no scene 'generated_track'; choose one of warehouse, mini_monaco"
    with FakeDonkeySim(port=0, scenes=("warehouse", "mini_monaco")) as sim, pytest.raises(BridgeError, match=expected):
        DonkeySim(port=sim.port, connect_timeout_s=3).start()


def test_lockstep_run_waits_for_the_next_telemetry() -> None:
    with FakeDonkeySim(port=0) as sim, client(sim) as part:
        times = [dict(zip(DonkeySim.OUTPUTS, part.run(0.0, 0.5, False), strict=True))["sim/time"]
                 for _ in range(5)]
    assert all(b > a for a, b in zip(times, times[1:], strict=False))


def test_bad_settings_are_rejected() -> None:
    with pytest.raises(ValueError, match="body_style"):
        CarLook(body_style="tank")
    with pytest.raises(ValueError, match="body_rgb"):
        CarLook(body_rgb=(0, 0, 300))
    with pytest.raises(ValueError, match="port"):
        DonkeySim(port=0)
    with pytest.raises(ValueError, match="max_cte"):
        DonkeySim(max_cte=0)


# -- the protocol module ---------------------------------------------------------------------------
def test_stream_reads_split_coalesced_and_unframed_objects() -> None:
    stream = proto.JsonStream()
    a = json.dumps({"msg_type": "a", "s": "x{y}\"z\\"}).encode()
    b = json.dumps({"msg_type": "b", "n": [1, {"k": 2}]}).encode()
    data = b"garbage" + a + b"\n" + b + a  # newline optional, junk between objects skipped
    out = []
    for i in range(len(data)):  # one byte at a time
        out += stream.feed(data[i:i + 1])
    assert [m["msg_type"] for m in out] == ["a", "b", "a"]
    assert out[0]["s"] == 'x{y}"z\\' and out[1]["n"] == [1, {"k": 2}]
    assert stream.feed(a + b + a) == [json.loads(a), json.loads(b), json.loads(a)]
    assert stream.errors == 0


def test_stream_repairs_comma_floats_and_counts_junk() -> None:
    stream = proto.JsonStream()
    out = stream.feed(b'{"msg_type":"telemetry","cte":-1,25,"speed":3,5E-02,"hit":"a,1"}\n{"x":}')
    assert out == [{"msg_type": "telemetry", "cte": -1.25, "speed": 0.035, "hit": "a,1"}]
    assert stream.errors == 1
    assert proto.repair_float_commas('{"a":1,"b":2}') == '{"a":1,"b":2}'  # valid JSON is untouched


def test_client_messages_are_strings_without_newline() -> None:
    msg = proto.client_message("control", steering=-0.5, throttle=1, brake=0.0)
    assert msg == b'{"msg_type":"control","steering":"-0.5","throttle":"1","brake":"0.0"}'
    assert proto.sim_message("car_loaded") == b'{"msg_type":"car_loaded"}\n'
    assert proto.scene_for("donkey-minimonaco-track-v0") == "mini_monaco"
    assert proto.scene_for("warehouse") == "warehouse"
    with pytest.raises(ValueError, match="non-finite"):
        proto.client_message("control", steering=float("nan"))


def test_send_commands_sends_the_loop_command_once() -> None:
    from parts.bridges.commands import SendCommands

    with FakeDonkeySim(port=0) as sim, client(sim) as part:
        send = SendCommands(part)
        send.run(0.0, 0.3)  # from the first loop on, SendCommands sends the loop's commands
        for i in range(10):
            outputs(part, 0.9, 0.9, False)  # the previous loop's commands: ignored once SendCommands runs
            send.run(-0.1 * (i % 2), 0.3)
            time.sleep(0.06)
        assert sim.wait_for(lambda f: len([m for m in f.messages(0, "control") if m["brake"] == "0.0"]) >= 8, 5)
    driven = [m for m in sim.messages(0, "control") if m["brake"] == "0.0"]
    assert {m["steering"] for m in driven} <= {"-0.1", "0.0", "-0.0"}
    assert all(m["throttle"] == "0.3" for m in driven)
    with pytest.raises(TypeError, match="command"):
        SendCommands(object())


# -- review fixes ---------------------------------------------------------------------------------
def test_fake_cte_is_what_carpath_computes() -> None:
    """The fake's cte has the sign and size of protocols.md §4.1's CarPath formula, computed here
    from the fake's path nodes (a circle, driven counter-clockwise seen from above) and its pos_x/z."""
    from fixtures.fake_donkey_sim import TOTAL_NODES, TRACK_RADIUS, FakeCar

    def node(i: int) -> tuple[float, float]:
        angle = 2 * np.pi * i / TOTAL_NODES
        return TRACK_RADIUS * np.cos(angle), TRACK_RADIUS * np.sin(angle)

    for s, right in ((3.0, 1.5), (40.0, -2.0), (90.0, 0.7)):
        tel = FakeCar(s=s, right=right).telemetry("", None)
        i = tel["activeNode"]
        expected = unity_cross_track_err(node(i), node(i + 1), (tel["pos_x"], tel["pos_z"]))
        assert tel["cte"] == pytest.approx(expected, abs=0.05)
        assert np.sign(tel["cte"]) == np.sign(right)


def test_cte_keeps_the_simulators_sign() -> None:
    """The simulator's cte is positive right of the path, as ours: passed through unchanged."""
    with FakeDonkeySim(port=0, wall_cte=100) as sim, client(sim, max_cte=None) as part:
        for right in (1.5, -0.75):
            sim.cars[0].right = right  # reaches the part with the next telemetry
            assert wait_until(lambda r=right: outputs(part, 0.0, 0.0, False)["sim/cte"] == pytest.approx(r, abs=0.05),
                              5.0), outputs(part, 0.0, 0.0, False)["sim/cte"]


def test_step_mode_is_not_asked_of_the_donkey_simulator(caplog: pytest.LogCaptureFixture) -> None:
    """Its step_mode synchronous freezes it for good (Time.timeScale = 0): real time instead."""
    with caplog.at_level("WARNING", logger="parts.bridges.donkey_client"), FakeDonkeySim(port=0) as sim, \
            client(sim, synchronous=True) as part:
        assert part.synchronous is False
        before = part.telemetry_count
        out = drive(part, 0.6, throttle=0.5)
        assert part.telemetry_count >= before + 5 and out["cam/ok"] is True
        assert not sim.time_scale_zero and not sim.messages(0, "step_mode")
        assert sim.messages(0, "get_protocol_version")
    assert any("pauses the simulation" in r.getMessage() for r in caplog.records)


def test_fake_step_mode_freezes_like_the_simulator() -> None:
    """What the fake reproduces (and why the client never asks the Donkey simulator for it)."""
    with FakeDonkeySim(port=0) as sim, client(sim, timeout_s=0.3) as part:
        drive(part, 0.3)
        part._outbox.append(proto.client_message("step_mode", step_mode="synchronous", time_step="0.05"))
        part._wake()
        assert sim.wait_for(lambda f: f.time_scale_zero, 5)
        time.sleep(0.2)
        frozen = sim.cars[0].telemetry_sent
        drive(part, 0.5, throttle=1.0)
        assert sim.cars[0].telemetry_sent == frozen and outputs(part, 0.0, 0.0, False)["cam/ok"] is False


def test_cam_config_carries_every_field_the_simulator_parses() -> None:
    with FakeDonkeySim(port=0) as sim, client(sim, image_w=128, image_h=96) as part:
        drive(part, 0.3)
        car = sim.cars[0]
        assert car.rejected == [] and (car.img_w, car.img_h) == (128, 96)
        assert part.run_threaded(0.0, 0.0, False)[0].shape == (96, 128, 3)


def test_a_stuck_loop_gets_the_car_braked() -> None:
    with FakeDonkeySim(port=0) as sim, client(sim, command_timeout_s=0.2) as part:
        drive(part, 0.5, throttle=0.8)
        assert sim.cars[0].throttle == pytest.approx(0.8)
        time.sleep(0.6)  # the loop stops calling the part
        car = sim.cars[0]
        assert (car.steering, car.throttle, car.brake) == (0.0, 0.0, 1.0)
