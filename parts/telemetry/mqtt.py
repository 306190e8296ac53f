"""MqttTelemetry: the car's status and chosen memory keys, published to an MQTT broker.

>>> part = MqttTelemetry("192.168.1.10", topic="vehicle/red", keys=["angle", "throttle"]).start()  # doctest: +SKIP
>>> V.add(part, inputs=list(part.INPUTS))   # doctest: +SKIP

paho-mqtt runs the connection in its own thread (``loop_start``): the loop only serialises a small
JSON object and queues it, at most ``status_hz`` + ``keys_hz`` times a second. A broker that is
down or unreachable costs the loop nothing: paho reconnects in the background, QoS 0 messages are
dropped meanwhile and at most :data:`MAX_QUEUED` QoS 1 messages wait. Topics (``topic`` prefix):

    PREFIX/status   {"time", "mode", "recording", "records", "loop_rate_hz", "loop_overruns",
                     "battery_v", "pilot", "pilot_error"}
    PREFIX/keys     {"time", KEY: value, ...}   (numbers, str, bool, lists of at most 64 values)
"""

from __future__ import annotations

import json
import logging
import math
import time
from collections.abc import Callable, Sequence
from typing import Any, ClassVar

import numpy as np

from vehicle.errors import VehicleError

logger = logging.getLogger(__name__)

#: QoS 1 messages kept while the broker is away (older ones are dropped by paho)
MAX_QUEUED = 100
#: seconds shutdown waits for the queued messages to leave
SHUTDOWN_WAIT_S = 1.0
#: longest list value published (a camera frame or a LiDAR scan is not telemetry)
MAX_LIST = 64


class TelemetryError(VehicleError):
    """Telemetry cannot start (paho-mqtt missing); the message says what to install or set."""


