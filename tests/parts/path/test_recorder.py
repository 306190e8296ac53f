"""The path part (record, save, load, clear) and the buttons that command it."""

from __future__ import annotations

import logging
import os
import threading
import time

import numpy as np
import pytest

from parts.controllers.gamepad import Gamepad
from parts.controllers.layouts import load_layout
from parts.controllers.linux_js import LinuxJoystick
from parts.controllers.logic import GamepadSettings
from parts.path.buttons import PathButtonError, PathCommands, resolve_button
from parts.path.pathfile import load_path
from parts.path.recorder import PathRecorder
from vehicle.config import Config
from vehicle.part_check import check_part


def test_records_a_point_every_min_dist_with_the_speed_and_saves_and_loads(tmp_path, caplog):
    rec = PathRecorder(tmp_path / "p.csv", min_dist=0.2)
    xy, speed, version, recording = rec.run(0.0, 0.0, True, 1.0, None)
    assert len(xy) == 0 and not recording
    rec.run(0.0, 0.0, True, 1.0, "record")
    for x in np.arange(0.05, 1.01, 0.05):  # 1 m in 5 cm steps
        xy, speed, version, recording = rec.run(float(x), 0.0, True, 1.5, None)
    assert recording
    np.testing.assert_allclose(xy[:, 0], [0.0, 0.2, 0.4, 0.6, 0.8, 1.0], atol=1e-6)
    assert speed[0] == 1.0 and speed[-1] == 1.5
    rec.run(1.2, 0.0, False, 1.0, None)  # a pose not trusted is not recorded
    xy2, _, version2, recording = rec.run(1.0, 0.0, True, 1.0, "record")
    assert not recording and len(xy2) == 6 and version2 == version
    rec.run(1.0, 0.0, True, 1.0, "save")
    assert len(load_path(tmp_path / "p.csv")) == 6
    xy3, _, version3, _ = rec.run(1.0, 0.0, True, 1.0, "clear")
    assert len(xy3) == 0 and version3 == version + 1 and xy3 is not xy2  # a new array for the view
    rec.run(1.0, 0.0, True, 1.0, "load")
    xy4 = _loaded(rec, version3)
    np.testing.assert_allclose(xy4, xy2, atol=1e-4)
    assert PathRecorder(tmp_path / "p.csv").path.length == pytest.approx(1.0, abs=1e-3)  # loaded at start


def test_failed_load_and_save_keep_the_path_and_the_car_driving(tmp_path, caplog):
    bad = tmp_path / "bad.csv"
    bad.write_text("x,y,speed\n0,0,1\n1,oops,1\n")
    rec = PathRecorder(bad)
    assert len(rec.path) == 0
    assert "bad.csv, line 3: not a number" in caplog.text
    rec.run(0.0, 0.0, True, 1.0, "record")
    rec.run(0.5, 0.0, True, 1.0, None)
    rec.run(0.5, 0.0, True, 1.0, "record")
    with caplog.at_level(logging.ERROR):
        xy, *_ = rec.run(0.5, 0.0, True, 1.0, "load")
    assert len(xy) == 2  # unchanged
    rec.filename = tmp_path / "no" / "such" / "dir" / "file.csv"
    (tmp_path / "no").write_text("a file, not a folder")
    assert rec.save() is False and "path not saved" in caplog.text


def _loaded(rec: PathRecorder, version: int) -> np.ndarray:
    """Run the part until the path read by its loader thread is swapped in; the new path/xy."""
    for _ in range(2000):
        xy, _, v, _ = rec.run(1.0, 0.0, True, 1.0, None)
        if v != version:
            return xy
        time.sleep(0.005)
    raise AssertionError("the path was never swapped in")


def test_a_path_is_loaded_off_the_loop_and_a_bad_one_never_stops_the_car(tmp_path, monkeypatch, caplog):
    """Hardening item 13: "load" read the file in run(): a 43 MB file held the loop for seconds and
    a field over csv's limit raised out of run() (the car stopped). Now the loop goes on while a
    thread reads, and a bad file is one logged line."""
    from parts.path import recorder as recorder_module

    good = tmp_path / "p.csv"
    good.write_text("x,y,speed\n0,0,1\n1,0,1\n")
    rec = PathRecorder(good, load=False)
    gate, real = threading.Event(), recorder_module.load_path
    monkeypatch.setattr(recorder_module, "load_path", lambda f: (gate.wait(10), real(f))[1])
    xy, _, version, _ = rec.run(0.0, 0.0, True, 1.0, "load")  # returns while the file is being read
    assert len(xy) == 0 and version == 0
    assert rec.run(0.0, 0.0, True, 1.0, None)[2] == 0  # the loop goes on: still the old path
    gate.set()
    np.testing.assert_allclose(_loaded(rec, 0), [[0, 0], [1, 0]])
    monkeypatch.setattr(recorder_module, "load_path", real)
    good.write_text("x,y,speed\n0,0,1\n1," + "9" * 140_000 + ",1\n")
    with caplog.at_level(logging.ERROR):
        rec.run(0.0, 0.0, True, 1.0, "load")
        for _ in range(2000):
            if "path not loaded" in caplog.text:
                break
            rec.run(0.0, 0.0, True, 1.0, None)
            time.sleep(0.005)
    assert "p.csv, line 3: not a CSV line (field larger than field limit" in caplog.text
    assert len(rec.run(0.0, 0.0, True, 1.0, None)[0]) == 2  # unchanged
    caplog.clear()
    assert len(PathRecorder(good).path) == 0  # present at start: logged, no traceback
    assert "path not loaded" in caplog.text
    rec.shutdown()


def test_recorder_keeps_the_part_contract(tmp_path):
    check_part(PathRecorder(tmp_path / "p.csv"))
    check_part(PathRecorder(tmp_path / "p.csv"), [0.0, 0.0, True, 1.0, "record"])


def test_button_names_translate_to_the_same_position_on_other_pads():
    assert resolve_button("square", {"a", "b", "x", "y"}, "SAVE_PATH_BTN") == "x"
    assert resolve_button("circle", {"south", "east", "west", "north"}, "X") == "east"
    assert resolve_button("dpad_up", {"dpad_up", "a"}, "RESET_ORIGIN_BTN") == "dpad_up"
    with pytest.raises(PathButtonError, match="SAVE_PATH_BTN = 'l5': this gamepad has no such button; use one of a"):
        resolve_button("l5", {"a", "b"}, "SAVE_PATH_BTN")


@pytest.fixture
def xbox_pad():
    layout = load_layout("xbox")
    r, w = os.pipe()
    pad = Gamepad(LinuxJoystick(fd=r, fallback_caps=layout.caps), layout, GamepadSettings())
    pad.open()
    yield pad, w, layout
    os.close(w)
    pad.close()


def test_every_press_of_a_path_button_is_one_command_and_the_page_follows(xbox_pad, stream_for):
    pad, w, layout = xbox_pad
    stream = stream_for(layout)
    os.write(w, stream.init_burst())
    pad.run()
    cmds = PathCommands.from_config(Config.defaults(), pad)
    assert cmds.buttons == {"record": "b", "save": "x", "load": "dpad_left", "clear": "dpad_down",
                            "reset_origin": "dpad_up"}
    os.write(w, stream.press("b") + stream.press("x") + stream.press("x"))  # three presses within one loop
    pad.run()
    assert [cmds.run(None) for _ in range(3)] == ["record", "save", "save"]
    assert cmds.run("load") == "load"  # the page's button
    assert cmds.run(None) is None


def test_path_commands_keep_the_part_contract():
    check_part(PathCommands())
    check_part(PathCommands(), ["save"])
