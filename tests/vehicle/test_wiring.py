"""Declared inputs and outputs, optional inputs, feedback, and the order check of the wiring."""

from __future__ import annotations

from typing import ClassVar

import pytest

from vehicle import ThreadedPart, Vehicle
from vehicle.clock import SimulatedClock
from vehicle.errors import WiringError
from vehicle.keys import is_valid_key, rename


class Source:
    OUTPUTS: ClassVar[tuple[str, ...]] = ("user/angle",)

    def __init__(self) -> None:
        self.n = 0

    def run(self) -> float:
        self.n += 1
        return float(self.n)


class Follower:
    """Reads the angle; the pilot's value may be absent."""

    INPUTS: ClassVar[tuple[str, ...]] = ("user/angle", "pilot/angle")
    OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("pilot/angle",)
    OUTPUTS: ClassVar[tuple[str, ...]] = ("angle",)

    def __init__(self) -> None:
        self.seen: list[tuple[object, object]] = []

    def run(self, user: object, pilot: object) -> object:
        self.seen.append((user, pilot))
        return user


def test_add_uses_the_part_declarations():
    V = Vehicle(clock=SimulatedClock())
    V.add(Source())
    follower = Follower()
    V.add(follower)
    assert V.parts[1].inputs == ("user/angle", "pilot/angle") and V.parts[1].outputs == ("angle",)
    assert V.parts[1].optional == {"pilot/angle"}
    V.start(rate_hz=20, max_loop_count=2)
    assert follower.seen == [(1.0, None), (2.0, None)]
    assert V.mem["angle"] == 2.0 and "pilot/angle" not in V.mem


def test_reading_before_the_producer_is_an_error_unless_declared_feedback():
    V = Vehicle(clock=SimulatedClock())
    V.add(Follower())  # added before the part producing user/angle: a one-loop lag
    V.add(Source())
    with pytest.raises(WiringError, match=r"'Follower' input 'user/angle' is read before part 'Source' "
                                          r"produces it .*feedback=\['user/angle'\]"):
        V.check_wiring()

    V = Vehicle(clock=SimulatedClock())
    follower = Follower()
    V.add(follower, feedback=["user/angle"])
    V.add(Source())
    V.start(rate_hz=20, max_loop_count=3)
    assert [user for user, _ in follower.seen] == [None, 1.0, 2.0]  # the previous loop's value


def test_an_input_nobody_produces_must_be_optional():
    V = Vehicle(clock=SimulatedClock())
    V.add(Follower(), optional_inputs=[])
    with pytest.raises(WiringError, match="'user/angle' is produced by no part and not seeded"):
        V.check_wiring()
    V = Vehicle(clock=SimulatedClock())
    V.add(Source())
    V.add(Follower(), optional_inputs=[])
    with pytest.raises(WiringError, match="'pilot/angle' is produced by no part .*optional_inputs"):
        V.check_wiring()


def test_seeded_keys_count_as_produced_and_feedback_must_be_an_input():
    V = Vehicle(clock=SimulatedClock())
    V.mem["user/angle"] = 0.5
    V.add(Follower())
    V.check_wiring()
    with pytest.raises(ValueError, match=r"feedback \['throttle'\] are not among its inputs"):
        V.add(Follower(), feedback=["throttle"])


def test_declared_optional_keys_follow_renamed_inputs():
    V = Vehicle(clock=SimulatedClock())
    V.add(Source())
    V.add(Follower(), inputs=["user/angle", "js/angle"])  # same order: pilot/angle is now js/angle
    assert V.parts[1].optional == {"js/angle"}
    V.check_wiring()
    V.add(Follower(), inputs=["user/angle"])  # another shape: the declaration does not apply
    assert V.parts[2].optional == frozenset()


def test_a_declaration_with_a_key_outside_its_inputs_is_refused():
    class Typo(Follower):
        OPTIONAL_INPUTS: ClassVar[tuple[str, ...]] = ("pilot/angel",)

    with pytest.raises(ValueError, match=r"'Typo': its OPTIONAL_INPUTS \['pilot/angel'\] are not among its INPUTS"):
        Vehicle().add(Typo())


def test_a_part_may_read_its_own_last_output_and_each_key_is_reported_once():
    V = Vehicle(clock=SimulatedClock())
    seen = []
    V.add(lambda last: seen.append(last) or (last or 0) + 1, inputs=["count/n"], outputs=["count/n"])
    V.start(rate_hz=20, max_loop_count=3)
    assert seen == [None, 1, 2]
    V = Vehicle(clock=SimulatedClock())
    V.add(Follower(), inputs=["user/flag", "pilot/angle"], run_condition="user/flag")
    with pytest.raises(WiringError) as err:
        V.check_wiring()
    assert str(err.value).count("'user/flag'") == 1 and "input 'user/flag'" in str(err.value)


def test_a_run_condition_produced_later_is_a_lag_too():
    V = Vehicle(clock=SimulatedClock())
    V.add(Source(), run_condition="recording")
    V.add(lambda: True, outputs=["recording"])
    with pytest.raises(WiringError, match="'Source' run_condition 'recording' is read before part 'lambda'"):
        V.check_wiring()


def test_an_undeclared_donkey_part_read_before_its_producer_is_a_warning(caplog):
    class DonkeyWeb:  # DonkeyCar's LocalWebController shows tub/num_records written later
        def run(self, num_records):
            return 0.0

    V = Vehicle(clock=SimulatedClock())
    V.add(DonkeyWeb(), inputs=["tub/num_records"], outputs=["user/angle"])
    V.add(lambda: 3, outputs=["tub/num_records"])
    V.check_wiring()
    assert "'DonkeyWeb' input 'tub/num_records' is read before part 'lambda'" in caplog.text


def test_declarations_are_read_statically_and_threaded_parts_are_checked():
    from unittest import mock

    V = Vehicle(clock=SimulatedClock())
    V.add(mock.MagicMock(), outputs=["user/angle"])  # a mock answers every attribute: no declaration
    assert V.parts[0].inputs == () and V.parts[0].outputs == ("user/angle",)

    class Cam(ThreadedPart):
        OUTPUTS: ClassVar[tuple[str, ...]] = ("cam/image_array",)
        INPUTS: ClassVar[tuple[str, ...]] = ("user/mode",)

        def poll(self):
            return ThreadedPart.NOTHING

    V.add(Cam(), threaded=True)
    with pytest.raises(WiringError, match="'Cam' input 'user/mode' is produced by no part"):
        V.check_wiring()


def test_produces_and_find():
    V = Vehicle()
    assert V.produces("loop/count") and not V.produces("user/angle")
    source = Source()
    V.add(source)
    assert V.produces("user/angle") and V.find(Source) == [source] and V.find(Follower) == []


def test_rename_and_key_rules():
    assert rename(("user/angle", "recording"), {"recording": "js/recording"}) == ("user/angle", "js/recording")
    with pytest.raises(ValueError, match=r"cannot rename \['user/angel'\]"):
        rename(("user/angle",), {"user/angel": "js/angle"})
    assert is_valid_key("angle") and is_valid_key("sim/cte") and is_valid_key("behavior/one_hot_state_array")
    assert not is_valid_key("Angle") and not is_valid_key("steering") and not is_valid_key("sim/")
