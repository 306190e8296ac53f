"""Correction mode: the pilot drives the simulated car, the gamepad's stick overrides while moved,
and only the override frames are recorded, labelled with the person's steering."""

from __future__ import annotations

import pytest

from parts.controllers.gamepad import Gamepad
from parts.controllers.layouts import load_layout
from parts.drive.correction import Correction
from parts.drive.modes import PilotCondition
from parts.sim.simulator import SimCar
from parts.tub.reader import load_records
from vehicle import Vehicle
from vehicle.app.assembly.drive import add_drive_mode, add_recording_rules
from vehicle.app.assembly.tub import add_tub_writer
from vehicle.clock import SimulatedClock
from vehicle.part_check import check_part

MOVE_AT, RELEASE_AT = 20, 31  # loops: the stick is pushed half right at loop 20 and let go at loop 31


class Pad:
    """The fake gamepad as the car's controller part: a PS4 js_event stream through a pipe."""

    OUTPUTS = Gamepad.OUTPUTS

    def __init__(self, pipe_pad):
        self.pad = pipe_pad(load_layout("ps4"), initial_mode="local")
        self.out = self.pad.send(self.pad.stream.init_burst())
        self.loop = 0

    def run(self):
        self.loop += 1
        if self.loop == MOVE_AT:
            self.out = self.pad.send(self.pad.stream.axis("left_stick_x", 16384))
        elif self.loop == RELEASE_AT:
            self.out = self.pad.send(self.pad.stream.axis("left_stick_x", 0))
        else:
            self.out = self.pad.logic.output()
        return tuple(self.out)


class Pilot:
    INPUTS = ("cam/image_array",)
    OUTPUTS = ("pilot/angle", "pilot/throttle")

    def run(self, image):
        return -0.1, 0.3


class Actuator:
    INPUTS = ("angle", "throttle")

    def __init__(self):
        self.commands = []

    def run(self, angle, throttle):
        self.commands.append((angle, throttle))

    def neutral(self):
        self.commands.append(("neutral", 0.0))


def test_override_frames_only_are_recorded_with_the_persons_steering(cfg, tmp_path, pipe_pad):
    c = cfg.replace(CORRECTION_MODE=True, CAR_PATH=str(tmp_path), DATA_PATH=str(tmp_path / "tub"),
                    AUTO_CREATE_NEW_TUB=False, AUTO_RECORD_ON_THROTTLE=True, RECORD_DURING_AI=False)
    V = Vehicle(clock=SimulatedClock())
    V.add(SimCar.from_config(c, seeds=[3], realtime=False))
    V.add(Pad(pipe_pad))
    V.add(PilotCondition())
    V.add(Pilot(), run_condition="run_pilot")
    add_drive_mode(V, c)
    actuator = Actuator()
    V.add(actuator)
    add_recording_rules(V, c)
    writer = add_tub_writer(V, c)
    V.start(rate_hz=20, max_loop_count=45, log_summary=False)

    assert set(writer.inputs) >= {"user/correction", "pilot/angle", "pilot/throttle"}
    records = [r.data for r in load_records([tmp_path / "tub"])]
    assert len(records) == RELEASE_AT - MOVE_AT  # the frames the stick was off centre, no other
    for rec in records:
        assert rec["user/correction"] is True and rec["user/mode"] == "local"
        assert rec["user/angle"] == pytest.approx(0.5, abs=0.01)  # the person's steering is the label
        assert rec["pilot/angle"] == -0.1 and rec["pilot/throttle"] == 0.3
        assert rec["user/throttle"] == pytest.approx(0.3)  # the throttle stick was left alone: the pilot's
    executed = actuator.commands
    assert executed[MOVE_AT - 1][0] == pytest.approx(0.5, abs=0.01)  # the car obeyed the person
    assert executed[0] == (-0.1, 0.3) and executed[-2] == (-0.1, 0.3)  # and the pilot otherwise
    assert executed[-1] == ("neutral", 0.0)


def test_correction_part_contract_and_modes():
    check_part(Correction())
    part = Correction(deadzone=0.05)
    # user mode: untouched, nothing marked
    assert part.run("user", 0.4, 0.2, 0.4, 0.2, True) == (0.4, 0.2, 0.4, 0.2, False, True)
    # local: throttle override, the pilot keeps steering; the labels are what the car did
    assert part.run("local", 0.0, 0.6, -0.2, 0.3) == (-0.2, 0.6, -0.2, 0.6, True, True)
    # local_angle: the throttle is the person's anyway and never counts as an override
    assert part.run("local_angle", 0.01, 0.5, -0.2, 0.5) == (-0.2, 0.5, -0.2, 0.5, False, False)
    # an emergency stop keeps the throttle at 0 even when the person pushes it
    assert part.run("local", 0.0, 0.6, 0.0, 0.0, None, True)[1] == 0.0
    with pytest.raises(ValueError, match="CORRECTION_DEADZONE"):
        Correction(deadzone=1.0)
