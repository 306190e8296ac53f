"""add_controller in a real Vehicle: the page drives the car's memory; gamepad arbitration wiring."""

from __future__ import annotations

import asyncio
import threading

import numpy as np
import pytest

from vehicle import Vehicle
from vehicle.app.assembly.controller import add_controller
from vehicle.config import Config
from vehicle.errors import UserError


class FakeCamera:
    """Frames with a moving bar, one per loop."""

    def __init__(self) -> None:
        self.i = 0

    def run(self) -> np.ndarray:
        self.i += 1
        img = np.full((120, 160, 3), 40, np.uint8)
        img[:, self.i % 160] = 255
        return img


def build(tmp_path, **overrides):
    cfg = Config.defaults(CAR_PATH=str(tmp_path), WEB_CONTROL_PORT=0, **overrides)
    V = Vehicle()
    V.add(FakeCamera(), outputs=["cam/image_array"])
    web = add_controller(V, cfg)
    from vehicle.app.assembly.drive import add_drive_mode

    add_drive_mode(V, cfg)
    return V, web


def test_web_only_wiring(tmp_path):
    V, web = build(tmp_path)
    entry = next(e for e in V.parts if e.part is web)
    assert entry.threaded and list(entry.outputs) == list(web.OUTPUTS)
    V.check_wiring()  # every telemetry input is produced or declared optional (it reads None)
    assert {"tub/num_records", "enc/speed"} <= entry.optional and "enc/speed" not in V.mem


def test_no_controller_is_a_user_error(tmp_path):
    cfg = Config.defaults(CAR_PATH=str(tmp_path), USE_WEB_CONTROLLER=False)
    with pytest.raises(UserError, match="USE_WEB_CONTROLLER"):
        add_controller(Vehicle(), cfg)


def test_web_and_gamepad_are_arbitrated(tmp_path):
    V, web = build(tmp_path, USE_JOYSTICK_AS_DEFAULT=True, CONTROLLER_TYPE="generic",
                   JOYSTICK_DEVICE_FILE=str(tmp_path / "no-such-js0"), CONTROLLER_PRIORITY="latest")
    names = [type(e.part).__name__ for e in V.parts]
    assert names[1:5] == ["WebController", "Gamepad", "GamepadStatus", "ControllerArbiter"]
    by_name = {type(e.part).__name__: e for e in V.parts}
    assert by_name["WebController"].outputs[:2] == ("web/angle", "web/throttle")
    assert by_name["Gamepad"].outputs[:2] == ("js/angle", "js/throttle")
    assert by_name["ControllerArbiter"].outputs[:2] == ("user/angle", "user/throttle")
    assert by_name["ControllerArbiter"].part.priority == "latest"
    V.check_wiring()


def drive_vehicle(V, loops: int):
    errors: list[BaseException] = []

    def body():
        try:
            V.start(rate_hz=50, max_loop_count=loops)
        except BaseException as exc:  # reported by the test
            errors.append(exc)

    thread = threading.Thread(target=body)
    thread.start()
    return thread, errors


@pytest.mark.parametrize("with_gamepad", [False, True], ids=["web", "web+gamepad"])
def test_page_drives_a_real_vehicle(tmp_path, client_cls, arun, with_gamepad):
    extra = dict(USE_JOYSTICK_AS_DEFAULT=True, CONTROLLER_TYPE="generic",
                 JOYSTICK_DEVICE_FILE=str(tmp_path / "no-such-js0")) if with_gamepad else {}
    V, web = build(tmp_path, WEB_MAX_THROTTLE=1.0, **extra)
    thread, errors = drive_vehicle(V, loops=100_000)

    async def main():
        while web.port == 0:  # the Vehicle starts the server in its thread
            await asyncio.sleep(0.01)
        c = client_cls()
        await c.connect(web.port)
        await c.call("set", {"recording": True})
        # the server starts before the loop's first pass ("throttle" is unset until then), and the
        # loop writes its keys part after part while we read: wait until all three are there
        while V.mem[["throttle", "angle", "recording"]] != [pytest.approx(0.7), pytest.approx(-0.3), True]:
            await c.call("drive", {"angle": -0.3, "throttle": 0.7})
            await asyncio.sleep(0.02)
        while len(c.frames) < 3:
            await asyncio.sleep(0.02)
        # the page's state messages carry the loop's health, written by the Vehicle
        while not any(s["telemetry"]["loop_rate_hz"] for s in c.states):
            await c.call("drive", {"angle": -0.3, "throttle": 0.7})
            await asyncio.sleep(0.05)
        await c.close()  # the driver leaves: the car stops
        while V.mem["throttle"] != 0.0:
            await asyncio.sleep(0.01)

    try:
        arun(main())
    finally:
        V.stop()
        thread.join(10)
    assert not errors, errors
    assert not web.running


def test_sensor_freshness_and_obstacle_stop_reach_the_page(tmp_path):
    from parts.web.controller import WebController

    web = WebController(port=0)
    try:
        values = dict.fromkeys(WebController.INPUTS)
        values.update({"enc/ok": True, "lidar/ok": False, "obstacle/stop": True, "obstacle/distance": 0.42,
                       "enc/speed": None})
        web.run(*[values[k] for k in WebController.INPUTS])
        tel = web.state.snapshot()["telemetry"]
        assert tel["sensors"] == {"enc": True, "lidar": False}  # no IMU or GPS on this car: not listed
        assert tel["obstacle_stop"] is True and tel["obstacle_distance"] == 0.42
        assert tel["speed"] is None  # a stale encoder: no speed, the page refuses a speed limit
    finally:
        web.shutdown()
