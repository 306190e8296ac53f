"""The path view's messages (parts/web/pathview.py) and the path buttons' Socket.IO event, against
a real server and a real python-socketio client (the browser side: test_web_pathview_browser.py)."""

from __future__ import annotations

import asyncio
import json
import math

import numpy as np
import pytest
from fixtures.load import scaled

from parts.web.pathview import MAX_PATH_POINTS, PATH_INPUTS, PathSender, PathSlot, encode_path, path_telemetry
from parts.web.protocol import ProtocolError, parse_path_command


# -- encoding -------------------------------------------------------------------------------------
def test_a_path_is_sent_as_one_flat_list_rounded_to_centimetres():
    xy = np.array([[0.0, 0.0], [1.23456, -2.0049], [3.0, 4.5]], np.float32)
    msg = encode_path(xy, 7)
    assert msg == {"version": 7, "xy": [0.0, 0.0, 1.23, -2.0, 3.0, 4.5], "points": 3, "step": 1}
    assert json.loads(json.dumps(msg)) == msg  # plain JSON, no numpy values


def test_rows_that_are_not_finite_are_dropped_json_has_no_nan():
    xy = np.array([[0, 0], [np.nan, 1], [2, np.inf], [3, 3]], np.float32)
    msg = encode_path(xy, 1)
    assert msg["xy"] == [0.0, 0.0, 3.0, 3.0] and msg["points"] == 4
    json.dumps(msg, allow_nan=False)


def test_a_long_path_is_thinned_to_the_limit_and_keeps_its_last_point():
    n = 5 * MAX_PATH_POINTS + 3
    xy = np.stack([np.arange(n) * 0.1, np.zeros(n)], axis=1)
    msg = encode_path(xy, 2)
    kept = np.array(msg["xy"]).reshape(-1, 2)
    assert len(kept) <= MAX_PATH_POINTS and len(kept) > MAX_PATH_POINTS * 0.8
    assert msg["step"] == 6 and msg["points"] == n
    assert kept[0].tolist() == [0.0, 0.0]
    assert kept[-1].tolist() == [round((n - 1) * 0.1, 2), 0.0]  # the end of the route is drawn
    assert np.all(np.diff(kept[:, 0]) > 0)  # in order
    assert len(json.dumps(msg)) < 40_000  # a few tens of kB, not the whole recording


@pytest.mark.parametrize("bad", [None, "a path", np.zeros((4, 3)), np.zeros(5), [[1, "x"]]])
def test_anything_but_an_n_by_2_array_is_an_empty_path(bad):
    assert encode_path(bad, 3) == {"version": 3, "xy": [], "points": 0, "step": 1}


def test_parse_path_command_accepts_the_five_buttons_only():
    for command in ("record", "save", "load", "clear", "reset_origin"):
        assert parse_path_command({"command": command}) == command
    for bad in ({"command": "follow"}, {"command": 1}, {}, {"command": "save", "x": 1}, "save", None):
        with pytest.raises(ProtocolError, match="path_command"):
            parse_path_command(bad)


# -- per-frame telemetry --------------------------------------------------------------------------
def test_no_path_keys_no_path_view():
    assert path_telemetry({k: None for k in PATH_INPUTS}) is None
    assert path_telemetry({}) is None


def test_the_pose_and_target_are_rounded_and_checked():
    values = {"loc/x": np.float32(1.23456), "loc/y": -0.5, "loc/angle": math.pi / 2, "loc/std": 0.25,
              "loc/ok": np.bool_(True), "loc/source": "fused", "path/version": np.int64(4),
              "path/target_x": 2.0, "path/target_y": float("nan"), "path/cte": -0.1234,
              "path/state": "following"}
    t = path_telemetry(values)
    assert t == {"state": "following", "version": 4, "x": 1.235, "y": -0.5, "angle": 1.571, "std": 0.25,
                 "ok": True, "source": "fused", "target": None, "cte": -0.123}
    json.dumps(t, allow_nan=False)
    t = path_telemetry({"path/state": "warp", "loc/source": 3, "loc/x": 1.0, "path/target_x": 1, "path/target_y": 2})
    assert t["state"] is None and t["source"] is None
    assert t["x"] is None and t["y"] is None  # half a position is no position
    assert t["target"] == [1.0, 2.0]


# -- the slot between the loop and the server ------------------------------------------------------
def test_the_slot_changes_only_with_the_version():
    slot = PathSlot()
    assert slot.message() == (None, 0)
    a = np.zeros((2, 2), np.float32)
    slot.put(a, 1)
    slot.put(a, 1)
    slot.put(a.copy(), 1)  # the same version: the same path, whatever the object
    assert slot.changes == 1
    first, changes = slot.message()
    assert first["version"] == 1 and changes == 1
    assert slot.message()[0] is first  # encoded once per change
    slot.put(np.ones((3, 2), np.float32), 2)
    assert slot.changes == 2 and slot.message()[0]["points"] == 3


def test_without_a_version_a_new_array_is_a_change():
    slot = PathSlot()
    a = np.zeros((2, 2), np.float32)
    slot.put(a, None)
    slot.put(a, None)
    assert slot.changes == 1
    slot.put(a.copy(), None)
    assert slot.changes == 2
    slot.put(None, None)  # nothing reported: nothing changes
    assert slot.changes == 2