def _plain(value: Any) -> Any:
    """``value`` as JSON (None when it is not telemetry: an image, a long array, NaN)."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, bool | int | str) or value is None:
        return value
    if isinstance(value, float):
        return value if math.isfinite(value) else None
    if isinstance(value, np.ndarray | list | tuple):
        arr = np.asarray(value)
        if arr.size > MAX_LIST or arr.dtype.kind not in "biuf":
            return None
        return [_plain(v) for v in arr.reshape(-1).tolist()]
    return None


def _next_due(due: float, period: float, now: float) -> float:
    """The next time a message is due: one period on from the last due time (no drift), or from
    now after a pause (no burst to catch up)."""
    following = due + period
    return following if now < following else now + period


class MqttTelemetry:
    """Part: publish the car's status and ``keys`` to an MQTT broker (see the module docstring).

    Args:
        broker: host name or address of the broker.
        port: its TCP port. Default 1883.
        topic: topic prefix. Default ``vehicle/car``.
        keys: memory keys published on ``PREFIX/keys`` (wire them after :data:`STATUS_INPUTS`).
        status_hz, keys_hz: messages per second on each topic. Default 1 and 5.
        qos: 0 or 1. Default 0.
        username, password: credentials, if the broker asks for them.
        client_id: the MQTT client id. Default: one made from the topic.
        clock: monotonic seconds (tests pass their own).
    """

    #: the status the part reads, in this order, before ``keys``
    STATUS_INPUTS: ClassVar[tuple[str, ...]] = ("user/mode", "recording", "tub/num_records", "loop/rate_hz",
                                                "loop/overruns", "battery/voltage", "pilot/model", "pilot/load_error")
    OUTPUTS: ClassVar[tuple[str, ...]] = ()

    def __init__(self, broker: str, port: int = 1883, *, topic: str = "vehicle/car", keys: Sequence[str] = (),
                 status_hz: float = 1.0, keys_hz: float = 5.0, qos: int = 0, username: str | None = None,
                 password: str | None = None, client_id: str | None = None,
                 clock: Callable[[], float] = time.monotonic) -> None:
        if not broker:
            raise ValueError("MQTT telemetry needs a broker: set MQTT_BROKER to your broker's address")
        if qos not in (0, 1):
            raise ValueError(f"MQTT qos must be 0 or 1, got {qos!r}")
        if not (status_hz > 0 and keys_hz > 0):
            raise ValueError(f"MQTT rates must be > 0 Hz, got {status_hz!r} and {keys_hz!r}")
        self.broker, self.port, self.topic = broker, port, topic.rstrip("/")
        self.keys = list(keys)
        self.status_period, self.keys_period = 1.0 / status_hz, 1.0 / keys_hz
        self.qos, self.username, self.password = qos, username, password
        self.client_id = client_id or f"vehicle-{self.topic.replace('/', '-')}"[:64]
        self._clock = clock
        self._next_status = self._next_keys = -math.inf
        self._client: Any = None
        self._last: Any = None  # the last message handed to paho (shutdown waits for it, briefly)
        self.published = 0  # messages handed to paho
        self.dropped = 0  # messages paho refused (not connected, queue full)

    @property
    def INPUTS(self) -> tuple[str, ...]:  # noqa: N802 - the part declaration read by Vehicle.add
        """The status keys, then ``keys``."""
        return (*self.STATUS_INPUTS, *self.keys)

    #: a car without a tub writer, a pilot or a battery sensor publishes None for those; a key of
    #: ``keys`` that no part writes is a wiring error (a typo in MQTT_KEYS), with a "did you mean"
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = (
        "user/mode", "recording", "tub/num_records", "loop/rate_hz", "loop/overruns", "battery/voltage",
        "pilot/model", "pilot/load_error")

    @classmethod
    def from_config(cls, cfg: Any) -> MqttTelemetry:
        """MQTT_* settings; the topic's ``{car}`` is CAR_NAME or the car folder's name."""
        from parts.web.controller import car_name

        return cls(cfg.MQTT_BROKER, cfg.MQTT_PORT, topic=cfg.MQTT_TOPIC.replace("{car}", car_name(cfg)),
                   keys=cfg.MQTT_KEYS, status_hz=cfg.MQTT_STATUS_HZ, keys_hz=cfg.MQTT_KEYS_HZ, qos=cfg.MQTT_QOS,
                   username=cfg.MQTT_USERNAME, password=cfg.MQTT_PASSWORD)

    @property
    def connected(self) -> bool:
        """Whether the broker accepted the connection and it holds."""
        return self._client is not None and self._client.is_connected()

    def start(self) -> MqttTelemetry:
        """Connect in the background (paho's thread); the car drives whether the broker answers or not."""
        try:
            import paho.mqtt.client as mqtt
        except ImportError:
            raise TelemetryError("MQTT_TELEMETRY needs paho-mqtt: pip install paho-mqtt (or set MQTT_TELEMETRY = False)"
                            ) from None
        client = mqtt.Client(mqtt.CallbackAPIVersion.VERSION2, client_id=self.client_id, protocol=mqtt.MQTTv311)
        if self.username:
            client.username_pw_set(self.username, self.password)
        client.max_queued_messages_set(MAX_QUEUED)
        client.reconnect_delay_set(1, 30)
        client.on_connect = self._on_connect
        client.on_disconnect = self._on_disconnect
        client.connect_async(self.broker, self.port, keepalive=30)
        client.loop_start()
        self._client = client
        logger.info("MQTT telemetry to %s:%d under %s/ (status %.3g Hz, %d keys %.3g Hz)", self.broker, self.port,
                    self.topic, 1 / self.status_period, len(self.keys), 1 / self.keys_period)
        return self

    def _on_connect(self, client: Any, userdata: Any, flags: Any, reason: Any, properties: Any = None) -> None:
        if getattr(reason, "is_failure", False):
            logger.warning("MQTT broker %s:%d refused the connection: %s (check MQTT_USERNAME/MQTT_PASSWORD)",
                           self.broker, self.port, reason)
        else:
            logger.info("MQTT telemetry connected to %s:%d", self.broker, self.port)

    def _on_disconnect(self, client: Any, userdata: Any, flags: Any, reason: Any, properties: Any = None) -> None:
        if getattr(reason, "is_failure", False):
            logger.warning("MQTT broker %s:%d lost (%s): reconnecting in the background", self.broker, self.port,
                           reason)

    def run(self, *values: Any) -> None:
        """Publish the status and the keys when each is due (at most once per loop each)."""
        if self._client is None:
            self.start()
        now = self._clock()
        n = len(self.STATUS_INPUTS)
        stamp = round(time.time(), 3)
        if now >= self._next_status:
            self._next_status = _next_due(self._next_status, self.status_period, now)
            mode, recording, records, rate, overruns, battery, model, error = values[:n]
            self._publish("status", {"time": stamp, "mode": _plain(mode), "recording": _plain(recording),
                                     "records": _plain(records), "loop_rate_hz": _plain(rate),
                                     "loop_overruns": _plain(overruns), "battery_v": _plain(battery),
                                     "pilot": _plain(model), "pilot_error": _plain(error)})
        if self.keys and now >= self._next_keys:
            self._next_keys = _next_due(self._next_keys, self.keys_period, now)
            payload = {"time": stamp}
            payload.update({k: _plain(v) for k, v in zip(self.keys, values[n:], strict=False)})
            self._publish("keys", payload)

    def _publish(self, sub: str, payload: dict[str, Any]) -> None:
        info = self._client.publish(f"{self.topic}/{sub}", json.dumps(payload, allow_nan=False), qos=self.qos)
        if info.rc == 0:
            self.published += 1
            self._last = info
        else:
            self.dropped += 1  # not connected (QoS 0) or the queue is full: telemetry, not data

    def shutdown(self) -> None:
        """Send what is queued (briefly), disconnect and stop paho's thread."""
        client, self._client = self._client, None
        if client is None:
            return
        last, self._last = self._last, None
        try:
            if last is not None and client.is_connected():
                last.wait_for_publish(SHUTDOWN_WAIT_S)  # what was queued before it goes out too
            client.disconnect()
        finally:
            client.loop_stop()
        logger.info("MQTT telemetry: %d messages published, %d dropped", self.published, self.dropped)
