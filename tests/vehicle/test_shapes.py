"""Declared shapes: the wiring check refuses, before the first loop, a part that expects another
shape than its producer makes."""

from __future__ import annotations

import pytest

from vehicle import Vehicle
from vehicle.errors import WiringError
from vehicle.shapes import fits, show


class Cam:
    OUTPUTS = ("cam/image_array",)

    def __init__(self, h, w, name="Cam"):
        self.OUTPUT_SHAPES = {"cam/image_array": (h, w, 3)}
        self.name = name

    def run(self):
        return None


class Model:
    INPUTS = ("cam/image_array",)
    OUTPUTS = ("pilot/angle",)
    INPUT_SHAPES = {"cam/image_array": (120, 160, 3)}

    def __init__(self, name="Model"):
        self.name = name

    def run(self, image):
        return 0.0


def test_fits_and_show():
    assert fits((120, 160, 3), (120, 160, 3)) and fits((None, 160, 3), (64, 160, 3))
    assert not fits((120, 160, 3), (120, 160)) and not fits((120, 160, 3), (240, 320, 3))
    assert show((None, 160, 3)) == "?x160x3"


def test_a_model_of_another_frame_size_is_refused_before_the_first_loop():
    V = Vehicle()
    V.add(Cam(240, 320, "camera"))
    V.add(Model("pilot"))
    with pytest.raises(WiringError, match=r"part 'pilot' expects cam/image_array of 120x160x3 but part 'camera' "
                                          r"makes 240x320x3"):
        V.start(max_loop_count=1)
    ok = Vehicle()
    ok.add(Cam(120, 160))
    ok.add(Model())
    ok.check_wiring()


def test_declarations_follow_the_wiring_and_the_last_producer_before_the_reader():
    V = Vehicle()
    V.add(Cam(240, 320, "raw"), outputs=["cam/raw"])
    V.add(Cam(120, 160, "camera"))  # the frames the model reads
    V.add(Model("pilot"))
    V.add(Model("raw pilot"), inputs=["cam/raw"])  # the renamed input keeps its expected shape
    with pytest.raises(WiringError) as info:
        V.check_wiring()
    assert "'pilot'" not in str(info.value).split(" expects")[0]
    assert "part 'raw pilot' expects cam/raw of 120x160x3 but part 'raw' makes 240x320x3" in str(info.value)


def test_the_pilot_part_declares_the_frames_its_model_was_trained_on(make_model_file, tmp_path):
    from parts.cameras.base import Camera
    from parts.cameras.mock import MockSource
    from parts.pilots import load_pilot

    pilot = load_pilot(make_model_file("linear"))
    assert pilot.INPUT_SHAPES == {"cam/image_array": (120, 160, 3)}
    V = Vehicle()
    V.add(Camera(MockSource(320, 240), 320, 240), threaded=True)
    V.add(pilot)  # by hand, without add_pilot's own check
    with pytest.raises(WiringError, match="expects cam/image_array of 120x160x3 but part 'Camera\\(mock\\)' makes "
                                          "240x320x3"):
        V.start(max_loop_count=1)
