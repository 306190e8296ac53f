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


def test_a_car_on_the_network_announces_itself_and_withdraws_at_shutdown(tmp_path):
    from parts.web.carlink import CarLink
    from parts.web.controller import WebController

    web = WebController("0.0.0.0", 0, "Kq3vT9xLm2Rw8ZpN4bYc", link=CarLink(tmp_path, tmp_path, name="blue"),
                        announce=True).start()
    try:
        found = [c for c in discover(1.5) if c["port"] == web.port]
    finally:
        web.shutdown()
    assert [(c["name"], c["url"]) for c in found] == [("blue", f"http://{found[0]['host']}:{web.port}/")]
    assert web._announcer is None  # withdrawn at shutdown
    quiet = WebController("127.0.0.1", 0, link=CarLink(tmp_path, tmp_path, name="green"), announce=True).start()
    try:  # a car on loopback is not on the network: nothing to announce
        assert quiet._announcer is None
    finally:
        quiet.shutdown()
