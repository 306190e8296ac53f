"""The `basic` car end to end on fakes: mock camera, recorded gamepad, mock PCA9685, real tub.

A recorded PS4 session (raw js_event bytes, replayed at its recorded pace) drives the car: throttle
and steering for about a second, then the stick is released and the recording ends (the pad is
lost). The car must record while the throttle is on, write camera frames with their capture
times, and leave the throttle ESC at neutral.
"""

from __future__ import annotations

import importlib.util
import sys

import pytest
from fixtures.gamepads import pack_event

from parts.controllers.events import AXIS, AXIS_MAX
from parts.controllers.layouts import load_layout

pytestmark = pytest.mark.slow


def recorded_session(path) -> None:
    """INIT burst at t=0, then right stick up (half) + left stick right (half) at 0.2 s, release at 1.2 s."""
    layout = load_layout("ps4")
    caps = layout.caps
    data = b"".join(pack_event(1, i, 0, init=True) for i in range(len(caps.button_codes)))
    for i, code in enumerate(caps.axis_codes):
        data += pack_event(AXIS, i, -AXIS_MAX if code in (2, 5) else 0, init=True)
    steer = caps.axis_codes.index(layout.axes["left_stick_x"].code)
    throttle = caps.axis_codes.index(layout.axes["right_stick_y"].code)
    data += pack_event(AXIS, steer, 16384, time_ms=200) + pack_event(AXIS, throttle, -AXIS_MAX, time_ms=200)
    data += pack_event(AXIS, throttle, 0, time_ms=1200) + pack_event(AXIS, steer, 0, time_ms=1200)
    path.write_bytes(data)


def load_manage(car):
    spec = importlib.util.spec_from_file_location("basic_manage", car / "manage.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_basic_car_drives_records_and_stops_on_fakes(tmp_path):
    from vehicle.app.commands.createcar import create_car, templates

    if "basic" not in templates():
        pytest.skip("the basic template is not there yet")
    car = tmp_path / "car"
    create_car(car, "basic")
    recorded_session(car / "pad.js")
    (car / "myconfig.py").write_text(
        'CAMERA_TYPE = "MOCK"\n'
        'DRIVE_TRAIN_TYPE = "MOCK"\n'
        'PCA9685_MOCK_TRACE = "pca.trace"\n'
        'ESC_ARM_TIME_S = 0.1\n'
        'USE_WEB_CONTROLLER = False\n'
        'USE_JOYSTICK_AS_DEFAULT = True\n'
        'CONTROLLER_TYPE = "ps4"\n'
        'JOYSTICK_DEVICE_FILE = "pad.js"\n'
        'JOYSTICK_MAX_THROTTLE = 0.4\n'
        'DRIVE_LOOP_HZ = 20\n')
    manage = load_manage(car)
    assert manage.main(["drive", "--max-loops", "36"]) == 0
    sys.modules.pop("basic_manage", None)

    # the tub: records only while the throttle was on, with the gamepad's commands and the frames
    from parts.tub.reader import load_records

    records = load_records([car / "data"])
    assert 10 <= len(records) <= 24  # ~1 s of throttle at 20 Hz (the pad arms and the loop starts)
    for rec in records:
        assert rec.data["user/throttle"] == pytest.approx(0.4)
        assert rec.data["user/angle"] == pytest.approx(0.5, abs=1e-3)
        assert rec.data["user/mode"] == "user"
        assert rec.image().shape == (120, 160, 3)
        assert rec.data["_timestamp_ms"] > 1.6e12  # capture time, time.time() in ms
    stamps = [r.data["_timestamp_ms"] for r in records]
    assert stamps == sorted(stamps) and len(set(stamps)) > len(stamps) // 2

    # the drivetrain: throttle went forward, and the last throttle pulse is neutral (370 ticks)
    lines = (car / "pca.trace").read_text().split()
    trace = [lines[i:i + 3] for i in range(0, len(lines), 3)]
    throttle_ticks = [t[2] for t in trace if t[1] == "0"]
    assert any(tick.isdigit() and int(tick) > 400 for tick in throttle_ticks)
    assert throttle_ticks[-1] in ("370", "off")
