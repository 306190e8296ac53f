"""Telemetry: the car's status and chosen memory keys published to an MQTT broker (optional)."""
