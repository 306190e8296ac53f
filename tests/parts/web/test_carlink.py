"""The car's laptop link on a real web server, with the real client on loopback: the token guards
every route, tubs are pulled incrementally and resumably, models are checked before they are kept."""

from __future__ import annotations

import http.client
import io
import json
import zipfile
from pathlib import Path

import numpy as np
import pytest
from fixtures.pilots import write_tub

from parts.tub import Tub
from parts.tub.transfer import TransferError, staging_folder
from parts.web.carlink import CarLink
from parts.web.controller import WebController
from vehicle.app.carlink.client import CarAddress, CarClient, CarLinkError
from vehicle.app.carlink.pull import plan, pull_all, pull_tub

TOKEN = "Kq3vT9xLm2Rw8ZpN4bYc"


@pytest.fixture
def car(tmp_path):
    """A web controller with the laptop link over a data folder of one tub (50 + 50 records, 3
    deleted) and an empty models folder; the test plays the loop when it needs telemetry."""
    data, models = tmp_path / "car" / "data", tmp_path / "car" / "models"
    models.mkdir(parents=True)
    write_tub(data / "tub_1", n=50, sessions=2)
    with Tub(data / "tub_1") as tub:
        tub.delete_records([3, 4, 99])
    link = CarLink(data, models, name="red", max_model_bytes=2_000_000)
    web = WebController("127.0.0.1", 0, TOKEN, link=link).start()
    yield web
    web.shutdown()


def client(web, token=TOKEN) -> CarClient:
    return CarClient(CarAddress("127.0.0.1", web.port, token))


def records(path: Path) -> dict[int, dict]:
    """index -> record (images as their bytes), live records only."""
    tub = Tub(path, read_only=True)
    out = {}
    for i, rec in tub.records():
        rec = {k: v for k, v in rec.items() if k != "_session_id"}
        rec["cam/image_array"] = (path / "images" / rec["cam/image_array"]).read_bytes()
        out[i] = rec
    tub.close()
    return out


def raw(web, method, path, headers=None, body=None):
    conn = http.client.HTTPConnection("127.0.0.1", web.port, timeout=10)
    conn.request(method, path, body=body, headers=headers or {})
    resp = conn.getresponse()
    data = resp.read()
    conn.close()
    return resp.status, data


@pytest.mark.parametrize("method, path", [("GET", "/car/status"), ("GET", "/car/tubs"),
                                          ("GET", "/car/tubs/tub_1/records?start=0"), ("GET", "/car/models"),
                                          ("PUT", "/car/models/x.pt"), ("POST", "/car/pilot")])
def test_a_laptop_without_the_token_gets_nothing(car, method, path):
    for headers in ({}, {"Authorization": "Bearer wrong-token-123456"}, {"Authorization": "Bearer "}):
        status, body = raw(car, method, path, headers, b"x" if method != "GET" else None)
        assert status == 401, (headers, body)
        assert b"tub_1" not in body and b"cam/image_array" not in body
    # a page of another site (DNS rebinding: its own host name) and a cross-origin page are refused too
    right = {"Authorization": f"Bearer {TOKEN}"}
    assert raw(car, "GET", "/car/tubs", {**right, "Host": "evil.example.com"})[0] == 403
    status, body = raw(car, "GET", "/car/tubs", {**right, "Origin": "http://evil.example.com"})
    assert status == 403 and b"other sites" in body
    status, body = raw(car, "GET", "/car/tubs", right)
    assert status == 200 and json.loads(body)["tubs"][0]["name"] == "tub_1"


def test_wrong_tokens_are_slowed(car):
    for _ in range(5):
        assert raw(car, "GET", "/car/status", {"Authorization": "Bearer wrong-token-123456"})[0] == 401
    status, body = raw(car, "GET", "/car/status", {"Authorization": "Bearer wrong-token-123456"})
    assert status == 429 and b"wait" in body
    assert raw(car, "GET", "/car/status", {"Authorization": f"Bearer {TOKEN}"})[0] == 200  # never the right one


def test_the_tub_list_gives_counts_and_sizes(car):
    (tub,) = client(car).tubs()
    assert (tub["name"], tub["records"], tub["current_index"], tub["deleted"]) == ("tub_1", 97, 100, 3)
    folder = car.link.data_dir / "tub_1"

    def on_disk():
        return sum(p.stat().st_size for p in folder.rglob("*") if p.is_file())

    assert tub["bytes"] == on_disk()
    assert client(car).tubs()[0]["bytes"] == on_disk()  # kept until the tub changes
    with Tub(folder) as t:  # the car records one more
        t.write_record({"cam/image_array": np.full((64, 64, 3), 9, np.uint8), "user/angle": 0.0, "user/throttle": 0.2,
                        "user/mode": "user", "behavior/one_hot_state_array": [1.0, 0.0]})
    (tub,) = client(car).tubs()
    assert (tub["records"], tub["bytes"]) == (98, on_disk())


def test_a_pull_copies_the_tub_then_only_new_records(car, tmp_path):
    laptop = tmp_path / "laptop"
    (first,) = pull_all(client(car), laptop)
    target = laptop / "red_tub_1"
    assert (first.tub, first.start, first.end, first.received, first.created) == (target, 0, 100, 97, True)
    assert first.skipped == {"deleted": 3}
    assert records(target) == records(car.link.data_dir / "tub_1")
    assert not staging_folder(target).exists()
    meta = Tub(target, read_only=True).metadata
    assert (meta["pulled_from"], meta["car_tub"]) == ("red", "tub_1")

    with Tub(car.link.data_dir / "tub_1") as tub:  # the car records 20 more
        for i in range(20):
            tub.write_record({"cam/image_array": np.full((64, 64, 3), i, np.uint8),
                              "user/angle": 0.01 * i, "user/throttle": 0.2, "user/mode": "user",
                              "behavior/one_hot_state_array": [1.0, 0.0]})
    assert [p.new for p in plan(client(car), laptop, "red")] == [20]
    (second,) = pull_all(client(car), laptop)
    assert (second.start, second.end, second.received, second.created) == (100, 120, 20, False)
    assert records(target) == records(car.link.data_dir / "tub_1")
    assert pull_all(client(car), laptop) == []  # nothing new


