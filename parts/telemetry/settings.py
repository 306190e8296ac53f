"""Settings of MQTT telemetry (:mod:`parts.telemetry.mqtt`).

Declared as the config loader reads them (see :mod:`vehicle.config`): ``NAME: type = value``, the
comment lines above a setting document it, ``# == Title ==`` starts a section of docs/config.md.
"""

from __future__ import annotations

from typing import Annotated

from vehicle.config_checks import Length, Range

# == MQTT telemetry ==

# Publish the car's status (mode, records, loop rate and overruns, battery, pilot) and the memory
# keys of MQTT_KEYS to your MQTT broker (`pip install paho-mqtt`). Off by default, and there is no
# default broker: a car never sends its data to a public one unless told to.
MQTT_TELEMETRY: bool = False
# The broker's host name or address, e.g. "192.168.1.10" or "broker.lan".
MQTT_BROKER: Annotated[str | None, Length(min=1, max=253)] = None
# The broker's TCP port (1883: MQTT without TLS).
MQTT_PORT: Annotated[int, Range(1, 65535)] = 1883
# Topic prefix; "{car}" becomes CAR_NAME (or the car folder's name). The status goes to
# PREFIX/status, the keys to PREFIX/keys, both as JSON objects.
MQTT_TOPIC: Annotated[str, Length(min=1, max=200)] = "vehicle/{car}"
# Status messages per second.
MQTT_STATUS_HZ: Annotated[float, Range(0, 50, lo_open=True, unit="Hz")] = 1.0
# Memory keys published on PREFIX/keys, e.g. ["angle", "throttle", "sim/cte"]. Numbers, strings,
# booleans and short lists (at most 64 values) are sent; camera frames never are.
MQTT_KEYS: list[str] = []
# Key messages per second.
MQTT_KEYS_HZ: Annotated[float, Range(0, 100, lo_open=True, unit="Hz")] = 5.0
# MQTT quality of service of every message: 0 (at most once) or 1 (at least once, acknowledged).
MQTT_QOS: Annotated[int, Range(0, 1)] = 0
# User name, if the broker asks for one.
MQTT_USERNAME: Annotated[str | None, Length(min=1, max=200)] = None
# Password, with MQTT_USERNAME (sent in clear: this part speaks MQTT without TLS, for a broker on
# your own network).
MQTT_PASSWORD: Annotated[str | None, Length(min=1, max=200, secret=True)] = None