def test_the_sender_sends_each_browser_the_newest_path_at_most_twice_a_second():
    slot = PathSlot()
    sender = PathSender(slot, send_hz=2.0)
    assert sender.for_new("a") is None and sender.due(["a"], 0.0) == (None, [])  # no path yet
    slot.put(np.zeros((2, 2), np.float32), 1)
    path, sids = sender.due(["a"], 10.0)
    assert path["version"] == 1 and sids == ["a"]
    assert sender.due(["a"], 10.6) == (None, [])  # a has it
    assert sender.for_new("b")["version"] == 1 and sender.due(["a", "b"], 10.7) == (None, [])
    for version in (2, 3, 4):  # a path growing while it is recorded
        slot.put(np.zeros((version, 2), np.float32), version)
    path, sids = sender.due(["a", "b"], 11.0)
    assert path["version"] == 4 and sids == ["a", "b"]  # the newest, to both
    slot.put(np.zeros((5, 2), np.float32), 5)
    assert sender.due(["a", "b"], 11.4) == (None, [])  # within half a second of the last
    path, sids = sender.due(["a", "b"], 11.5)
    assert path["version"] == 5 and sids == ["a", "b"]
    sender.forget("b")
    slot.put(np.zeros((6, 2), np.float32), 6)
    assert sender.due(["a"], 12.0)[1] == ["a"]
    assert sender.sent == 7  # a: versions 1, 4, 5, 6; b: 1 (on connect), 4, 5


# -- the server: the path event and the buttons ----------------------------------------------------
PATH_A = np.array([[0, 0], [1, 0], [2, 1]], np.float32)
POSE = {"loc/x": 0.5, "loc/y": 0.1, "loc/angle": 0.2, "loc/std": 0.3, "loc/ok": True, "loc/source": "odometry",
        "path/state": "ready", "path/cte": 0.05}


def _recorder(client):
    paths: list[dict] = []
    client.sio.on("path", paths.append)
    return paths


async def _until(cond, seconds=5.0):
    end = asyncio.get_running_loop().time() + scaled(seconds)
    while not cond():
        if asyncio.get_running_loop().time() > end:
            raise AssertionError("condition not met in time")
        await asyncio.sleep(0.01)


def test_the_path_is_sent_on_connect_and_again_only_when_its_version_changes(web, loop_side, client_cls, arun):
    async def main():
        loop_side.step(**POSE, **{"path/xy": PATH_A, "path/version": 1})
        c = client_cls()
        paths = _recorder(c)
        hello = await c.connect(web.port)
        await _until(lambda: len(paths) == 1)
        assert paths[0] == {"version": 1, "xy": [0.0, 0.0, 1.0, 0.0, 2.0, 1.0], "points": 3, "step": 1}
        assert hello["state"]["telemetry"]["path"]["state"] == "ready"
        for _ in range(30):  # the same path every loop, for longer than a path send period
            loop_side.step()
            await asyncio.sleep(0.02)
        n_states = len(c.states)
        await _until(lambda: len(c.states) > n_states + 3)
        assert len(paths) == 1  # unchanged: not sent again
        path_b = np.array([[0, 0], [0, 3]], np.float32)
        loop_side.step(**{"path/xy": path_b, "path/version": 2, "path/state": "recording"})
        await _until(lambda: len(paths) == 2)
        assert paths[1]["version"] == 2 and paths[1]["xy"] == [0.0, 0.0, 0.0, 3.0]
        state = c.states[-1]["telemetry"]["path"]
        assert state["x"] == 0.5 and state["angle"] == 0.2 and state["version"] == 2
        for _ in range(10):
            loop_side.step()
            await asyncio.sleep(0.02)
        await _until(lambda: len(c.states) > n_states + 10)
        assert len(paths) == 2
        assert web.server.paths.sent == 2
        await c.close()

    arun(main())


def test_a_path_button_is_one_command_for_one_loop_and_only_the_driver_may_press(web, loop_side, client_cls, arun):
    async def main():
        loop_side.step(**POSE)
        driver, viewer = client_cls(), client_cls()
        await driver.connect(web.port)
        await viewer.connect(web.port)
        assert loop_side.step()["web/path_command"] is None
        assert await driver.call("path_command", {"command": "save"}) == {"ok": True}
        assert await driver.call("path_command", {"command": "clear"}) == {"ok": True}
        outs = [loop_side.step()["web/path_command"] for _ in range(4)]
        assert outs == ["save", "clear", None, None]  # one per loop, each once, in order
        res = await viewer.call("path_command", {"command": "record"})
        assert res["ok"] is False and "Take control" in res["error"]
        res = await driver.call("path_command", {"command": "follow"})
        assert res["ok"] is False and "reset_origin" in res["error"]
        assert [loop_side.step()["web/path_command"] for _ in range(3)] == [None] * 3
        # the emergency stop does not refuse them: none moves the car
        assert await viewer.call("estop", {"on": True}) == {"ok": True}
        assert await driver.call("path_command", {"command": "reset_origin"}) == {"ok": True}
        assert loop_side.step()["web/path_command"] == "reset_origin"
        await driver.close()
        await viewer.close()

    arun(main())


def test_a_car_without_path_follow_refuses_the_buttons(web, loop_side, client_cls, arun):
    async def main():
        c = client_cls()
        await c.connect(web.port)
        loop_side.step()
        res = await c.call("path_command", {"command": "record"})
        assert res["ok"] is False and "path_follow" in res["error"]
        assert loop_side.step()["web/path_command"] is None
        await _until(lambda: len(c.states) > 0)
        assert c.states[-1]["telemetry"]["path"] is None
        await c.close()

    arun(main())


def test_the_controller_reads_every_key_the_path_view_draws():
    from parts.web.controller import WebController

    assert set(PATH_INPUTS) <= set(WebController.INPUTS)
    assert set(PATH_INPUTS) <= set(WebController.OPTIONAL_INPUTS)