class _Cut(io.RawIOBase):
    """A response that breaks after ``limit`` bytes (the car killed, the Wi-Fi gone)."""

    def __init__(self, resp, limit):
        self.resp, self.left = resp, limit

    def readable(self):
        return True

    def readinto(self, buf):
        if self.left <= 0:
            raise ConnectionResetError("connection reset by peer")
        data = self.resp.read(min(len(buf), self.left))
        self.left -= len(data)
        buf[:len(data)] = data
        return len(data)


def test_an_interrupted_first_pull_leaves_no_tub_and_resumes(car, tmp_path, monkeypatch):
    laptop = tmp_path / "laptop"
    c = client(car)
    original = c.open_records
    monkeypatch.setattr(c, "open_records", lambda tub, start: (lambda conn, resp: (conn, io.BufferedReader(
        _Cut(resp, 120_000))))(*original(tub, start)))
    (item,) = plan(c, laptop, "red")
    with pytest.raises(TransferError, match="run the pull again"):
        pull_tub(c, item, "red")
    target = laptop / "red_tub_1"
    assert not target.exists()  # never half a tub where the datasets are
    kept = Tub(staging_folder(target), read_only=True)
    have = kept.current_index
    kept.close()
    assert 0 < have < 100
    monkeypatch.setattr(c, "open_records", original)
    (report,) = pull_all(c, laptop)
    live_before = sum(1 for i in range(have) if i not in (3, 4))
    assert (report.start, report.received, report.created) == (have, 97 - live_before, True)
    assert records(target) == records(car.link.data_dir / "tub_1")
    assert not staging_folder(target).exists()


def test_a_damaged_image_on_the_car_is_left_out_and_said(car, tmp_path):
    image = car.link.data_dir / "tub_1" / "images" / "7_cam_image_array_.jpg"
    data = bytearray(image.read_bytes())
    data[len(data) // 2] ^= 0xFF
    image.write_bytes(bytes(data))
    (report,) = pull_all(client(car), tmp_path / "laptop")
    assert report.received == 96
    assert report.skipped == {"deleted": 3, "its image 7_cam_image_array_.jpg fails its CRC-32 on the car (damaged)": 1}
    pulled = records(tmp_path / "laptop" / "red_tub_1")
    assert 7 not in pulled and 8 in pulled


# -- models --------------------------------------------------------------------------------------------
def test_a_good_model_is_kept_atomically_and_a_second_push_of_it_is_a_no_op(car, make_model_file):
    path = make_model_file("linear", name="good")
    answer = client(car).push(path)
    assert answer == {"ok": True, "model": "good.pt", "bytes": path.stat().st_size, "new": True}
    models = car.link.models_dir
    assert (models / "good.pt").read_bytes() == path.read_bytes()
    assert [p.name for p in models.iterdir()] == ["good.pt"]  # no temporary file left
    assert client(car).push(path)["new"] is False
    other = make_model_file("linear", name="other", seed=1)
    with pytest.raises(CarLinkError, match="another good.pt already"):
        client(car).push(other, "good.pt")
    assert [m["name"] for m in client(car).models()] == ["good.pt"]


def test_hostile_and_broken_models_are_refused_with_a_reason(car, tmp_path):
    class Evil:
        def __reduce__(self):
            return (print, ("pwned",))

    hostile = tmp_path / "hostile.pt"
    import torch

    torch.save({"format": "vehicle-pilot", "x": Evil()}, hostile)
    with pytest.raises(CarLinkError, match="refused: hostile.pt refused: .*pickled Python objects"):
        client(car).push(hostile)
    junk = tmp_path / "junk.pt"
    junk.write_bytes(b"not a model at all")
    with pytest.raises(CarLinkError, match="junk.pt refused: .*not a model file"):
        client(car).push(junk)
    bomb = tmp_path / "bomb.pt"
    with zipfile.ZipFile(bomb, "w", zipfile.ZIP_DEFLATED) as zf:
        zf.writestr("archive/data.pkl", b"\0" * 9_000_000)
    with pytest.raises(CarLinkError, match="expands to 9 MB"):
        client(car).push(bomb)
    big = tmp_path / "big.pt"
    big.write_bytes(b"\0" * 2_000_001)
    with pytest.raises(CarLinkError, match="over this car's limit of 2.0 MB .CAR_MAX_MODEL_MB"):
        client(car).push(big)
    with pytest.raises(CarLinkError, match="a .pt file named"):
        client(car).push(junk, "../../etc/passwd.pt")
    assert list(car.link.models_dir.iterdir()) == []  # nothing kept, no temporary left


def test_a_model_that_does_not_fit_the_car_is_refused(car, make_model_file):
    from parts.pilots.pilot import Pilot

    pilot = Pilot(make_model_file("linear", name="driving"), frame_shape=(120, 160, 3))
    car.link.check_model = pilot.check_file
    wide = make_model_file("linear", name="wide", frames=(160, 320))
    with pytest.raises(CarLinkError, match="wide.pt refused: .*160"):
        client(car).push(wide)
    assert not (car.link.models_dir / "wide.pt").exists()
    assert client(car).push(make_model_file("linear", name="fits", seed=3))["new"] is True
    pilot.shutdown()
