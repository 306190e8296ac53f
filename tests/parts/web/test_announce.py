"""Cars announce themselves by mDNS (python-zeroconf) and the laptop finds them, on loopback; without
zeroconf both say what to install in one line."""

from __future__ import annotations

import sys

import pytest

pytest.importorskip("zeroconf")

from parts.web.announce import Announcer, service_label  # noqa: E402
from vehicle.app.carlink.discovery import DiscoveryUnavailable, discover  # noqa: E402

LOOPBACK = ["127.0.0.1"]


def test_a_car_announced_is_found_then_gone_when_it_stops():
    car = Announcer("red.car", 18887, "127.0.0.1", interfaces=LOOPBACK).start()
    try:
        found = discover(1.0, interfaces=LOOPBACK)
    finally:
        car.stop()
    assert [c for c in found if c["port"] == 18887] == [
        {"name": "red.car", "host": "127.0.0.1", "port": 18887, "url": "http://127.0.0.1:18887/"}]
    assert not [c for c in discover(0.5, interfaces=LOOPBACK) if c["port"] == 18887]
    car.stop()  # twice is fine
    assert service_label("red.car") == "red-car" and len(service_label("x" * 99)) == 63


def test_without_zeroconf_the_car_drives_and_the_laptop_is_told(monkeypatch, caplog):
    monkeypatch.setitem(sys.modules, "zeroconf", None)  # import zeroconf -> ImportError
    caplog.set_level("INFO")
    car = Announcer("red", 18888, "127.0.0.1").start()
    assert "pip install zeroconf" in caplog.text and "by its address" in caplog.text
    car.stop()
    with pytest.raises(DiscoveryUnavailable, match="pip install zeroconf .or add the car by its address"):
        discover(0.5)
