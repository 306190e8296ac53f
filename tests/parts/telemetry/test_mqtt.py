"""MQTT telemetry against a fake broker written from the MQTT 3.1.1 specification (tests/fixtures/fake_mqtt.py):
what is published, at which rates, with which QoS and credentials; a broker that is away costs the
car nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from fixtures.fake_mqtt import FakeBroker

pytest.importorskip("paho.mqtt")

from parts.telemetry.mqtt import MqttTelemetry  # noqa: E402


@pytest.fixture
def broker():
    b = FakeBroker(credentials=("car", "s3cret"))
    yield b
    b.close()


class Clock:
    def __init__(self) -> None:
        self.t = 0.0

    def __call__(self) -> float:
        return self.t


STATUS = ["local", True, 120, 19.8, 3, 7.4, "b.pt", None]


def test_status_and_keys_at_their_rates_with_qos_1_and_credentials(broker):
    clock = Clock()
    part = MqttTelemetry("127.0.0.1", broker.port, topic="vehicle/red/", keys=["angle", "cam/image_array", "lidar"],
                         status_hz=2, keys_hz=10, qos=1, username="car", password="s3cret", clock=clock).start()
    broker.wait(lambda: part.connected)
    image = np.zeros((120, 160, 3), np.uint8)
    for i in range(21):  # one second of a 20 Hz loop
        clock.t = i * 0.05
        part.run(*STATUS, np.float32(0.25 * (i % 4)), image, [1.5, float("nan"), 2.0])
    part.shutdown()
    broker.wait(lambda: broker.sessions[-1].disconnected)
    status, keys = broker.on("vehicle/red/status"), broker.on("vehicle/red/keys")
    assert len(status) == 3 and len(keys) == 11  # t = 0, 0.5, 1.0 and every 0.1 s
    first = json.loads(status[0].payload)
    assert {k: v for k, v in first.items() if k != "time"} == {
        "mode": "local", "recording": True, "records": 120, "loop_rate_hz": 19.8, "loop_overruns": 3,
        "battery_v": 7.4, "pilot": "b.pt", "pilot_error": None}
    assert [json.loads(m.payload)["angle"] for m in keys[:4]] == [0.0, 0.5, 0.0, 0.5]  # loops 0, 2, 4, 6
    assert json.loads(keys[0].payload)["cam/image_array"] is None  # a camera frame is not telemetry
    assert json.loads(keys[0].payload)["lidar"] == [1.5, None, 2.0]
    assert {m.qos for m in status + keys} == {1} and len({m.packet_id for m in status + keys}) == 14
    session = broker.sessions[0]
    assert (session.client_id, session.username, session.password) == ("vehicle-vehicle-red", "car", b"s3cret")
    assert (part.published, part.dropped) == (14, 0) and not broker.violations


def test_a_broker_that_is_away_costs_the_loop_nothing():
    import socket

    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        port = s.getsockname()[1]
    clock = Clock()
    part = MqttTelemetry("127.0.0.1", port, keys=["angle"], status_hz=20, keys_hz=20, clock=clock).start()
    for i in range(10):
        clock.t = i * 0.05
        part.run(*STATUS, 0.1)
    part.shutdown()
    assert (part.published, part.dropped) == (0, 20)  # QoS 0 without a connection: dropped and counted


def test_the_car_publishes_through_its_assembly(broker, tmp_path):
    from vehicle import Vehicle
    from vehicle.app import assembly
    from vehicle.config import Config
    from vehicle.errors import UserError, WiringError

    settings = {"CAR_PATH": str(tmp_path), "CAR_NAME": "red", "MQTT_TELEMETRY": True, "MQTT_PORT": broker.port,
                "MQTT_USERNAME": "car", "MQTT_PASSWORD": "s3cret", "MQTT_QOS": 1, "MQTT_KEYS": ["angle"]}
    with pytest.raises(UserError, match="MQTT_TELEMETRY needs your broker: set MQTT_BROKER"):
        assembly.add_telemetry(Vehicle(), Config.defaults(**settings))
    assert assembly.add_telemetry(Vehicle(), Config.defaults(CAR_PATH=str(tmp_path))) is None  # off by default

    V = Vehicle()
    V.add(lambda: 0.3, outputs=["angle"])
    part = assembly.add_telemetry(V, Config.defaults(MQTT_BROKER="127.0.0.1", **settings))
    broker.wait(lambda: part.connected)
    V.start(rate_hz=100, max_loop_count=3)
    broker.wait(lambda: broker.sessions[-1].disconnected)  # the vehicle's shutdown disconnected it
    status = [json.loads(m.payload) for m in broker.on("vehicle/red/status")]
    keys = [json.loads(m.payload) for m in broker.on("vehicle/red/keys")]
    assert len(status) == 1 and status[0]["mode"] is None and status[0]["records"] is None
    assert [k["angle"] for k in keys] == [0.3]  # 5 Hz: the first of three loops 10 ms apart
    assert part.published == 2

    typo = Vehicle()
    typo.add(lambda: 0.3, outputs=["angle"])
    with pytest.raises(WiringError, match="angel"):
        assembly.add_telemetry(typo, Config.defaults(MQTT_BROKER="127.0.0.1", **{**settings, "MQTT_KEYS": ["angel"]}))
        typo.start(rate_hz=100, max_loop_count=1)
