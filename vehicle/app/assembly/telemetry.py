"""Assembly of MQTT telemetry (``add_telemetry``)."""

from __future__ import annotations

from typing import Any

from vehicle.config import Config
from vehicle.errors import UserError


def add_telemetry(V: Any, cfg: Config) -> Any:
    """Add :class:`parts.telemetry.mqtt.MqttTelemetry` last (MQTT_TELEMETRY): the car's status and
    the MQTT_KEYS every part added before writes. Returns the part, or None when MQTT_TELEMETRY is
    off (the default).

    Raises:
        UserError: MQTT_TELEMETRY without MQTT_BROKER, or paho-mqtt is not installed.
    """
    if not cfg.MQTT_TELEMETRY:
        return None
    if not cfg.MQTT_BROKER:
        raise UserError(f"{cfg.where('MQTT_TELEMETRY')}MQTT_TELEMETRY needs your broker: set MQTT_BROKER = "
                        "\"192.168.1.10\" (its address) in myconfig.py; there is no default broker")
    from parts.telemetry.mqtt import MqttTelemetry

    part = MqttTelemetry.from_config(cfg).start()  # connects in paho's thread: the loop never waits for it
    V.add(part, inputs=list(part.INPUTS))
    return part
